"""The fixed-design (score) bootstrap of the variance estimator (issue 34, entry 41).

Expected values are computed here from the raw samples of a linear model split into
units (blocks), by ``numpy.linalg.lstsq`` on the stacked samples and the units' own
residuals, sharing nothing with `fit_variance`'s normal-equation algebra:

* the resampled steps' covariance is the cluster sandwich ``A^-1 (sum_u g_u g_u^T)
  A^-1`` (``g_u = X_u^T (y_u - X_u theta)``, ``theta`` the least-squares solution);
* every resample keeps the whole data's normal matrix, and the resampled right-hand
  sides average to the data's own;
* a design with one high-leverage unit: the pairs bootstrap (the design resampled)
  states that column wider than the sandwich, the fixed-design one does not.
"""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.missions.messenger.fit_breaks import (
    N_PARAMETERS,
    fixed_design_resamples,
)
from fluxcal.missions.messenger.fit_variance import (
    VarianceStatistics,
    solve_variance,
)

#: Units, samples per unit, parameters of the small closed-form model.
UNITS, PER_UNIT, P = 40, 30, 3


def _units(seed: int, lever: bool = False):
    """Raw samples of ``y = X theta + e`` in `UNITS` units, all alike; with ``lever``,
    column 2 ten times smaller in every unit but unit 0 (a lever arm only it gives, as
    the few warm intervals give the law at 0 C)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((UNITS, PER_UNIT, P))
    if lever:
        x[1:, :, 2] *= 0.1
    y = x @ np.array([0.5, -1.0, 2.0]) + rng.standard_normal((UNITS, PER_UNIT))
    return x, y


def _sandwich(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares on the stacked samples and the cluster sandwich, from the raw data."""
    theta = np.linalg.lstsq(x.reshape(-1, x.shape[-1]), y.ravel(), rcond=None)[0]
    a_inv = np.linalg.inv(np.einsum("usi,usj->ij", x, x))
    g = np.einsum("usi,us->ui", x, y - x @ theta)
    return theta, a_inv @ (g.T @ g) @ a_inv


def test_fixed_design_resamples_give_the_cluster_sandwich() -> None:
    x, y = _units(1)
    theta, cov = _sandwich(x, y)
    a_u = np.einsum("usi,usj->uij", x, x)
    v_u = np.einsum("usi,us->ui", x, y)
    rng = np.random.default_rng(2)
    n_boot = 20_000
    picks = np.stack([np.bincount(rng.integers(0, UNITS, UNITS), minlength=UNITS)
                      for _ in range(n_boot)])
    a_r, v_r, yy_r = fixed_design_resamples(picks, a_u, v_u, a_u.sum(0), v_u.sum(0),
                                            7.0, theta)
    # the design kept: every resample's normal matrix is the whole data's
    np.testing.assert_allclose(a_r, np.broadcast_to(a_u.sum(0), a_r.shape), rtol=1e-12)
    np.testing.assert_array_equal(yy_r, np.full(n_boot, 7.0))
    steps = np.linalg.solve(a_r, v_r[..., None])[..., 0]
    # mean: the solution (the counts average 1); spread: the sandwich. 20 000 resamples
    # put the standard deviation's sampling error near 0.5 %: tolerance 3 %
    np.testing.assert_allclose(steps.mean(0), theta, atol=0.05 * np.sqrt(np.diag(cov)).max())
    np.testing.assert_allclose(np.std(steps, axis=0), np.sqrt(np.diag(cov)), rtol=0.03)


def _stats(x: np.ndarray, y: np.ndarray) -> VarianceStatistics:
    """The variance estimator's per-block statistics of the small model: its columns in
    the first three of `N_PARAMETERS` (the x law's ``a``, ``b``, ``c``); every other
    column an independent unit regressor of no signal, so that the system is full rank."""
    rng = np.random.default_rng(3)
    big = rng.standard_normal((UNITS, PER_UNIT, N_PARAMETERS))
    big[:, :, :P] = x
    return VarianceStatistics(
        normal=np.einsum("usi,usj->uij", big, big), rhs=np.einsum("usi,us->ui", big, y),
        yy=np.einsum("us,us->u", y, y), samples=np.full(UNITS, float(PER_UNIT)),
        block_start=np.arange(UNITS) * 7200.0)


@pytest.mark.parametrize("lever", [False, True])
def test_solve_variance_fixed_design_against_pairs(lever: bool) -> None:
    x, y = _units(4, lever)
    stats = _stats(x, y)
    pairs = solve_variance(stats, n_bootstrap=2000, seed=5)
    fixed = solve_variance(stats, n_bootstrap=2000, seed=5, fixed_design=True)
    np.testing.assert_allclose(fixed.step, pairs.step, rtol=1e-12, atol=1e-12)
    assert fixed.widening == pairs.widening
    # the sandwich of the whole model (all free columns), from the raw samples
    rng = np.random.default_rng(3)
    big = rng.standard_normal((UNITS, PER_UNIT, N_PARAMETERS))
    big[:, :, :P] = x
    free = np.zeros(N_PARAMETERS, dtype=bool)
    free[:15] = True
    free[-2:] = True  # the per-axis columns and tau, dt (no break shifts without a law)
    _, cov = _sandwich(big[:, :, free], y)
    sd_fixed = np.std(fixed.boot[:, free], axis=0)
    # 2000 resamples: the standard deviation's sampling error about 1.6 %; tolerance 6 %
    np.testing.assert_allclose(sd_fixed, np.sqrt(np.diag(cov)), rtol=0.06)
    ratio = np.std(pairs.boot[:, 2]) / sd_fixed[2]
    if not lever:  # no unit dominates: the two agree to sampling error
        assert 0.9 < ratio < 1.15
    else:  # one unit carries column 2's lever arm: resampling it widens the pairs spread
        assert ratio > 1.3
