"""Interpolation grids over the spans of the samples, never over a long gap (issue 31).

Two files of one MESSENGER run months apart (2012-06-01 and 2013-01-09, after the clock
reset), with kernels that cover each file and not the months between: the interpolated
positions, rotations and sec. 10.2 angles must ask SPICE only where samples are, and
agree with one direct SPICE call per sample (``spkpos``, ``pxform``; the oracle paths)
within the interpolators' stated tolerances (1e-4 km, 1e-9 rad; the angles to 1e-7 deg,
the products' printed precision).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import spiceypy

from fluxcal.geometry.axes import spherical_rtn
from fluxcal.geometry.frames import Rotator, pxform_oracle
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.positions import position, position_oracle
from fluxcal.geometry.spans import intervals_with_samples, sample_spans, span_grid
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

STARTS = ("2012-06-01T00:00:00", "2013-01-09T02:00:00")
SPAN_S = 600.0


def test_sample_spans_split_at_long_gaps_only() -> None:
    et = np.array([0.0, 10.0, 610.0, 1211.0, 1211.0, 5000.0])  # gaps 600 (kept), 601
    np.testing.assert_array_equal(sample_spans(et), [[0, 610], [1211, 1211], [5000, 5000]])
    assert sample_spans(np.empty(0)).shape == (0, 2)


def test_span_grid_has_no_node_in_a_gap() -> None:
    nodes, inner = span_grid(np.array([[0.0, 1000.0], [5000.0, 5000.0], [9000.0, 9300.0]]),
                             300.0)
    # ceil(1000/300) = 4 intervals of 250 s; a lone node; one interval of 300 s
    np.testing.assert_array_equal(nodes, [0, 250, 500, 750, 1000, 5000, 9000, 9300])
    np.testing.assert_array_equal(inner, [1, 1, 1, 1, 0, 0, 1])
    spans = np.array([[0.0, 1000.0], [9000.0, 9300.0]])
    # samples only at an end of [-5, 0] and [1000, 4000]: taken exactly at the node
    np.testing.assert_array_equal(
        intervals_with_samples(np.array([-5.0, 0, 1000, 4000, 8999, 9100, 9400]), spans),
        [0, 1, 0, 0, 1, 1])
    lone = np.array([[5.0, 5.0]])  # a lone sample inside an interval, or at its node
    np.testing.assert_array_equal(intervals_with_samples(np.array([0.0, 10, 20]), lone),
                                  [1, 0])
    np.testing.assert_array_equal(intervals_with_samples(np.array([0.0, 5, 20]), lone),
                                  [0, 0])


@pytest.fixture(scope="module")
def gap_kernels(tmp_path_factory) -> list[Path]:
    """Kernels over each file's 600 s (and 600 s each side), nothing in between."""
    files: list[Path] = []
    for i, start in enumerate(STARTS):
        mk = write_messenger_like_kernels(tmp_path_factory.mktemp(f"k{i}"), start, SPAN_S,
                                          margin_s=600.0)
        names = ("msgr_synthetic.bsp", "msgr_synthetic_sc.bc")
        if i == 0:
            names = ("msgr_synthetic.tsc", "msgr_synthetic.tf", *names)
        files += [mk.parent / n for n in names]
    return files


def _samples() -> np.ndarray:
    with KernelPool():
        starts = [spiceypy.str2et(s) for s in STARTS]
    return np.concatenate([t0 + np.arange(0.0, SPAN_S, 0.05) for t0 in starts])  # 20 Hz


def test_positions_rotations_and_angles_across_a_long_gap(gap_kernels) -> None:
    et = _samples()
    with KernelPool(gap_kernels):
        with pytest.raises(Exception, match="SPKINSUFFDATA|CKINSUFF|insufficient|no C-kernel"):
            position_oracle("MESSENGER", "SUN", "J2000", np.array([et[0] + 30 * 86400.0]))
        sun = position("MESSENGER", "SUN", "J2000", et)  # was: SPICE error in the gap
        pick = np.r_[0:et.size:997, et.size - 1]
        truth = position_oracle("MESSENGER", "SUN", "J2000", et[pick])
        assert np.abs(sun[pick] - truth).max() < 1e-4  # km, the interpolator's tolerance

        rot = Rotator("MSGR_SPACECRAFT", et).matrices("J2000")
        exact = pxform_oracle("MSGR_SPACECRAFT", "J2000", et[pick])
        assert np.abs(rot[pick] - exact).max() < 1e-9  # rad, DEFAULT_TOLERANCE

        angles = spherical_rtn(sun, et, "MESSENGER")
        direct = spherical_rtn(sun[pick], et[pick], "MESSENGER", method="oracle")
        np.testing.assert_allclose(angles[pick, 0], direct[:, 0], rtol=1e-15)
        assert np.abs(angles[pick, 1:] - direct[:, 1:]).max() < 1e-7  # deg, as printed
