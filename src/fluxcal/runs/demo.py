"""``make demo``: a first run of every mission in seconds; ``--full``: the whole tour.

The quick demo (`DemoPart.quick <fluxcal.runs.contract.DemoPart>`) gives each mission a
calibrated product, a quicklook and the run's HTML report, and writes ``<out>/index.html``
linking them; the full tour (``fluxcal demo --full``, ``make demo-full``) runs every
other part: fits, batch on Dask, cleaning, the archive round trip.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import typer

from fluxcal.products.html_report import (
    REPORT_NAME,
    ProductFile,
    run_products,
    write_run_report,
)
from fluxcal.products.paths import make_folder
from fluxcal.runs import registry
from fluxcal.runs.contract import DemoPart, load_reference
from fluxcal.runs.display_cli import compilation_notice, status_display

log = logging.getLogger(__name__)

#: The generic part of the tour: ``fluxcal batch`` over every mission's demo days.
BATCH_PART = DemoPart("Batch processing on Dask", "fluxcal.runs.batch_demo:run_demo", "batch",
                      50)


def parts(full: bool = True) -> list[DemoPart]:
    """Every registered mission's demo parts of the tour, in tour order.

    ``full``: the full tour (every part but the quick ones, and the batch part); else
    the quick first run (`DemoPart.quick`).
    """
    found = [p for m in registry.missions().values() for p in m.demo_parts
             if p.quick != full]
    found += [BATCH_PART] if full else []
    return sorted(found, key=lambda p: (p.order, p.folder))


def _overview(out: Path) -> Path | None:
    """Write ``out/index.html``: each part's report, quicklooks and product files, linked.

    A part's products are the files of the folder its report describes
    (`~fluxcal.products.html_report.run_products`): data products, quicklooks and
    text reports; the simulated inputs beside them are not products.
    """
    files = []
    for report in sorted(out.glob(f"*/**/{REPORT_NAME}")):
        folder = report.parent.relative_to(out)
        files.append(ProductFile(report.relative_to(out).as_posix(), report, "run report",
                                 None))
        files += [dataclasses.replace(p, rel=(folder / p.rel).as_posix())
                  for p in run_products(report.parent)]
    return write_run_report(out, title="fluxcal demo", products=files) if files else None


def run_demo(out: Path, full: bool = False) -> None:
    """Run the demo into ``out`` (the quick one, or with ``full`` the tour) and summarise."""
    out = out.resolve()
    make_folder(out)
    with compilation_notice():  # a first run compiles the numerical kernels: say so
        for part in parts(full):
            run = load_reference(part.run)
            folder = out / part.folder
            typer.secho(f"\n== {part.title} ==", bold=True)
            start = time.perf_counter()
            with status_display(part.title):
                summary = run(folder)
            typer.echo(summary)
            typer.echo(f"({time.perf_counter() - start:.1f} s; products in {folder})")
    if full:
        typer.secho(f"\nAll demo products are in {out}", bold=True)
        return
    overview = _overview(out)
    typer.secho(f"\nAll demo products are in {out}; open {overview or out} in a browser.\n"
                "The full tour (fits, batch on Dask, cleaning, archive round trip): "
                "fluxcal demo --full (make demo-full).", bold=True)
