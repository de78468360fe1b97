"""The ``fluxcal`` command line.

The command is built from the registered missions (`build_app`, `fluxcal.runs.registry`):
each mission's commands are defined next to the code they drive and declared in its
`~fluxcal.runs.contract.Mission`; ``batch`` and ``demo`` come from `fluxcal.runs`, ``plot``
and ``compare`` from `fluxcal.product_commands`.  `main` takes ``argv`` so tests can call it.
"""

from __future__ import annotations

import atexit
import errno
import gc
import logging
import os
import signal
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import typer

from fluxcal import product_commands
from fluxcal.cli_help import HELP_WIDTH, QUIET, HelpGroup
from fluxcal.errors import FluxcalError
from fluxcal.process import malloc_defaults, numpy_allocation_defaults
from fluxcal.products.provenance import COMMAND_ARGS
from fluxcal.products.staging import (
    Interrupted,
    interrupt_signals,
    interrupted_signal,
    owned_run,
    reads_back,
)
from fluxcal.runs import registry
from fluxcal.runs.cli import batch_app, unavailable_command
from fluxcal.runs.contract import Mission


def _print_version(value: bool) -> None:
    """Print the version and stop (``fluxcal --version``, eager: before any command)."""
    if value:
        from fluxcal import __version__

        typer.echo(__version__)
        raise typer.Exit()


