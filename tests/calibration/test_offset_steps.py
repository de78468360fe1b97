import numpy as np

from fluxcal.calibration.offset_steps import largest_steps
from fluxcal.calibration.offsets import breakpoint_temperature, two_segment_offset


def test_largest_step_per_component_and_segments():
    off = np.zeros((10, 2))
    off[4:, 0] += 1.5  # step before sample 4
    off[7:, 1] -= 3.0  # step before sample 7, but across a segment boundary
    seg = np.array([0] * 7 + [1] * 3)
    rep = largest_steps(off, seg)
    np.testing.assert_array_equal(rep.largest_step, [1.5, 0.0])
    assert rep.index[0] == 4
    rep = largest_steps(off)
    np.testing.assert_array_equal(rep.largest_step, [1.5, 3.0])
    np.testing.assert_array_equal(rep.index, [4, 7])


def test_two_segment_closed_form():
    # a made-up line pair: 1 + 1 T below, 5 + 3 T above -> T_m = (1 - 5) / (3 - 1) = -2
    coef = np.array([[1.0, 1.0, 5.0, 3.0]])
    assert breakpoint_temperature(coef)[0] == -2.0
    got = two_segment_offset(np.array([-10.0, -2.0, 4.0]), coef)[:, 0]
    np.testing.assert_allclose(got, [-9.0, -1.0, 17.0])
