"""A run owns only what it wrote: the output folder's lock, staged products, clean-up.

Every command that writes into an ``--out`` folder (`fluxcal.cli.main` for the single
commands, the batch runner for a batch; `owned_default` for a folder a
command writes into when ``--out`` is not given) holds that folder's lock
(`output_lock`) for the whole run, so two runs never write into one folder at once: the
second refuses at once (`OutputFolderBusy`, one line, exit 2) and touches nothing.

A single run (`owned_run`) then

- removes the temporaries a killed run left (`clean_stale_temporaries`; logged);
- writes every product under a temporary name and renames them all into place only
  when the whole command succeeded (`fluxcal.products.atomic.atomic_group`), so an
  existing product is replaced only by a complete, successful run;
- on a failure or an interruption removes only what it created: its temporaries, and
  the files and folders its writers recorded (`fluxcal.products.paths.note_created`);
  a file another program put into the folder meanwhile stays.

`interrupt_signals` turns SIGINT and SIGTERM into `Interrupted`, so the clean-up above
runs before the command exits 130 or 143 (docs/decisions/products.md, decisions 52-57).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import shutil
import signal
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import Any, TypeVar

from fluxcal.errors import FluxcalError
from fluxcal.preflight import writable_folder
from fluxcal.products.atomic import atomic_group, process_alive, ungrouped
from fluxcal.products.paths import (
    LOCK_NAME,
    current_folder,
    open_lock_file,
    own_leftover,
    remove_created,
    what_stands_at,
    write_scope,
)

log = logging.getLogger(__name__)

__all__ = ["LOCK_NAME", "Interrupted", "OutputFolderBusy", "clean_stale_temporaries",
           "interrupt_signals", "interrupted_signal", "output_lock", "owned_default",
           "owned_run", "reads_back", "report_stale"]


class OutputFolderBusy(FluxcalError):  # noqa: N818 - reads as a state
    """Another fluxcal run holds the lock of the output folder."""


class Interrupted(BaseException):  # noqa: N818 - reads as what happened
    """SIGINT or SIGTERM arrived during a command (`interrupt_signals`).

    A `BaseException` (as `KeyboardInterrupt` is), so ``except Exception`` clauses let
    it through; not a `KeyboardInterrupt`, which typer turns into a return value
    (exit code 130) before the command's clean-up could run.

    Parameters
    ----------
    signum : int
        The signal received; the command exits ``128 + signum`` (130, 143).
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(signal.Signals(signum).name)


def clean_stale_temporaries(out_dir: Path, *, below: bool = True) -> list[Path]:
    """Remove the temporaries a killed fluxcal writer left below ``out_dir``.

    Only names fluxcal gives its temporaries are touched
    (``.<name>.<pid>.<random>.fluxcal-tmp<suffix>``, and a directory product's
    ``.<name>.<pid>.fluxcal-old`` half-way through its swap;
    `fluxcal.products.paths.own_leftover`): a user's ``.draft.tmp`` or ``.bashrc.old``
    never matches.  Files and directories (a Zarr store is written as a temporary
    directory) alike; no link is followed or removed, and no folder where another run
    holds a lock (a run writing into a folder nested below ``out_dir``) is entered.  A
    temporary whose pid is that of another process still running is left alone: it is
    being written.  ``below`` False: ``out_dir``'s own entries only, no subfolder is
    entered (a folder the user did not name, `owned_run`).
    """
    removed: list[Path] = []
    me = os.getpid()
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return removed
    for folder, dirs, files in os.walk(out_dir, followlinks=False):
        here = Path(folder)
        if here != out_dir and os.path.lexists(here / LOCK_NAME):
            dirs[:] = []  # another run's --out, being written now: not ours to clean
            continue
        for name in sorted([*dirs, *files]):
            found = own_leftover(name)
            if found is None:
                continue
            kind, owner, final = found
            p = here / name
            if name in dirs:
                dirs.remove(name)  # removed whole (or kept): never walked into
            if p.is_symlink():
                continue  # fluxcal never makes links: not its own
            if owner != me and process_alive(owner):
                continue  # being written by another running process (a command, a worker)
            if kind == "old" and not os.path.lexists(here / final):
                continue  # the only copy of a directory product whose swap was cut: keep it
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink(missing_ok=True)
            removed.append(p)
        if not below:
            break  # os.walk gives ``out_dir`` first: its own entries only
    return removed


