"""Issue 34, open item 1: the breaks' errors from the residual's profile (entry 51).

`fit_breaks.break_profile` against ``numpy.linalg.lstsq`` on the explicit rows of a hinge
world (the moved hinge written from its definition, ``(1 - lambda) max(0, T - T_m - s_k)
+ lambda max(0, T - T_m - s_n)``); a noise-free world whose breaks lie on grid points,
where the profile is 0 at the truth and the interval closes on it;
`fit_breaks.profile_threshold` against the cluster sandwich computed on those rows; and
the interval's coverage of the truth over many noise draws of entry 27's sparse hinge
world (`test_fit_breaks._sparse_peaks`: the breaks seen only in a few warm blocks).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_break_profile import profile_break_errors
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    PER_AXIS,
    break_profile,
    profile_interval,
    profile_threshold,
)
from fluxcal.missions.messenger.fit_variance import law_parameters, resampling_units
from tests.missions.messenger.test_fit_breaks import NOISE, _sparse_peaks
from tests.missions.messenger.test_fit_variance import _hinge_rows

GRID = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
#: Noise draws of the coverage test, and its tolerance: three binomial standard errors of
#: a share near 0.79 over 100 draws (sqrt(0.79 * 0.21 / 100) = 0.041).
DRAWS = 100
COVERAGE_TOL = 3.0 * np.sqrt(0.79 * 0.21 / DRAWS)


@pytest.fixture(scope="module")
def now():
    return law_parameters(load_calibration("2010-03-01"))


def _kept_columns(axis: int | None) -> list[int]:
    """The free columns with every break kept (shifted hinges not free); ``axis``'s own
    hinge slope and break step left out (its moved hinge is a column of its own)."""
    cols = [j * PER_AXIS + i for j in range(3) for i in range(PER_AXIS)
            if not (j == axis and i in (2, 3))]
    return cols + [N_PARAMETERS - 2, N_PARAMETERS - 1]


def _lstsq_profile(x, y, temp, u, now, axis, s):
    """The least residual with ``axis``'s break at ``s`` (C from ``now``) on the rows."""
    k = min(np.searchsorted(GRID, s, side="right") - 1, GRID.size - 2)
    lam = (s - GRID[k]) / (GRID[k + 1] - GRID[k])
    tm = now[axis, 3]
    hinge = ((1.0 - lam) * np.maximum(0.0, temp - tm - GRID[k])
             + lam * np.maximum(0.0, temp - tm - GRID[k + 1]))
    # the current hinge cancelled: its column times -c moved to the data side
    y_adj = y + now[axis, 2] * x[:, axis * PER_AXIS + 2]
    design = np.column_stack([x[:, _kept_columns(axis)], u[:, axis] * hinge])
    beta = np.linalg.lstsq(design, y_adj, rcond=None)[0]
    return float(np.sum((y_adj - design @ beta) ** 2))


def test_the_profile_is_least_squares_on_the_rows_with_the_hinge_moved(now):
    # a noisy hinge world (the truth 0.3 / -1.3 / +2.6 C from the current breaks): at grid
    # points and between them the profile from the normal equations equals lstsq on the
    # explicit rows with the moved hinge written from its definition (1e-9 of the data's
    # sum of squares: rounding of two different solvers)
    true = now.copy()
    true[:, 3] += (0.3, -1.3, 2.6)
    rng = np.random.default_rng(41)
    stats, x, y, temp, u = _hinge_rows(now, true, rng,
                                       noise=NOISE * rng.normal(size=48 * 300))
    free = np.ones(N_PARAMETERS, dtype=bool)
    a, v, yy = stats.normal.sum(axis=0), stats.rhs.sum(axis=0), float(stats.yy.sum())
    s = np.array([-2.6, -1.0, -0.25, 0.0, 0.3, 0.5, 1.7, 2.6, 8.0])
    for j in range(3):
        got = break_profile(a, v, yy, free, now, (-1, -1, -1), j, s)
        want = [_lstsq_profile(x, y, temp, u, now, j, si) for si in s]
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * yy)
        # the least lies nearest the truth (the grid's rounded corner: within 0.3 C)
        assert abs(s[np.argmin(got)] - (true[j, 3] - now[j, 3])) <= 0.3 + 1e-9


def test_a_noise_free_profile_closes_on_the_truth(now):
    # breaks on grid points (+2, -1, +0.5 C), the other axes at their true shifts: the
    # law is exact there, so the profile is 0 at the truth (to rounding) and above it
    # everywhere else; no noise, a threshold of 1e-9 of the data's sum of squares: the
    # interval closes on the truth (within the scan step, 0.01 C)
    true = now.copy()
    off = np.array([2.0, -1.0, 0.5])
    true[:, 3] += off
    stats = _hinge_rows(now, true, np.random.default_rng(42))[0]
    choice = tuple(BREAK_SHIFTS_C.index(o) for o in off)
    free = np.ones(N_PARAMETERS, dtype=bool)
    a, v, yy = stats.normal.sum(axis=0), stats.rhs.sum(axis=0), float(stats.yy.sum())
    for j in range(3):
        r = break_profile(a, v, yy, free, now, choice, j, GRID)
        at = int(np.flatnonzero(GRID == off[j])[0])
        assert r[at] <= 1e-10 * yy
        assert np.all(np.delete(r, at) > 1e3 * max(r[at], 1e-12 * yy))
        fine = np.arange(-8.0, 8.001, 0.01)
        lo, hi, c_lo, c_hi = profile_interval(
            fine, break_profile(a, v, yy, free, now, choice, j, fine), 1e-9 * yy)
        assert off[j] - 0.01 <= lo <= off[j] <= hi <= off[j] + 0.01 and c_lo and c_hi


