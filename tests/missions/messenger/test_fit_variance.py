"""Issue 21, item 1: the variance estimator on an independent realistic solar wind.

The wind (`tests/missions/messenger/_realistic_wind.py`, numpy only) is 18 nT with
Alfvenic rotations (f^-5/3, dB/B ~ 0.5), Parker sectors of 1-3 days fixed in sensor
axes: its mean over any bin of the seed's averages is far from zero, so the zero-mean
estimator cannot hold, while |B| is constant within an hour up to the compressive part.
`flight_sim` turns it into raw streams with true tables that differ from the seed's
(Table 2/3 and tau changed by 25-60 %).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools

import numpy as np
import pytest

from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import FitRefusedError, FluxcalError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    N_SHIFTS,
    PER_AXIS,
)
from fluxcal.missions.messenger.fit_guards import MAX_BREAK_ERROR_C, check_fit
from fluxcal.missions.messenger.fit_holds import (
    HOLD_BREAK_WIDTH_C,
    HOLD_SLOPE_CHANGE_WIDTH,
    undetermined_upper,
)
from fluxcal.missions.messenger.fit_passes import (
    CONVERGENCE_SIGMA,
    LAW_TOLERANCE_COUNTS,
    Chunk,
    day_chunks,
    fit_days,
    pass_changes,
)
from fluxcal.missions.messenger.fit_variance import (
    VarianceSettings,
    VarianceStatistics,
    apply_step,
    law_parameters,
    law_to_table,
    reduce_variance,
    solve_variance,
)
from fluxcal.missions.messenger.fit_write import break_outside_lines, held_upper_lines
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.runs.batch import release_worker_kernel_pool, worker_kernel_pool
from tests.missions.messenger._realistic_wind import realistic_wind

START = dt.date(2010, 3, 1)


def _law(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Table 2 offset (counts): the larger of the two lines (eq. 3a, 3b; convex)."""
    return np.maximum(c[:, 0] + c[:, 1] * t[:, None], c[:, 2] + c[:, 3] * t[:, None])


def test_law_parametrisation_round_trips():
    cal = load_calibration(str(START))
    np.testing.assert_allclose(law_to_table(law_parameters(cal)), cal.offset_coefficients(),
                               atol=1e-9)


