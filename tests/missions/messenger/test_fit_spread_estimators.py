"""Spread estimators of the stated errors and the drawn true law (issue 34, entry 39).

The estimators the pull harness compares (``benchmarks/messenger_fit_pulls.py
--summarise DIR --estimators``) on drawn samples whose spreads are known in closed form:
a normal core with a rare discrete jump (the break shift a few bootstrap resamples take),
``(1 - p) N(0, 1) + p N(J, 1)``.  Its standard deviation is ``sqrt(1 + p (1 - p) J^2)``;
its percentiles and median absolute deviation solve the mixture's CDF
``(1 - p) Phi(x) + p Phi(x - J)`` (root-finding on `scipy.special.ndtr`, not the
estimators' own `numpy.percentile` / `numpy.median`).  Then the forward model's drawn
Table 2 (`_hard_worlds.drawn_law`): its ranges, eq. 4, and one draw per seed.
"""

from __future__ import annotations

import types

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ndtr

from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    PER_AXIS,
)
from fluxcal.missions.messenger.fit_variance import (
    law_parameters,
)
from fluxcal.missions.messenger.flight_sim import write_true_calibration
from tests.missions.messenger._hard_worlds import LAW_FACTORS, LAW_TM_SHIFT_C, drawn_law
from tests.missions.messenger.test_fit_variance import _variance_result

#: Draws per sample: the standard deviation's relative sampling error is about
#: ``kurtosis / sqrt(n)`` < 0.3 %, the percentiles' a few 0.1 %; tolerance 1.5 %.
N = 400_000
RTOL = 0.015


@pytest.fixture(scope="module")
def bench(pulls_bench):
    return pulls_bench


