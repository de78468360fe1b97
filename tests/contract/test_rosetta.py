"""Rosetta RPC-MAG (``fluxcal rosetta calibrate``, LEVEL_A CDF) under the shared contract.

Expected values: the independent forward model (`fluxcal.missions.rosetta.simulate`,
written from seed 003 only; tests/missions/test_forward_independence.py), its truth
``b_urf`` of the good vectors at the truth's epochs.  Tolerance 0.1 nT per sample: the
20-bit field LSB (0.0286 nT, half of it from rounding) and the thermistor word read back
<= 0.04 K off times |A_1| <= 1.67 nT/K (<= 0.067 nT), as tests/missions/rosetta/
test_round_trip.py states; 0.064 nT measured there.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cdflib
import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.rosetta import io
from fluxcal.testing import MissionContract, Truth
from tests.contract._spoil import replace_csv_field
from tests.missions.rosetta._tables import rosetta_tables, simulate_with


class TestRosetta(MissionContract):
    mission = "rosetta"
    day = dt.date(2014, 8, 1)
    seconds = 300.0
    tolerance_nt = 0.1

    def simulate(self, folder: Path, start: str, seconds: float) -> Truth:
        folder.mkdir(parents=True, exist_ok=True)
        with KernelPool():
            sim = simulate_with(rosetta_tables(), start, seconds, seed=3)
            path = io.write_science_csv(sim.science["OB"], folder / "science_OB.csv")
        truth = sim.truth["OB"]
        good = truth["good"].values
        time = np.asarray(cdflib.cdfepoch.to_datetime(truth["epoch"].values[good]), "M8[ns]")
        return Truth(time, truth["b_urf"].values[good], [path], ("ground", "time_shift"))

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        return ["rosetta", "calibrate", "--science", str(truth.inputs[0]), "--sensor", "OB",
                "--out", str(out), "--levels", "A", "--formats", "cdf"]

    def product_names(self, day: dt.date) -> list[str]:
        return [f"rosetta_rpcmag_cla-ob_{day:%Y%m%d}_v01.cdf"]

    def break_input(self, truth: Truth) -> Path:
        return replace_csv_field(truth.inputs[0], 5, -2, "x")  # a field that is not a number
