"""The batch part of ``make demo``: ``fluxcal batch`` over two simulated days per mission.

For each registered mission with a batch day task and a ``simulate_days`` (the
contract, `fluxcal.runs.contract.Mission`), its demo days are simulated in the task's
input layout, ``fluxcal batch <mission>`` runs them on a local Dask cluster of two
worker processes (with ``--quicklook``), and then runs again to show that the
up-to-date days are skipped.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import logging
from pathlib import Path

from fluxcal.errors import FluxcalError
from fluxcal.products.paths import make_folder
from fluxcal.runs import registry
from fluxcal.runs.cli import batch
from fluxcal.runs.contract import Mission

log = logging.getLogger(__name__)


def _batch(mission: Mission, days: list[_dt.date], input_dir: Path, out_dir: Path,
           force: bool = False) -> int:
    """Run ``fluxcal batch <mission> --quicklook --quiet`` over ``days``; return its exit code.

    ``force`` redoes days an earlier demo left up to date (the demo removes no folder).
    """
    options = None
    if mission.options is not None:
        options = mission.load("options")()
        if any(f.name == "quicklook" for f in dataclasses.fields(options)):
            options = dataclasses.replace(options, quicklook=True)
    try:
        batch(mission, days[0].isoformat(), days[-1].isoformat(), input_dir, out_dir, options,
              quiet=True, force=force)
    except SystemExit as exc:
        return int(exc.code or 0)
    except (FluxcalError, OSError) as exc:
        log.warning("fluxcal batch %s: %s", mission.name, exc)
        return 2
    return 0


def _run(mission: Mission, days: list[_dt.date], input_dir: Path, out_dir: Path) -> list[str]:
    code = _batch(mission, days, input_dir, out_dir, force=True)
    name = mission.name
    report_path = out_dir / f"batch_report_{name}.json"
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    counts = report.get("counts", {})
    pngs = sorted(out_dir.glob("*.png"))
    n_products = sum(len(d.get("products", [])) for d in report.get("days", []))
    lines = [f"{name}: exit {code}; {counts.get('done', 0)} done, "
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
    code2 = _batch(mission, days, input_dir, out_dir)  # rerun: every done day is skipped
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    lines.append(f"  rerun: exit {code2}; {report.get('counts', {}).get('skipped', 0)} "
                 "day(s) skipped as up to date")
    return lines


def run_demo(out: Path) -> str:
    """Run ``fluxcal batch`` over two simulated days of each mission; return a summary."""
    out = Path(out)  # an earlier demo's files are overwritten, never removed (decision 66)
    lines: list[str] = []
    for mission in _demo_missions():
        inp = out / mission.name / "input"
        make_folder(inp)
        days = list(mission.demo_days)
        try:
            mission.load("simulate_days")(inp, days)
        except Exception as exc:  # noqa: BLE001 - the demo reports and goes on
            log.warning("could not simulate %s days: %s", mission.name, exc)
            lines.append(f"{mission.name}: simulation failed: {exc}")
            continue
        lines += _run(mission, days, inp, out / mission.name / "products")
    return "\n".join(lines)


def _demo_missions() -> list[Mission]:
    """Missions with a day task, demo days and a simulator; the synthetic one first."""
    ready = [m for m in registry.missions().values()
             if m.day_task and m.simulate_days and m.demo_days]
    return sorted(ready, key=lambda m: (m.name != "synthetic", m.name))
