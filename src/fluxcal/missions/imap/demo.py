"""The IMAP part of ``make demo``: packets -> L1A and L1B products.

fluxcal ships none of the IMAP MAG team's files: the demo reads their ground-test packets,
SCLK kernel, calibration and packet definition from ``../shared/data/imap/`` beside the
checkout (`fluxcal.missions.imap.sources.shared_folder`).  Without them it says so in
one line and runs on fluxcal's forward model instead (`fluxcal.missions.imap.simulate`:
simulated packets with fluxcal's own simulated kernel, calibration and XTCE), comparing
the L1B field with the simulation's truth.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from fluxcal.missions.imap import simulate
from fluxcal.missions.imap.chain import process
from fluxcal.missions.imap.options import ImapOptions
from fluxcal.missions.imap.routes import ImapRun
from fluxcal.missions.imap.sources import TEAM_FILES, missing_team_files, shared_folder
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.runs import driver

#: The simulated inputs of the demo without the team's files: one hour of normal mode,
#: two minutes of burst, every compression width, range changes (a second or two).
SIM_HOURS, SIM_BURST_MINUTES = 1.0, 2.0


def _inputs(out: Path) -> tuple[dict[str, Path], dict | None]:
    """Return the team's files by role, or a simulation written under ``out`` and its truth."""
    folder = shared_folder()
    if folder is not None:
        return ({"inputs": [folder / TEAM_FILES["norm"], folder / TEAM_FILES["burst"]],
                 "calib": folder / TEAM_FILES["calib"], "kernels": folder / TEAM_FILES["sclk"],
                 "xtce": folder / TEAM_FILES["xtce"]}, None)
    sim = out / "simulated_inputs"
    paths = simulate.write_support(sim)
    data, truth, _ = simulate.simulate_day("2025-10-17T00:00:00", SIM_HOURS,
                                           SIM_BURST_MINUTES)
    packets = atomic_write_bytes(sim / simulate.packet_file_name(_dt.date(2025, 10, 17)),
                                 data)
    return {**paths, "inputs": [packets]}, truth


def _truth_line(datasets: dict, truth: dict) -> str:
    """Largest L1B error against the simulation's truth, in half counts of W bits."""
    worst_nt, worst_share = 0.0, 0.0
    for (mode, sensor), t in truth.items():
        err = np.abs(datasets[(mode, sensor)]["b"].values - t.b_nt)
        half = simulate.quantisation_bound(t, sensor)
        worst_nt = max(worst_nt, float(err.max()))
        worst_share = max(worst_share, float((err / half).max()))
    return (f"  L1B vs the simulation's truth: largest |dB| {worst_nt:.3g} nT, "
            f"{np.floor(worst_share * 1e4) / 100:.2f} % of half a count of W bits (the "
            "counts' rounding: <= 100 %)")


def _run(out: Path, level: str, quicklook: bool) -> tuple[str, list[str]]:
    """One level of normal and burst packets into ``out``: what it ran on, summary lines."""
    files, truth = _inputs(out)
    datasets = process(files["inputs"], level=level, calib=files["calib"],
                       kernels=files["kernels"], xtce=files["xtce"])
    options = ImapOptions(level=level, calib=files["calib"], xtce=files["xtce"],
                          quicklook=quicklook)
    paths = driver.write(ImapRun(), datasets, out, options, inputs=files["inputs"],
                         kernel_list=[str(files["kernels"])])
    counts = ", ".join(f"{m}-{s} {ds.sizes['time']}" for (m, s), ds in datasets.items())
    lines = [f"{counts} vectors; {len(paths)} files in {out}"]
    if truth is None:
        return "real IMAP MAG ground-test packets", lines
    lines.append(f"  ran on fluxcal's forward model: {missing_team_files()}")
    if level == "l1b":
        lines.append(_truth_line(datasets, truth))
    return "simulated packets (fluxcal simulate imap)", lines


def run_demo(out: Path) -> str:
    """Decode, time and calibrate IMAP MAG packets (the team's or simulated); summarise."""
    out = Path(out)
    lines = []
    for level in ("l1a", "l1b"):
        source, done = _run(out / level, level, quicklook=level == "l1b")
        lines += [f"{level.upper()} from {source}: {done[0]}", *done[1:]]
    return "\n".join(lines)


def run_quick_demo(out: Path) -> str:
    """``make demo``: packets -> L1B CDFs, quicklooks and the HTML report."""
    from fluxcal.products.html_report import write_run_report

    out = Path(out)
    source, done = _run(out, "l1b", quicklook=True)
    kind = "real" if source.startswith("real") else "simulated"
    report = write_run_report(out, title=f"fluxcal demo: IMAP MAG L1B from {kind} packets")
    return "\n".join([f"IMAP MAG L1B from {source}: {done[0]}", *done[1:],
                      f"  report: {report}"])
