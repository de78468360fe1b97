"""An unseen day recalibrated with a calibration folder, against the flight model's truth.

The figure of merit of issue 21 (an unseen day's rms error per sensor axis), shared by
``test_fit_verification.py`` and ``benchmarks/messenger_fit_pulls.py --unseen``; and the
fit demo's unseen 2-h orbit (`unseen_orbit`), shared by ``test_fit_demo_range.py`` and
``benchmarks/messenger_fit_advice.py``.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger import fit_demo
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.fit_merit import day_samples
from fluxcal.missions.messenger.flight_sim import read_flight_truth
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.simulate import SimulationConfig


def day_streams(inp: Path, day: dt.date):
    """The raw streams of ``day`` in a batch input folder (heater and temperature with the
    neighbouring days' records that reach into it)."""
    one = dt.timedelta(days=1)

    def f(code, d):
        return inp / f"MAG{code}_{d:%Y%j}.csv"

    return (read_science([f("SCI", day)]),
            read_heater([p for p in (f("HTR", day - one), f("HTR", day)) if p.exists()]),
            read_temperature([p for p in (f("TMP", day - one), f("TMP", day),
                                          f("TMP", day + one)) if p.exists()]))


def recalibrate_errors(inp: Path, day: dt.date, folder: Path | None
                       ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The pipeline's field less the truth (nT, sensor axes) per sample, and the truth."""
    sci, htr, tmp = day_streams(inp, day)
    cal = load_calibration(np.datetime64(str(day)), folder)
    with KernelPool(inp / "kernels.tm"):
        ds = calibrate(sci, htr, tmp, cal, frames=("sc",), max_offset_step=None)
    truth = read_flight_truth(inp, day)
    assert np.array_equal(ds["met"].values, truth["met"])
    return ds["b_sensor"].values - truth["b_sensor"], truth


def inside_ranges(truth: dict[str, np.ndarray],
                  t_range: StatedRanges | tuple[float, float] | None = None,
                  d_range: tuple[float, float] | None = None) -> np.ndarray:
    """Samples whose true temperature lies in ``t_range`` (C, closed intervals) and, when heater-on
    (the truth's duty cycle of at least the sec. 6 persistence, 10 %), whose duty cycle
    lies in ``d_range`` (percent, ``lo <= d < hi``: ``D_RANGE``)."""
    ok = np.ones(truth["met"].size, dtype=bool)
    if t_range is not None:
        temp = truth["temperature_c"]
        ok &= StatedRanges.of(t_range).contains(temp)
    if d_range is not None:
        d = truth["duty_percent"]
        on = (d >= 10) & (d < 100)
        ok &= ~on | ((d >= d_range[0]) & (d < d_range[1]))
    return ok


def commanded_duty(et: np.ndarray, start_utc: str) -> np.ndarray:
    """The duty cycle (percent) `simulate` commands at each ET (0 before its schedule).

    `SimulationConfig`'s default schedule: 1000-s blocks cycling through its duty cycles
    from ``lead_s`` before ``start_utc`` (the fit demo's unseen 2-h orbit).
    """
    config = SimulationConfig()
    et0 = float(utc_to_et(np.array([start_utc]))[0])
    block = np.floor((np.asarray(et, dtype=float) - et0 + config.lead_s)
                     / config.block_s).astype(int)
    duty = np.asarray(config.duty_cycles_percent)
    return np.where(block >= 0, duty[np.mod(np.maximum(block, 0), duty.size)], 0)


def rms(err: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Per-axis rms of ``err`` over ``mask`` (NaN where no sample)."""
    e = err if mask is None else err[mask]
    return np.sqrt((e ** 2).mean(axis=0)) if e.size else np.full(err.shape[1], np.nan)


def recalibrate_rms(inp: Path, day: dt.date, folder: Path | None,
                    t_range: StatedRanges | tuple[float, float] | None = None) -> np.ndarray:
    """Per-axis rms (nT, sensor axes) of the pipeline's field against the truth.

    ``t_range``: only the samples whose true sensor temperature lies in it (C; the range
    a fitted table states, ``T_RANGE``: `StatedRanges` or one ``(lo, hi)``).
    """
    err, truth = recalibrate_errors(inp, day, folder)
    return rms(err, inside_ranges(truth, t_range))


def unseen_orbit(out: Path, truth_cal, cal, fitted) -> dict:
    """The fit demo's unseen 2-h orbit (`fit_demo.simulate_unseen` with the true tables
    ``truth_cal``, kernels written under ``out``) and the pipeline's calibration of it with
    ``cal`` (spacecraft frame, no offset-step limit).

    Returns ``sim`` (the forward model's streams and truth), ``day`` (the orbit's
    `fit_merit.DaySamples`: its offset moments and heater-on samples per duty bin,
    reduced with the fitted calibration ``fitted``, for the fit's prediction on it),
    ``calibrated`` and ``duty`` (the duty cycle the forward model's schedule commands at
    each true sample, `commanded_duty`).
    """
    with KernelPool(fit_demo.unseen_kernels(out), frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        sim = fit_demo.simulate_unseen(truth_cal, sclk)
        day = day_samples(sim["science"], sim["heater"], sim["temperature"], sclk, fitted)
        ds = calibrate(sim["science"], sim["heater"], sim["temperature"], cal,
                       frames=("sc",), max_offset_step=None)
        # the forward model's schedule (the leapseconds kernel loaded)
        duty = commanded_duty(sim["truth"]["et"].values, fit_demo.UNSEEN_START)
    return {"sim": sim, "day": day, "calibrated": ds, "duty": duty}
