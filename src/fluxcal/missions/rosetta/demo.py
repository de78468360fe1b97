"""Rosetta part of ``make demo``: simulate, calibrate, compare with the truth."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


def _rms(diff: np.ndarray) -> str:
    rms = np.sqrt(np.mean(diff**2, axis=0))
    return " ".join(f"{v:.4f}" for v in rms)


def run_demo(out: Path, *, hours: float = 1.0) -> str:
    """Simulate ``hours`` of RPC-MAG telemetry, calibrate A, B, C, E, F, G, and summarise.

    Returns
    -------
    str
        A few lines: files written, recovered-minus-true rms per level and sensor.
    """
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import run_files
    from fluxcal.missions.rosetta.simulate import read_truth_csv, write_simulation

    t0 = time.perf_counter()
    out = Path(out)
    paths = write_simulation(out / "raw", hours=hours)
    lines = [f"Rosetta RPC-MAG: simulated {hours:g} h at 20 Hz into {out / 'raw'}"]
    n_files = 0
    for sensor in ("OB", "IB"):
        made: dict = {}
        written = run_files(
            paths[f"science_{sensor}"],
            sensor,
            out / "products",
            hk=paths["hk"] if sensor == "OB" else None,
            kernels=paths["kernels"],
            # the frame of the simulator's truth (default: CSEQ by date)
            options=RosettaOptions(calib=paths["calib"], levels=tuple("ABCEFG"),
                                   frame="ECLIPJ2000"),
            on_calibrated=lambda run: made.update(run.sensors[0].levels),  # noqa: B023
        )
        n_files += len(written)
        truth = read_truth_csv(paths[f"truth_{sensor}"])
        good = truth["good"]
        order = np.argsort(truth["epoch"][good], kind="stable")
        parts = []
        for level, name in (("A", "b_urf"), ("B", "b_sc"), ("C", "b_ref")):
            diff = made[level]["b"].values - truth[name][good][order]
            parts.append(f"{level} {_rms(diff)}")
        g = made["G"]
        lines.append(
            f"  {sensor}: {made['A'].sizes['time']} vectors "
            f"({made['A'].attrs['n_dropped_quality']} bad dropped), {g.sizes['time']} 1-s "
            f"averages; recovered-true rms x y z [nT]: " + "; ".join(parts)
        )
    lines.append(
        f"  {n_files} product files in {out / 'products'} ({time.perf_counter() - t0:.1f} s)"
    )
    return "\n".join(lines)


def run_quick_demo(out: Path, *, hours: float = 0.25) -> str:
    """``make demo``: 15 min of simulated RPC-MAG data -> LEVEL_A..C CDFs, quicklook, report.

    The outboard sensor of `run_demo`'s simulation (RO-IGEP-TR0028 sec. 4.1-4.4), written
    as CDF with its quicklook and the run's HTML report (``products/index.html``).
    """
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import run_files
    from fluxcal.missions.rosetta.simulate import read_truth_csv, write_simulation
    from fluxcal.products.html_report import write_run_report

    out = Path(out)
    paths = write_simulation(out / "raw", hours=hours)
    products = out / "products"
    levels: dict = {}
    written = run_files(
        paths["science_OB"], "OB", products, hk=paths["hk"], kernels=paths["kernels"],
        options=RosettaOptions(calib=paths["calib"], levels=("A", "B", "C"),
                               frame="ECLIPJ2000", formats=("cdf",), quicklook=True),
        on_calibrated=lambda run: levels.update(run.sensors[0].levels),
    )
    truth = read_truth_csv(paths["truth_OB"])
    good = truth["good"]
    order = np.argsort(truth["epoch"][good], kind="stable")
    diff = levels["C"]["b"].values - truth["b_ref"][good][order]
    report = write_run_report(products, title="fluxcal demo: Rosetta RPC-MAG levels")
    return "\n".join([
        f"Rosetta RPC-MAG: {hours * 60:g} min simulated at 20 Hz (OB), "
        f"{levels['A'].sizes['time']} vectors, {len(written)} product files in "
        f"{products}", f"  report: {report}",
        f"  LEVEL_C recovered - true rms x y z [nT]: {_rms(diff)}"])
