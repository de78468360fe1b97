"""``make demo``: run every pipeline on simulated data and say where the products are."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import typer

from fluxcal.runs import registry
from fluxcal.runs.contract import DemoPart, load_reference

log = logging.getLogger(__name__)

#: The generic part of the tour: ``fluxcal batch`` over every mission's demo days.
BATCH_PART = DemoPart("Batch processing on Dask", "fluxcal.runs.batch_demo:run_demo", "batch",
                      50)


def parts() -> list[DemoPart]:
    """Every registered mission's demo parts and the batch part, in tour order."""
    found = [p for m in registry.missions().values() for p in m.demo_parts]
    return sorted([*found, BATCH_PART], key=lambda p: (p.order, p.folder))


def run_demo(out: Path) -> None:
    """Run the demo into ``out`` and print a summary of each part."""
    out = out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    for part in parts():
        run = load_reference(part.run)
        folder = out / part.folder
        typer.secho(f"\n== {part.title} ==", bold=True)
        start = time.perf_counter()
        summary = run(folder)
        typer.echo(summary)
        typer.echo(f"({time.perf_counter() - start:.1f} s; products in {folder})")
    typer.secho(f"\nAll demo products are in {out}", bold=True)
