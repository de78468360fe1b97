"""IMAP MAG under the shared mission contract (`fluxcal.testing.MissionContract`).

Streams come from fluxcal's IMAP forward model (`fluxcal.missions.imap.simulate`: its
own bit packer, SCLK kernel, calibration and XTCE; it imports no decoder, L1A or L1B
code): normal mode only, uncompressed (``W = 16``), no forced range change, so every
vector is in range 3, the most sensitive one (asserted on the truth).  The truth's UTC
times are cdflib's conversion of the forward model's TT2000 ``epoch_b`` (the time each
sample measures).  The product read back is ``norm-mago``.

Tolerance: L1B is the calibration matrix times integer counts, so each component is
within half a count of the truth: ``0.5 * sum_j |M[3]_ij|`` of the forward model's
matrices, at most 0.00232 nT (MAGi's second row); 0.0024 nT allows the float rounding.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import cdflib
import numpy as np

from fluxcal.missions.imap import simulate
from fluxcal.runs import registry
from fluxcal.testing import MissionContract, Truth

RANGE = 3  # the most sensitive range: a solar-wind field of a few nT


class TestImapContract(MissionContract):
    mission = "imap"
    day = dt.date(2024, 3, 12)
    seconds = 600.0
    tolerance_nt = 0.0024

    def simulate(self, folder: Path, start: str, seconds: float) -> Truth:
        support = simulate.write_support(folder)
        data, truth, _ = simulate.simulate_day(start, seconds / 3600, 0, widths=(0,),
                                               range_changes=False)
        packets = folder / "stream.pkts"
        packets.write_bytes(data)
        for t in truth.values():
            assert (t.ranges == RANGE).all() and (t.width == 0).all()
        worst = max(float((0.5 * np.abs(simulate.matrices(s)[RANGE]).sum(axis=1)).max())
                    for s in ("mago", "magi"))
        assert worst < self.tolerance_nt
        mago = truth[("norm", "mago")]
        times = np.asarray(cdflib.cdfepoch.to_datetime(mago.epoch_b), dtype="M8[ns]")
        self.support = support
        return Truth(times, mago.b_nt, [packets], ("imap_mag_l1b",))

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        return ["imap", "calibrate", "--input", str(truth.inputs[0]), "--out", str(out),
                "--kernels", str(self.support["kernels"]), "--calib",
                str(self.support["calib"]), "--xtce", str(self.support["xtce"])]

    def product_names(self, day: dt.date) -> list[str]:
        return [f"imap_mag_l1b_norm-{s}_{day:%Y%m%d}_v001.cdf" for s in ("mago", "magi")]

    def break_input(self, truth: Truth) -> Path:
        path = truth.inputs[0]
        data = path.read_bytes()
        path.write_bytes(data[:len(data) // 2 + 7])  # the last packet cut short
        return path

    def day_task(self, folder: Path, out: Path, truth: Truth) -> Any:
        make_day_task = registry.get(self.mission).load("day_task")
        return make_day_task(folder, out, kernels=self.support["kernels"],
                             calib=self.support["calib"], xtce=self.support["xtce"])
