"""Segments and the line removed within each (`fluxcal.calibration.segment_trends`).

Expected values are closed forms: a line per segment leaves nothing; a parabola
``t^2`` on a segment of ``n`` evenly spaced samples leaves the Legendre-like residual
``t^2 - (line through it)``, whose mean square is ``(n^2 - 1)(n^2 - 4) / 180`` in units of
the sample step to the fourth (the variance of the degree-2 orthogonal polynomial).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration.segment_trends import (
    remove_segment_lines,
    segment_codes,
    segment_variance,
)


def test_segment_codes_split_each_interval():
    seconds = np.arange(0.0, 3600.0, 10.0)
    intervals = (seconds // 1200).astype(int)
    codes, m = segment_codes(seconds, intervals, np.array([0.0, 1200.0, 2400.0]), 300.0)
    assert m == 12
    np.testing.assert_array_equal(codes, (seconds // 300).astype(int))
    with pytest.raises(ValueError, match="positive"):
        segment_codes(seconds, intervals, np.zeros(3), 0.0)


@settings(max_examples=30, deadline=None)
@given(a=st.floats(-50, 50), b=st.floats(-1, 1), n=st.integers(3, 40))
def test_a_line_per_segment_leaves_nothing(a, b, n):
    t = np.arange(4 * n, dtype=float)
    codes = np.repeat(np.arange(4), n)
    values = np.column_stack([a + b * t * (codes + 1), -a + 0 * t])
    out = remove_segment_lines(values, codes, 4, t)
    np.testing.assert_allclose(out, 0.0, atol=1e-9 * (1 + abs(a) + abs(b) * 4 * n * 4))


@pytest.mark.parametrize("n", [5, 16, 60])
def test_a_parabola_leaves_its_second_orthogonal_polynomial(n):
    t = np.arange(n, dtype=float)
    codes = np.zeros(n, dtype=int)
    out = remove_segment_lines(t**2, codes, 1, t)
    expected = (n**2 - 1) * (n**2 - 4) / 180.0
    assert segment_variance(out, codes, 1)[0] == pytest.approx(expected, rel=1e-9)
    # the mean only: the variance of t^2 itself
    mean_only = remove_segment_lines(t**2, codes, 1, t, line=False)
    assert segment_variance(mean_only, codes, 1)[0] == pytest.approx(np.var(t**2), rel=1e-9)


def test_hedgecock_with_segments_is_exact_under_a_linear_magnitude_trend():
    """A rotating field whose |B| grows linearly in time (a slow compressive trend) plus an
    offset: with a line removed per segment |B - O| has no residual at the true O, so the
    offset comes back to rounding; with the interval mean only the trend biases it."""
    from fluxcal.calibration.variance_offsets import hedgecock_offsets

    t = np.arange(0.0, 6 * 3600.0, 1.0)
    rng = np.random.default_rng(5)
    phase = np.cumsum(rng.normal(0.0, 0.02, (t.size, 2)), axis=0)
    u = np.column_stack([np.cos(phase[:, 0]) * np.cos(phase[:, 1]),
                         np.sin(phase[:, 0]) * np.cos(phase[:, 1]), np.sin(phase[:, 1])])
    offset = np.array([1.5, -2.0, 0.7])
    b = u * (10.0 + 2e-4 * t)[:, None] + offset
    sub = (t // 1200).astype(int)
    est = hedgecock_offsets(b, sub, seconds=t, segment_s=60.0, n_bootstrap=0,
                            max_compressibility=1.0)
    np.testing.assert_allclose(est.offset, offset, atol=1e-6)
    plain = hedgecock_offsets(b, sub, n_bootstrap=0, max_compressibility=1.0)
    assert np.abs(plain.offset - offset).max() > 1e-3
