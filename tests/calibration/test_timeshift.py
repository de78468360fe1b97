import numpy as np
import pytest

from fluxcal.calibration import timeshift


def test_lookup_and_errors():
    shifts = timeshift.mode_shifts([3, 1, 3], [1, 2, 3], [0.5, np.nan, 2.0])
    np.testing.assert_array_equal(shifts, [2.0, 0.5, 2.0])
    with pytest.raises(KeyError) as info:
        timeshift.mode_shifts([1, 2], [1, 2, 3], [0.5, np.nan, 2.0])
    assert info.value.args == (1, 2)
    with pytest.raises(KeyError):
        timeshift.mode_shifts([4], [1, 2, 3], [0.5, 1.0, 2.0])


def test_shift_epoch_exact_ns():
    out = timeshift.shift_epoch(np.array([10**18], dtype=np.int64), np.array([223.7]))
    assert out[0] == 10**18 + 223_700_000_000
