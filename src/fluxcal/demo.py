"""``make demo``: run every pipeline on embedded/simulated data and say where products are."""

from __future__ import annotations

from pathlib import Path


def run_demo(out: Path) -> None:
    """Run the demo into ``out``."""
    from fluxcal.geometry.demo import run_geometry_demo

    out.mkdir(parents=True, exist_ok=True)
    run_geometry_demo(out / "geometry")
