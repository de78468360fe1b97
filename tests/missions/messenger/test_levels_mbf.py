"""MBF without a mission PCK: warned and noted (issue 11)."""

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import utc_to_et
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.chain import calibrate


def _iau_mercury(et):
    return np.array(spiceypy.pxform("J2000", "IAU_MERCURY", et))


def test_builtin_mercury_rotation_detected_and_its_size(shared_kernels):
    pck = shared_kernels / "messenger" / "pck00010_msgr_v23.tpc"
    with KernelPool([]):
        assert levels.mercury_orientation_is_builtin()
        et = float(utc_to_et(np.array(["2012-06-01T00:00:00"]))[0])
        builtin = _iau_mercury(et)
    with KernelPool([pck]):
        assert not levels.mercury_orientation_is_builtin()
        mission = _iau_mercury(et)
    # angle of the rotation between the two MBF frames (SPICE, both kernels real): the
    # 0.094 deg of the issue, 0.5 nT on 300 nT
    angle = np.degrees(np.arccos((np.trace(builtin @ mission.T) - 1.0) / 2.0))
    assert 0.09 < angle < 0.10
    assert 300.0 * np.radians(angle) > 0.45


def test_mbf_product_without_mission_pck_is_warned(messenger_kernels, simulated, calibration,
                                                   caplog):
    sci = simulated["science"].isel(time=slice(0, None, 200))
    with KernelPool(messenger_kernels), caplog.at_level("WARNING"):
        ds = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                       frames=("mso", "mbf"), max_offset_step=None)
        assert "no mission PCK" in ds.attrs["mbf_rotation"]
        assert "no mission PCK" in caplog.text
        caplog.clear()
        ds = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                       frames=("mso",), max_offset_step=None)
        assert "mbf_rotation" not in ds.attrs and "no mission PCK" not in caplog.text
