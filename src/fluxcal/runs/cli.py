"""``fluxcal batch <mission>``: one sub-command per registered mission with a day task.

Every batch command takes the generic options (days, input and output folders, Dask
scheduler, kernels) and the mission's run options from its options dataclass
(`fluxcal.runs.options`), the same dataclass its single-run command takes.
"""

from __future__ import annotations

import datetime as _dt
import inspect
import logging
import time
from pathlib import Path
from typing import Any

import click
import typer

from fluxcal import preflight
from fluxcal.cli_help import HelpGroup, quiet_requested
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.extras import require, require_for_options
from fluxcal.products.staging import Interrupted
from fluxcal.runs import options as run_options
from fluxcal.runs import registry
from fluxcal.runs.contract import Mission


def _parse_date(text: str, option: str) -> _dt.date:
    try:
        return _dt.date.fromisoformat(text)
    except ValueError as exc:
        raise InputFormatError(f"{text!r} is not a date YYYY-MM-DD", field=option) from exc


def batch(
    mission: Mission,
    start: str,
    end: str,
    input_dir: Path,
    out: Path,
    options: Any = None,
    *,
    scheduler: str | None = None,
    force: bool = False,
    workers: int = 2,
    kernels: Path | None = None,
    quiet: bool = False,
) -> None:
    """Process many days of ``mission`` on Dask, one task per day; exit 1 if a day failed.

    ``options`` is the mission's run-options dataclass (or None for its defaults).
    Everything that can be checked is checked before the first day (`_preflight`).
    """
    from rich.console import Console

    from fluxcal.runs.batch import day_range

    d0, d1 = _parse_date(start, "--start"), _parse_date(end, "--end")
    if d1 < d0:
        raise InputFormatError(f"--end {d1} is before --start {d0}", field="--end")
    factory = registry.load_piece(mission, "day_task")
    values = run_options.as_keywords(options) if options is not None else {}
    require_for_options(options)  # plot/zarr extras the options ask for
    if scheduler != "serial":
        require("batch", "fluxcal batch on Dask (--scheduler serial runs without it)")
    _preflight(out, kernels, values.get("calib"), scheduler)
    if kernels is not None:
        values["kernels"] = kernels
    task = factory(input_dir, out, **values)
    if mission.before_batch is not None:
        registry.load_piece(mission, "before_batch")(task)
    days = day_range(d0, d1)
    quiet = quiet or quiet_requested()  # fluxcal -q batch ...
    console = Console(stderr=True)
    if scheduler != "serial" and not logging.getLogger().isEnabledFor(logging.INFO):
        import fluxcal.runs.cluster  # noqa: F401 - importing distributed sets its logger to INFO

        logging.getLogger("distributed").setLevel(
            logging.ERROR if quiet_requested() else logging.WARNING)
    try:
        report = _run_with_progress(days, task, out, scheduler, workers, force, mission.name,
                                    console, quiet)
    except (KeyboardInterrupt, Interrupted) as exc:  # Ctrl-C, SIGTERM: report written
        partial = getattr(exc, "batch_report", None)
        if partial is not None:
            _summary(partial, console, full=not quiet)
        raise
    _summary(report, console, full=not quiet)
    if not report.ok:
        # SystemExit, not typer.Exit: fluxcal.cli.main runs click with
        # standalone_mode=False, where typer.Exit's code is returned and dropped.
        raise SystemExit(1)


def _preflight(out: Path, kernels: Path | None, calib: Path | None,
               scheduler: str | None) -> None:
    """Check what can be checked before the first day.

    An unwritable ``--out``, a missing ``--kernels`` file or ``--calib`` folder (a file
    for missions whose calibration is one file, e.g. IMAP's CDF) and an
    unreachable ``--scheduler`` each raise a `FluxcalError` (one line, exit 2) before
    any day is computed or any file is written (the mission's options were checked when
    they were parsed).
    """
    if kernels is not None:
        preflight.existing_file(kernels, "--kernels")
    if calib is not None and not Path(calib).is_file():
        preflight.existing_folder(calib, "--calib")
    preflight.writable_folder(out, "--out")
    if scheduler is not None and scheduler != "serial":
        preflight.reachable_scheduler(scheduler)


