"""The synthetic mission (``fluxcal batch synthetic``) under the shared contract.

Forward model written here from its format (fluxcal.runs.synthetic_task's docstring):
counts = round(B / gain + offset), times TT2000 by cdflib.  Tolerance: whole counts,
half a count times the gain (0.5 * 0.05 nT) plus float rounding: 0.026 nT.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cdflib
import numpy as np

from fluxcal.testing import MissionContract, Truth
from tests.contract._spoil import replace_csv_field

GAIN, OFFSET = 0.05, np.array([12.0, -7.0, 3.0])


def _tt2000(times: np.ndarray) -> np.ndarray:
    fields = [[int(x) for x in (str(t)[:4], str(t)[5:7], str(t)[8:10], str(t)[11:13],
                                str(t)[14:16], str(t)[17:19])] + [0, 0, 0] for t in times]
    return np.asarray(cdflib.cdfepoch.compute_tt2000(fields), dtype=np.int64)


class TestSynthetic(MissionContract):
    mission = "synthetic"
    day = dt.date(2024, 1, 1)
    tolerance_nt = 0.026
    field = "B"
    bad_input_exit = 1

    def simulate(self, folder: Path, start: str, seconds: float) -> Truth:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "synthetic_calib.txt").write_text(
            f"# test calibration\noffset = {OFFSET[0]} {OFFSET[1]} {OFFSET[2]}\ngain = {GAIN}\n")
        t = np.arange(int(seconds))
        times = np.datetime64(start, "ns") + t.astype("m8[s]")
        b = np.stack([300 * np.sin(t / 50), -200 * np.cos(t / 70), 50 + 0 * t], axis=1)
        counts = np.round(b / GAIN + OFFSET).astype(np.int64)
        epoch = _tt2000(times)
        inputs = []
        for day in np.unique(times.astype("M8[D]")):
            rows = times.astype("M8[D]") == day
            path = folder / f"SYNTH_{str(day).replace('-', '')}.csv"
            np.savetxt(path, np.column_stack([epoch[rows], counts[rows]]), fmt="%d",
                       delimiter=",", header="epoch_ns,cx,cy,cz", comments="")
            inputs.append(path)
        return Truth(times, b, inputs, ("synthetic_calib",))

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        return ["batch", "synthetic", "--start", str(truth.time.min())[:10], "--end",
                str(truth.time.max())[:10], "--input", str(folder), "--out", str(out),
                "--scheduler", "serial", "--quiet", "--formats", "cdf"]

    def product_names(self, day: dt.date) -> list[str]:
        return [f"SYNTH_{day:%Y%m%d}_v01.cdf"]

    def break_input(self, truth: Truth) -> Path:
        return replace_csv_field(truth.inputs[0], 3, -1, "1.5")  # not an integer count
