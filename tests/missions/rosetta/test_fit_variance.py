"""``fluxcal rosetta fit --estimator variance`` on a calm wind with a daily mean (issue 21).

Data: the independent forward model of `_daily_mean_wind` (a 3-nT Alfvenic field whose
direction wanders about a sector direction: the day's mean field is 1.5-2 nT; a 3 %
compressive part) through the seed's instrument model (`fluxcal.missions.rosetta.
forward`).  The seed's criterion (the day's field averages to zero) puts the mean field
into ``P_0``; the variance estimator assumes only rotations at nearly constant ``|B|``.

Tolerances: the issue's 0.2 nT rms per component, for the curve over the day's
temperatures and for an unseen stretch calibrated with the written file.  The
constant-magnitude case has the closed-form bound of the ADC and thermistor steps
(test_fit.py: 0.05 nT).
"""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.errors import FitRefusedError
from fluxcal.missions.rosetta import calib, forward, io

from . import _daily_mean_wind as wind

DAY = "2009-11-13"
TARGET = 0.2  # nT rms per component (issue 21)


def _level_a(raw):
    from fluxcal.missions.rosetta import level_a
    from fluxcal.missions.rosetta.fit import reduced_temperature

    cal = calib.load_ground_calibration("OB")
    a = level_a.level_a(raw, cal, calib.load_time_shift_table(),
                        calib.load_nominal_conversion())
    return a, reduced_temperature(a, cal)


def _curve_rms(fit, temp, coefficients):
    tt = forward.reduced_temperature(temp, calib.load_ground_calibration("OB"))
    err = wind.curve(fit.coefficients, tt) - wind.curve(coefficients, tt)
    return np.sqrt((err**2).mean(axis=0))


@pytest.fixture(scope="module")
def day():
    from fluxcal.geometry.kernels import KernelPool

    coefficients = wind.true_coefficients()
    with KernelPool():
        raw, b, temp = wind.simulate_raw(DAY, 0.0, 24.0, coefficients, seed=3, rate_hz=0.25)
        a, tt = _level_a(raw)
    return coefficients, raw, b, temp, a, tt


def test_variance_recovers_the_curve_where_zero_mean_takes_the_mean_field(day, pool):
    from fluxcal.missions.rosetta.fit import fit_extended_model
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    coefficients, _, b, temp, a, tt = day
    assert np.linalg.norm(b.mean(axis=0)) > 1.0  # the premise of zero-mean fails
    variance = fit_extended_model_variance(a, tt)
    zero_mean = fit_extended_model(a, tt)
    rms_v = _curve_rms(variance, temp, coefficients)
    rms_z = _curve_rms(zero_mean, temp, coefficients)
    assert np.all(rms_v < TARGET), rms_v  # measured 0.02-0.07 nT over seeds 1-6
    assert rms_z.max() > 3 * TARGET, rms_z  # 0.7-1.5 nT: the day's mean field
    # the stated error covers the truth (5 sigma of the bootstrap, at the data)
    sig = variance.offset_sigma(tt).mean(axis=0)
    assert np.all(rms_v < 5 * sig + 0.02), (rms_v, sig)
    assert variance.estimator == "variance" and variance.coefficients[4:].any() == 0
    assert "accepted" in variance.notes["intervals"]


def test_variance_exact_for_a_constant_magnitude_field(pool):
    """No compressive part: the curve comes back to the ADC/thermistor bound (0.05 nT)."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    coefficients = wind.true_coefficients()
    raw, _, temp = wind.simulate_raw(DAY, 0.0, 24.0, coefficients, seed=7, rate_hz=0.2,
                                     compression=0.0)
    a, tt = _level_a(raw)
    fit = fit_extended_model_variance(a, tt)
    assert np.all(_curve_rms(fit, temp, coefficients) < 0.05)


def test_variance_refuses_a_field_that_does_not_rotate(day, pool):
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    _, _, b, _, a, tt = day
    steady = a.copy(deep=True)
    # offset + a fixed field: the temperature drift alone moves |B|, along one line
    steady["b"].values[:] = a["b"].values - b + b.mean(axis=0)
    with pytest.raises(FitRefusedError,
                       match="rejected: .*(compressive|ill_conditioned)"):
        fit_extended_model_variance(steady, tt)


def test_variance_refuses_a_curve_it_cannot_determine(day, pool):
    """Five hours (15 intervals) for a cubic over 8 C: refused by its sigma (~5 nT)."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    _, _, _, _, a, tt = day
    part = slice(0, 5 * 900)  # 5 h at 0.25 Hz
    with pytest.raises(FitRefusedError, match=r"offset curve [xyz] = .* \+- .* nT at T~"):
        fit_extended_model_variance(a.isel(time=part), tt[part], degree=3)
    with pytest.raises(FitRefusedError, match=r"15 interval\(s\) of 1200 s .* for 18 "
                       "parameters, need 19"):
        fit_extended_model_variance(a.isel(time=part), tt[part], degree=5)


