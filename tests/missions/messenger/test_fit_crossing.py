"""The crossing benchmark's interpolation (verification section 51).

Expected values by hand: the straight line between the two levels around the first rise
past the goal (messenger_fit_verification.md section 51).
"""

from __future__ import annotations

import math

import pytest

from tests.missions.messenger._benchmarks import load_benchmark


@pytest.fixture(scope="module")
def crossing_share():
    return load_benchmark("messenger_fit_crossing").crossing_share


def test_linear_between_the_levels_around_the_crossing(crossing_share):
    # 0.08 nT at 50 %, 0.12 nT at 60 %: 0.1 is halfway, 55 %; the order given is not
    # the shares' order
    where, share = crossing_share([(0.6, 0.12), (0.3, 0.05), (0.5, 0.08), (0.7, 0.2)], 0.1)
    assert where == "at"
    assert share == pytest.approx(0.55, abs=1e-12)


def test_the_first_rise_past_the_goal_counts(crossing_share):
    # up between 30 and 40 % (0.06 -> 0.14: halfway, 35 %), down again, up again
    where, share = crossing_share([(0.3, 0.06), (0.4, 0.14), (0.5, 0.09), (0.6, 0.2)], 0.1)
    assert (where, round(share, 12)) == ("at", 0.35)


def test_never_crossed_and_crossed_before_the_first_level(crossing_share):
    assert crossing_share([(0.35, 0.05), (0.73, 0.096)], 0.1) == ("above", 0.73)
    assert crossing_share([(0.35, 0.11), (0.73, 0.2)], 0.1) == ("below", 0.35)
    # on the goal is not above it
    assert crossing_share([(0.35, 0.05), (0.5, 0.1)], 0.1) == ("above", 0.5)


@pytest.fixture(scope="module")
def crossing():
    return load_benchmark("messenger_fit_crossing")


def test_binomial_interval_by_hand(crossing):
    # 1 of 2 at the 68 % level (tail 0.16 each side): P(X >= 1) = 1 - (1 - p)^2 = 0.16 gives
    # p = 1 - sqrt(0.84) = 0.083485; P(X <= 1) = 1 - p^2 = 0.16 gives p = sqrt(0.84) = 0.916515
    lo, hi = crossing.binomial_interval(1, 2, level=0.68)
    assert (lo, hi) == (pytest.approx(0.083485, abs=1e-6), pytest.approx(0.916515, abs=1e-6))
    # none of 20: from 0 to the p with P(X = 0) = (1 - p)^20 = 0.16, 1 - 0.16^(1/20) = 0.087556;
    # all of 20: its mirror
    assert crossing.binomial_interval(0, 20, level=0.68) == (
        0.0, pytest.approx(0.087556, abs=1e-6))
    assert crossing.binomial_interval(20, 20, level=0.68) == (
        pytest.approx(0.912444, abs=1e-6), 1.0)


def test_binomial_interval_ends_hold_their_tail(crossing):
    # 7 of 20 at the default (one sigma): the binomial sums at each end equal the tail
    n, k = 20, 7
    tail = (1 - crossing.ONE_SIGMA_LEVEL) / 2
    lo, hi = crossing.binomial_interval(k, n)

    def pmf(j, p):
        return math.comb(n, j) * p**j * (1 - p) ** (n - j)

    assert sum(pmf(j, lo) for j in range(k, n + 1)) == pytest.approx(tail, abs=1e-9)
    assert sum(pmf(j, hi) for j in range(k + 1)) == pytest.approx(tail, abs=1e-9)
    assert lo < k / n < hi


def test_bracket_counts(crossing):
    by_seed = {1: [(0.55, 0.06), (0.62, 0.08)],   # within at both
               2: [(0.62, 0.12), (0.54, 0.09)],   # within at the lower share, above at the higher
               3: [(0.53, 0.11), (0.61, 0.15)],   # above at both
               4: [(0.54, 0.13), (0.63, 0.07)],   # above, then within
               5: [(0.54, 0.1), (0.62, 0.1)],     # on the goal is within
               6: [(0.55, 0.2)]}                  # one level: left out
    assert crossing.bracket_counts(by_seed, 0.1) == {
        "within": [1, 5], "crossed": [2], "above": [3], "fell": [4]}


def test_guard_tally(crossing):
    verdicts = ["refused: variance estimator: 805 of 1536 intervals rejected as compressive",
                "refused: variance estimator: 839 of 1536 intervals rejected as compressive",
                "refused: not converged after 12 passes (law x at -6 C)",
                "accepted"]
    alone = [{"share": "variance estimator: 805 of 1536", "converged": "",
              "check_fit": "duty-cycle law: fitted D0 z stated 12 %", "merit": ""},
             {"share": "variance estimator: 839 of 1536", "converged": "",
              "check_fit": "relaxation time tau stated 6 %", "merit": ""},
             {"share": "", "converged": "not converged after 12 passes",
              "check_fit": "duty-cycle law: fitted D0 z stated 20 %",
              "merit": "temperature law band above its limit everywhere"},
             {"share": "", "converged": "", "check_fit": "", "merit": ""}]
    assert crossing.guard_tally(verdicts, alone) == {
        "verdict": {"share": 2, "not converged": 1, "written": 1},
        "share": {"share": 2}, "converged": {"not converged": 1},
        "check_fit": {"D0 z": 2, "tau": 1}, "merit": {"law band": 1}}
