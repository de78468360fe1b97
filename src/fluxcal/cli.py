"""The ``fluxcal`` command line.

Sub-commands are defined next to the code they drive (``missions/<m>/cli.py``,
``products/cli.py``) and registered here.  `main` takes ``argv`` so tests can call it.
"""

from __future__ import annotations

import atexit
import errno
import gc
import logging
import os
import signal
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import typer

from fluxcal.errors import FluxcalError
from fluxcal.process import defer_dask_array_import, malloc_defaults, numpy_allocation_defaults
from fluxcal.products.staging import (
    Interrupted,
    interrupt_signals,
    interrupted_signal,
    owned_run,
)

app = typer.Typer(
    name="fluxcal",
    help="Calibrate fluxgate-magnetometer telemetry into science-ready magnetic-field products.",
    no_args_is_help=True,
    add_completion=False,
)
simulate_app = typer.Typer(
    help="Forward models: write raw telemetry and kernels from a known field."
)
app.add_typer(simulate_app, name="simulate")


@app.callback()
def _root(
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Log progress to stderr."),
    debug: bool = typer.Option(False, "--debug", help="Show the full traceback of an error "
                               "(also: FLUXCAL_DEBUG=1)."),
) -> None:
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


@app.command()
def version() -> None:
    """Print the fluxcal version."""
    from fluxcal import __version__

    typer.echo(__version__)


@app.command()
def demo(
    out: Path = typer.Option(Path("demo-output"), help="Folder for the demo products."),
) -> None:
    """Run the main job on the embedded default data and say where the products are."""
    from fluxcal.demo import run_demo

    run_demo(out)


def _register() -> None:
    from fluxcal.missions.messenger import cli as messenger_cli
    from fluxcal.missions.rosetta import clean_cli
    from fluxcal.missions.rosetta import cli as rosetta_cli
    from fluxcal.products import cli as products_cli

    app.add_typer(messenger_cli.app, name="messenger")
    rosetta_cli.app.command("clean")(clean_cli.clean)
    app.add_typer(rosetta_cli.app, name="rosetta")
    simulate_app.command("messenger")(messenger_cli.simulate)
    simulate_app.command("rosetta")(rosetta_cli.simulate)
    app.command("plot")(products_cli.plot)
    app.command("batch")(products_cli.batch)
    app.command("compare")(products_cli.compare)


_register()


DEBUG_ENV = "FLUXCAL_DEBUG"

#: Full (generation-2) collections during a command: at most one per this many
#: generation-1 collections (CPython's default: 10).
FULL_COLLECTION_EVERY = 100


@contextmanager
def _long_lived_imports() -> Iterator[None]:
    """Keep the cyclic garbage collector off the imported modules while a command runs.

    A command's process holds some 250,000 container objects of imported modules
    (xarray, pandas, numba, dask, matplotlib) that live until exit.  CPython's full
    collection walks all of them; with its default thresholds a cold ``edr2cdr`` ran
    three during the run (0.3-0.5 s on the benchmark machine).  Here the objects alive
    at the start are frozen (`gc.freeze`: never walked, never collected) and full
    collections are ten times rarer; young collections run as usual, so short-lived
    cycles are still freed promptly.  Both are undone on leaving, so a caller's process
    (tests, a notebook) keeps its collector as it was (objects the caller had frozen
    itself stay frozen, with those frozen here).
    """
    threshold = gc.get_threshold()
    caller_froze = gc.get_freeze_count() > 0
    gc.freeze()
    gc.set_threshold(threshold[0], threshold[1], max(threshold[2], FULL_COLLECTION_EVERY))
    _IN_COMMAND.append(True)
    try:
        yield
    finally:
        _IN_COMMAND.pop()
        gc.set_threshold(*threshold)
        if not caller_froze:
            gc.unfreeze()


_IN_COMMAND: list[bool] = []


def imports_loaded() -> None:
    """Settle the libraries a command has just imported, when it runs under `main`.

    For a command to call right after importing its libraries, before it makes any
    data: the modules join those `_long_lived_imports` keeps off the collector
    (`gc.freeze`; the data stays collectable, and `main` unfreezes everything when the
    command ends), and xarray checks for dask arrays without importing ``dask.array``
    (`fluxcal.process.defer_dask_array_import`).  Outside `main` (tests, a notebook)
    it does nothing.
    """
    if _IN_COMMAND:
        defer_dask_array_import()
        gc.freeze()


def _freeze_at_exit() -> None:
    """Skip the interpreter's final walks over every object (0.3-0.6 s of exit).

    Registered as an `atexit` handler by `main` (once per process; a process that only
    imports this module keeps its usual exit), so it runs after the command: every
    product is written and closed by then; objects alive at exit are freed by reference
    counting as usual, only cycles are left to the operating system (Python never
    promised their ``__del__`` at exit).
    """
    gc.freeze()


def _debug_requested(args: list[str]) -> bool:
    """``--debug`` (removed from ``args``) or ``FLUXCAL_DEBUG=1``: show tracebacks."""
    debug = "--debug" in args
    while "--debug" in args:
        args.remove("--debug")
    return debug or os.environ.get(DEBUG_ENV, "").strip() not in ("", "0")