def test_variance_refuses_too_few_intervals_naming_them(day, pool):
    """One hour = 3 intervals of 1200 s for 12 parameters: the cause, not the start fit's."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    _, _, _, _, a, tt = day
    hour = slice(0, 900)  # 1 h at 0.25 Hz
    with pytest.raises(FitRefusedError, match=r"2009-11-13 .*3 interval\(s\) of 1200 s .* "
                       r"for 12 parameters, need 13; give at least 4.3 h"):
        fit_extended_model_variance(a.isel(time=hour), tt[hour])


def test_variance_refuses_a_constant_temperature(day, pool):
    """One temperature determines P_0 only: P_1 .. P_3 are refused by name."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    _, _, _, _, a, tt = day
    with pytest.raises(FitRefusedError, match=r"takes 1 distinct value.* P_1 \.\. P_3 are not "
                       r"determined.*--degree 0"):
        fit_extended_model_variance(a, np.full_like(tt, -105.0))


def test_variance_refuses_an_offset_outside_the_physical_range(day, pool):
    """A 300-nT constant in x (a field taken for an offset) is outside +-200 nT."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    coefficients, _, _, _, a, tt = day
    shifted = a.copy(deep=True)
    shifted["b"].values[:, 0] += 300.0
    true_x = wind.curve(coefficients, tt)[:, 0] + 300.0  # 279-299 nT over the day
    assert true_x.min() > 200.0
    with pytest.raises(FitRefusedError, match=r"offset curve x = 2\d\d\.?\d* \+- .* nT at T~ = "
                       r".* outside the physical range \+-200 nT"):
        fit_extended_model_variance(shifted, tt)


def test_variance_names_why_it_did_not_converge(day, pool):
    from fluxcal.missions.rosetta.fit_variance import (
        VarianceSettings,
        fit_extended_model_variance,
    )

    _, _, _, _, a, tt = day
    with pytest.raises(FitRefusedError, match=r"no convergence in 2 Gauss-Newton steps: the "
                       r"curve still moves \(last step .* nT, tolerance 0.0001 nT\)"):
        fit_extended_model_variance(a, tt, settings=VarianceSettings(max_iterations=2))


def _compressive_share(b: np.ndarray, seconds: np.ndarray) -> float:
    """Share of 1200-s intervals of the *true* field with var(|B|) / trace C above 0.1."""
    k = (seconds // 1200).astype(int)
    mag = np.linalg.norm(b, axis=1)
    n = np.bincount(k)
    var = lambda v: np.bincount(k, v**2) / n - (np.bincount(k, v) / n) ** 2  # noqa: E731
    trace = sum(var(b[:, i]) for i in range(3))
    return float(np.mean(var(mag) / trace > 0.1))


def test_variance_refuses_a_compressive_day(pool):
    """|B| fluctuating by 25 %: most intervals are not rotations; refused with the count."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    raw, b, _ = wind.simulate_raw(DAY, 0.0, 24.0, wind.true_coefficients(), seed=8,
                                  rate_hz=0.1, compression=0.25)
    assert _compressive_share(b, np.arange(b.shape[0]) * 10.0) > 0.5  # the truth says so
    a, tt = _level_a(raw)
    with pytest.raises(FitRefusedError, match=r"\d+ of 72 intervals of 1200 s rejected as "
                       r"compressive \(limit 33%\)"):
        fit_extended_model_variance(a, tt)


