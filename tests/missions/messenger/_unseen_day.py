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
from fluxcal.missions.messenger.fit_variance import reduce_variance
from fluxcal.missions.messenger.flight_sim import read_flight_truth
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.pipeline import calibrate
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature


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

    Returns ``sim`` (the forward model's streams and truth), ``moments`` (the orbit's
    offset moments, `reduce_variance` with the fitted calibration ``fitted``, for the
    fit's prediction on it), ``calibrated`` and ``start_et`` (`fit_demo.UNSEEN_START`).
    """
    with KernelPool(fit_demo.unseen_kernels(out), frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        sim = fit_demo.simulate_unseen(truth_cal, sclk)
        moments = reduce_variance(sim["science"], sim["heater"], sim["temperature"], sclk,
                                  fitted).offset_moments
        ds = calibrate(sim["science"], sim["heater"], sim["temperature"], cal,
                       frames=("sc",), max_offset_step=None)
        start_et = float(utc_to_et(np.array([fit_demo.UNSEEN_START]))[0])
    return {"sim": sim, "moments": moments, "calibrated": ds, "start_et": start_et}
