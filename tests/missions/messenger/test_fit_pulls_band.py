"""The pull harness's design-fixed law bands that cannot pinch (``--bands``; entry 46).

``benchmarks/messenger_fit_pulls.py --summarise DIR --bands`` states the law's error at
each temperature by rules that combine the fit's pairs resamples with replayed
fixed-design ones (`BANDS`), and gives the pulls each would give.  Expected values:

* the rules on resampled laws built with exactly known moments (two normal draws
  whitened to mean 0 and unit covariance, so that the resamples' standard deviation of
  ``a + b T`` is ``sqrt(s_a^2 + T^2 s_b^2 + 2 T rho s_a s_b)`` to rounding): the
  fixed-design band made to pinch to 0 at -58 C (``rho = 1``), the pairs band least at
  ``-rho s_a / s_b`` with ``s_a sqrt(1 - rho^2)`` there, every value in closed form;
* the pulls ``(fit - truth) / band`` by hand on those closed forms;
* the leverage ratio (CR2 over CR0) from raw samples: each unit's block of the hat
  matrix ``H_uu = X_u A^-1 X_u^T`` by matrix products on the samples, its inverse square
  root by an eigendecomposition of that (samples x samples) matrix, the adjusted scores
  ``X_u^T (I - H_uu)^(-1/2) e_u``; nothing of the harness's normal-equation identity.

Tolerances: 1e-9 relative on the closed forms (whitening and the standard deviation
agree to about 1e-14); 1e-6 relative for the leverage ratio (the normal equations
against ``lstsq`` on the samples: about 1e-12 apart).
"""

from __future__ import annotations

import datetime as dt
import types

import numpy as np
import pytest

from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.missions.messenger.calibration_data import load_calibration
from tests.missions.messenger.test_fit_pulls_core import (
    BLOCKS,
    LAW_T,
    N_PARAMETERS,
    _fit,
    _independent,
    _raw,
)

START = dt.date(2010, 3, 1)
#: Pairs band: a (counts at 0 C), b (counts/C), their correlation: least at -54 C.
PAIRS = (3.0, 0.05, 0.9)
#: Fixed-design band: perfectly correlated, so it pinches to 0 at -2.32 / 0.04 = -58 C.
FIXED = (2.32, 0.04, 1.0)
#: The data's range (C): the grid the floors look over (0.5 C).
DATA = (-60.0, -40.0)
REL = 1e-9


@pytest.fixture(scope="module")
def bench(pulls_bench):
    return pulls_bench


def _resamples(sa: float, sb: float, rho: float, n: int = 400, seed: int = 0) -> np.ndarray:
    """Laws (n, 3, 4) ``(a, b, c, T_m)``: ``a``, ``b`` with exactly the given standard
    deviations and correlation (population moments), ``c`` 0.5 and ``T_m`` 100 C fixed
    (no hinge below 100 C), the same on every axis."""
    z = np.random.default_rng(seed).normal(size=(n, 2))
    z -= z.mean(axis=0)
    z = z @ np.linalg.inv(np.linalg.cholesky(np.cov(z, rowvar=False, ddof=0))).T
    a = 1.0 + sa * z[:, 0]
    b = 0.02 + sb * (rho * z[:, 0] + np.sqrt(max(0.0, 1.0 - rho ** 2)) * z[:, 1])
    law = np.stack([a, b, np.full(n, 0.5), np.full(n, 100.0)], axis=-1)
    return np.repeat(law[:, None, :], 3, axis=1)


def _closed(sa: float, sb: float, rho: float, t: np.ndarray) -> np.ndarray:
    """The band of ``a + b T`` in closed form, (len(t), 3)."""
    t = np.asarray(t, dtype=float)
    var = sa ** 2 + t ** 2 * sb ** 2 + 2.0 * t * rho * sa * sb
    return np.repeat(np.sqrt(np.clip(var, 0.0, None))[:, None], 3, axis=1)


T = np.array([-60.0, -58.0, -54.0, -50.0, -45.0, -40.0, 0.0, 25.0])
DATA_T = np.arange(DATA[0], DATA[1] + 0.01, 0.5)


def test_the_fixed_design_band_pinches_and_max_takes_the_larger(bench):
    pairs, fixed = _resamples(*PAIRS), _resamples(*FIXED, seed=1)
    p, f = _closed(*PAIRS, T), _closed(*FIXED, T)
    assert f[1, 0] < 1e-9  # the pinch at -58 C
    np.testing.assert_allclose(bench.band_fixed(pairs, fixed, T, DATA_T), f, rtol=REL,
                               atol=1e-9)
    np.testing.assert_allclose(bench.band_max(pairs, fixed, T, DATA_T), np.maximum(p, f),
                               rtol=REL)