def _root(
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Log progress to stderr."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Only errors: no warnings, no "
                               "progress display."),
    debug: bool = typer.Option(False, "--debug", help="Show the full traceback of an error "
                               "(also: FLUXCAL_DEBUG=1)."),
    show_version: bool = typer.Option(False, "--version", is_eager=True,
                                      callback=_print_version,
                                      help="Print the fluxcal version and exit."),
) -> None:
    if verbose and quiet:
        raise typer.BadParameter("-v/--verbose and -q/--quiet exclude each other",
                                 param_hint="'--quiet'")
    QUIET.set(quiet)
    # other libraries (numba, distributed, matplotlib ...) say warnings and errors only;
    # -v makes fluxcal's own steps readable (`fluxcal.runs.driver`: read, calibrated,
    # written, with sizes and times)
    others = logging.ERROR if quiet else logging.WARNING
    logging.basicConfig(level=others, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger().setLevel(others)  # also where a host (pytest, a notebook) set up logging
    logging.getLogger("fluxcal").setLevel(logging.INFO if verbose else logging.NOTSET)
    _quiet_other_loggers(others)


def _quiet_other_loggers(level: int) -> None:
    """Raise the loggers of other libraries that set their own lower level to ``level``.

    ``distributed`` sets its logger to INFO when imported; its lines would fill ``-v``.
    (`fluxcal.runs.cli` does the same after importing it for a batch.)
    """
    for name, logger in list(logging.root.manager.loggerDict.items()):
        if (isinstance(logger, logging.Logger) and name.split(".")[0] != "fluxcal"
                and logging.NOTSET < logger.level < level):
            logger.setLevel(level)


def version() -> None:
    """Print the fluxcal version."""
    from fluxcal import __version__

    typer.echo(__version__)


def demo(
    out: Path = typer.Option(Path("demo-output"), help="Folder for the demo products."),
    full: bool = typer.Option(False, "--full", help="The full tour: fits, batch on Dask, "
                              "cleaning, archive round trip (minutes)."),
) -> None:
    """Calibrate a product of each mission, with its quicklook and HTML report (seconds).

    ``--full`` runs the whole tour instead.
    """
    from fluxcal.runs.demo import run_demo

    run_demo(out, full=full)


def build_app(missions: dict[str, Mission] | None = None) -> typer.Typer:
    """Build the ``fluxcal`` command from the registered missions (`fluxcal.runs.registry`).

    Each mission adds its commands (``fluxcal <mission> ...``), its simulator
    (``fluxcal simulate <mission>``) and its batch command (``fluxcal batch <mission>``,
    from its day task and options dataclass); ``plot``, ``compare``, ``provenance``, ``demo`` and
    ``version`` work on every mission's products.
    """
    if missions is None:  # a broken plugin: skipped here, said once by `main`
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", registry.PluginWarning)
            missions = registry.missions()
    # rich_markup_mode=None: click's plain help, which wraps long option names and paths
    # instead of cutting them with an ellipsis and shows no metavar for flags (issue 25)
    root = typer.Typer(
        name="fluxcal",
        help="Calibrate fluxgate-magnetometer telemetry into science-ready magnetic-field "
             "products.",
        no_args_is_help=True,
        add_completion=False,
        rich_markup_mode=None,
        cls=HelpGroup,
    )
    root.callback(context_settings={"max_content_width": HELP_WIDTH})(_root)
    root.command()(version)
    root.command()(reads_back(demo))
    simulate_app = typer.Typer(
        help="Forward models: write raw telemetry and kernels from a known field.",
        rich_markup_mode=None, cls=HelpGroup)
    for name, mission in sorted(missions.items()):
        if mission.commands is not None:
            try:
                commands = registry.load_piece(mission, "commands")
                commands = commands if isinstance(commands, typer.Typer) else commands()
                root.add_typer(commands, name=name, help=mission.title or None)
            except FluxcalError as exc:
                unavailable_command(root, name, str(exc))
        if mission.simulate is not None:
            try:
                simulate_app.command(name)(reads_back(registry.load_piece(mission, "simulate")))
            except FluxcalError as exc:
                unavailable_command(simulate_app, name, str(exc))
    batch = batch_app(missions)
    for name, message in registry.broken().items():
        if name not in missions and ":" not in name:  # an entry point's name
            for group in (root, simulate_app, batch):
                unavailable_command(group, name, message)
    root.add_typer(simulate_app, name="simulate")
    root.add_typer(batch, name="batch")
    root.command("plot")(product_commands.plot)
    root.command("compare")(product_commands.compare)
    root.command("provenance")(product_commands.provenance)
    return root


def _warn_broken_plugins(args: Sequence[str]) -> None:
    """Print one line per mission plugin that failed to load (not under ``-q``)."""
    if "-q" in args or "--quiet" in args:
        return
    for message in registry.broken().values():
        typer.echo(f"fluxcal: warning: {message}; skipped", err=True)


app = build_app()


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
    try:
        yield
    finally:
        gc.set_threshold(*threshold)
        if not caller_froze:
            gc.unfreeze()


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
    """Return the ``--out`` folder of a command other than ``batch`` (its days are atomic).

    Raises
    ------
    FluxcalError
        ``--out`` given more than once (the command would write into the last one while
        the lock is taken on the first), or empty (``--out "$UNSET"`` would write into the
        current folder).
    """
    command = next((a for a in args if not a.startswith("-")), "")
    if "--help" in args:
        return None
    given = [args[i + 1] for i, a in enumerate(args) if a == "--out" and i + 1 < len(args)]
    given += [a.split("=", 1)[1] for a in args if a.startswith("--out=")]
    if any(not g.strip() for g in given):  # an unset variable: not the current folder
        raise FluxcalError("--out is empty: name a folder ('.' for the current one)")
    found = [Path(g) for g in given]
    if len(found) > 1:
        raise FluxcalError(f"--out given {len(found)} times ({', '.join(map(str, found))}); "
                           "give one output folder")
    return found[0] if found and command != "batch" else None


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
    _warn_broken_plugins(args)
    quiet = QUIET.set(False)  # set by the root callback for this command only
    command = COMMAND_ARGS.set(("fluxcal", *args))  # what products record (not pytest's argv)
    try:
        # commands that read back what they wrote declare it (`staging.reads_back`)
        with interrupt_signals() as signalled, _long_lived_imports(), \
                owned_run(_out_folder(args)):
            code = app(args=args, prog_name="fluxcal", standalone_mode=False)
            signalled()  # a signal whose exception a library swallowed: still 130/143
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
    finally:
        QUIET.reset(quiet)
        COMMAND_ARGS.reset(command)
    return int(code) if isinstance(code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
