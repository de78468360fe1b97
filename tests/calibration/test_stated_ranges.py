"""`StatedRanges`: the intervals a fitted law is stated over (entry 24).

Expected values by hand (bins merged, ends included, distances to the nearest end) and
a round trip of the header text over random interval sets (hypothesis).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fluxcal.calibration.stated_ranges import StatedRanges


def test_adjacent_bins_merge_and_a_gap_splits():
    edges = np.arange(-3.0, 4.0)  # bins [-3,-2) ... [2,3)
    ranges = StatedRanges.from_bins(edges, [True, False, True, True, False, True])
    assert ranges.intervals == ((-3.0, -2.0), (-1.0, 1.0), (2.0, 3.0))
    assert ranges.span == (-3.0, 3.0)
    assert StatedRanges.from_bins(edges, [False] * 6) is None
    assert StatedRanges.from_bins(edges, [True] * 6).intervals == ((-3.0, 3.0),)


def test_contains_and_distance_by_hand():
    ranges = StatedRanges(((-50.0, -49.0), (2.0, 40.0)))
    x = np.array([-51.0, -50.0, -49.0, -48.0, -30.0, 1.5, 2.0, 40.0, 41.0, np.nan])
    np.testing.assert_array_equal(
        ranges.contains(x), [False, True, True, False, False, False, True, True, False, False])
    np.testing.assert_allclose(ranges.distance(x[:-1]),
                               [1.0, 0.0, 0.0, 1.0, 19.0, 0.5, 0.0, 0.0, 1.0])
    assert str(ranges) == "-50..-49, 2..40" and f"{ranges:.1f}" == "-50.0..-49.0, 2.0..40.0"
    assert StatedRanges.of((-5, 3)) == StatedRanges(((-5.0, 3.0),))
    assert StatedRanges.of([(-5, 3), (4, 6)]).intervals == ((-5.0, 3.0), (4.0, 6.0))


@pytest.mark.parametrize("intervals", [(), ((1.0, 1.0),), ((2.0, 1.0),), ((0.0, np.inf),),
                                       ((0.0, 2.0), (1.0, 3.0)), ((0.0, 2.0), (2.0, 3.0)),
                                       ((4.0, 5.0), (0.0, 1.0))])
def test_empty_unordered_or_overlapping_intervals_are_refused(intervals):
    with pytest.raises(ValueError):
        StatedRanges(intervals)


@given(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=2, max_size=12, unique=True))
def test_header_text_reads_back_exactly(values):
    ends = sorted(values)
    if len(ends) % 2:
        ends = ends[:-1]
    ranges = StatedRanges(tuple(zip(ends[::2], ends[1::2], strict=True)))
    assert StatedRanges.parse(ranges.header_text()) == ranges