@pytest.mark.slow
def test_variance_errors_cover_the_truth_over_realisations(pool):
    """Pulls over 6 realisations (54): spread near 1 and none beyond 4.

    Truth: the offset the LEVEL_A data carry (``B_A - B_true``, forward model's field),
    averaged over the vectors within 0.5 C of the 10th/50th/90th percentile of the
    day's temperature; it includes the 0.004/0.006-nT constant of the ADC and thermistor
    conversions, which the fit rightly puts into ``P_0``.  100 realisations give a
    spread of 1.02 (benchmarks/rosetta_fit_pulls.py); 54 pulls estimate it to about
    +-0.15, hence the band 0.6-1.5.
    """
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    coefficients = wind.true_coefficients()
    pulls = []
    for seed in range(6):
        raw, b, temp = wind.simulate_raw(DAY, 0.0, 24.0, coefficients, seed=500 + seed,
                                         rate_hz=0.1)
        a, tt = _level_a(raw)
        true_tt = forward.reduced_temperature(temp, calib.load_ground_calibration("OB"))
        carried = a["b"].values - b
        fit = fit_extended_model_variance(a, tt, seed=seed)
        for v in np.percentile(true_tt, [10, 50, 90]):
            m = np.abs(true_tt - v) < 0.5
            err = fit.offset(tt[m]).mean(axis=0) - carried[m].mean(axis=0)
            pulls.append(err / fit.offset_sigma(np.array([tt[m].mean()]))[0])
    pulls = np.array(pulls).ravel()
    assert np.abs(pulls).max() < 4.0, pulls
    assert 0.6 < pulls.std() < 1.5, pulls.std()
    assert abs(pulls.mean()) < 0.6, pulls.mean()


@pytest.mark.slow
def test_cli_variance_file_calibrates_an_unseen_stretch(day, tmp_path):
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.products import read_fluxcal_product

    coefficients, raw, _, _, _, _ = day
    with KernelPool():
        io.write_science_csv(raw, tmp_path / "day.csv")
        unseen, b_unseen, _ = wind.simulate_raw(DAY, 50_000.0, 6.0, coefficients, seed=99,
                                                phase=0.9, rate_hz=0.25)
        io.write_science_csv(unseen, tmp_path / "unseen.csv")
    errors = {}
    for estimator, flag in (("variance", []), ("zero-mean", ["--estimator", "zero-mean"])):
        fitted = tmp_path / f"fitted-{estimator}"  # variance is the default
        assert main(["rosetta", "fit", "--science", str(tmp_path / "day.csv"), "--sensor",
                     "OB", "--out", str(fitted), *flag]) == 0
        text = (fitted / "RPCMAG_091113_006_CALIB_OB.TXT").read_text()
        assert ("least within-interval variance" in text) == (estimator == "variance")
        out = tmp_path / estimator
        assert main(["rosetta", "calibrate", "--science", str(tmp_path / "unseen.csv"),
                     "--sensor", "OB", "--levels", "A", "--formats", "cdf", "--out", str(out),
                     "--calib", str(fitted)]) == 0
        a = read_fluxcal_product(out / "rosetta_rpcmag_cla-ob_20091113_v01.cdf")
        errors[estimator] = np.sqrt(((a["b"].values - b_unseen) ** 2).mean(axis=0))
    print({k: v.round(3) for k, v in errors.items()})
    assert np.all(errors["variance"] < TARGET), errors  # measured 0.012 / 0.048 / 0.029 nT
    assert errors["zero-mean"].max() > 3 * TARGET, errors  # measured 1.12 / 1.12 / 1.02 nT
    assert main(["rosetta", "fit", "--science", str(tmp_path / "day.csv"), "--sensor", "OB",
                 "--out", str(tmp_path / "x"), "--estimator", "median"]) == 2


# ----------------------------------------------------------------------------------------
# Appendix B jumps: a field with a mean (B_z in CSEQ not zero), any attitude
# ----------------------------------------------------------------------------------------
TRUE_JUMPS = wind.TRUE_JUMPS
INTERVALS = wind.JUMP_INTERVALS
_jump_data = wind.jump_data


