"""Simulate MESSENGER MAG telemetry, run ``edr2cdr`` on it and compare with the truth."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.simulate import (
    SimulationConfig,
    read_truth,
    simulate,
    write_inputs,
)
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

log = logging.getLogger(__name__)


def simulate_to_dir(
    out: str | Path, start_utc: str = "2012-06-01T00:00:00", duration_s: float = 7200.0,
    solar_wind: str = "realistic",
) -> dict[str, Path]:
    """Write synthetic kernels, the three input streams and the truth into ``out``.

    ``solar_wind``: the interplanetary field, ``realistic`` or ``quiet``
    (`SimulationConfig`).

    Returns
    -------
    dict
        Paths keyed ``kernels`` (meta-kernel), ``science``, ``heater``, ``temperature``,
        ``truth``.
    """
    out = Path(out)
    config = SimulationConfig(start_utc=start_utc, duration_s=duration_s,
                              solar_wind=solar_wind)
    # the sensor sees the Sun (+Y sunward) in the second quarter of the interval
    mk = write_messenger_like_kernels(
        out / "kernels", start_utc, duration_s + 2 * config.lead_s,
        plus_y_sunward=[(0.25 * duration_s, 0.45 * duration_s)],
    )
    cal = load_calibration(start_utc)
    with KernelPool(mk, frames=FRAME_KERNELS):
        sim = simulate(config, cal, SclkKernel.from_pool(SPACECRAFT_ID))
    paths = write_inputs(sim, out / "inputs")
    return {"kernels": mk, **paths}


def compare(product_tabs: list[Path], truth_path: Path) -> dict[str, np.ndarray]:
    """Recovered-minus-true MSO field statistics per range from MAGMSOSCI tables."""
    from fluxcal.products import read_fluxcal_product

    parts = []
    for tab in sorted(product_tabs):
        prod = read_fluxcal_product(tab)
        parts.append(np.asarray(prod["b"].values, dtype=float))
    truth = read_truth(truth_path)
    # the products are in time order (fast -> slow switches move samples back)
    truth = truth.isel(time=np.argsort(truth["epoch"].values, kind="stable"))
    err = np.concatenate(parts) - truth["b_mso"].values
    stats = {}
    for name, sel in (("fine", truth["range"].values == 0), ("coarse", truth["range"].values == 1)):
        if sel.any():
            stats[f"{name}_rms"] = np.sqrt((err[sel] ** 2).mean(axis=0))
            stats[f"{name}_max"] = np.abs(err[sel]).max(axis=0)
    return stats


def run_demo(out: Path) -> str:
    """Simulate ~2 h of MESSENGER MAG data, run edr2cdr, return the error statistics text."""
    from fluxcal.missions.messenger.routes import run_edr2cdr

    out = Path(out)
    paths = simulate_to_dir(out / "simulation")
    products = out / "products"
    written = run_edr2cdr([paths["science"]], [paths["heater"]], [paths["temperature"]],
                          paths["kernels"], products)
    tabs = [p for p in written if p.name.startswith("MAGMSOSCI1") and p.suffix == ".TAB"]
    stats = compare(tabs, paths["truth"])
    lines = [f"MESSENGER demo: {len(written)} product files in {products}",
             "recovered - true field in MSO (nT), per axis x y z:"]
    for key, value in stats.items():
        lines.append(f"  {key:11s} " + " ".join(f"{v:8.4f}" for v in value))
    return "\n".join(lines)


def run_quick_demo(out: Path, *, duration_s: float = 1800.0) -> str:
    """``make demo``: 30 min of simulated MAG data -> an MSO CDF, its quicklook and report.

    The same chain as `run_demo` (EDR -> CDR, MESSENGER MAG EDR-to-CDR Processing sec.
    5-13) on a shorter interval, one frame (MSO), one format (CDF) and the 60-s average:
    a calibrated product, the offset report and its figure, the quicklook and the run's
    HTML report (``products/index.html``) in seconds.
    """
    from fluxcal.missions.messenger.routes import run_edr2cdr
    from fluxcal.products.html_report import write_run_report

    out = Path(out)
    paths = simulate_to_dir(out / "simulation", duration_s=duration_s)
    products = out / "products"
    written = run_edr2cdr([paths["science"]], [paths["heater"]], [paths["temperature"]],
                          paths["kernels"], products, frames=("mso",), formats=("cdf", "png"),
                          averages=(60,), quicklook=True)
    cdfs = [p for p in written if p.name.startswith("messenger_mag_mso-sci")]
    stats = compare(cdfs, paths["truth"])
    report = write_run_report(products, title="fluxcal demo: MESSENGER MAG EDR -> CDR")
    lines = [f"MESSENGER: {duration_s / 60:g} min simulated, {len(written)} product files in "
             f"{products}", f"  report: {report}",
             "  recovered - true field in MSO (nT), per axis x y z:"]
    for key, value in stats.items():
        lines.append(f"    {key:11s} " + " ".join(f"{v:8.4f}" for v in value))
    return "\n".join(lines)
