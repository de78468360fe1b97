"""A run owns only what it wrote: the output folder's lock, staged products, clean-up.

Every command that writes into an ``--out`` folder (`fluxcal.cli.main` for the single
commands, `fluxcal.runs.batch.run_batch` for a batch) holds that folder's lock
(`output_lock`) for the whole run, so two runs never write into one folder at once: the
second refuses at once (`OutputFolderBusy`, one line, exit 2) and touches nothing.

A single run (`owned_run`) then

- removes the temporaries a killed run left (`clean_stale_temporaries`; logged);
- writes every product under a temporary name and renames them all into place only
  when the whole command succeeded (`fluxcal.products.atomic.atomic_group`), so an
  existing product is replaced only by a complete, successful run;
- on a failure or an interruption removes only what it created: its temporaries, and
  the files that appeared in the folder during the run (with the lock held, no other
  fluxcal run can have written them).

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
from fluxcal.products.atomic import atomic_group, process_alive, temporary_owner, ungrouped

log = logging.getLogger(__name__)

#: Lock file of an output folder (an ``flock``; held by single runs and batches alike).
LOCK_NAME = ".fluxcal.lock"


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


def clean_stale_temporaries(out_dir: Path) -> list[Path]:
    """Remove temporaries left by a killed writer (``.<name>.*.tmp<suffix>``).

    Files and directories (a Zarr store is written as a temporary directory) alike, and
    a directory product's old copy (``.<name>.old``) left half-way through its swap.
    A temporary whose name carries the id of another process still running
    (`fluxcal.products.atomic.temporary_owner`) is left alone: it is being written.
    """
    removed: list[Path] = []
    me = os.getpid()
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return removed
    found = [*out_dir.rglob(".*.tmp*"), *out_dir.rglob(".*.old")]
    for p in sorted(found):
        if any(r in p.parents for r in removed):
            continue  # inside a temporary directory already removed
        owner = temporary_owner(p)
        if owner is not None and owner != me and process_alive(owner):
            continue  # being written by another running process (a command, a worker)
        if p.suffix == ".old" and not p.with_name(p.name[1:-4]).exists():
            continue  # the only copy of a directory product whose swap was cut: keep it
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        elif p.exists():
            p.unlink(missing_ok=True)
        else:
            continue
        removed.append(p)
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
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise OutputFolderBusy(
                f"--out {out_dir}: another fluxcal run (pid {holder}) is writing into this "
                "folder; wait for it to finish, or choose another --out") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # locked a file the previous holder had just removed: take the new one
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        path.unlink(missing_ok=True)  # still locked here: no other run is inside
        os.close(fd)


class _NewFiles:
    """What a run created under its output folder (``undo`` removes exactly that)."""

    def __init__(self, out: Path, existed: bool) -> None:
        self.out = out
        self.existed = existed
        self.before = set(out.rglob("*")) if existed and out.is_dir() else set()

    def undo(self) -> None:
        out = self.out
        if not out.exists():
            return
        if not self.existed:
            shutil.rmtree(out, ignore_errors=True)
            return
        if not out.is_dir():
            return
        new = sorted(set(out.rglob("*")) - self.before, key=lambda p: len(p.parts),
                     reverse=True)
        for p in new:
            if p.name == LOCK_NAME and p.parent == out:
                continue  # ours: `output_lock` removes it
            try:
                if p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    p.unlink(missing_ok=True)
            except OSError:
                pass


@contextlib.contextmanager
def owned_run(out: Path | None) -> Iterator[None]:
    """Run a command that writes into ``out`` so that it owns only what it wrote.

    Takes ``out``'s lock (`output_lock`; creating ``out`` for it, removed again if the
    run fails), removes stale temporaries of killed runs (logged, `report_stale`),
    stages every product of the run (`fluxcal.products.atomic.atomic_group`: renamed
    into place only at the successful end; a command that reads back what it wrote,
    such as the demo tour, declares it with `reads_back`) and,
    on any exception (an error, an interruption), removes what the run created and
    re-raises.

    ``out`` None (a command without ``--out``), or a path that cannot hold a lock (a
    file, an unwritable parent), runs the command unguarded: its own checks then report
    the path (one line, exit 2) before it writes anything.

    Raises
    ------
    OutputFolderBusy
        Another run holds ``out``'s lock; nothing is touched.
    """
    if out is None:
        yield
        return
    out = Path(out)
    existed = out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = output_lock(out)
        lock.__enter__()
    except OutputFolderBusy:
        raise
    except OSError:
        if not existed:
            shutil.rmtree(out, ignore_errors=True)
        yield  # the command's own preflight names the path
        return
    try:
        report_stale(clean_stale_temporaries(out), out)
        created = _NewFiles(out, existed)
        try:
            with atomic_group():
                yield
        except BaseException:
            created.undo()
            raise
    except BaseException as exc:
        lock.__exit__(type(exc), exc, exc.__traceback__)
        raise
    lock.__exit__(None, None, None)


@contextlib.contextmanager
def interrupt_signals() -> Iterator[None]:
    """Turn SIGINT and SIGTERM into `Interrupted` in the main thread while the block runs.

    The exception unwinds the run like any error, so every ``finally`` and every
    clean-up (temporaries, staged products, files the run created) runs before the
    process exits.  A second signal during that clean-up is ignored.  Outside the main
    thread (a command run from a worker thread) nothing is installed.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired: list[int] = []

    def handler(signum: int, frame: FrameType | None) -> None:
        if fired:
            return  # already unwinding: let the clean-up finish
        fired.append(signum)
        raise Interrupted(signum)

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
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
    """
    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        with ungrouped():
            return command(*args, **kwargs)

    return run  # type: ignore[return-value]
