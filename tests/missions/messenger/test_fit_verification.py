"""Issue 13 verification: the in-flight fit recovers calibration tables it was not given.

`fluxcal.missions.messenger.flight_sim` (a forward model sharing no code with the fit or
the pipeline, tests/missions/test_forward_independence.py) simulates cruise days from
*true* tables that differ from the seed's (Table 2/3 coefficients and tau changed by
25-60 %, Tables 6-8 scaled by 0.7-1.4 per axis).  The fit (`fit_days`, started from the
shipped tables) must recover them, and the tables it writes must calibrate an unseen day.

Two solar winds (docs/decisions/messenger_fit_verification.md):

* ``quiet``: the heater schedule, temperature excursions and instrument of a real cruise,
  but a weak zero-mean field (0.02 nT, 60-s rotations) plus 0.02 nT noise.  The
  statistical error of every binned average is then far below the issue's tolerances
  (derived at each assertion), so these check the *estimators*: any bias (binning,
  iteration, the look-back) shows up.  The tolerances are the issue's numbers.
* ``realistic``: 5-10 nT Alfvenic rotations with sector changes.  In days, a binned
  average of such a field cannot reach the issue's numbers (sigma / sqrt(N) with an
  hour-long correlation time: tens of counts per temperature bin); the test checks
  the fit against that statistical bound and that the fitted tables still beat the
  shipped ones.  The issue's numbers need ~1-2 years of such data (the decision note).
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.flight_sim import (
    FlightConfig,
    SolarWindModel,
    read_flight_truth,
    simulate_flight,
)
from tests.missions.messenger._unseen_day import recalibrate_rms

fit_passes = pytest.importorskip("fluxcal.missions.messenger.fit_passes",
                                 reason="the issue 13 fit (helper H3) is not in the tree yet")
if not all(hasattr(fit_passes, n) for n in ("fit_days", "day_chunks")):
    pytest.skip("fluxcal.missions.messenger.fit_passes lacks fit_days/day_chunks",
                allow_module_level=True)
fit_write = pytest.importorskip("fluxcal.missions.messenger.fit_write")

START = dt.date(2010, 3, 1)
#: Fine-range nT per count (Table 4 kx ~ 0.047): 2 counts ~ 0.094 nT.
NT_PER_COUNT = 1530.0 / 32768.0


def _law(tables: forward.SeedTables | np.ndarray, t: np.ndarray) -> np.ndarray:
    """Table 2 offset (counts) at temperatures ``t``: the larger of the two lines."""
    c = tables if isinstance(tables, np.ndarray) else np.column_stack(
        [tables.a0, tables.b0, tables.a1, tables.b1])
    return np.maximum(c[:, 0] + c[:, 1] * t[:, None], c[:, 2] + c[:, 3] * t[:, None])


def _binned_law_error(temps: np.ndarray, tables: forward.SeedTables, edges: np.ndarray,
                      t: np.ndarray) -> np.ndarray:
    """Error of the seed's estimator itself, without noise (an independent computation).

    The exact law averaged in each 10-C bin of the heater-off temperatures ``temps``,
    placed at the bin's mean temperature, fitted by two lines joined at a free break
    (scipy least squares from 30 starting breaks, sqrt(N) amplitude weights, eq. 3-4);
    returns max |fit - law| over ``t`` per axis.  A convex law's bin mean lies above
    the law at the mean temperature where the break falls inside a bin.
    """
    from scipy.optimize import least_squares

    law = _law(tables, temps)
    k = np.digitize(temps, edges)
    bins = np.unique(k)
    x = np.array([temps[k == b].mean() for b in bins])
    w = np.sqrt([np.count_nonzero(k == b) for b in bins])

    def model(p, x):
        a0, b0, b1, tm = p
        return np.where(x <= tm, a0 + b0 * x, a0 + b0 * tm + b1 * (x - tm))

    out = []
    for j in range(3):
        y = np.array([law[k == b, j].mean() for b in bins])
        fits = [least_squares(lambda p, y=y: w * (model(p, x) - y), [y.mean(), 1.0, 3.0, tm0])
                for tm0 in np.arange(-40.0, 20.0, 2.0)]
        best = min(fits, key=lambda r: r.cost)
        out.append(np.abs(model(best.x, t) - _law(tables, t)[:, j]).max())
    return np.array(out)


def _run(tmp: Path, config: FlightConfig, fit_days: int, passes: int):
    """Simulate ``fit_days`` + 1 days, fit the first ones, write the folder."""
    run = simulate_flight(tmp / "sim", config)
    days = run.days[:fit_days]
    base = load_calibration(np.datetime64(str(START)))
    result = fit_passes.fit_days(fit_passes.day_chunks(run.input_dir, days), base, passes=passes)
    out = tmp / "fitted"
    fit_write.write_calibration_folder(result, out, None, {
        "inputs": {}, "intervals": "all data", "days": f"{days[0]}..{days[-1]}",
        "command": "test_fit_verification"})
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    return run, result, true, out


# --------------------------------------------------------------------------------------
# quiet wind: the tolerances
# --------------------------------------------------------------------------------------
QUIET = SolarWindModel(b_median_nt=0.02, parker_strength=0.0, alfven_correlation_s=30.0,
                       compressive_correlation_s=30.0, noise_nt=0.02)
#: Per-sample scatter of the counts about the zero level (counts): field (0.02 nT over
#: three axes, 0.012 nT each), noise 0.02 nT, rounding 1/sqrt(12): sqrt(0.25^2 + 0.43^2
#: + 0.29^2) = 0.57 counts; correlated over ~4 tau = 120 s (two cascaded 30-s stages).
QUIET_SIGMA_COUNTS = 0.57
QUIET_CORRELATION_S = 120.0
QUIET_FIT_DAYS = 3


def test_fit_recovers_altered_tables_in_a_quiet_wind(tmp_path):
    # one test, one fit (~30-60 s): under pytest-xdist separate tests would each redo it
    config = FlightConfig(start=str(START), days=QUIET_FIT_DAYS + 1, seed=1313,
                          solar_wind=QUIET)
    run, result, true, folder = _run(tmp_path, config, QUIET_FIT_DAYS, passes=6)
    cal = result.calibration
    errors = {}
    # --- temperature law -----------------------------------------------------------------
    # every 10-C bin centred on -60..+40 C holds >= 1000 s of 1-Hz heater-off data, so its
    # mean has sigma <= 0.57 * sqrt(120 / 1000) = 0.2 counts (most bins 10x more data,
    # ~0.06 counts); the two-segment fit's value at any temperature is a weighted mix of
    # a few bins: <= 0.3 counts at 1 sigma where it leans on the sparsest bin, ~0.1
    # elsewhere.  The default estimator (bin averages of the law over each bin's
    # temperatures, docs/decisions/messenger_fit.md entry 8) has no bias of its own
    # (tests/calibration/test_constrained_fits.py), so it must reach that statistical
    # error: 0.3 counts (0.014 nT), besides the 2 counts.
    centres = result.stats.temperature.centers
    counts = result.stats.temperature.count[(centres >= -60) & (centres <= 40)]
    assert counts.min() >= 1000, counts
    assert result.temperature_law == "distribution"
    t = np.arange(-60.0, 40.01, 0.5)
    law = np.abs(_law(cal.temperature_coefficients, t) - _law(true, t)).max(axis=0)
    errors["temperature law max |error| (counts), tol 2"] = (law, 2.0)
    errors["temperature law max |error| (counts), statistical tol 0.3"] = (law, 0.3)
    # the seed's estimator (law at the bins' mean temperatures), selected for one more
    # pass from the converged tables, is the binned estimator's own error (here up to
    # 1.7 counts on z, the break inside a bin), computed without noise from the true
    # heater-off temperatures: the fit equals it within its statistical error (0.3 count)
    seed_fit = fit_passes.fit_days(fit_passes.day_chunks(run.input_dir, run.days[:-1]), cal,
                                   passes=1, temperature_law="binned-mean",
                                   guard=False)  # a study pass
    assert seed_fit.temperature_law == "binned-mean"
    seed_law = np.abs(_law(seed_fit.calibration.temperature_coefficients, t)
                      - _law(true, t)).max(axis=0)
    truths = [read_flight_truth(run.input_dir, d) for d in run.days[:-1]]
    temps = np.concatenate([tr["temperature_c"][tr["duty_percent"] == 0] for tr in truths])
    expected = _binned_law_error(temps, true, np.arange(-105.0, 106.0, 10.0), t)
    errors["binned-mean: |fit error - binned-estimator error| (counts), tol 0.3"] = (
        np.abs(seed_law - expected), 0.3)
    # the bias is there to be removed: > 1 count on z with the seed's estimator
    assert expected[2] > 1.0 and seed_law[2] > 1.0, (expected, seed_law)
    # --- duty-cycle law -------------------------------------------------------------------
    # D0 from ~8 4-% bins over 100-450 ppt, each > 10^4 samples: statistical error
    # ~0.57 * sqrt(120 / 10^4) / 300 ppt = 2e-4 counts/ppt, < 1 % of the smallest D0 (z,
    # 0.024); the held intercept (temperature law at -50 C, <= 0.3 count at 1 sigma)
    # moves it by <= 0.3 / 280 ppt = 1e-3 (4 % of z at 1 sigma, < 1.5 % of x and y).
    d0 = np.abs(cal.duty_cycle_d0 / true.d0 - 1.0)
    errors["D0 relative error, tol 0.05"] = (d0, 0.05)
    # --- relaxation time ------------------------------------------------------------------
    # ~40 changes of >= 50 ppt per day, ~120 events in 3 days: per 5-s lag bin the
    # epoch (counts per ppt of step) scatters 0.57 counts / 100 ppt / sqrt(120 events)
    # = 5e-4, 0.2 % of the unit response (D0 of y, 0.23); an exponential through ~200
    # such bins pins tau far below 1 %.  Issue: 10 %.
    tau = cal.constants["relaxation"]["tau_s"] / true.constants["relaxation"]["tau_s"] - 1
    errors["tau relative error, tol 0.10"] = (np.array([abs(tau)]), 0.10)
    # --- heater waveforms -----------------------------------------------------------------
    # per phase second of one 4-% bin: >= 150 heater cycles in 3 days, scatter 0.57
    # counts, decorrelated between cycles (the field's 2-min correlation < the 100-s
    # period spacing x a few) -> 0.57 / sqrt(150) = 0.05 counts per phase; the rms over
    # the cycle the same: the 0.3 is 6 sigma.  A column's mean over the cycle
    # belongs to the duty-cycle law (fit_reduce): both sides compared without it.
    f0 = cal.heater_signal - cal.heater_signal[:, :-1].mean(axis=1, keepdims=True)
    r0 = true.heater - true.heater[:, :-1].mean(axis=1, keepdims=True)
    rms = np.sqrt(((f0 - r0)[:, :-1] ** 2).mean(axis=1))  # (axis, duty bin)
    errors["waveform rms (counts) per axis x bin, tol 0.3"] = (rms, 0.3)
    # --- recalibrating an unseen day ------------------------------------------------------
    # the fitted zero level errs by <~1 count (the laws above), 0.05 nT; rounding adds
    # 0.047 / sqrt(12) = 0.014 nT: 0.1 nT rms holds if the fit is unbiased.
    unseen = run.days[-1]
    fitted = recalibrate_rms(run.input_dir, unseen, folder)
    errors["unseen day rms (nT), fitted tables, tol 0.1"] = (fitted, 0.1)
    shipped = recalibrate_rms(run.input_dir, unseen, None)
    report = "\n".join(f"{k}: {np.round(v, 4).tolist()}" for k, (v, _) in errors.items())
    print(report + f"\nunseen day rms (nT), shipped tables: {shipped.round(3).tolist()}"
          f"\nbinned-mean temperature law max |error| (counts): {seed_law.round(3).tolist()}"
          f", noise-free binned estimator: {expected.round(3).tolist()}")
    failed = [k for k, (v, tol) in errors.items() if not np.all(v <= tol)]
    assert not failed, f"{failed}\n{report}"
    # the shipped tables miss the altered offsets by tens of counts: several nT
    assert shipped.max() >= 1.0, shipped


@pytest.mark.slow
def test_temperature_law_with_the_break_at_a_bin_centre(tmp_path):
    from fluxcal.missions.messenger.flight_sim import CalibrationChanges

    # The worst case of a binned average of the convex Table 2 law: z's break temperature
    # on the fit's bin centre -10 C (seed T_m(z) = -14.7866 C).  The bin's mean then
    # lies above the law at its mean temperature by 1.25 (B1 - B0) = 3.0 counts for a
    # uniform spread in the bin (docs/decisions/messenger_fit_verification.md, finding
    # 2).  The default estimator models that bin as the law's average over its samples:
    # within the statistical error of the quiet test (<= 0.3 count); the seed's estimator
    # (selected) equals the noise-free binned estimator's own error within the same.
    changes = CalibrationChanges(tm_shift_c=(-6.0, 5.0, 4.7866))
    config = FlightConfig(start=str(START), days=QUIET_FIT_DAYS, seed=1313, solar_wind=QUIET)
    run = simulate_flight(tmp_path / "sim", config, changes)
    base = load_calibration(np.datetime64(str(START)))
    chunks = fit_passes.day_chunks(run.input_dir, run.days)
    result = fit_passes.fit_days(chunks, base, passes=6)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    assert abs(-(true.a0[2] - true.a1[2]) / (true.b0[2] - true.b1[2]) + 10.0) < 1e-3
    t = np.arange(-60.0, 40.01, 0.5)
    err = np.abs(_law(result.calibration.temperature_coefficients, t) - _law(true, t))
    seed_fit = fit_passes.fit_days(chunks, result.calibration, passes=1,
                                   temperature_law="binned-mean", guard=False)  # a study pass
    seed_err = np.abs(_law(seed_fit.calibration.temperature_coefficients, t) - _law(true, t))
    truths = [read_flight_truth(run.input_dir, d) for d in run.days]
    temps = np.concatenate([tr["temperature_c"][tr["duty_percent"] == 0] for tr in truths])
    expected = _binned_law_error(temps, true, np.arange(-105.0, 106.0, 10.0), t)
    print("temperature law max |error| with T_m(z) at a bin centre:", err.max(axis=0),
          "binned-mean:", seed_err.max(axis=0), "binned estimator without noise:", expected)
    assert err.max() <= 0.3, err.max(axis=0)
    assert seed_err.max() <= 2.0, seed_err.max(axis=0)
    assert np.abs(seed_err.max(axis=0) - expected).max() <= 0.3, (seed_err.max(axis=0),
                                                                  expected)
