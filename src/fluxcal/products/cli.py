"""``fluxcal plot`` and ``fluxcal batch`` commands.

The functions keep the names the lead registered in ``fluxcal/cli.py``
(``app.command("plot")(plot)``, ``app.command("batch")(batch)``).
"""

from __future__ import annotations

import datetime as _dt
import logging
from pathlib import Path

import typer

from fluxcal.errors import InputFormatError


def plot(
    product: Path = typer.Argument(..., exists=True, help="Product (.cdf, .nc or .TAB)."),
    out: Path | None = typer.Option(None, "--out", help="Folder for the PNGs "
                                    "(default: beside the product)."),
    spectrogram: bool = typer.Option(False, "--spectrogram",
                                     help="Also write a spectrogram PNG of the field."),
    field: str | None = typer.Option(None, "--field",
                                     help="Field variable to plot (default: the first "
                                          "B* vector in nT)."),
) -> None:
    """Render a quicklook PNG per day of a product."""
    from fluxcal import preflight
    from fluxcal.products.quicklook import (
        epoch_from_table,
        save_png,
        spectrogram_figure,
        write_quicklooks,
    )
    from fluxcal.products.writer import read_product

    out_dir = out or product.parent
    preflight.writable_folder(out_dir, "--out")
    ds = epoch_from_table(read_product(product))
    paths = write_quicklooks(ds, out_dir, product.stem, field=field)
    if spectrogram:
        paths.append(save_png(spectrogram_figure(ds, field),
                              out_dir / f"{product.stem}_spec.png"))
    for p in paths:
        typer.echo(str(p))


def _parse_date(text: str, option: str) -> _dt.date:
    try:
        return _dt.date.fromisoformat(text)
    except ValueError as exc:
        raise InputFormatError(f"{text!r} is not a date YYYY-MM-DD", field=option) from exc


