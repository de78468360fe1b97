"""Change-point score test of an offset step (`fluxcal.calibration.step_scan`).

A linear model written here: interval ``k`` has regressors ``X_k`` (n x 3, random) and
data ``y_k = X_k (o + [k >= j*] D) + e`` with white noise ``e`` of unit variance.  At the
least-squares ``o`` without a step, ``N_k = X_k^T X_k`` and ``r_k = X_k^T (y_k - X_k o)``
are what a variance fit hands over.  Expected: the step's interval ``j*`` and size ``D``
(to 3 of the stated sigma), and under no step a ``chi2`` of 3 dof (the largest of 40
splits below 25, the limit of docs/decisions/rosetta_fit.md entry 16).
"""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.calibration.step_scan import scan_offset_step


def _normal_equations(step: np.ndarray, at: int, seed: int, k: int = 48, n: int = 40):
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1.0, (k, n, 3))
    o = np.array([0.3, -0.2, 0.1])
    y = np.einsum("kni,i->kn", x, o) + rng.normal(0.0, 1.0, (k, n))
    y[at:] += np.einsum("kni,i->kn", x[at:], step)
    normal = np.einsum("kni,knj->kij", x, x)
    fitted = np.linalg.solve(normal.sum(axis=0), np.einsum("kni,kn->i", x, y))
    rhs = np.einsum("kni,kn->ki", x, y - np.einsum("kni,i->kn", x, fitted))
    return normal, rhs


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_step_is_found_at_its_interval_with_its_size(seed):
    step = np.array([0.5, -0.4, 0.3])
    normal, rhs = _normal_equations(step, 20, seed)
    scan = scan_offset_step(normal, rhs, np.ones(48, bool), np.arange(3), 6)
    assert scan.split == 20 and scan.statistic > 25
    assert np.all(np.abs(scan.step - step) < 3 * scan.sigma), (scan.step, scan.sigma)
    assert scan.splits == 48 - 12 + 1


@pytest.mark.parametrize("seed", [4, 5, 6, 7])
def test_no_step_stays_below_the_limit(seed):
    normal, rhs = _normal_equations(np.zeros(3), 0, seed)
    scan = scan_offset_step(normal, rhs, np.ones(48, bool), np.arange(3), 6)
    assert scan.statistic < 25.0


def test_too_few_intervals_scan_nothing():
    normal, rhs = _normal_equations(np.zeros(3), 0, 8, k=10)
    scan = scan_offset_step(normal, rhs, np.ones(10, bool), np.arange(3), 6)
    assert scan.split == -1 and scan.splits == 0
