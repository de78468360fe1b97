"""When a day's own heater-waveform error is worth a warning (`heater_error.exceeds_stated`).

The rule (docs/decisions/messenger_fit.md entry 36): a day's own total, the stated
total with its waveform part replaced by the day's, warns when it exceeds the goal or
exceeds the stated total by more than the stated part's own scatter, ``W_s / sqrt(2 (K -
1))`` for a delete-a-fold jackknife over ``K`` folds.  Expected values: the closed form
worked by hand on chosen numbers, the exact scatter of a jackknife standard error (the
chi distribution with ``K - 1`` degrees of freedom, from gamma functions) and a brute-force
jackknife over drawn folds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fluxcal.calibration.heater_error import day_total, exceeds_stated, part_scatter


def test_day_total_swaps_the_waveform_part_in_quadrature():
    # stated total 0.05 nT of which 0.04 is the waveform part: the rest 0.03 (3-4-5);
    # a day whose own part is 0.08: sqrt(0.03^2 + 0.08^2) = sqrt(0.0073)
    got = day_total([0.05, 0.05, 0.05], [0.04, 0.04, 0.04], [0.08, 0.04, 0.0])
    np.testing.assert_allclose(got, [math.sqrt(0.0073), 0.05, 0.03], rtol=1e-12)
    # a stated part above the stated total (files of two fits): the rest is none
    np.testing.assert_allclose(day_total([0.03], [0.04], [0.05]), [0.05], rtol=1e-12)


def _chi_scatter(dof: int) -> float:
    """Exact relative standard deviation of ``sqrt(chi2_dof / dof)`` (an rms estimated
    with ``dof`` degrees of freedom, against its truth 1)."""
    mean = math.sqrt(2.0 / dof) * math.gamma((dof + 1) / 2.0) / math.gamma(dof / 2.0)
    return math.sqrt(1.0 - mean ** 2)


def test_part_scatter_is_a_jackknife_standard_errors_own_scatter():
    # the asymptotic 1/sqrt(2 (K - 1)) of the code against the exact chi scatter (3
    # degrees of freedom: 0.389) within 6 %, and the exact one against a brute-force
    # delete-a-fold jackknife of a mean over 4 equal folds (20 000 draws: the scatter of
    # the scatter is about 0.5 %, so within 2 %)
    k = 4
    rel = float(part_scatter(1.0, k))
    assert rel == pytest.approx(1.0 / math.sqrt(6.0), rel=1e-12)
    exact = _chi_scatter(k - 1)
    assert exact == pytest.approx(0.3888, abs=5e-4)
    assert rel == pytest.approx(exact, rel=0.06)
    rng = np.random.default_rng(11)
    n_fold, draws = 50, 20000
    x = rng.normal(size=(draws, k, n_fold))           # unit noise, folds of 50 samples
    fold_mean = x.mean(axis=2)
    without = (fold_mean.sum(axis=1, keepdims=True) - fold_mean) / (k - 1)  # x_(-k)
    var = (k - 1) / k * ((without - without.mean(axis=1, keepdims=True)) ** 2).sum(axis=1)
    truth = 1.0 / math.sqrt(k * n_fold)               # the pooled mean's standard error
    brute = float(np.std(np.sqrt(var) / truth))
    assert brute == pytest.approx(exact, rel=0.02)
    with pytest.raises(ValueError, match="at least 2"):
        part_scatter(1.0, 1)


def test_a_part_over_several_columns_scatters_less_than_one_column():
    # the stated part over 4 columns of equal weight, each column's error a jackknife
    # estimate (3 degrees of freedom): independent estimates scatter about half as much
    # as one column (1/sqrt(4)); fully shared estimates as much; never more than the
    # bound part_scatter states (why the bound holds whatever the columns' correlation)
    rng = np.random.default_rng(5)
    draws, cols = 20000, 4
    chi = np.sqrt(rng.chisquare(3, size=(draws, cols)) / 3.0)
    independent = float(np.std(np.sqrt((chi ** 2).mean(axis=1))))
    shared = float(np.std(chi[:, 0]))
    bound = float(part_scatter(1.0, 4))
    assert independent == pytest.approx(_chi_scatter(3) / 2.0, rel=0.1)
    assert independent < shared <= bound


# the hand-made cases (nT): the rest of the stated total, the stated part, the goal
@pytest.mark.parametrize(("total", "stated", "day", "goal", "expected"), [
    # a 16-day table (0.043 stated, 0.040 of it the waveforms), a day 1.18x the part
    # (the largest of the 40 unseen days): total sqrt(0.043^2 - 0.04^2 + 0.0472^2) =
    # 0.0496, 0.0066 above the stated against its scatter 0.04 / sqrt(6) = 0.0163
    (0.043, 0.040, 0.0472, 0.1, False),
    # the same table, a day 1.75x: 0.0714, 0.0284 above (> 0.0163), under the goal
    (0.043, 0.040, 0.070, 0.1, True),
    # a table near its goal (0.095 of 0.1), a day 1.11x its part: sqrt(0.095^2 - 0.09^2
    # + 0.1^2) = 0.1045 > 0.1, though 0.0095 above is within the scatter 0.0367
    (0.095, 0.090, 0.100, 0.1, True),
    # the same day, the goal 0.11: silent
    (0.095, 0.090, 0.100, 0.11, False),
    # a day lighter than the stated mix: silent ...
    (0.043, 0.040, 0.020, 0.1, False),
    # ... unless the table itself is over its goal (a study table, written refused)
    (0.12, 0.05, 0.020, 0.1, True),
    # no goal stated (inf): the scatter alone, 1.5x of a part that is the whole total:
    # 0.06 - 0.04 = 0.02 > 0.0163
    (0.040, 0.040, 0.060, math.inf, True),
    (0.040, 0.040, 0.055, math.inf, False),
])
def test_exceeds_stated_on_hand_made_numbers(total, stated, day, goal, expected):
    beyond, t_d = exceeds_stated([day, 0.0, 0.0], [stated] * 3, [total] * 3, goal, 4)
    hand = math.sqrt(max(total ** 2 - stated ** 2, 0.0) + day ** 2)
    assert t_d[0] == pytest.approx(hand, rel=1e-12)
    assert bool(beyond[0]) is expected
    # the quiet axes (no waveform error that day) are below the stated total
    assert not beyond[1:].any() or total > goal