def batch_command(mission: Mission) -> Any:
    """Return the ``fluxcal batch <mission.name>`` command function for typer."""
    def command(
        start: str = typer.Option(..., "--start", help="First day, YYYY-MM-DD."),
        end: str = typer.Option(..., "--end", help="Last day (inclusive), YYYY-MM-DD."),
        input_dir: Path = typer.Option(..., "--input", exists=True, file_okay=False,
                                       help="Folder of raw inputs."),
        out: Path = typer.Option(..., "--out", help="Folder for products, manifests, report."),
        scheduler: str | None = typer.Option(None, "--scheduler",
                                             help="Address of an existing Dask scheduler; "
                                                  "'serial' runs in this process."),
        force: bool = typer.Option(False, "--force", help="Redo days that are up to date."),
        workers: int = typer.Option(2, "--workers", min=1,
                                    help="Workers of the local cluster."),
        kernels: Path | None = typer.Option(None, "--kernels",
                                            help="Meta-kernel for the days."),
        quiet: bool = typer.Option(False, "--quiet",
                                   help="No progress bar; one-line summary."),
        options: Any = None,
    ) -> None:
        batch(mission, start, end, input_dir, out, options, scheduler=scheduler, force=force,
              workers=workers, kernels=kernels, quiet=quiet)

    command.__doc__ = (f"{mission.title or mission.name}: process many days on Dask, one "
                       "task per day; resumable; exits 1 if a day failed.")
    if mission.options is not None:
        # the batch writes its folder's HTML report itself (fluxcal.runs.batch.run_batch)
        return run_options.with_options(registry.load_piece(mission, "options"),
                                        report=False)(command)
    signature = inspect.signature(command)
    command.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[p for p in signature.parameters.values() if p.name != "options"])
    return command


def unavailable_command(group: typer.Typer, name: str, message: str) -> None:
    """Add a hidden command ``name`` to ``group`` that refuses with ``message`` (exit 2).

    The place of a mission plugin (or a piece of one) that failed to load
    (`fluxcal.runs.registry`): the other commands work; asking for it is one error line.
    """
    def unavailable() -> None:
        raise FluxcalError(message)

    group.command(name, hidden=True, add_help_option=False,
                  context_settings={"allow_extra_args": True,
                                    "ignore_unknown_options": True})(unavailable)


def batch_app(missions: dict[str, Mission]) -> typer.Typer:
    """Return the ``fluxcal batch`` group: one command per mission with a day task."""
    app = typer.Typer(help="Process many days on Dask, one task per day; resumable.",
                      rich_markup_mode=None, cls=HelpGroup)
    names = sorted(name for name, m in missions.items() if m.day_task is not None)
    for name in names:
        try:
            app.command(name)(batch_command(missions[name]))
        except FluxcalError as exc:  # a plugin's options fail to load: refused when asked
            unavailable_command(app, name, str(exc))

    @app.callback(invoke_without_command=True)
    def _needs_a_mission(ctx: typer.Context) -> None:
        if ctx.invoked_subcommand is None:
            raise click.UsageError(f"Missing mission: one of {', '.join(names)}", ctx=ctx)

    return app


def _run_with_progress(days, task, out, scheduler, workers, force, name, console, quiet):
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    from fluxcal.runs.batch import run_batch

    t0 = time.perf_counter()
    totals = {"vectors": 0, "failed": 0}
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[rate]:>12,.0f} vectors/s"),
                  TextColumn("failures: {task.fields[failed]}"), TimeElapsedColumn(),
                  console=console, disable=quiet) as progress:
        bar = progress.add_task(f"{name} days", total=len(days), rate=0.0, failed=0)

        def done(st) -> None:
            totals["vectors"] += st.n_vectors if st.status == "done" else 0
            totals["failed"] += st.status == "failed"
            rate = totals["vectors"] / max(time.perf_counter() - t0, 1e-9)
            progress.update(bar, advance=1, rate=rate, failed=totals["failed"])

        return run_batch(days, task, out, scheduler=scheduler, n_workers=workers, force=force,
                         name=name, on_day_done=done)
def _summary(report, console, full: bool = True) -> None:
    from rich.markup import escape
    from rich.table import Table

    statuses = ("done", "skipped", "no_data", "failed")
    statuses += ("interrupted",) if report.count("interrupted") else ()
    counts = ", ".join(f"{report.count(s)} {s}" for s in statuses)
    if not full:
        console.print(f"fluxcal batch {report.name}: {counts}; report: {report.report_path}",
                      soft_wrap=True)
        return

    table = Table(title=f"fluxcal batch {report.name}: {report.wall_seconds:.1f} s on "
                        f"{report.scheduler} ({report.n_workers} workers)")
    for col in ("day", "status", "why", "vectors", "seconds", "error"):
        table.add_column(col)
    style = {"done": "green", "skipped": "cyan", "no_data": "yellow", "failed": "bold red",
             "interrupted": "magenta"}
    for d in report.days:
        table.add_row(d.day, f"[{style.get(d.status, '')}]{d.status}",
                      escape((d.reason or "")[:60]), f"{d.n_vectors:,}", f"{d.seconds:.2f}",
                      (d.error or "")[:120])
    console.print(table)
    console.print(f"{counts}; report: {report.report_path}", soft_wrap=True)



