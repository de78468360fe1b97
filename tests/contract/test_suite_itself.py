"""The shared contract fails for the right reasons: a repeated or a moved sample."""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.testing import MissionContract, Truth

T = np.datetime64("2024-03-12T23:59:59", "ns") + np.arange(4) * np.timedelta64(500, "ms")


def test_match_keeps_samples_of_equal_time_apart() -> None:
    truth = Truth(np.r_[T[:2], T[1:]], np.zeros((5, 3)))  # the forward model repeats T[1]
    index = MissionContract().match(truth, np.r_[T[1], T[1], T[0], T[2], T[3]])
    assert sorted(index) == [0, 1, 2, 3, 4]


def test_a_sample_written_twice_is_caught() -> None:
    truth = Truth(T, np.zeros((4, 3)))
    with pytest.raises(AssertionError, match="ns from its sample"):
        MissionContract().match(truth, np.r_[T[:2], T[1], T[2]])


def test_a_sample_moved_in_time_is_caught() -> None:
    truth = Truth(T, np.zeros((4, 3)))
    with pytest.raises(AssertionError, match="ns from its sample"):
        MissionContract().match(truth, T + np.timedelta64(2, "us"))
