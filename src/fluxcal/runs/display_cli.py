"""What a command shows on stderr while it runs: progress bar, spinner, compilation notice.

A command module (its numerical and display libraries load when a command runs, not
when the command line is built: tests/test_cli_startup.py).

One mechanism for every mission and route: a command wraps its run in
`progress_display` and hands the yielded callback to the run
(`fluxcal.runs.driver.run`'s ``progress(description, done, total)``); a step without
steps of its own gets a `status_display` spinner; `compilation_notice` says once that
numba compiles the numerical kernels (a cold cache: the first run after an install or
an upgrade).  Off a terminal (logs, pipes) and under ``fluxcal -q`` no bar or spinner is
shown; the notice is shown but under ``-q``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import typer

from fluxcal.cli_help import progress_wanted, quiet_requested

#: The notice a cold numba cache prints (once per command).  The wall time is what a
#: cold ``fluxcal demo`` took more than a warm one on a 2-core machine (CHANGELOG,
#: issue 31): the kernels are compiled once and loaded from numba's cache afterwards.
COMPILE_NOTICE = ("fluxcal: compiling the numerical kernels once (first run only, "
                  "~1-2 min; cached afterwards) ...")


@contextmanager
def compilation_notice() -> Iterator[None]:
    """Say once on stderr when numba compiles a kernel (the first run, before the cache).

    Listens to numba's ``numba:compile`` event, which fires only for a real compilation
    (a kernel loaded from numba's on-disk cache does not raise it), so later runs are
    quiet; ``fluxcal -q`` says nothing.
    """
    if quiet_requested():
        yield
        return
    from numba.core import event

    class Notice(event.Listener):
        said = False

        def on_start(self, ev: event.Event) -> None:
            if not self.said:
                self.said = True
                typer.echo(COMPILE_NOTICE, err=True)

        def on_end(self, ev: event.Event) -> None:
            pass

    with event.install_listener("numba:compile", Notice()):
        yield


@contextmanager
def status_display(text: str) -> Iterator[None]:
    """Show a rich spinner with ``text`` on a terminal (stderr) while a long step runs."""
    if not progress_wanted():
        yield
        return
    from rich.console import Console

    with Console(stderr=True).status(text):
        yield


@contextmanager
def progress_display(name: str = "run") -> Iterator[Callable[[str, int, int], None] | None]:
    """Show a rich progress bar on a terminal (stderr), nothing otherwise.

    Yields the ``progress(description, done, total)`` callback of
    `fluxcal.runs.driver.run` (first labelled ``name``), or ``None`` when stderr is not
    a terminal (logs and pipes stay quiet) or under ``fluxcal -q``.
    """
    if not progress_wanted():
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(),
                  console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task(name, total=None)

        def update(description: str, done: int, total: int) -> None:
            bar.update(task, description=description, completed=done, total=total)

        yield update
