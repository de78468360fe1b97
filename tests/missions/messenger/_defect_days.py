"""Forward-model days carrying every MESSENGER telemetry defect class (issue 23).

The raw streams come from the forward model (`fluxcal.missions.messenger.simulate`, which
shares no code with the pipeline: ``tests/missions/test_forward_independence.py``); the
defects are put into those raw streams here, with numpy, before they are written as CSV
(or as EDRs by ``edr_write``).  Nothing of the pipeline (readers, levels, defects) is used.
The truth (one row per true sample) is left as simulated.

One 6-h day, each defect in its own part (seconds after the start of the science):

=====================  ==================================================================
defect                 how it is made
=====================  ==================================================================
heater gap             heater records removed over `HEATER_GAP` (200 s > one period)
temperature gap        temperature records removed over `TEMP_GAP` (900 s > 600 s)
temperature glitch     +5 degC on the record nearest `GLITCH_AT`
science gap            science samples removed over `SCIENCE_GAP`
rate change at a gap   the rate setting changes inside the science gap `RATE_GAP`
range change at a gap  the range goes coarse inside the science gap `RANGE_GAP`
clock jump             the samples of `SPIKE` get MET + 3000 s; those of `REPEAT` are
                       sent a second time after it (MET jumps back)
=====================  ==================================================================
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

START = "2012-06-01T00:00:00"
DAY_S = 6 * 3600.0
LEAD_S = 1200.0  # SimulationConfig.lead_s: the heater schedule starts this long before
HEATER_GAP = (300.0, 500.0)
TEMP_GAP = (6000.0, 6900.0)
GLITCH_AT = 8000.0
SCIENCE_GAP = (10000.0, 10300.0)
RATE_GAP = (12600.0, 12700.0)
RANGE_GAP = (14900.0, 15000.0)
COARSE = (14950.0, 15500.0)
SPIKE = (17000.0, 17010.0)
REPEAT = (19000.0, 19020.0)
SPIKE_S = 3000.0
#: Every cause the day carries (names of docs/formats/messenger.md, "Defect flag").
CAUSES = ("heater_gap", "temperature_gap", "temperature_glitch", "science_gap",
          "rate_change_at_gap", "range_change_at_gap", "clock_jump")


def kernels(folder: Path) -> Path:
    """A synthetic kernel set for the day (+Y sunward over 1-2 h)."""
    return write_messenger_like_kernels(folder, START, DAY_S + 2 * LEAD_S,
                                        plus_y_sunward=[(3600.0, 7200.0)])


def config(rate: int, other_rate: int, sign: float) -> SimulationConfig:
    """The day's schedule: ``rate`` until `RATE_GAP`, ``other_rate`` after; field sign."""
    windows = [(0.0, SCIENCE_GAP[0]), (SCIENCE_GAP[1], RATE_GAP[0]),
               (RATE_GAP[1], RANGE_GAP[0]), (RANGE_GAP[1], DAY_S)]
    mid = 0.5 * (RATE_GAP[0] + RATE_GAP[1])
    return SimulationConfig(
        start_utc=START, duration_s=DAY_S, lead_s=LEAD_S,
        rate_segments=[(0.0, rate), (mid / DAY_S, other_rate)],
        coarse_intervals=[(COARSE[0] / DAY_S, COARSE[1] / DAY_S)],
        science_windows=windows,
        heater_gaps=[(HEATER_GAP[0] + LEAD_S, HEATER_GAP[1] + LEAD_S)],
        imf_nt=(12.0 * sign, -8.0 * sign, 5.0 * sign), solar_wind="quiet",  # the sign flips
        waves=[(3.0 * sign, 2.0), (1.0 * sign, 0.31)],
    )


def inject(sim: dict[str, xr.Dataset], *, clock: bool = True) -> dict[str, xr.Dataset]:
    """The temperature gap and glitch and (``clock``) the clock jumps, on the raw streams."""
    out = dict(sim)
    met0 = float(sim["science"]["met"].values[0])  # the first sample: the science start
    temp = sim["temperature"]
    rel = temp["met"].values - met0
    keep = ~((rel > TEMP_GAP[0]) & (rel < TEMP_GAP[1]))
    values = temp["temperature_c"].values.copy()
    values[int(np.argmin(np.abs(rel - GLITCH_AT)))] += 5.0
    out["temperature"] = temp.assign(temperature_c=("temperature_time", values)).isel(
        temperature_time=keep)
    if clock:
        sci = sim["science"]
        rel = sci["met"].values - met0
        met = sci["met"].values.copy()
        spike = (rel >= SPIKE[0]) & (rel < SPIKE[1])
        met[spike] += SPIKE_S
        sci = sci.assign(met=("time", met, sci["met"].attrs))
        repeat = np.flatnonzero((rel >= REPEAT[0]) & (rel < REPEAT[1]))
        order = np.concatenate([np.arange(repeat[-1] + 1), repeat,
                                np.arange(repeat[-1] + 1, rel.size)])
        out["science"] = sci.isel(time=order)
    return out


def day(folder: Path, mk: Path, rate: int, other_rate: int, sign: float,
        *, clock: bool = True) -> tuple[dict[str, xr.Dataset], dict[str, Path]]:
    """Simulate, inject, write the CSV streams; return the streams and their paths."""
    with KernelPool(mk):
        sim = simulate(config(rate, other_rate, sign), load_calibration(START),
                       SclkKernel.from_pool(-236))
    sim = inject(sim, clock=clock)
    return sim, write_inputs(sim, folder)

