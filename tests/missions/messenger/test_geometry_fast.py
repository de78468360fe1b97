"""The fast geometry of `add_geometry` against SPICE per sample (issue 3 speed work).

* RTN from the Sun -> spacecraft position and the solar axis (`rtn_from_position`),
  used only when the loaded MSGR_RTN is fluxcal's two-vector definition;
* the sec. 10.2 angles on a 1-s grid, interpolated (`spherical_rtn`);
* the attitude matrices used one block at a time for the field and the Sun direction.
"""

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.positions import position, rtn_spherical
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.chain import calibrate


def _sub(ds, step):
    return ds.isel(time=slice(0, None, step))


def test_rtn_from_position_matches_pxform(messenger_kernels, simulated):
    et = simulated["truth"]["et"].values[::97]
    b = simulated["truth"]["b_mso"].values[::97]  # any vectors: use the field (nT)
    with KernelPool(messenger_kernels):
        assert levels.rtn_is_sun_pole_two_vector("MSGR_RTN")
        sun = position("MESSENGER", "SUN", "J2000", et, method="oracle")
        fast = levels.rtn_from_position(b, sun, et)
        ref = np.einsum("nij,nj->ni", np.array(
            [spiceypy.pxform("J2000", "MSGR_RTN", float(t)) for t in et]), b)
    # same construction as SPICE's two-vector frame: agreement to rounding, 1e-9 nT
    # for |B| < 1000 nT (1e-12 relative)
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-9)


def test_other_rtn_definitions_use_spice(messenger_kernels, simulated, calibration, tmp_path):
    """A kernel redefining MSGR_RTN turns the closed form off: SPICE's frame is used."""
    fk = tmp_path / "other_rtn.tf"
    fk.write_text("KPL/FK\n\\begindata\nFRAME_1499003_SEC_FRAME = 'J2000'\n\\begintext\n")
    sci = _sub(simulated["science"], 500)
    with KernelPool(messenger_kernels):
        assert not levels.rtn_is_sun_pole_two_vector("MSGR_MSO")
        assert not levels.rtn_is_sun_pole_two_vector("NO_SUCH_FRAME")
        spiceypy.furnsh(str(fk))
        try:
            assert not levels.rtn_is_sun_pole_two_vector("MSGR_RTN")
            ds = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                           frames=("rtn", "j2000"), max_offset_step=None)
            et = ds["et"].values
            ref = np.einsum("nij,nj->ni", np.array(
                [spiceypy.pxform("J2000", "MSGR_RTN", float(t)) for t in et]),
                ds["b_j2000"].values)
        finally:
            spiceypy.unload(str(fk))
    # interpolated legs: 5e-10 rad times |B| < 1000 nT
    np.testing.assert_allclose(ds["b_rtn"].values, ref, rtol=0, atol=1e-6)


def test_spherical_rtn_grid_matches_every_sample(messenger_kernels, simulated):
    """20 Hz samples (denser than the 1-s grid): angles within 1e-8 deg of per-sample
    evaluation (bound ~5e-10 deg; the products print 1e-7 deg), r exact to 1e-6 km."""
    et = simulated["truth"]["et"].values
    assert et.size > 4 * (et[-1] - et[0])  # the grid path is taken
    with KernelPool(messenger_kernels):
        sun = position("MESSENGER", "SUN", "J2000", et)
        fast = levels.spherical_rtn(sun, et)
        r, lat, az = rtn_spherical("MESSENGER", et, target_position=sun)
    np.testing.assert_allclose(fast[:, 0], r, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast[:, 1], lat, rtol=0, atol=1e-8)
    daz = (fast[:, 2] - az + 180.0) % 360.0 - 180.0
    assert np.abs(daz).max() < 1e-8
    assert np.all(np.abs(fast[:, 2]) <= 180.0)


def test_spherical_rtn_azimuth_wraps():
    """Unwrapping across +-180 deg: linear interpolation of the continuous angle."""
    from unittest import mock

    grid_et = np.linspace(0.0, 100.0, 101)
    az_grid = ((179.0 + 0.02 * grid_et) + 180.0) % 360.0 - 180.0  # crosses 180 at t=50
    et = np.linspace(0.0, 100.0, 2001)
    sun = np.tile([1.0e8, 0.0, 0.0], (et.size, 1))
    fake = mock.Mock(return_value=(np.ones(grid_et.size), np.zeros(grid_et.size), az_grid))
    with mock.patch("fluxcal.geometry.axes.rtn_spherical", fake):
        out = levels.spherical_rtn(sun, et)
    expected = ((179.0 + 0.02 * et) + 180.0) % 360.0 - 180.0
    d = (out[:, 2] - expected + 180.0) % 360.0 - 180.0
    assert np.abs(d).max() < 1e-9 and np.all(np.abs(out[:, 2]) <= 180.0)


def test_fast_chain_matches_oracle_on_rtn_and_sun(messenger_kernels, simulated, calibration):
    sci = _sub(simulated["science"], 400)
    with KernelPool(messenger_kernels):
        fast = calibrate(sci, simulated["heater"], simulated["temperature"], calibration)
        slow = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                         method="oracle")
    # unit Sun direction in the spacecraft frame: interpolated attitude, 5e-10 rad
    np.testing.assert_allclose(fast["sun_sc"].values, slow["sun_sc"].values, atol=1e-9)
    np.testing.assert_allclose(fast["pos_rtn"].values[:, 0], slow["pos_rtn"].values[:, 0],
                               atol=1e-3)  # km: 1e-4 km position tolerance, margin
    # this subsample is sparse (< 4 samples per grid step): angles are evaluated per
    # sample from the interpolated position, 1e-4 km / 5e7 km ~ 1e-10 deg
    np.testing.assert_allclose(fast["pos_rtn"].values[:, 1:], slow["pos_rtn"].values[:, 1:],
                               atol=1e-8)


def test_fast_positions_in_mso_and_mbf_match_spkpos(messenger_kernels, simulated, calibration):
    # the fast path rotates MESSENGER-Mercury (J2000) with the field's J2000 -> MSO/MBF
    # matrices; the oracle is one spkpos per sample in each frame.  Tolerance 1e-3 km:
    # 1e-4 km Hermite tolerance plus 1e-9 rad x ~2e4 km of rotation error, with margin.
    sci = _sub(simulated["science"], 400)
    with KernelPool(messenger_kernels):
        fast = calibrate(sci, simulated["heater"], simulated["temperature"], calibration)
        et = fast["et"].values
        for var, frame in (("pos_mso", "MSGR_MSO"), ("pos_mbf", "IAU_MERCURY")):
            expected = np.array(
                [spiceypy.spkpos("MESSENGER", float(t), frame, "NONE", "MERCURY")[0] for t in et]
            )
            np.testing.assert_allclose(fast[var].values, expected, rtol=0, atol=1e-3)
