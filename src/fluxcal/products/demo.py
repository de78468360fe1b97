"""The batch part of ``make demo``: ``fluxcal batch`` over two simulated days per mission.

For each mission with a batch day task, two days of raw input are simulated in the
task's input layout, ``fluxcal batch <mission>`` runs them on a local Dask cluster of
two worker processes (with ``--quicklook``), and then runs again to show that the
up-to-date days are skipped.  The synthetic task always runs, so the demo shows the
machinery even when a mission task is missing.

A mission's ``batch_task`` module may provide ``simulate_days(input_dir, days)`` to
write its demo inputs (Rosetta: 15 minutes of both sensors per day, with a kernel set,
so the task makes LEVEL_A, B, C, E, F, G and the HK product); for MESSENGER, a
fallback simulates a stretch across a UTC midnight with the mission's forward model
and splits the three CSV streams by the UTC day of their recorded MET.
"""

from __future__ import annotations

import datetime as _dt
import importlib
import json
import logging
import shutil
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

SYNTHETIC_DAYS = (_dt.date(2024, 1, 1), _dt.date(2024, 1, 2))
MESSENGER_DAYS = (_dt.date(2012, 6, 1), _dt.date(2012, 6, 2))
ROSETTA_DAYS = (_dt.date(2014, 11, 1), _dt.date(2014, 11, 2))


def _split_by_day(path: Path, stream: str, out_dir: Path, sclk) -> list[Path]:
    """Split a MESSENGER CSV (``partition,met,...``) into ``MAG<stream>_YYYYDDD.csv``."""
    from fluxcal.geometry.time import et_to_utc

    lines = path.read_text().splitlines()
    header, rows = lines[0], np.array(lines[1:])
    pm = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1), ndmin=2)
    et = sclk.to_et(pm[:, 0].astype(int), pm[:, 1])
    days = np.array([u[:10] for u in et_to_utc(et, style="iso", digits=0)])
    written = []
    for day in np.unique(days):
        d = _dt.date.fromisoformat(str(day))
        dest = out_dir / f"MAG{stream}_{d:%Y%j}.csv"
        dest.write_text("\n".join([header, *rows[days == day].tolist()]) + "\n")
        written.append(dest)
    return written


def simulate_messenger_days(input_dir: Path, duration_s: float = 1800.0,
                            start: _dt.datetime | None = None,
                            rate_setting: int | None = None) -> list[_dt.date]:
    """Simulate MESSENGER MAG telemetry; write the batch input layout (one file per day).

    By default ``duration_s`` centred on the midnight between the two demo days.  With
    ``rate_setting`` (Table 1, e.g. 6 = 1 vector/s) the whole stretch uses that rate
    (long benchmark stretches).  Returns the UTC days that received science data.
    """
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.synthetic import copy_meta_kernel
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

    input_dir = Path(input_dir)
    work = input_dir / "simulation"
    if start is None:
        start = _dt.datetime.combine(MESSENGER_DAYS[1], _dt.time()) - _dt.timedelta(
            seconds=duration_s / 2)
    start_utc = start.strftime("%Y-%m-%dT%H:%M:%S")
    config = SimulationConfig(start_utc=start_utc, duration_s=duration_s)
    if rate_setting is not None:
        config.rate_segments = [(0.0, rate_setting)]
    mk = write_messenger_like_kernels(work / "kernels", start_utc,
                                      duration_s + 2 * config.lead_s,
                                      plus_y_sunward=[(0.25 * duration_s, 0.45 * duration_s)])
    with KernelPool(mk):
        sim = simulate(config, load_calibration(start_utc), SclkKernel.from_pool(-236))
    paths = {"kernels": mk, **write_inputs(sim, work / "inputs")}
    with KernelPool(paths["kernels"]):
        sclk = SclkKernel.from_pool(-236)
        days = []
        for key, stream in (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP")):
            written = _split_by_day(Path(paths[key]), stream, input_dir, sclk)
            if key == "science":
                days = [_dt.datetime.strptime(p.stem[-7:], "%Y%j").date() for p in written]
    copy_meta_kernel(paths["kernels"], input_dir / "kernels.tm")  # paths relative to it
    return days


def _mission_inputs(mission: str, input_dir: Path) -> list[_dt.date] | None:
    """Write the demo inputs of ``mission``; ``None`` if the mission cannot be simulated."""
    try:
        module = importlib.import_module(f"fluxcal.missions.{mission}.batch_task")
    except ModuleNotFoundError:
        return None
    sim = getattr(module, "simulate_days", None)
    if callable(sim):
        days = list(MESSENGER_DAYS if mission == "messenger" else ROSETTA_DAYS)
        sim(input_dir, days)
        return days
    if mission == "messenger":
        return simulate_messenger_days(input_dir)
    return None


def _run(mission: str, days: list[_dt.date], input_dir: Path, out_dir: Path,
         extra: list[str]) -> list[str]:
    from fluxcal.cli import main

    args = ["batch", mission, "--start", days[0].isoformat(), "--end", days[-1].isoformat(),
            "--input", str(input_dir), "--out", str(out_dir), "--quicklook", "--quiet", *extra]
    code = main(args)
    report_path = out_dir / f"batch_report_{mission}.json"
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    counts = report.get("counts", {})
    pngs = sorted(out_dir.glob("*.png"))
    n_products = sum(len(d.get("products", [])) for d in report.get("days", []))
    lines = [f"{mission}: exit {code}; {counts.get('done', 0)} done, "
             f"{counts.get('skipped', 0)} skipped, {counts.get('failed', 0)} failed in "
             f"{report.get('wall_seconds', 0):.1f} s "
             f"({report.get('vectors_per_second', 0):,.0f} vectors/s)",
             f"  inputs:     {input_dir}",
             f"  products:   {out_dir} ({n_products} files, manifests in "
             f"{out_dir / 'manifests'})",
             f"  quicklooks: {len(pngs)} PNG"
             + (f", e.g. {pngs[0].name}" if pngs else ""),
             f"  report:     {report_path}"]
    for d in report.get("days", []):
        if d["status"] == "failed":
            lines.append(f"  FAILED {d['day']}: {d['error']}")
    code2 = main(args)  # rerun: every done day is skipped
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    lines.append(f"  rerun: exit {code2}; {report.get('counts', {}).get('skipped', 0)} "
                 "day(s) skipped as up to date")
    return lines


def run_demo(out: Path) -> str:
    """Run ``fluxcal batch`` over two simulated days of each mission; return a summary."""
    from fluxcal.products.synthetic_task import write_synthetic_inputs

    out = Path(out)
    if out.exists():
        shutil.rmtree(out)
    lines: list[str] = []
    inp = out / "synthetic" / "input"
    write_synthetic_inputs(inp, list(SYNTHETIC_DAYS), n_per_day=86_400)
    lines += _run("synthetic", list(SYNTHETIC_DAYS), inp, out / "synthetic" / "products", [])
    for mission in ("messenger", "rosetta"):
        inp = out / mission / "input"
        inp.mkdir(parents=True, exist_ok=True)
        try:
            days = _mission_inputs(mission, inp)
        except Exception as exc:  # noqa: BLE001 - the demo reports and goes on
            log.warning("could not simulate %s days: %s", mission, exc)
            lines.append(f"{mission}: simulation failed: {exc}")
            continue
        if days is None:
            lines.append(f"{mission}: no batch day task (fluxcal.missions.{mission}.batch_task)"
                         " or demo simulation yet; skipped")
            continue
        lines += _run(mission, days, inp, out / mission / "products", [])
    return "\n".join(lines)
