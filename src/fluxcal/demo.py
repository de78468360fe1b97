"""``make demo``: run every pipeline on simulated data and say where the products are."""

from __future__ import annotations

import importlib
import logging
import time
from pathlib import Path

import typer

log = logging.getLogger(__name__)

#: Parts of the demo, in order: (title, module, function(out: Path) -> str, sub-folder).
PARTS = [
    ("Geometry core", "fluxcal.missions.messenger.geometry_demo", "run_geometry_demo",
     "geometry"),
    ("MESSENGER MAG EDR -> CDR", "fluxcal.missions.messenger.demo", "run_demo", "messenger"),
    ("Rosetta RPC-MAG levels", "fluxcal.missions.rosetta.demo", "run_demo", "rosetta"),
    ("Rosetta disturbance removal", "fluxcal.missions.rosetta.cleaning_demo", "run_demo",
     "rosetta_cleaning"),
    ("Batch processing on Dask", "fluxcal.products.demo", "run_demo", "batch"),
    ("MESSENGER in-flight calibration: simulate, fit, recalibrate, compare",
     "fluxcal.missions.messenger.fit_demo", "run_demo", "messenger_fit"),
    ("Rosetta archive round trip: EDITED raw -> calibrate -> archived products -> compare",
     "fluxcal.missions.rosetta.archive_demo", "run_demo", "rosetta_archive"),
]


def run_demo(out: Path) -> None:
    """Run the demo into ``out`` and print a summary of each part."""
    out = out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    for title, module_name, func_name, sub in PARTS:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError:
            log.info("demo part %s not available", module_name)
            continue
        folder = out / sub
        typer.secho(f"\n== {title} ==", bold=True)
        start = time.perf_counter()
        summary = getattr(module, func_name)(folder)
        typer.echo(summary)
        typer.echo(f"({time.perf_counter() - start:.1f} s; products in {folder})")
    typer.secho(f"\nAll demo products are in {out}", bold=True)