def test_the_floors_are_the_pairs_band_least_or_at_the_regulated_temperature(bench):
    pairs, fixed = _resamples(*PAIRS), _resamples(*FIXED, seed=1)
    sa, sb, rho = PAIRS
    f = _closed(*FIXED, T)
    least = sa * np.sqrt(1.0 - rho ** 2)  # at -rho sa / sb = -54 C, on the grid
    at_50 = np.sqrt(sa ** 2 + 2500.0 * sb ** 2 - 100.0 * rho * sa * sb)
    assert at_50 > least
    np.testing.assert_allclose(bench.band_floor_least(pairs, fixed, T, DATA_T),
                               np.maximum(f, least), rtol=REL)
    np.testing.assert_allclose(bench.band_floor_regulated(pairs, fixed, T, DATA_T),
                               np.maximum(f, at_50), rtol=REL)
    # a data range without -50 C (nor -54 C): the least over it, at its warm end -55 C
    cold = np.arange(-60.0, -54.99, 0.5)
    at_55 = np.sqrt(sa ** 2 + 55.0 ** 2 * sb ** 2 - 110.0 * rho * sa * sb)
    np.testing.assert_allclose(bench.band_floor_regulated(pairs, fixed, T, cold),
                               np.maximum(f, at_55), rtol=REL)
    # the leverage rule: the fixed band times the ratio (never below the fixed band),
    # under the same floor
    for r in (1.5, 0.5):
        def lever(t, r=r):
            return np.full((np.size(t), 3), r)

        np.testing.assert_allclose(
            bench.band_leverage_floored(pairs, fixed, T, DATA_T, lever),
            np.maximum(max(r, 1.0) * f, at_50), rtol=REL)


def test_the_correlation_rule_keeps_the_pairs_correlation_at_the_fixed_widths(bench):
    pairs, fixed = _resamples(*PAIRS), _resamples(*FIXED, seed=1)
    np.testing.assert_allclose(bench.band_correlation(pairs, fixed, T, DATA_T),
                               _closed(FIXED[0], FIXED[1], PAIRS[2], T), rtol=REL)


def test_band_pulls_at_the_law_temperatures_and_over_the_stated_range(bench):
    pairs, fixed = _resamples(*PAIRS), _resamples(*FIXED, seed=1)
    # the fitted Table 2 (A0, B0, A1, B1): the lower line 1 + 0.02 T up to T_m = 100 C;
    # the truth 0.3 counts higher, so every pull below 100 C is -0.3 / band
    table = np.tile([1.0, 0.02, 1.0 - 0.5 * 100.0, 0.52], (3, 1))
    res = types.SimpleNamespace(
        calibration=types.SimpleNamespace(temperature_coefficients=table),
        stated_ranges=StatedRanges(((-58.0, -40.0),)), fitted_range=DATA,
        bootstrap={"law": pairs})
    true = types.SimpleNamespace(a0=table[:, 0] + 0.3, b0=table[:, 1], a1=table[:, 2] + 0.3,
                                 b1=table[:, 3])
    out = bench.band_pulls(res, true, fixed, bench.band_floor_regulated)
    sa, sb, rho = PAIRS
    floor = np.sqrt(sa ** 2 + 2500.0 * sb ** 2 - 100.0 * rho * sa * sb)
    expect = -0.3 / np.maximum(_closed(*FIXED, LAW_T), floor)
    expect[~((LAW_T >= -58.0) & (LAW_T <= -40.0))] = np.nan  # outside the stated range
    np.testing.assert_allclose(out["law_pull"], expect, rtol=REL)
    grid = np.arange(-58.0, -39.99, 0.5)
    np.testing.assert_allclose(
        out["grid_max"], (0.3 / np.maximum(_closed(*FIXED, grid), floor)).max(axis=0),
        rtol=REL)


# --- the leverage ratio against raw samples -------------------------------------------


@pytest.fixture(scope="module")
def lever_fit():
    """`test_fit_pulls_core`'s raw-sample world with one 2-h block's regressors 6x
    larger (a unit that carries much of every column's information, as a few warm peaks
    carry a law's lever arm)."""
    x, y = _raw(5)
    x[7] *= 6.0
    res = _fit(x, y, load_calibration(str(START)))
    return x, y, res


def test_the_leverage_ratio_is_the_raw_samples_cr2_over_cr0(bench, lever_fit):
    x, y, res = lever_fit
    assert not res.held_upper and not np.any(res.break_shift)  # `_independent`'s layout
    ind = _independent(x, y, res, {})
    f, a_inv, unit, theta = ind["f"], ind["a_inv"], ind["unit"], ind["theta"]
    adjusted = np.zeros((ind["n"], f.size))
    for u in range(ind["n"]):
        xu = x[unit == u][..., f].reshape(-1, f.size)
        eu = (y[unit == u] - x[unit == u][..., f] @ theta).ravel()
        h = xu @ a_inv @ xu.T  # the unit's block of the hat matrix, samples x samples
        lam, vec = np.linalg.eigh(0.5 * (h + h.T))
        adjusted[u] = xu.T @ (vec @ ((vec.T @ eu) / np.sqrt(1.0 - np.clip(lam, 0.0, None))))
    cr2 = np.zeros((N_PARAMETERS, N_PARAMETERS))
    cr2[np.ix_(f, f)] = a_inv @ (adjusted.T @ adjusted) @ a_inv
    ratio = bench.leverage_ratio(res)(LAW_T)
    for j, a in enumerate("xyz"):
        for i, t in enumerate(LAW_T):
            g = ind["grads"][f"law {a} {t:+g}"]
            expect = np.sqrt(g @ cr2 @ g / (g @ ind["cov"] @ g))
            assert ratio[i, j] == pytest.approx(expect, rel=1e-6)
    # the heavy unit moves the ratio off 1 (it can fall below 1 in a direction where
    # the inflated scores cancel): the comparison above is not one of ones
    assert np.abs(ratio - 1.0).max() > 0.05
    assert BLOCKS % ind["k"] == 0