def test_variance_jumps_recovered_with_a_mean_field(pool, tmp_path):
    from fluxcal.missions.rosetta.fit import fit_offset_jumps, write_offset_jump_table
    from fluxcal.missions.rosetta.fit_variance import fit_offset_jumps_variance

    epoch, b_sc, rot, b_cseq = _jump_data(5)
    assert abs(b_cseq[:, 2].mean()) > 0.5  # the zero-mean criterion's premise fails
    start, end = (np.array(c) for c in zip(*INTERVALS, strict=True))
    fit = fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB")
    err = fit.jumps - TRUE_JUMPS
    assert np.all(np.abs(err) < TARGET), err
    assert np.all(np.abs(err) < 5 * fit.sigma + 0.02), (err, fit.sigma)
    seed_fit = fit_offset_jumps(epoch, b_sc, rot, start, end, sensor="OB", max_sigma=None)
    assert np.abs(seed_fit.jumps - TRUE_JUMPS).max() > 3 * TARGET
    path = write_offset_jump_table([fit], tmp_path / calib.JUMPS_FILE)
    assert "least variance of |B - JUMP|" in path.read_text()
    np.testing.assert_allclose(calib.read_offset_jump_table(path).jumps["OB"], fit.jumps,
                               atol=5e-5)


def test_variance_jumps_refused_without_rotation(pool):
    from fluxcal.missions.rosetta.fit_variance import fit_offset_jumps_variance

    epoch, b_sc, rot, b_cseq = _jump_data(5)
    noise = np.random.default_rng(1).normal(0.0, 0.01, b_sc.shape)  # 0.01 nT, no rotation
    steady = b_sc - np.einsum("nji,nj->ni", rot, b_cseq) + b_cseq.mean(axis=0) + noise
    start, end = (np.array(c) for c in zip(*INTERVALS, strict=True))
    with pytest.raises(FitRefusedError, match="do not determine the offset"):
        fit_offset_jumps_variance(epoch, steady, start, end, sensor="IB")


def test_variance_jumps_refused_outside_the_physical_range(pool):
    """A jump of about 150 nT (6 x the largest shipped, 25 nT) is refused, naming axis and error."""
    from fluxcal.missions.rosetta.fit_variance import fit_offset_jumps_variance

    epoch, b_sc, _, _ = _jump_data(5, rate_hz=0.05)
    b_sc = b_sc + np.array([0.0, 150.0, 0.0])  # J_y = 142.7 and 155.2 nT
    start, end = (np.array(c) for c in zip(*INTERVALS, strict=True))
    with pytest.raises(FitRefusedError, match=r"2014-08-01T00:00:00 .*J_y = 142\.\d* \+- .* nT "
                       r"is outside the physical range \+-100 nT"):
        fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB")


def test_variance_jumps_refused_for_a_compressive_field(pool):
    from fluxcal.missions.rosetta.fit_variance import fit_offset_jumps_variance

    epoch, b_sc, _, b_cseq = _jump_data(6, rate_hz=0.05, compression=0.25)
    assert _compressive_share(b_cseq, (epoch - epoch[0]) / wind.NS) > 0.5
    start, end = (np.array(c) for c in zip(*INTERVALS, strict=True))
    with pytest.raises(FitRefusedError, match=r"2014-08-01T00:00:00 .* sub-intervals of 1200 s "
                       r"rejected as compressive \(limit 33%\)"):
        fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB")


def test_cli_variance_jumps_need_no_kernels(tmp_path):
    """``--jumps --estimator variance`` without kernels: a stretch with no jump gives J ~ 0.

    The forward model adds no jump and no daily offset here, so the true J is 0 in every
    axis; 6 h at 0.5 Hz (18 sub-intervals) determine it to the 0.2-nT target.
    """
    from fluxcal.geometry.kernels import KernelPool

    with KernelPool():
        raw, _, _ = wind.simulate_raw("2014-08-01", 3600.0, 6.0, np.zeros((6, 3)), seed=4,
                                      rate_hz=0.5)
        io.write_science_csv(raw, tmp_path / "day.csv")
    (tmp_path / "iv.csv").write_text("start_utc,end_utc\n2014-08-01T00:00:00,"
                                     "2014-08-02T00:00:00\n")
    args = ["rosetta", "fit", "--science", str(tmp_path / "day.csv"), "--sensor", "OB",
            "--jumps", "--intervals", str(tmp_path / "iv.csv"), "--out", str(tmp_path / "f")]
    assert main([*args, "--estimator", "zero-mean"]) == 2  # needs the attitude (--kernels)
    assert main(args) == 0  # variance, the default, does not
    table = calib.read_offset_jump_table(tmp_path / "f" / calib.JUMPS_FILE)
    assert np.all(np.abs(table.jumps["OB"]) < TARGET), table.jumps
    assert np.isnan(table.jumps["IB"]).all()
