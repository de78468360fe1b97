"""The crossing benchmark's interpolation (verification section 51).

Expected values by hand: the straight line between the two levels around the first rise
past the goal (messenger_fit_verification.md section 51).
"""

from __future__ import annotations

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
