import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fluxcal.calibration import counts


@given(st.integers(-(2**19), 2**19 - 1))
def test_signed_round_trip(c):
    v = counts.signed_to_value(np.array([c]), -15000.0, 15000.0, 20)
    assert counts.value_to_signed(v, -15000.0, 15000.0, 20)[0] == c


def test_signed_range_and_ends():
    v = counts.signed_to_value(np.array([-(2**19), 2**19 - 1]), -2.5, 2.5, 20)
    np.testing.assert_allclose(v, [-2.5, 2.5])
    with pytest.raises(ValueError):
        counts.signed_to_value(np.array([2**19]), -2.5, 2.5, 20)


def test_twos_complement_and_signed():
    np.testing.assert_array_equal(
        counts.twos_complement_to_offset_binary([0, 0x7FFF, 0x8000, 0xFFFF], 16),
        [0x8000, 0xFFFF, 0, 0x7FFF],
    )
    np.testing.assert_array_equal(counts.to_signed([0x80, 0x7F, 0xFF, 0], 8), [-128, 127, -1, 0])
    with pytest.raises(ValueError):
        counts.to_signed([256], 8)