def _mixture(p: float, jump: float, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """``(x, moved)``: N draws of the mixture, and which came from the jump."""
    rng = np.random.default_rng(seed)
    moved = rng.random(N) < p
    return rng.standard_normal(N) + jump * moved, moved


def _cdf(p: float, jump: float):
    return lambda x: (1.0 - p) * ndtr(x) + p * ndtr(x - jump)


def _quantile(p: float, jump: float, q: float) -> float:
    f = _cdf(p, jump)
    return brentq(lambda x: f(x) - q, -20.0, 20.0 + jump, xtol=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize(("p", "jump"), [(0.0, 0.0), (0.05, 8.0), (0.10, 4.0), (0.30, 6.0)])
def test_estimators_on_a_mixture_match_their_closed_forms(bench, p, jump, sign):
    x, moved = _mixture(p, sign * jump)
    sd = np.sqrt(1.0 + p * (1.0 - p) * jump ** 2)
    assert bench.spread_sd(x) == pytest.approx(sd, rel=RTOL)
    # half the 15.87-84.13 % width of the mixture's own CDF
    lo = _quantile(p, sign * jump, 0.158655)
    hi = _quantile(p, sign * jump, 0.841345)
    assert bench.spread_percentile(x) == pytest.approx(0.5 * (hi - lo), rel=RTOL)
    # MAD: the median m, then d with F(m + d) - F(m - d) = 1/2
    f = _cdf(p, sign * jump)
    m = _quantile(p, sign * jump, 0.5)
    d = brentq(lambda d: f(m + d) - f(m - d) - 0.5, 1e-9, 20.0 + jump, xtol=1e-12)
    assert bench.spread_mad(x) == pytest.approx(1.4826 * d, rel=RTOL)
    # the mixture states a jump rarer than the one-sided 1-sigma tail apart (the core's
    # sigma, 1); a commoner one is the error itself (the standard deviation)
    got = bench.spread_mixture(x[:, None], moved[:, None])[0]
    assert got == pytest.approx(1.0 if p < 0.15866 else sd, rel=RTOL)
    # without labels it is the standard deviation
    assert bench.spread_mixture(x) == pytest.approx(sd, rel=RTOL)


def test_a_rare_jump_sets_the_standard_deviation_not_the_robust_spreads(bench):
    # the late-peak world's case (entry 39): 5 % of the resamples 8 sigma away
    # double the standard deviation (2.01) while the percentile and MAD spreads stay
    # within 10 % of the core's 1
    x, _ = _mixture(0.05, 8.0)
    assert bench.spread_sd(x) > 1.9
    assert bench.spread_percentile(x) < 1.1
    assert bench.spread_mad(x) < 1.1


def test_mixture_takes_each_axis_and_temperature_apart(bench):
    # (n, temperature, axis) samples: axis 0 with a rare jump (its core stated), axis 1
    # with a common one (its standard deviation), the same per temperature
    xa, ma = _mixture(0.05, 8.0, seed=1)
    xb, mb = _mixture(0.30, 6.0, seed=2)
    x = np.stack([np.stack([xa, xb], axis=1), np.stack([2 * xa, 3 * xb], axis=1)], axis=1)
    got = bench.spread_mixture(x, np.stack([ma, mb], axis=1))
    sd_b = np.sqrt(1.0 + 0.3 * 0.7 * 36.0)
    np.testing.assert_allclose(got, [[1.0, sd_b], [2.0, 3 * sd_b]], rtol=RTOL)


def test_moved_resamples_compare_each_resample_with_the_solution(bench):
    # hand values: the solution took +2 C on x, kept y and z; resample 0 kept x's +2
    # and moved z to -4, resample 1 went back to the linearised step on x
    res = types.SimpleNamespace(
        bootstrap={"break_shift": np.array([[2.0, 0.0, -4.0], [0.0, 0.0, 0.0]])},
        break_shift=np.array([2.0, 0.0, 0.0]))
    np.testing.assert_array_equal(bench.moved_resamples(res),
                                  [[False, False, True], [True, False, False]])


SEED_TABLE2_TM = (-10.1817, -12.6662, -14.7866)  # seed sec. 7, Table 2


@pytest.mark.parametrize("seed", [3500, 3501, 3519, 12])
def test_drawn_law_lies_in_its_ranges_and_keeps_table2s_form(tmp_path, seed):
    ch = drawn_law(seed)
    assert drawn_law(seed) == ch  # a function of the seed
    assert drawn_law(seed + 1) != ch
    for name, (lo, hi) in LAW_FACTORS.items():
        assert all(lo <= f <= hi for f in getattr(ch, name)), name
    assert all(LAW_TM_SHIFT_C[0] <= s <= LAW_TM_SHIFT_C[1] for s in ch.tm_shift_c)
    true = forward.read_tables(write_true_calibration(tmp_path, ch))
    # eq. 4 on the written table: the seed's break moved by the drawn shift (the table
    # rounds to 6 decimals: 1e-4 C); convex, B1 > B0
    tm = (true.a0 - true.a1) / (true.b1 - true.b0)
    np.testing.assert_allclose(tm, np.add(SEED_TABLE2_TM, ch.tm_shift_c), atol=1e-3)
    assert np.all(true.b1 > true.b0)
    assert np.all((tm > -23.0) & (tm < -2.0))


def test_the_fit_keeps_each_resamples_break_shift(bench):
    # closed-form normal equations (test_fit_variance._variance_result) whose solution
    # moves x's break by +2 C (its hinge cancelled, the hinge at +2 C carrying the
    # shipped slope change): the solution and nearly every resample take that shift,
    # their shifts lie on the grid, and none moves; with the upper segments unseen
    # every axis is held and no resample tries a shift (entry 21)
    shipped = load_calibration("2010-03-01")
    c = law_parameters(shipped)[0, 2]
    step = np.zeros(N_PARAMETERS)
    step[2] = -c
    step[3 * PER_AXIS + BREAK_SHIFTS_C.index(2.0)] = c
    res = _variance_result(shipped, step)
    shifts = res.bootstrap["break_shift"]
    assert shifts.shape == (200, 3)
    assert set(np.unique(shifts)) <= {0.0, *BREAK_SHIFTS_C}
    assert res.break_shift[0] == 2.0
    assert np.mean(shifts[:, 0] == 2.0) > 0.9
    assert bench.moved_resamples(res).mean() < 0.05
    held = _variance_result(shipped, np.zeros(N_PARAMETERS), counts_to_c=-30.0,
                            upper_unseen=True)
    assert sorted(held.held_upper) == ["x", "y", "z"]
    np.testing.assert_array_equal(held.bootstrap["break_shift"], 0.0)