def _stats(starts, rng, truth):
    """Normal equations of blocks whose data follow ``y = X truth`` plus noise."""
    n = len(starts)
    x = rng.normal(size=(n, 400, N_PARAMETERS))
    y = x @ truth + 1e-3 * rng.normal(size=(n, 400))
    return VarianceStatistics(
        normal=np.einsum("bni,bnj->bij", x, x), rhs=np.einsum("bni,bn->bi", x, y),
        yy=np.einsum("bn,bn->b", y, y), samples=np.full(n, 400.0),
        block_start=np.asarray(starts, dtype=float), interval_start=np.zeros(n),
        reason=np.array(["", "compressive"] * (n // 2) + [""] * (n % 2)))


def _truth(rng):
    """A random step in the columns a solve without break shifts frees (the hinge
    columns at shifted breaks are used only when `choose_breaks` takes a shift)."""
    truth = rng.normal(size=N_PARAMETERS)
    truth[3 * PER_AXIS:3 * PER_AXIS + 3 * N_SHIFTS] = 0.0
    return truth


def test_statistics_merge_sums_shared_blocks_and_solve_recovers_the_step():
    rng = np.random.default_rng(5)
    truth = _truth(rng)
    a = _stats([0.0, 10800.0, 21600.0], rng, truth)
    b = _stats([21600.0, 32400.0], rng, truth)  # a day boundary inside block 21600
    m = a.merge(b)
    np.testing.assert_array_equal(m.block_start, [0.0, 10800.0, 21600.0, 32400.0])
    np.testing.assert_allclose(m.normal[2], a.normal[2] + b.normal[0])
    np.testing.assert_allclose(m.normal.sum(axis=0), a.normal.sum(axis=0) + b.normal.sum(axis=0))
    assert m.rejections() == {"compressive": 2} and m.reason.size == 5
    # 4 blocks cannot give the errors of 17 parameters: refused, naming the count
    with pytest.raises(FluxcalError, match=r"4 bootstrap blocks of 2 h .* need more than "
                                           r"19 for the errors of 17 parameters"):
        solve_variance(m, n_bootstrap=50)
    many = m.merge(_stats(np.arange(4, 24) * 7200.0, rng, truth))
    sol = solve_variance(many, n_bootstrap=50)
    np.testing.assert_allclose(sol.step, truth, atol=1e-4)
    # the bootstrap spread is the noise's: 1e-3 / sqrt(9600 samples) = 1e-5 per
    # parameter, widened by sqrt(24 / (24 - 17))
    assert np.all(sol.boot.std(axis=0) < 5e-5)


def _merged_by_add_at(a, b):
    """`VarianceStatistics.merge` as it was written before entry 54: every
    block's arrays summed by ``np.add.at`` over the concatenation, in its order."""
    uniq, inv = np.unique(np.concatenate([a.block_start, b.block_start]),
                          return_inverse=True)
    out = {}
    for name in ("normal", "rhs", "yy", "samples"):
        both = np.concatenate([getattr(a, name), getattr(b, name)])
        out[name] = np.zeros((uniq.size, *both.shape[1:]))
        np.add.at(out[name], inv, both)
    return out


@pytest.mark.parametrize("starts_a, starts_b", [
    ([0.0, 10800.0, 21600.0], [21600.0, 32400.0]),  # a block on both sides
    ([32400.0, 0.0], [7200.0, 0.0, 36000.0]),  # unsorted, shared
    ([0.0, 7200.0], [14400.0]),  # disjoint
    ([], [0.0, 7200.0]),  # an empty side
    ([0.0, 0.0, 7200.0], [7200.0, 7200.0]),  # a side repeating a start: np.add.at kept
])
def test_statistics_merge_sums_as_add_at_did_bit_for_bit(starts_a, starts_b):
    rng = np.random.default_rng(11)
    truth = _truth(rng)
    a = _stats(starts_a, rng, truth) if starts_a else VarianceStatistics()
    b = _stats(starts_b, rng, truth)
    if a.normal.size:
        a.normal[0, 0, :3] = [-0.0, 0.0, -0.0]  # signed zeros: 0 + (-0) is +0 both ways
    for x, y in ((a, b), (b, a)):
        m, want = x.merge(y), _merged_by_add_at(x, y)
        for name, w in want.items():
            assert getattr(m, name).tobytes() == w.tobytes(), name


@pytest.mark.parametrize("starts", [
    [[0.0, 7200.0], [7200.0, 14400.0], [0.0, 21600.0], [28800.0]],  # shared, also 1st-3rd
    [[0.0], [7200.0], [14400.0], [21600.0], [28800.0]],  # days apart
    [[], [0.0, 7200.0], [7200.0], []],  # empty parts
    [[0.0, 0.0], [7200.0], [0.0]],  # a part repeating a start: folded
    [[0.0], [7200.0]],  # two: `merge` itself
])
def test_merge_all_is_the_fold_bit_for_bit(starts):
    # the merge tree's node merges all its parts in one pass (entry 54): the
    # same bits as merging them pairwise left to right, signed zeros included
    rng = np.random.default_rng(12)
    truth = _truth(rng)
    parts = [_stats(x, rng, truth) if x else VarianceStatistics() for x in starts]
    for x in parts:
        if x.normal.size:
            x.normal[0, 0, :2] = [-0.0, -0.0]
            x.rhs[0, :1] = -0.0
    got, want = VarianceStatistics.merge_all(parts), functools.reduce(
        VarianceStatistics.merge, parts)
    for f in dataclasses.fields(VarianceStatistics):
        g, w = getattr(got, f.name), getattr(want, f.name)
        assert np.asarray(g).dtype == np.asarray(w).dtype, f.name
        assert np.asarray(g).tobytes() == np.asarray(w).tobytes(), f.name


def test_unknown_estimator_is_refused(tmp_path):
    chunk = Chunk("x", (tmp_path / "s.csv",), (), (), ())
    with pytest.raises(FluxcalError, match="estimator must be one of zero-mean, variance"):
        fit_days([chunk], load_calibration(str(START)), estimator="mean")


@pytest.mark.slow
def test_variance_estimator_recovers_the_laws_in_a_rotating_wind(tmp_path):
    # two days of a rotating 18-nT wind without its compressive part (|B| constant
    # within an hour up to the 12-h log-normal drift): the premise of the estimator
    # holds, the field's mean does not vanish (sectors fixed in sensor axes)
    wind = functools.partial(realistic_wind, compressive=0.0)
    run = simulate_flight(tmp_path / "sim", FlightConfig(start=str(START), days=2, seed=2121),
                          wind=wind, truth=False)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    base = load_calibration(str(START))
    chunks = day_chunks(run.input_dir, run.days)
    # guard off to see the estimator's own errors; the guards are checked below
    res = fit_days(chunks, base, passes=4, estimator="variance", guard=False)
    cal = res.calibration
    assert res.estimator == "variance" and res.variance is not None
    t = np.arange(-60.0, 40.01, 1.0)
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    law = np.abs(_law(cal.temperature_coefficients, t) - _law(tc, t)).max(axis=0)
    d0 = cal.duty_cycle_d0 / true.d0 - 1.0
    tau = cal.constants["relaxation"]["tau_s"] / true.constants["relaxation"]["tau_s"] - 1.0
    d0_pull = (cal.duty_cycle_d0 - true.d0) / [f.slope_err for f in res.duty]
    print(f"law max |error| counts {law.round(2)}, D0 rel {d0.round(3)} pulls "
          f"{d0_pull.round(2)}, tau rel {tau:.3f} +- "
          f"{res.relaxation.tau_err / true.constants['relaxation']['tau_s']:.3f}")
    # measured (seed 2121): see docs/decisions/messenger_fit.md entry 11; the issue's
    # numbers: law 0.15 nT (3.2 counts), D0 5 % (x, y; z's D0 is 10x smaller), tau 5 %
    assert np.all(law < 3.2), law
    assert np.all(np.abs(d0[:2]) < 0.05), d0
    assert np.all(np.abs(d0_pull) < 3.0), d0_pull
    assert abs(tau) < 0.05, tau
    # the stated errors cover the truth at 3 sigma (bootstrap over 2-h blocks)
    assert abs(cal.constants["relaxation"]["tau_s"] - true.constants["relaxation"]["tau_s"]
               ) < 3 * res.relaxation.tau_err + 1.0
    # z's D0 (10x smaller than x, y) is not determined by two days: the guard refuses
    # the fit naming it, or passes it within its stated error
    try:
        check_fit(res)
    except FitRefusedError as exc:
        print(f"variance: refused: {exc}")
        assert "D0 z" in str(exc), exc
    # every interval is accounted for: accepted or rejected with a named reason
    assert set(res.variance.rejections()) <= {"too_few_samples", "ill_conditioned",
                                              "small_fluctuations", "compressive"}
    # the seed's estimator on the same days: the field's own mean fills its bins; it is
    # refused by the guards, or misses by far more
    try:
        zm = fit_days(chunks, base, passes=1, estimator="zero-mean")
    except FluxcalError as exc:
        print(f"zero-mean: refused: {exc}")
    else:
        zm_law = np.abs(_law(zm.calibration.temperature_coefficients, t) - _law(tc, t))
        print(f"zero-mean law max |error| counts {zm_law.max(axis=0).round(2)}")
        assert zm_law.max() > 3 * law.max()


# ---------------------------------------------------------------------------------------
# item 2: the guards on the variance path (closed-form normal equations)
# ---------------------------------------------------------------------------------------
def _variance_result(base, step, *, noise=1e-3, counts_from_c=-60.0, counts_to_c=40.0,
                     sparse_to_c=None, hold_d0=(), upper_unseen=False, hinge_scale=None):
    """`fit_variance_calibration` on normal equations whose solution is ``step``.

    48 one-hour blocks of 400 rows ``y = X step + noise``; accepted samples' temperatures
    fill the 5-C bins from ``counts_from_c`` to ``counts_to_c`` (3000 each; 500 each on
    to ``sparse_to_c``, fewer than `MIN_RANGE_SAMPLES`); no heater
    phase data (the waveforms are kept from ``base``).  ``upper_unseen``: the hinge
    regressors (``max(0, T - T_m)``, the break step, the shifted hinges) are zero, as
    they are when no accepted sample lies above the breaks.  ``hinge_scale`` (per axis):
    those regressors multiplied by it, their columns' errors divided by it (few or
    short intervals above the break).
    """
    from fluxcal.missions.messenger.fit import fit_variance_calibration
    from fluxcal.missions.messenger.fit_reduce import DayStatistics, FitSettings
    from fluxcal.missions.messenger.fit_variance import TEMPERATURE_EDGES_C

    rng = np.random.default_rng(11)
    v = _stats(np.arange(48) * 3600.0, rng, np.zeros(N_PARAMETERS))
    x = rng.normal(size=(48, 400, N_PARAMETERS))
    if upper_unseen:
        x[..., [j * PER_AXIS + k for j in range(3) for k in (2, 3)]] = 0.0
        x[..., 3 * PER_AXIS:3 * PER_AXIS + 3 * N_SHIFTS] = 0.0
    for j, scale in enumerate(() if hinge_scale is None else hinge_scale):
        x[..., [j * PER_AXIS + 2, j * PER_AXIS + 3]] *= scale
        x[..., 3 * PER_AXIS + j * N_SHIFTS:3 * PER_AXIS + (j + 1) * N_SHIFTS] *= scale
    y = x @ step + noise * rng.normal(size=(48, 400))
    centre = 0.5 * (TEMPERATURE_EDGES_C[:-1] + TEMPERATURE_EDGES_C[1:])
    v.normal, v.rhs = np.einsum("bni,bnj->bij", x, x), np.einsum("bni,bn->bi", x, y)
    v.reason = np.full(48, "")
    v.temperature_count = np.where((centre > counts_from_c) & (centre < counts_to_c),
                                   3000.0, 0.0)
    if sparse_to_c is not None:
        v.temperature_count[(centre > counts_to_c) & (centre < sparse_to_c)] = 500.0
    return fit_variance_calibration(DayStatistics.empty(FitSettings()), v, base,
                                    hold_d0=hold_d0)


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(str(START))


def test_variance_fit_inside_its_ranges_passes_the_guards(shipped):
    step = np.zeros(N_PARAMETERS)
    step[-2] = 100.0  # tau 872 -> 972 s
    res = _variance_result(shipped, step)
    assert res.estimator == "variance" and res.fitted_range == (-60.0, 40.0)
    assert res.relaxation.tau == pytest.approx(972.0, abs=0.01)
    check_fit(res)


def test_variance_break_outside_the_fitted_range_is_held_with_its_width(shipped):
    # accepted samples only at -60..-30 C: the shipped breaks (-15..-10 C) and the upper
    # segments are not in the data; they are held at the start table's values with the
    # default widths (entry 21), no longer refused, and not judged by the break guard
    res = _variance_result(shipped, np.zeros(N_PARAMETERS), counts_to_c=-30.0,
                           upper_unseen=True)
    assert res.fitted_range == (-60.0, -30.0)
    assert sorted(res.held_upper) == ["x", "y", "z"]
    law = law_parameters(shipped)
    for j, a in enumerate("xyz"):
        h = res.held_upper[a]
        assert h["Tm_c"] == (pytest.approx(law[j, 3]), HOLD_BREAK_WIDTH_C)
        assert h["slope_change"] == (pytest.approx(law[j, 2]),
                                     pytest.approx(HOLD_SLOPE_CHANGE_WIDTH * abs(law[j, 2])))
        # the break is the held one; its stated error is its width (200 draws: 15 %)
        assert res.temperature[j].x_m == pytest.approx(law[j, 3], abs=1e-9)
        assert res.temperature[j].x_m_err == pytest.approx(HOLD_BREAK_WIDTH_C, rel=0.15)
    # the band above the breaks is the widths' (closed form, first order: the lower line
    # is known to 1e-3): (w_c (T - T_m))^2 + (c w_T)^2 at +40 C, within the draws' 15 %
    t = 40.0
    expect = np.hypot(HOLD_SLOPE_CHANGE_WIDTH * np.abs(law[:, 2]) * (t - law[:, 3]),
                      np.abs(law[:, 2]) * HOLD_BREAK_WIDTH_C)
    assert res.law_error(np.array([t]))[0] == pytest.approx(expect, rel=0.15)
    # below the breaks (by three widths) the law keeps the data's own error
    assert np.all(res.law_error(np.array([-45.0]))[0] < 1e-2)
    check_fit(res)
    # fewer samples (500 per bin) on to 0 C: two bins above every break hold an
    # interval's worth: nothing held, the law stated over -60..-30 C, the breaks pass
    res = _variance_result(shipped, np.zeros(N_PARAMETERS), counts_to_c=-30.0,
                           sparse_to_c=0.0)
    assert res.fitted_range == (-60.0, -30.0) and res.held_upper == {}
    check_fit(res)


def test_undetermined_upper_judges_the_stated_spreads():
    # constructed resamples (closed form): law c = +2 / -2 / +2 counts/C; the stated error
    # is the resamples' standard deviation times the widening (1.5 here)
    rng = np.random.default_rng(3)
    law = np.array([[0.0, 1.0, 2.0, -10.0], [0.0, 1.0, -2.0, -12.0], [0.0, 1.0, 2.0, -15.0]])
    z = rng.standard_normal((4000, 3, 4))
    z = (z - z.mean(axis=0)) / z.std(axis=0)  # unit spread exactly
    # c spread 1.2 x 1.5 = 1.8 < 2 (free); 1.4 x 1.5 = 2.1 > 2 (held, either sign of c);
    # break spread 6 x 1.5 = 9 C < 10 C, 7 x 1.5 = 10.5 C > 10 C
    for c_sd, tm_sd, expect in [((1.2, 1.2, 1.2), 6.0, [False] * 3),
                                ((1.4, 1.2, 1.2), 6.0, [True, False, False]),
                                ((1.2, 1.4, 1.2), 6.0, [False, True, False]),
                                ((1.2, 1.2, 1.2), 7.0, [True] * 3)]:
        b = law + z * np.array([[[0.0, 0.0, c, tm_sd]] for c in c_sd]).reshape(1, 3, 4)
        assert list(undetermined_upper(law, b, 1.5)) == expect, (c_sd, tm_sd)
    assert MAX_BREAK_ERROR_C == 10.0  # the break figures above assume it
    nan = law.copy()
    nan[0, 2] = np.nan  # no slope change stated: not judged determined
    assert list(undetermined_upper(nan, law + 0.0 * z, 1.0)) == [True, False, False]


@pytest.mark.parametrize(("noise", "held"), [(0.02, False), (0.2, True)])
def test_variance_upper_slope_of_undetermined_sign_is_held(shipped, noise, held):
    # x's hinge regressors 1000x weaker than the rest (few, short intervals above its
    # break) while every 5-C bin to +40 C holds samples, so the bin rule holds nothing.
    # noise 0.2: a free fit states B1 - B0 = 3.3 +- 5.2 counts/C (true 1.34: the shipped
    # value, the step is 0) with its break +- 5.2 C (< 10 C): neither earlier rule held it
    # (section 24's 3507 x); the error exceeds |c|, so x is held at the start table's
    # values with the widths (entry 35).  noise 0.02: +- 0.19 counts/C, free.
    res = _variance_result(shipped, np.zeros(N_PARAMETERS), noise=noise,
                           hinge_scale=(1e-3, 1.0, 1.0))
    assert res.fitted_range == (-60.0, 40.0)
    law = law_parameters(shipped)
    f = res.temperature[0]
    if not held:
        assert res.held_upper == {}
        assert f.b1_err < abs(f.b1 - f.b0)
        return
    assert sorted(res.held_upper) == ["x"]  # y and z: well determined, free
    h = res.held_upper["x"]
    assert h["Tm_c"] == (pytest.approx(law[0, 3]), HOLD_BREAK_WIDTH_C)
    assert h["slope_change"] == (pytest.approx(law[0, 2]),
                                 pytest.approx(HOLD_SLOPE_CHANGE_WIDTH * abs(law[0, 2])))
    # the written law is the held one, its stated error the widths' (200 draws: 15 %)
    assert f.b1 - f.b0 == pytest.approx(law[0, 2], abs=1e-6)
    assert f.x_m == pytest.approx(law[0, 3], abs=1e-6)
    assert f.x_m_err == pytest.approx(HOLD_BREAK_WIDTH_C, rel=0.15)
    header = "\n".join(held_upper_lines(res))
    assert header.startswith("x: upper segment (eq. 3b) held") and "B1 - B0 +- more" in header


def test_a_free_break_beyond_t_range_is_said_in_the_header(shipped):
    # the shipped breaks (seed 000 Table 2, eq. 4) lie inside -60..40 C: no line; T_RANGE
    # cut to end 5 C below the lowest break: every free axis says how far above it lies
    res = _variance_result(shipped, np.zeros(N_PARAMETERS))
    assert res.held_upper == {} and res.stated_ranges.span == (-60.0, 40.0)
    assert break_outside_lines(res) == []
    tm = law_parameters(shipped)[:, 3]
    top = float(np.min(tm)) - 5.0
    res = dataclasses.replace(res, temperature_ranges=StatedRanges(((-60.0, top),)))
    lines = break_outside_lines(res)
    assert len(lines) == 3
    for a, line, t in zip("xyz", lines, tm, strict=True):
        assert line.startswith(f"{a}: the break Tm = {t:.2f} +- ")
        assert f"lies {t - top:.1f} C above T_RANGE (-60..{top:g})" in line
    below = dataclasses.replace(res, temperature_ranges=StatedRanges(((top + 40.0, 50.0),)))
    assert all(" C below T_RANGE" in line for line in break_outside_lines(below))


def test_variance_tau_outside_its_range_is_refused(shipped):
    # a pass that starts at 1.9x the shipped tau and steps +25 %: 2071 s > 2 x 872 s
    base = shipped
    rel = {**base.constants["relaxation"], "tau_s": 1.9 * 872.0}
    base = dataclasses.replace(base, constants={**base.constants, "relaxation": rel})
    step = np.zeros(N_PARAMETERS)
    step[-2] = 0.25 * 1.9 * 872.0
    res = _variance_result(base, step)
    with pytest.raises(FitRefusedError, match=r"tau = 2071 \+- 0 s lies outside 436\.\.1744 "
                                              r"s .*duty-cycle changes"):
        check_fit(res)


def test_variance_meaningless_error_is_refused(shipped):
    # noise 1e8 times the closed-form one: tau's bootstrap error exceeds 30 % of tau
    res = _variance_result(shipped, np.zeros(N_PARAMETERS), noise=1e5)
    assert res.relaxation.tau_err > 0.3 * res.relaxation.tau
    with pytest.raises(FitRefusedError, match=r"tau = \d+ \+- \d+ s, a relative error above "
                                              r"the 5% goal.*duty-cycle changes"):
        check_fit(res)


def test_d0_the_data_put_out_of_range_is_refused_naming_the_hold_option(shipped):
    # D0 z stepped to 5x its shipped value (outside 1/3..3x): refused, and the message
    # names the way out (the user keeps the base value of that axis)
    d0 = np.asarray(shipped.duty_cycle_d0, dtype=float)
    step = np.zeros(N_PARAMETERS)
    step[2 * 5 + 4] = 4.0 * d0[2]   # D0 z -> 5x
    step[0 * 5 + 4] = 0.1 * d0[0]   # D0 x -> 1.1x
    res = _variance_result(shipped, step)
    assert res.duty[2].slope == pytest.approx(5.0 * d0[2], rel=1e-3)
    with pytest.raises(FitRefusedError, match=r"D0 z = .* is 5x the shipped .*not written\. "
                                              r"Needs .*, or hold it with a stated width "
                                              r"\(--hold-d0 z: the start table.s D0, its "
                                              r"width 50% of the value, entry 18; or "
                                              r"z=VALUE\+-WIDTH from a better source\)"):
        check_fit(res)


def test_held_d0_keeps_the_base_value_and_the_other_parameters(shipped, tmp_path):
    import tomllib

    from fluxcal.missions.messenger.fit_write import report_text, write_calibration_folder

    d0 = np.asarray(shipped.duty_cycle_d0, dtype=float)
    step = np.zeros(N_PARAMETERS)
    step[0 * 5 + 4] = 0.1 * d0[0]   # D0 x -> 1.1x (free)
    step[-2] = 50.0                 # tau 872 -> 922 s
    res = _variance_result(shipped, step, hold_d0=("z",))
    # z is the base value exactly, with the default width (half the held value, entry
    # 18; 200 draws: the spread within 15 %); x and tau still come from the data
    assert res.duty[2].slope == d0[2]
    assert res.duty[2].slope_err == pytest.approx(0.5 * d0[2], rel=0.15)
    assert res.held == {"z": (d0[2], 0.5 * d0[2])}
    assert res.duty[0].slope == pytest.approx(1.1 * d0[0], rel=1e-4)
    assert res.relaxation.tau == pytest.approx(922.0, abs=0.05)
    assert res.held_d0 == ("z",)
    check_fit(res)
    prov = {"inputs": {}, "intervals": "all data", "days": "x", "command": "test"}
    write_calibration_folder(res, tmp_path / "out", None, prov)
    header = next((tmp_path / "out").glob("offsets_duty_cycle_v*.csv")).read_text()
    width = 0.5 * d0[2]
    assert (f"z: D0 held at {d0[2]:.6g} +- {width:.3g} (--hold-d0; the width enters every "
            "stated error)") in header
    report = tomllib.loads((tmp_path / "out" / "fit_report.toml").read_text())
    assert report["duty_cycle"]["z"]["D0_held"] and not report["duty_cycle"]["x"]["D0_held"]
    assert report["duty_cycle"]["z"]["D0_held_width"] == pytest.approx(width)
    assert "held at" not in report_text(res, prov).split("x: C0")[1].split("\n")[0]
    assert f"(held at {d0[2]:.5g} +- {width:.3g}: --hold-d0)" in report_text(res, prov)


def test_hold_d0_is_checked_before_any_input_is_read(tmp_path, capsys):
    from fluxcal.cli import main

    base = ["messenger", "fit", "--input-dir", str(tmp_path / "missing"), "--out",
            str(tmp_path / "out")]
    for extra, message in ((["--hold-d0", "w"], "--hold-d0 takes a comma list of the axes"),
                           (["--hold-d0", "z", "--estimator", "zero-mean"],
                            "--hold-d0 needs --estimator variance"),
                           # nan and inf switch no check on (README, "numbers finite");
                           # before entry 62 z=inf ran the fit into a tau refusal and
                           # z+-nan was refused after the inputs were read
                           (["--hold-d0", "z=inf"], "numbers finite"),
                           (["--hold-d0", "z=0.01+-nan"], "numbers finite")):
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err
        assert message in err and "--hold-d0" in err and err.count("\n") == 1
        assert not (tmp_path / "out").exists()
    # entry 62: before, checked after the science was read, not naming the option
    for extra, message in ((["--estimator", "median"],
                            "'--estimator': 'median': choose one of zero-mean, variance"),
                           (["--temperature-law", "mean"],
                            "'--temperature-law': 'mean': choose one of distribution")):
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, err
        assert not (tmp_path / "out").exists()


def test_an_out_holding_tables_is_refused_before_any_input_is_read(tmp_path, capsys):
    """entry 62: before, the fit ran to its end (minutes to hours) and then refused."""
    from fluxcal.cli import main

    out = tmp_path / "fitted"
    out.mkdir()
    (out / "offsets_temperature_v2.csv").write_text("# a table of an earlier fit\n")
    (out / "notes.txt").write_text("another program's file\n")
    assert main(["messenger", "fit", "--input-dir", str(tmp_path / "missing"), "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (f"fluxcal: error: {out}: already holds calibration tables "
                   "(offsets_temperature_v2.csv); give an empty or new folder\n")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "offsets_temperature_v2.csv"]


def test_variance_without_a_fitted_temperature_bin_aborts_naming_it(shipped):
    with pytest.raises(FluxcalError, match=r"no 5-C temperature bin holds 1800 accepted "
                                           r"samples .*not constrained"):
        _variance_result(shipped, np.zeros(N_PARAMETERS), counts_from_c=0.0,
                         counts_to_c=0.0)


def test_fitted_range_needs_enough_samples_per_bin():
    from fluxcal.missions.messenger.fit_variance import TEMPERATURE_EDGES_C

    v = VarianceStatistics()
    assert np.isnan(v.fitted_range()).all()
    counts = np.zeros(TEMPERATURE_EDGES_C.size - 1)
    i0 = int(np.searchsorted(TEMPERATURE_EDGES_C, -55.0))  # bin -55..-50 C
    counts[i0], counts[i0 + 1], counts[i0 + 14] = 1800, 1799, 5000  # -55, -50, +15 C
    v.temperature_count = counts
    assert v.fitted_range() == (-55.0, 20.0)
    assert v.merge(v).fitted_range(min_samples=3600) == (-55.0, 20.0)
    assert v.fitted_range(min_samples=1801) == (15.0, 20.0)


def test_fitted_range_is_stated_in_the_written_folder(shipped, tmp_path):
    import tomllib

    from fluxcal.missions.messenger.fit_write import report_text, write_calibration_folder

    res = _variance_result(shipped, np.zeros(N_PARAMETERS), counts_to_c=-30.0,
                           sparse_to_c=0.0)
    prov = {"inputs": {}, "intervals": "all data", "days": "x", "command": "test"}
    write_calibration_folder(res, tmp_path / "out", None, prov)
    header = next((tmp_path / "out").glob("offsets_temperature_v*.csv")).read_text()
    assert "fitted range: -60..-30 C (5-C bins holding >= 1800 samples" in header
    assert "the law is not constrained outside it" in header
    report = tomllib.loads((tmp_path / "out" / "fit_report.toml").read_text())
    assert report["temperature"]["fitted_range_c"] == [-60.0, -30.0]
    assert "fitted range: -60..-30 C" in report_text(res, prov)
    # the method's lengths are in the report (entry 17: 60-s segments of 900-s intervals)
    assert (report["variance_intervals"]["interval_s"],
            report["variance_intervals"]["segment_s"]) == (900.0, 60.0)
    assert "within 60-s segments of the accepted intervals" in report_text(res, prov)


def test_bootstrap_resamples_runs_of_blocks_when_the_days_allow():
    # 72 two-hour blocks for 17 parameters: runs of k = 72 // 34 = 2 consecutive blocks
    # are resampled together; the same normal equations summed by hand into 36 blocks
    # (36 < 2 x 17: resampled one by one) give the identical bootstrap
    rng = np.random.default_rng(8)
    truth = _truth(rng)
    fine = _stats(np.arange(72) * 7200.0, rng, truth)
    pairs = VarianceStatistics(
        normal=fine.normal.reshape(36, 2, N_PARAMETERS, N_PARAMETERS).sum(axis=1),
        rhs=fine.rhs.reshape(36, 2, N_PARAMETERS).sum(axis=1),
        yy=fine.yy.reshape(36, 2).sum(axis=1), samples=fine.samples.reshape(36, 2).sum(axis=1),
        block_start=fine.block_start[::2], interval_start=fine.interval_start,
        reason=fine.reason)
    a, b = solve_variance(fine, n_bootstrap=40, seed=3), solve_variance(pairs, n_bootstrap=40,
                                                                        seed=3)
    np.testing.assert_allclose(a.step, b.step, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.boot, b.boot, rtol=1e-9, atol=1e-12)


def test_law_change_between_passes_is_the_largest_shift_over_the_grid(shipped):
    # entry 16/18: a pass's law change is the largest shift of the Table 2 law (counts)
    # over -65..+55 C per axis, here in closed form
    from fluxcal.missions.messenger.fit_passes import LAW_TOLERANCE_COUNTS, pass_changes

    res = _variance_result(shipped, np.zeros(N_PARAMETERS))
    coeff = np.asarray(res.calibration.temperature_coefficients, dtype=float)
    shifted = coeff.copy()
    shifted[:, [0, 2]] -= 0.3  # both lines of every axis down by 0.3 counts (old)
    moved = dataclasses.replace(res.calibration, temperature_coefficients=shifted)
    np.testing.assert_allclose(pass_changes(moved, res)["law_counts"], 0.3, atol=1e-9)
    assert 0.3 > LAW_TOLERANCE_COUNTS
    # the upper line's slope of x 0.01 counts/C smaller before: the upper segment turns
    # about T = 0 C of its own line (A1 + B1 T), largest at +55 C: 0.55 counts
    steeper = coeff.copy()
    steeper[0, 3] -= 0.01
    got = pass_changes(dataclasses.replace(res.calibration,
                                           temperature_coefficients=steeper), res)
    assert got["law_counts"][0] == pytest.approx(0.55, abs=1e-9)


def test_law_change_is_judged_over_the_span_of_the_stated_range_only(shipped):
    # issue 34, item 1: the law's change between passes is judged over the span of the
    # T_RANGE the table states.  The old table differs from the new by a slope change
    # above x's break only (A1 - d T_m, B1 + d: the lines still meet at T_m, eq. 4), so
    # the law's change is d (T - T_m) above T_m and 0 below, in closed form.
    res = _variance_result(shipped, np.zeros(N_PARAMETERS))
    coeff = np.asarray(res.calibration.temperature_coefficients, dtype=float)
    tm = float(law_parameters(res.calibration)[0, 3])
    d = 0.1  # counts/C
    old = coeff.copy()
    old[0, 2] -= d * tm
    old[0, 3] += d
    old = dataclasses.replace(res.calibration, temperature_coefficients=old)
    # a break beyond T_RANGE (5-6 C above its end): no change inside, converged
    below = StatedRanges(((-60.0, np.floor(tm) - 5.0),))
    got = pass_changes(old, res, ranges=below)
    assert got["law_counts"][0] == pytest.approx(0.0, abs=1e-9)
    assert got["ratio"] == 0.0 and got["over"] == []
    assert got["law_range_c"] == [-60.0, np.floor(tm) - 5.0]
    # where no T_RANGE is stated (None), -65..+55 C: d (55 - T_m) at +55 C, not converged
    every = pass_changes(old, res)
    assert every["law_counts"][0] == pytest.approx(d * (55.0 - tm), rel=1e-9)
    assert every["ratio"] > 1.0
    # T_RANGE whose span holds the break, the break in the gap between two intervals:
    # judged up to the span's end hi, d (hi - T_m) there, against its allowance
    hi = np.ceil(tm) + 6.0
    around = StatedRanges(((-60.0, np.floor(tm) - 5.0), (np.ceil(tm) + 3.0, hi)))
    got = pass_changes(old, res, ranges=around)
    change = d * (hi - tm)
    allow = max(LAW_TOLERANCE_COUNTS, CONVERGENCE_SIGMA * float(res.law_error(hi)[0, 0]))
    assert got["law_counts"][0] == pytest.approx(change, rel=1e-9)
    assert got["ratio"] == pytest.approx(change / allow, rel=1e-9) and change > allow
    # the new law is the flatter one: its change is negative
    assert got["over"] == [f"law x at {hi:+.0f} C {-change:+.4g} counts (allowed {allow:.2g})"]


def _hinge_statistics(law_now, law_true, rng, shifts=BREAK_SHIFTS_C, temp=None, noise=None):
    """Normal equations of ``|B'| = u . (true law - current law)(T)``, written from the
    column definitions of the module docstring (unit matrix, M = 1): per axis ``u_j``
    times ``1, T, max(0, T - T_m), [T > T_m], R`` and the hinges at the shifted breaks,
    then tau and dt (zero here); 48 two-hour blocks over -60..+40 C, or over the
    temperatures ``temp`` (one per sample, the blocks in order; the accepted samples
    per 5-C bin then counted from them), plus ``noise`` (counts, one per sample) on
    ``|B'|``."""
    return _hinge_rows(law_now, law_true, rng, shifts, temp, noise)[0]


def _hinge_rows(law_now, law_true, rng, shifts=BREAK_SHIFTS_C, temp=None, noise=None):
    """`_hinge_statistics` and the rows it sums: ``(stats, x, y, temp, u)``."""
    n = 48 * 300 if temp is None else temp.size
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    given = temp is not None
    temp = np.asarray(temp, dtype=float) if given else rng.uniform(-60.0, 40.0, n)
    ratio = rng.uniform(0.0, 400.0, n)

    def offset(law):
        a, b, c, tm = law.T
        return a + b * temp[:, None] + c * np.maximum(0.0, temp[:, None] - tm)

    y = np.einsum("ij,ij->i", u, offset(law_true) - offset(law_now))
    cols = []
    for j in range(3):
        tm = law_now[j, 3]
        cols += [u[:, j] * f for f in (np.ones(n), temp, np.maximum(0.0, temp - tm),
                                       (temp > tm).astype(float), ratio)]
    for j in range(3):
        cols += [u[:, j] * np.maximum(0.0, temp - law_now[j, 3] - d) for d in shifts]
    x = np.column_stack([*cols, rng.normal(size=n), rng.normal(size=n)])
    if noise is not None:
        y = y + noise
    xb, yb = x.reshape(48, n // 48, -1), y.reshape(48, n // 48)
    from fluxcal.missions.messenger.fit_variance import TEMPERATURE_EDGES_C

    centre = 0.5 * (TEMPERATURE_EDGES_C[:-1] + TEMPERATURE_EDGES_C[1:])
    count = (np.histogram(temp, TEMPERATURE_EDGES_C)[0].astype(float) if given
             else np.where((centre > -60) & (centre < 40), 3000.0, 0.0))
    return VarianceStatistics(
        normal=np.einsum("bni,bnj->bij", xb, xb), rhs=np.einsum("bni,bn->bi", xb, yb),
        yy=np.einsum("bn,bn->b", yb, yb), samples=np.full(48, n / 48),
        block_start=np.arange(48) * 7200.0, interval_start=np.zeros(48),
        reason=np.full(48, ""), temperature_count=count), x, y, temp, u


def test_a_distant_break_is_moved_exactly_to_the_shift_of_least_residual(shipped):
    # the true x break 4 C above the current one, y 2 C below, z unchanged but its
    # slope 10 % larger: the linearised step alone would move a break a fraction of the
    # way per pass; the shifted hinge fits the true law exactly in one step
    now = law_parameters(shipped)
    true = now.copy()
    true[0, 3] += 4.0
    true[1, 3] -= 2.0
    true[2, 1] *= 1.1
    stats = _hinge_statistics(now, true, np.random.default_rng(21))
    sol = solve_variance(stats, n_bootstrap=20, law=now)
    np.testing.assert_array_equal(sol.break_shift, [4.0, -2.0, 0.0])
    law, d0, _, _ = apply_step(shipped, sol.step, break_shift=sol.break_shift)
    np.testing.assert_allclose(law, true, atol=1e-8)
    np.testing.assert_allclose(d0, shipped.duty_cycle_d0, atol=1e-9)
    # without the law the shifts are not tried: the linearised step is taken
    plain = solve_variance(stats, n_bootstrap=20)
    np.testing.assert_array_equal(plain.break_shift, [0.0, 0.0, 0.0])


def test_a_shift_outside_the_fitted_range_is_not_tried(shipped):
    # the break moved 8 C, but only 4 C of it lie inside the data (-60..+40 C is the
    # test's range; the bins above -10 C emptied): the shift is refused, the break stays
    now = law_parameters(shipped)
    true = now.copy()
    true[0, 3] += 8.0
    stats = _hinge_statistics(now, true, np.random.default_rng(22))
    from fluxcal.missions.messenger.fit_variance import TEMPERATURE_EDGES_C

    stats.temperature_count[TEMPERATURE_EDGES_C[:-1] >= now[0, 3] + 5.0] = 0.0
    sol = solve_variance(stats, n_bootstrap=20, law=now)
    assert sol.break_shift[0] in (0.0, 0.5, 1.0, 2.0, 4.0)
    assert now[0, 3] + sol.break_shift[0] <= stats.fitted_range()[1]


def test_the_regressors_do_not_carry_the_heater_waveform_table(tmp_path):
    # entry 31: a waveform table's error in the regressors' direction u and in |B'|
    # together biases D0 along the field (even in the error), so u is taken before the
    # table is subtracted.  By construction: two tables that differ by a random error
    # give the same regressors (normal matrices equal to rounding) and different |B'|
    # (right-hand sides differ), on one simulated day of the rotating wind.
    run = simulate_flight(tmp_path / "sim", FlightConfig(start=str(START), days=1, seed=3131),
                          wind=functools.partial(realistic_wind, compressive=0.0), truth=False)
    base = load_calibration(str(START))
    chunk = day_chunks(run.input_dir, run.days)[0]
    rng = np.random.default_rng(31)
    wrong = dataclasses.replace(base, heater_signal=base.heater_signal + rng.normal(
        0.0, 5.0, base.heater_signal.shape))
    # unweighted: the inverse-variance weights are taken from |B'| and would differ
    worker_kernel_pool(list(chunk.kernels), FRAME_KERNELS)
    try:
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        streams = (read_science(list(chunk.science)), read_heater(list(chunk.heater)),
                   read_temperature(list(chunk.temperature)), sclk)
        plain = VarianceSettings(weighting="none")
        a = reduce_variance(*streams, base, settings=plain)
        b = reduce_variance(*streams, wrong, settings=plain)
    finally:
        release_worker_kernel_pool()
    assert a.normal.shape == b.normal.shape and a.normal.size
    scale = np.abs(a.normal).max()
    assert np.allclose(a.normal, b.normal, rtol=0, atol=1e-9 * scale)
    assert not np.allclose(a.rhs, b.rhs, rtol=1e-6, atol=0)
