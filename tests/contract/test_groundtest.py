"""The plugin template (templates/fluxcal-plugin-groundtest) under the shared contract.

Registered with ``FLUXCAL_MISSIONS`` from its source folder (the installed package is
tested in tests/test_plugin_template.py).  Expected values: the template's forward model
(`fluxcal_groundtest.simulate`, the bench values typed in again, no pipeline code).
Tolerance: counts are whole numbers, so each axis is off by up to half a count times its
gain (<= 0.5 * 0.11 * (1 + 1.5e-4 * 25) nT), mixed by a misalignment row whose absolute
sum is <= 1.004: 0.0553 nT; 0.06 nT allows the float rounding.
"""

from __future__ import annotations

import datetime as dt
import sys
from pathlib import Path

import pytest

from fluxcal.testing import MissionContract, Truth

TEMPLATE = Path(__file__).resolve().parents[2] / "templates" / "fluxcal-plugin-groundtest"
sys.path.insert(0, str(TEMPLATE / "src"))
from fluxcal_groundtest import simulate as forward  # noqa: E402


class GroundTest(MissionContract):
    mission = "groundtest"
    tolerance_nt = 0.06

    def register(self, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setenv("FLUXCAL_MISSIONS", "fluxcal_groundtest.mission:MISSION")

    def simulate(self, folder: Path, start: str, seconds: float) -> Truth:
        folder.mkdir(parents=True, exist_ok=True)
        times, counts, temp, b = forward.simulate(start, seconds)
        path = forward.write_csv(folder / f"GT_{start[:10].replace('-', '')}.csv", times,
                                 counts, temp)
        return Truth(times.astype("M8[ns]"), b, [path], ("groundtest_calib",))

    def product_names(self, day: dt.date) -> list[str]:
        return [f"GROUNDTEST_{day:%Y%m%d}{s}" for s in (".cdf", ".TAB", ".LBL")]

    def break_input(self, truth: Truth) -> Path:
        path = truth.inputs[0]
        lines = path.read_text().splitlines()
        lines[5] = lines[5].replace(",", ",x", 1)  # a count that is not a number
        path.write_text("\n".join(lines) + "\n")
        return path


class TestGroundTestSingleRun(GroundTest):
    """``fluxcal groundtest calibrate --input ... --out ...``."""

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        return ["groundtest", "calibrate", *[a for p in truth.inputs for a in ("--input", str(p))],
                "--out", str(out)]


class TestGroundTestBatch(GroundTest):
    """``fluxcal batch groundtest``: a failed day is reported (exit 1), the others done."""

    bad_input_exit = 1

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        d0 = str(truth.time.min())[:10]
        d1 = str(truth.time.max())[:10]
        return ["batch", "groundtest", "--start", d0, "--end", d1, "--input", str(folder),
                "--out", str(out), "--scheduler", "serial", "--quiet"]
