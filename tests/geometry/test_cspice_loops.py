"""The CSPICE loops against spiceypy's own per-call wrappers (the outside tool)."""

from __future__ import annotations

import numpy as np
import pytest
import spiceypy

from fluxcal.errors import KernelError
from fluxcal.geometry import cspice_loops, frames, positions
from fluxcal.geometry.kernels import KernelPool


@pytest.fixture(scope="module")
def msgr_epochs(messenger_kernels):
    with KernelPool([messenger_kernels]):
        et0 = spiceypy.str2et("2012-06-01T00:00:00")
        # random epochs over the day and the day's two ends (sorted and unsorted)
        et = et0 + np.random.default_rng(3).uniform(0.0, 86400.0, 200)
        yield np.concatenate([[et0, et0 + 86400.0], et])


@pytest.mark.parametrize(("source", "target"), [
    ("MSGR_SPACECRAFT", "J2000"), ("J2000", "MSGR_MSO"), ("MSGR_MAG", "IAU_MERCURY"),
    ("MSGR_RTN", "MSGR_SPACECRAFT"),
])
def test_pxform_into_is_spiceypy_pxform_bit_for_bit(msgr_epochs, source, target):
    # the same CSPICE routine: equality, not a tolerance
    expected = np.array([spiceypy.pxform(source, target, float(t)) for t in msgr_epochs])
    out = np.empty((msgr_epochs.size, 3, 3))
    assert cspice_loops.pxform_into(source, target, msgr_epochs, out)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(frames.pxform_oracle(source, target, msgr_epochs), expected)


@pytest.mark.parametrize(("target", "observer", "frame"), [
    ("MESSENGER", "SUN", "J2000"), ("MESSENGER", "MERCURY", "MSGR_MSO"),
    ("EARTH", "SUN", "J2000"),
])
def test_spkezr_into_is_spiceypy_spkezr_bit_for_bit(msgr_epochs, target, observer, frame):
    expected = np.array([spiceypy.spkezr(target, float(t), frame, "NONE", observer)[0]
                         for t in msgr_epochs])
    out = np.empty((msgr_epochs.size, 6))
    assert cspice_loops.spkezr_into(target, observer, frame, msgr_epochs, out)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(
        positions.states_oracle(target, observer, frame, msgr_epochs), expected)


def test_errors_reset_and_name_the_epoch(messenger_kernels):
    with KernelPool([messenger_kernels]):
        et0 = spiceypy.str2et("2012-06-01T00:00:00")
        late = spiceypy.str2et("2013-06-01T00:00:00")  # after the synthetic CK and SPK
        et = np.array([et0, late, et0 + 10.0])
        assert not cspice_loops.pxform_into("MSGR_SPACECRAFT", "J2000", et,
                                            np.empty((3, 3, 3)))
        assert not spiceypy.failed()  # the error state is reset for the next caller
        assert not cspice_loops.spkezr_into("MESSENGER", "SUN", "J2000", et, np.empty((3, 6)))
        assert not spiceypy.failed()
        with pytest.raises(KernelError, match=r"MSGR_SPACECRAFT -> J2000 at 2013-06-01"):
            frames.pxform_oracle("MSGR_SPACECRAFT", "J2000", et)
        with pytest.raises(KernelError, match=r"MESSENGER relative to SUN in J2000 at 2013-06"):
            positions.states_oracle("MESSENGER", "SUN", "J2000", et)
        # later calls are unaffected
        np.testing.assert_array_equal(frames.pxform_oracle("MSGR_SPACECRAFT", "J2000", et[:1]),
                                      spiceypy.pxform("MSGR_SPACECRAFT", "J2000", et0)[None])


def test_output_layout_is_checked():
    with pytest.raises(ValueError, match="C-contiguous"):
        cspice_loops.pxform_into("J2000", "J2000", np.zeros(2), np.empty((2, 3, 3))[:, :, ::-1])
    with pytest.raises(ValueError, match="shape"):
        cspice_loops.spkezr_into("EARTH", "SUN", "J2000", np.zeros(2), np.empty((2, 3)))