def report_stale(removed: list[Path], out_dir: Path) -> None:
    """Log one line naming the stale temporaries `clean_stale_temporaries` removed."""
    if removed:
        names = ", ".join(p.name for p in removed[:5]) + (" ..." if len(removed) > 5 else "")
        log.warning("removed %d stale temporary file(s) of an earlier, killed run from %s: %s",
                    len(removed), out_dir, names)


@contextlib.contextmanager
def output_lock(out_dir: Path) -> Iterator[Path]:
    """Hold an exclusive lock on ``out_dir`` for one run (``<out>/.fluxcal.lock``).

    The lock is an ``flock`` on that file: the kernel drops it when the holder ends, even
    killed, so a crash never leaves a stale lock.  The file holds the holder's pid and
    is removed when the run ends.

    Raises
    ------
    OutputFolderBusy
        If another run (another process, or another lock in this one) holds the lock:
        the second run refuses at once instead of touching the first one's files.
    """
    import fcntl  # POSIX only: imported where the lock is taken

    path = Path(out_dir) / LOCK_NAME
    while True:
        fd = open_lock_file(path)  # never through a link (paths rule 2)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise OutputFolderBusy(
                f"--out {out_dir}: another fluxcal run (pid {holder}) is writing into this "
                "folder; wait for it to finish, or choose another --out") from None
        same = _same_file(fd, path)
        if same:
            break
        os.close(fd)  # locked a file the previous holder had just removed: take the new one
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        if _same_file(fd, path):  # still locked here: no other run is inside
            path.unlink(missing_ok=True)
        os.close(fd)


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` (not followed) is the file open as ``fd``."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    return (st.st_ino, st.st_dev) == (mine.st_ino, mine.st_dev)


def _undo(out: Path, created: list[Path]) -> None:
    """Remove what a failed run created in ``out``, and nothing else.

    The files and folders the run's writers recorded (`fluxcal.products.paths.note_created`;
    a folder only once empty) and its temporaries (by name, `clean_stale_temporaries`).
    A file that appears in ``out`` or below during the run and that the run did not
    record is not removed: the lock keeps other fluxcal runs out, not the user's other
    programs (a download, an editor), nor a run under its own ``--out`` nested below.
    """
    remove_created(created)
    if not out.is_dir():
        return
    clean_stale_temporaries(out)  # its own, by name (a store a library was still writing)


@contextlib.contextmanager
def owned_run(out: Path | None, *, named: bool = True) -> Iterator[None]:
    """Run a command that writes into ``out`` so that it owns only what it wrote.

    Takes ``out``'s lock (`output_lock`; creating ``out`` for it, removed again if the
    run fails), removes stale temporaries of killed runs (logged, `report_stale`),
    stages every product of the run (`fluxcal.products.atomic.atomic_group`: renamed
    into place only at the successful end; a command that reads back what it wrote,
    such as the demo tour, declares it with `reads_back`) and,
    on any exception (an error, an interruption), removes what the run created and
    re-raises.

    ``out`` is checked first, before the command reads any input (`_make_out`: a file
    in its path, a folder that cannot be written); every write of the run must lie
    inside it (`fluxcal.products.paths.write_scope`).  ``out`` None (a command without
    ``--out``) runs the command unguarded.  ``named`` False: a folder the command writes
    into by default, which the user did not name (`owned_default`): the stale
    temporaries are looked for in that folder only, no subfolder is entered.

    Raises
    ------
    OutputFolderBusy
        Another run holds ``out``'s lock; nothing is touched.
    FluxcalError
        ``out`` cannot be a folder this run writes, or its lock file is a link or not a
        regular file (left as it is).
    """
    if out is None:
        yield
        return
    out = Path(out)
    made = _make_out(out)
    try:
        lock = output_lock(out)
        lock.__enter__()
    except BaseException:
        _remove_folders(made)
        raise
    try:
        report_stale(clean_stale_temporaries(out, below=named), out)
        with write_scope(out) as created:
            try:
                with atomic_group():
                    yield
            except BaseException:
                _undo(out, created)
                raise
    except BaseException as exc:
        lock.__exit__(type(exc), exc, exc.__traceback__)
        _remove_folders(made)  # only those that are empty again
        raise
    lock.__exit__(None, None, None)


def owned_default(folder: Path) -> contextlib.AbstractContextManager[None]:
    """Own ``folder``, a command's default output folder, unless a run owns one already.

    A command that writes beside its input or into the current folder when ``--out`` is
    not given (`fluxcal.product_commands.plot`, ``compare``) takes that folder's lock
    like every other writer (`owned_run`, ``named=False``): two commands never write
    into one folder at once, a busy folder is one line (`OutputFolderBusy`, exit 2),
    and every write is staged and confined to it.  With ``--out`` given, `fluxcal.cli.main`
    owns that folder already and nothing more is taken.
    """
    return owned_run(Path(folder), named=False) if current_folder() is None \
        else contextlib.nullcontext()


def _make_out(out: Path) -> list[Path]:
    """Create ``out`` (and missing parents) and check it can be written; return what was made.

    Runs before the command reads any input, so an unusable ``--out`` (a file in its
    path, a read-only folder) is one line at once, not after a day's calibration.

    Raises
    ------
    FluxcalError
        A file stands in the path, or the folder cannot be created or written.
    """
    missing: list[Path] = []
    p = out
    while not os.path.lexists(p) and p != p.parent:
        missing.append(p)
        p = p.parent
    if os.path.lexists(p) and not p.is_dir():
        raise FluxcalError(f"--out {out}: {p} is {what_stands_at(p)}; choose another --out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_folders(missing)
        raise FluxcalError(f"--out {out}: cannot create it ({exc.strerror}); choose a folder "
                           "you can write to") from None
    try:
        writable_folder(out, "--out")  # a real write: root on a read-only mount too
    except FluxcalError:
        _remove_folders(missing)
        raise
    return missing


def _remove_folders(folders: list[Path]) -> None:
    """Remove the folders `_make_out` created, deepest first, each only if empty."""
    for folder in folders:
        with contextlib.suppress(OSError):
            os.rmdir(folder)


@contextlib.contextmanager
def interrupt_signals() -> Iterator[Callable[[], None]]:
    """Turn SIGINT and SIGTERM into `Interrupted` in the main thread while the block runs.

    The exception unwinds the run like any error, so every ``finally`` and every
    clean-up (temporaries, staged products, files the run created) runs before the
    process exits.  A second signal during that clean-up is ignored.  Outside the main
    thread (a command run from a worker thread) nothing is installed.

    Python runs a handler between two bytecodes of the main thread, which may be inside
    code that swallows exceptions (a ``__del__``, a weakref or garbage-collector
    callback, a library's ``except BaseException``): the exception is then lost.  So the
    block gets a function that raises `Interrupted` again if a signal arrived; the
    command line (`fluxcal.cli.main`) calls it when the command returns, before its
    products are committed: a SIGTERM is never ignored (exit 143).
    """
    fired: list[int] = []

    def pending() -> None:
        if fired:
            raise Interrupted(fired[0])

    if threading.current_thread() is not threading.main_thread():
        yield pending
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        if fired:
            return  # already unwinding: let the clean-up finish
        fired.append(signum)
        raise Interrupted(signum)

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield pending
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def interrupted_signal(exc: BaseException) -> int:
    """Return the signal behind an interruption (`Interrupted`; else SIGINT)."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, Interrupted):
            return e.signum
        e = e.__cause__ or e.__context__
    return int(signal.SIGINT)


_Command = TypeVar("_Command", bound=Callable[..., Any])


def reads_back(command: _Command) -> _Command:
    """Declare a command that reads back the files it writes (a demo tour, a simulator).

    `owned_run` stages a command's products as one group, renamed at its successful end;
    such a command instead has each file renamed into place as soon as it is complete
    (`fluxcal.products.atomic.ungrouped`; each file is still written atomically, and a
    failed run still removes what it created).  The signature is kept for the CLI.

    Such commands have a default ``--out`` (a simulator's, the demo's), which
    `fluxcal.cli.main` cannot see on the command line: when no run owns a folder yet,
    the command's ``out`` is owned here (`owned_run`: checked, locked, writes confined).
    """
    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        out = kwargs.get("out")
        owner = owned_run(Path(out)) if out is not None and current_folder() is None \
            else contextlib.nullcontext()
        with owner, ungrouped():
            return command(*args, **kwargs)

    return run  # type: ignore[return-value]