def test_the_threshold_is_the_cluster_sandwich_over_the_naive_variance(now):
    # dense data (-60..+40 C), noise 3 counts with a per-block scale (correlated units):
    # the threshold is w^2 (A^-1 S A^-1)_qq / (A^-1)_qq, S the blocks' scores' outer
    # products; here computed on the rows by lstsq; and in this smooth world the
    # interval's half-width is the widened sandwich error of the break (the profile
    # nearly quadratic over +-1 standard error: within 10 %)
    rng = np.random.default_rng(43)
    scale = np.repeat(rng.uniform(0.5, 3.0, 48), 300)
    stats, x, y, temp, u = _hinge_rows(now, now, rng,
                                       noise=NOISE * scale * rng.normal(size=48 * 300))
    cols = _kept_columns(None)
    xf = x[:, cols]
    beta = np.linalg.lstsq(xf, y, rcond=None)[0]
    e = y - xf @ beta
    inv = np.linalg.inv(xf.T @ xf)
    g = np.stack([xf[b * 300:(b + 1) * 300].T @ e[b * 300:(b + 1) * 300] for b in range(48)])
    cov = inv @ (g.T @ g) @ inv
    n, p = 48, len(cols)
    assert resampling_units(stats.normal, stats.rhs, stats.yy, p)[0].shape[0] == n
    w2 = n / (n - p)
    free = np.ones(N_PARAMETERS, dtype=bool)
    for j in range(3):
        q = cols.index(j * PER_AXIS + 3)
        thr = profile_threshold(stats.normal, stats.rhs, free, now, (-1, -1, -1), j,
                                widening=np.sqrt(w2))
        assert thr == pytest.approx(w2 * cov[q, q] / inv[q, q], rel=1e-6)
    out = profile_break_errors(stats, now)
    se = np.sqrt(w2 * np.diag(cov)[[cols.index(j * PER_AXIS + 3) for j in range(3)]])
    se = se / np.abs(now[:, 2])
    print("half-width", 0.5 * (out["hi"] - out["lo"]), "sandwich", se)
    np.testing.assert_allclose(0.5 * (out["hi"] - out["lo"]), se, rtol=0.10)


def test_profile_interval_keeps_a_second_minimum_inside_the_threshold():
    # two minima: the second (0.5 above the least) inside a threshold of 1, outside 0.4
    s = np.linspace(-4.0, 4.0, 801)
    r = np.minimum((s + 2.0) ** 2, 0.5 + 4.0 * (s - 2.0) ** 2)
    lo, hi, c_lo, c_hi = profile_interval(s, r, 1.0)
    assert lo == pytest.approx(-3.0, abs=1e-3)
    assert hi == pytest.approx(2.0 + np.sqrt(0.125), abs=1e-3)
    assert c_lo and c_hi
    lo, hi, _, _ = profile_interval(s, r, 0.4)
    assert lo == pytest.approx(-2.0 - np.sqrt(0.4), abs=1e-3)
    assert hi == pytest.approx(-2.0 + np.sqrt(0.4), abs=1e-3)
    # an interval reaching the scan's end is open there
    assert profile_interval(s, r, 40.0)[2:] == (False, False)


@pytest.mark.slow
def test_the_profile_interval_covers_the_truth_in_the_sparse_hinge_world(now):
    # entry 27's world: the breaks seen only in 16 warm peaks (300-830 samples per 5-C
    # bin above -45 C); the truth 0.3 / -0.7 / 0 C from the linearisation point; noise
    # 3 counts, DRAWS draws.  The interval is +-1 standard error widened by
    # w = sqrt(n / (n - p)) = sqrt(48 / 31): where the sandwich is right it covers the
    # truth in 2 Phi(w) - 1 = 0.787 of the draws; COVERAGE_TOL is three binomial
    # standard errors (measured 0.71 / 0.74 / 0.76; 16 s on the shared 2-core host)
    true = now.copy()
    off = np.array([0.3, -0.7, 0.0])
    true[:, 3] += off
    temp = _sparse_peaks()
    hit = np.zeros(3)
    for d in range(DRAWS):
        rng = np.random.default_rng(700 + d)
        stats = _hinge_rows(now, true, rng, temp=temp,
                            noise=NOISE * rng.normal(size=temp.size))[0]
        out = profile_break_errors(stats, now)
        hit += (out["lo"] <= off) & (off <= out["hi"])
    expected = 2.0 * norm.cdf(np.sqrt(48 / 31)) - 1.0
    print("coverage", hit / DRAWS, "expected", round(expected, 3))
    np.testing.assert_allclose(hit / DRAWS, expected, atol=COVERAGE_TOL)