def batch(
    mission: str = typer.Argument(..., help="messenger, rosetta (or synthetic)."),
    start: str = typer.Option(..., "--start", help="First day, YYYY-MM-DD."),
    end: str = typer.Option(..., "--end", help="Last day (inclusive), YYYY-MM-DD."),
    input_dir: Path = typer.Option(..., "--input", exists=True, file_okay=False,
                                   help="Folder of raw inputs."),
    out: Path = typer.Option(..., "--out", help="Folder for products, manifests, report."),
    scheduler: str | None = typer.Option(None, "--scheduler",
                                         help="Address of an existing Dask scheduler; "
                                              "'serial' runs in this process."),
    force: bool = typer.Option(False, "--force", help="Redo days that are up to date."),
    workers: int = typer.Option(2, "--workers", min=1, help="Workers of the local cluster."),
    kernels: Path | None = typer.Option(None, "--kernels", help="Meta-kernel for the days."),
    calib: Path | None = typer.Option(None, "--calib", help="Calibration folder."),
    formats: str | None = typer.Option(
        None, "--formats", help="Product formats (default: the mission's: tab,cdf for "
        "rosetta; tab,cdf,png for messenger, png being the offset report's figure)."),
    quicklook: bool = typer.Option(False, "--quicklook", help="Also write a PNG per day."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar; one-line summary."),
) -> None:
    """Process many days on Dask, one task per day; resumable; exits 1 if a day failed."""
    from rich.console import Console

    from fluxcal.products.batch import day_range, task_factory
    from fluxcal.products.staging import Interrupted

    d0, d1 = _parse_date(start, "--start"), _parse_date(end, "--end")
    if d1 < d0:
        raise InputFormatError(f"--end {d1} is before --start {d0}", field="--end")
    factory = task_factory(mission)
    fmts = _preflight(out, kernels, calib, formats, scheduler, mission)
    options = {"kernels": kernels, "calib": calib, "quicklook": quicklook or None,
               "formats": fmts}
    task = factory(input_dir, out, **{k: v for k, v in options.items() if v is not None})
    if mission == "rosetta":
        from fluxcal.missions.rosetta.cli import warn_placeholder_alignment

        warn_placeholder_alignment(task.calib_dir())
    days = day_range(d0, d1)
    console = Console(stderr=True)
    if not logging.getLogger().isEnabledFor(logging.INFO):  # no --verbose
        import distributed  # noqa: F401 - its import sets the 'distributed' logger to INFO

        logging.getLogger("distributed").setLevel(logging.WARNING)
    try:
        report = _run_with_progress(days, task, out, scheduler, workers, force, mission,
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


def _preflight(out: Path, kernels: Path | None, calib: Path | None, formats: str | None,
               scheduler: str | None, mission: str) -> tuple[str, ...] | None:
    """Check what can be checked before the first day; return the formats.

    An unwritable ``--out``, a missing ``--kernels`` file or ``--calib`` folder, an
    unknown format and an unreachable ``--scheduler`` each raise a `FluxcalError`
    (one line, exit 2) before any day is computed or any file is written.  ``formats``
    None (no ``--formats``) returns None: the mission's task keeps its default.
    """
    from fluxcal import preflight
    from fluxcal.products.batch import accepted_formats

    fmts = None
    if formats is not None:
        known = accepted_formats(mission)
        fmts = tuple(f.strip().lower() for f in formats.split(",") if f.strip())
        bad = [f for f in fmts if f not in known]
        if bad or not fmts:
            raise InputFormatError(f"{formats!r}: unknown product format(s) {bad}; choose "
                                   f"from {','.join(known)}", field="--formats")
    if kernels is not None:
        preflight.existing_file(kernels, "--kernels")
    if calib is not None:
        preflight.existing_folder(calib, "--calib")
    preflight.writable_folder(out, "--out")
    if scheduler is not None and scheduler != "serial":
        preflight.reachable_scheduler(scheduler)
    return fmts


def _run_with_progress(days, task, out, scheduler, workers, force, name, console, quiet):
    import time

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    from fluxcal.products.batch import run_batch

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
    for col in ("day", "status", "vectors", "seconds", "error"):
        table.add_column(col)
    style = {"done": "green", "skipped": "cyan", "no_data": "yellow", "failed": "bold red",
             "interrupted": "magenta"}
    for d in report.days:
        table.add_row(d.day, f"[{style.get(d.status, '')}]{d.status}", f"{d.n_vectors:,}",
                      f"{d.seconds:.2f}", (d.error or "")[:120])
    console.print(table)
    console.print(f"{counts}; report: {report.report_path}", soft_wrap=True)



def compare(
    product_a: Path = typer.Argument(..., help="Product A (.TAB/.LBL, .cdf, .nc or .zarr), "
                                     "e.g. an archived CDR."),
    product_b: Path = typer.Argument(..., help="Product B, e.g. fluxcal's reprocessing."),
    tolerance: str = typer.Option("0.01s", "--tolerance",
                                  help="Largest time difference of a matched pair "
                                       "(s, ms, us or ns; default 0.01s)."),
    out: Path | None = typer.Option(None, "--out", help="Folder for the difference plot "
                                    "(default: the current folder)."),
    force: bool = typer.Option(False, "--force", help="Compare even if the frames differ."),
) -> None:
    """Match two products in time; print A - B statistics per component and quality flag."""
    from fluxcal import preflight
    from fluxcal.products.compare import (
        compare as run_compare,
    )
    from fluxcal.products.compare import (
        format_report,
        load_product,
        parse_tolerance,
        write_difference_plot,
    )

    tol = parse_tolerance(tolerance)
    out_dir = out or Path.cwd()
    preflight.writable_folder(out_dir, "--out")
    a, b = load_product(product_a), load_product(product_b)
    result = run_compare(a, b, tol, path_a=str(product_a), path_b=str(product_b), force=force)
    png = write_difference_plot(result, out_dir)
    typer.echo(format_report(result))
    typer.echo(f"plot: {png}")