def error_line(exc: BaseException) -> str:
    """Return the one line ``fluxcal: error: ...`` printed for a user-facing error.

    `FluxcalError` messages already name the file, record and field.  An `OSError`
    names the path (and a second path for renames) and says what to do for the usual
    causes (no space left, no permission, a file where a folder is expected).
    """
    if isinstance(exc, OSError) and not isinstance(exc, FluxcalError):
        paths = " -> ".join(str(p) for p in (exc.filename, exc.filename2) if p)
        what = exc.strerror or str(exc) or type(exc).__name__
        hint = {
            errno.ENOSPC: "free space on that disk or choose another --out",
            errno.EDQUOT: "free space on that disk or choose another --out",
            errno.EACCES: "choose a folder you can write to (--out) or fix its permissions",
            errno.EPERM: "choose a folder you can write to (--out) or fix its permissions",
            errno.EROFS: "the file system is read-only: choose another --out",
            errno.ENOTDIR: "a file stands where a folder is expected: choose another path",
            errno.EEXIST: "a file stands where a folder is expected: choose another path",
            errno.ENOENT: "check the path",
            errno.EISDIR: "give a file, not a folder",
        }.get(exc.errno or -1, "")
        text = f"{paths}: {what}" if paths else what
        line = f"{text} ({hint})" if hint else text
    else:
        line = str(exc) or type(exc).__name__
    return "fluxcal: error: " + " ".join(line.split())


def _out_folder(args: list[str]) -> Path | None:
    """Return the ``--out`` folder of a command other than ``batch`` (its days are atomic)."""
    command = next((a for a in args if not a.startswith("-")), "")
    if command == "batch" or "--help" in args:
        return None
    for i, a in enumerate(args):
        if a == "--out" and i + 1 < len(args):
            return Path(args[i + 1])
        if a.startswith("--out="):
            return Path(a.split("=", 1)[1])
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``) and return the exit code.

    Exit codes: 0 success; 1 a batch with a failed day, or an internal error (a bug:
    one line, the traceback with ``--debug``); 2 every user-facing error -- usage errors
    (click's message), `FluxcalError` and `OSError` (unwritable folder, full disk,
    missing file) -- printed as one line ``fluxcal: error: ...`` naming the path and
    what to do.  A command with ``--out`` runs as the folder's owner
    (`fluxcal.products.staging.owned_run`: its lock, products staged until the command
    succeeds, only its own files removed on failure; ``batch`` takes the lock itself and
    keeps its finished days).  ``--debug`` (anywhere on the line) or ``FLUXCAL_DEBUG=1``
    re-raises instead, with the full traceback.  ``typer.Exit(code)`` returns ``code``
    (a non-zero code counts as a failure); SIGINT and SIGTERM clean up, print one line
    ``fluxcal: interrupted: ...`` and return 130 and 143
    (`fluxcal.products.staging.interrupt_signals`).

    First the process-wide allocation settings (`fluxcal.process`: numpy's huge-page
    advice, glibc's heap reuse; a user's own settings are kept).
    """
    numpy_allocation_defaults()
    malloc_defaults()
    atexit.unregister(_freeze_at_exit)  # registered once, however often main runs
    atexit.register(_freeze_at_exit)
    args = list(sys.argv[1:] if argv is None else argv)
    debug = _debug_requested(args)
    try:
        with interrupt_signals(), _long_lived_imports(), owned_run(_out_folder(args)):
            code = app(args=args, prog_name="fluxcal", standalone_mode=False)
            if code == 130:  # typer's return for a KeyboardInterrupt it caught
                raise Interrupted(signal.SIGINT)
            if isinstance(code, int) and code != 0:
                raise SystemExit(code)  # a failed command: owned_run removes its files
    except SystemExit as exc:
        return int(exc.code or 0)
    except (FluxcalError, OSError) as exc:
        if debug:
            raise
        typer.echo(error_line(exc), err=True)
        return 2
    except (typer.Abort, KeyboardInterrupt, Interrupted) as exc:
        signum = interrupted_signal(exc)
        typer.echo(f"fluxcal: interrupted: {signal.Signals(signum).name}; this run's "
                   "unfinished files were removed", err=True)
        return 128 + signum
    except Exception as exc:
        # click's (and typer's vendored click's) usage errors and Exit carry exit_code
        exit_code = getattr(exc, "exit_code", None)
        if exit_code is None:
            if debug:
                raise
            typer.echo(f"fluxcal: internal error: {type(exc).__name__}: "
                       f"{' '.join(str(exc).split())[:300]} (a bug: please report it with "
                       f"the traceback that --debug or {DEBUG_ENV}=1 shows)", err=True)
            return 1
        message = getattr(exc, "format_message", None)
        ctx = getattr(exc, "ctx", None)
        if callable(message) and ctx is not None and type(exc).__name__ != "NoArgsIsHelpError":
            # a usage error: one line, like every other error
            text = " ".join(str(message()).split())
            typer.echo(f"fluxcal: error: {text} (see '{ctx.command_path} --help')", err=True)
            return int(exit_code)
        show = getattr(exc, "show", None)
        if callable(show):
            show()
        return int(exit_code)
    return int(code) if isinstance(code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
