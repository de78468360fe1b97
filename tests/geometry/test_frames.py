"""Rotations: the interpolated path against per-sample pxform, and the fluxcal frame
definitions against independent vector geometry from DE421 state vectors."""

from __future__ import annotations

import numpy as np
import pytest
import spiceypy
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.geometry import frames
from fluxcal.geometry.kernels import KernelPool

DAY0 = "2012-06-01T00:00:00"
TARGETS = ["J2000", "MSGR_MSO", "IAU_MERCURY", "MSGR_RTN", "MSGR_SPACECRAFT", "MSGR_VSO"]


@pytest.fixture(scope="module")
def day_epochs(msgr_pool):
    et0 = spiceypy.str2et(DAY0)
    rng = np.random.default_rng(42)
    return np.sort(et0 + rng.uniform(0.0, 86400.0, 1500))


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle of a @ b.T, computed robustly for tiny angles."""
    rel = np.einsum("nij,nkj->nik", a, b)
    skew = 0.5 * (rel - np.swapaxes(rel, 1, 2))
    return np.linalg.norm(skew[:, [2, 0, 1], [1, 2, 0]], axis=1)


@pytest.mark.parametrize("target", TARGETS)
def test_interpolated_matches_pxform_oracle(msgr_pool, day_epochs, target):
    fast = frames.rotation_matrices("MSGR_MAG", target, day_epochs)
    oracle = frames.rotation_matrices("MSGR_MAG", target, day_epochs, method="oracle")
    # requirement: exact to 1e-9 rad
    assert np.max(_angle(fast, oracle)) < 1e-9


def test_rotate_returns_vectors_and_matrices(msgr_pool, day_epochs):
    b = np.random.default_rng(1).normal(size=(day_epochs.size, 3)) * 300.0
    rotated, m = frames.rotate(b, day_epochs, "MSGR_MAG", "MSGR_MSO", return_matrices=True)
    expected = np.array(
        [spiceypy.mxv(spiceypy.pxform("MSGR_MAG", "MSGR_MSO", float(t)), v)
         for t, v in zip(day_epochs, b, strict=True)]
    )
    assert np.max(np.abs(rotated - expected)) < 1e-9 * 300 * 3
    # the vector-only path (quaternions applied without matrices) meets the same bound
    plain = frames.rotate(b, day_epochs, "MSGR_MAG", "MSGR_MSO")
    assert np.max(np.abs(plain - expected)) < 1e-9 * 300 * 3
    # rotations preserve |B| and are proper orthogonal
    np.testing.assert_allclose(np.linalg.norm(rotated, axis=1), np.linalg.norm(b, axis=1),
                               rtol=1e-12)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)


def test_mso_axes_from_de421_states(msgr_pool, day_epochs):
    """seed 000 sec. 3.3: X = Mercury->Sun, -Y = velocity of Mercury about the Sun
    projected normal to X, Z = X x Y."""
    m = frames.rotation_matrices("J2000", "MSGR_MSO", day_epochs[::50])
    for t, mat in zip(day_epochs[::50], m, strict=True):
        sun = spiceypy.spkpos("SUN", float(t), "J2000", "NONE", "MERCURY")[0]
        vel = spiceypy.spkezr("MERCURY", float(t), "J2000", "NONE", "SUN")[0][3:]
        x = sun / np.linalg.norm(sun)
        v_perp = vel - np.dot(vel, x) * x
        y = -v_perp / np.linalg.norm(v_perp)
        z = np.cross(x, y)
        np.testing.assert_allclose(mat, np.vstack([x, y, z]), atol=1e-9)


def test_vso_x_axis_points_from_venus_to_sun(msgr_pool, day_epochs):
    m = frames.rotation_matrices("J2000", "MSGR_VSO", day_epochs[:3])
    for t, mat in zip(day_epochs[:3], m, strict=True):
        sun = spiceypy.spkpos("SUN", float(t), "J2000", "NONE", "VENUS")[0]
        np.testing.assert_allclose(mat[0], sun / np.linalg.norm(sun), atol=1e-9)


def test_rtn_axes_from_state_and_solar_pole(msgr_pool, day_epochs):
    """seed 000 sec. 3.5: R = Sun->spacecraft, T = Omega_sun x R, N = R x T, with the
    solar rotation axis from the IAU pole (RA 286.13, Dec 63.87 deg, constant)."""
    ra, dec = np.radians(286.13), np.radians(63.87)
    omega = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    m = frames.rotation_matrices("J2000", "MSGR_RTN", day_epochs[::50])
    for t, mat in zip(day_epochs[::50], m, strict=True):
        r = spiceypy.spkpos("MESSENGER", float(t), "J2000", "NONE", "SUN")[0]
        r_hat = r / np.linalg.norm(r)
        t_vec = np.cross(omega, r_hat)
        t_hat = t_vec / np.linalg.norm(t_vec)
        n_hat = np.cross(r_hat, t_hat)
        np.testing.assert_allclose(mat, np.vstack([r_hat, t_hat, n_hat]), atol=1e-9)


def test_mbf_is_iau_mercury(msgr_pool, day_epochs):
    """seed 000 sec. 3.4: MBF is the planetocentric frame; its Z is Mercury's pole."""
    m = frames.rotation_matrices("J2000", "IAU_MERCURY", day_epochs[:5])
    for t, mat in zip(day_epochs[:5], m, strict=True):
        ra, dec, _w, _lam = spiceypy.bodeul(199, float(t))
        pole = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
        np.testing.assert_allclose(mat[2], pole, atol=1e-9)


def test_real_messenger_frames_kernel(msgr_pool, shared_kernels, day_epochs):
    """The real msgr_v231.tf and the mission PCK replace the synthetic definitions:
    MSGR_MAG -> MSGR_SPACECRAFT is the real fixed rotation, and the chain through the
    synthetic CK is still interpolated exactly."""
    with KernelPool(
        [shared_kernels / "messenger" / "msgr_v231.tf",
         shared_kernels / "messenger" / "pck00010_msgr_v23.tpc"],
        generic=False, fluxcal_frames=False,
    ):
        fixed = spiceypy.pxform("MSGR_MAG", "MSGR_SPACECRAFT", float(day_epochs[0]))
        # MANIFEST: a fixed ~4.9 degree rotation about Y
        angle = np.degrees(np.arccos((np.trace(fixed) - 1) / 2))
        assert angle == pytest.approx(4.9, abs=0.1)
        fast = frames.rotation_matrices("MSGR_MAG", "IAU_MERCURY", day_epochs[:300])
        oracle = frames.rotation_matrices("MSGR_MAG", "IAU_MERCURY", day_epochs[:300],
                                          method="oracle")
        assert np.max(_angle(fast, oracle)) < 1e-9


def test_rosetta_cseq_and_ecliptic(rosetta_kernels):
    with KernelPool([rosetta_kernels]):
        et = spiceypy.str2et("2014-09-01T00:00:00") + np.sort(
            np.random.default_rng(5).uniform(0, 86400, 400))
        for target in ("ECLIPJ2000", "67P/C-G_CSEQ"):
            fast = frames.rotation_matrices("ROS_SPACECRAFT", target, et)
            oracle = frames.rotation_matrices("ROS_SPACECRAFT", target, et, method="oracle")
            assert np.max(_angle(fast, oracle)) < 1e-9
        # CSEQ X axis: from the comet toward the Sun
        m = frames.rotation_matrices("J2000", "67P/C-G_CSEQ", et[:2])
        sun = spiceypy.spkpos("SUN", float(et[0]), "J2000", "NONE", "1000012")[0]
        np.testing.assert_allclose(m[0][0], sun / np.linalg.norm(sun), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(min_value=0.0, max_value=86400.0), min_size=2, max_size=40,
                unique=True))
def test_rotation_law_orthogonal_and_norm_preserving(msgr_pool, offsets):
    et = spiceypy.str2et(DAY0) + np.sort(np.array(offsets))
    m = frames.rotation_matrices("MSGR_MAG", "MSGR_MSO", et)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", m, m),
                               np.broadcast_to(np.eye(3), m.shape), atol=1e-12)


@given(seed=st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_quat_rotate_equals_matrix_product(seed):
    # the matrix-free rotation equals R(q) @ v with scipy's independent quaternion matrix
    from scipy.spatial.transform import Rotation

    from fluxcal.geometry.frames import quat_rotate

    rng = np.random.default_rng(seed)
    q = Rotation.random(50, random_state=rng).as_quat()  # scalar last, as fluxcal
    v = rng.normal(scale=1e4, size=(50, 3))
    expected = np.einsum("nij,nj->ni", Rotation.from_quat(q).as_matrix(), v)
    np.testing.assert_allclose(quat_rotate(q, v), expected, rtol=0, atol=1e-9)


def test_ck_nodes_from_record_quaternions(msgr_pool, day_epochs):
    # the CK leg's node matrices come from the segment's own quaternions (not pxform);
    # they must equal pxform at every node to 1e-10 (pxform converts the record's ET back
    # to ticks and lands a fraction of a tick off it: ~1e-11 rad at the simulated slew
    # rates; a tenth of the 1e-9 requirement), and the leg must have taken that path
    rot = frames.Rotator("MSGR_MAG", day_epochs)
    leg = rot._legs["MSGR_MAG"]
    nodes = leg.nodes
    fast = leg._record_matrices(nodes)
    assert fast is not None
    truth = frames.pxform_oracle("MSGR_MAG", "J2000", nodes)
    assert np.abs(fast - truth).max() < 1e-10


def _special_rotations() -> np.ndarray:
    """Identity, 90/180 deg about each axis and diagonals: every branch of the
    matrix -> quaternion choice, with ties between the diagonal and the trace."""
    from scipy.spatial.transform import Rotation

    axes = np.vstack([np.eye(3), -np.eye(3), [[1, 1, 0], [1, 1, 1], [0, -1, 1]]])
    rotvecs = [np.zeros(3)] + [a / np.linalg.norm(a) * ang for a in axes
                               for ang in (np.pi / 2, np.pi, np.pi - 1e-9, 1e-9)]
    return Rotation.from_rotvec(np.array(rotvecs)).as_matrix()


def test_quaternions_of_matrices_are_scipys_bit_for_bit(msgr_pool, day_epochs):
    # expected: scipy itself (the implementation the nodes were built with), over
    # random orientations on the whole sphere, the branch edges and pxform's matrices
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(12)
    m = np.concatenate([Rotation.random(50_000, random_state=rng).as_matrix(),
                        _special_rotations()]
                       + [frames.pxform_oracle(f, "J2000", day_epochs)
                          for f in ("MSGR_SPACECRAFT", "MSGR_MSO", "IAU_MERCURY")])
    np.testing.assert_array_equal(frames._quaternions_of_matrices(m),
                                  Rotation.from_matrix(m).as_quat())


def test_quaternions_of_matrices_hand_the_rest_to_scipy():
    from scipy.spatial.transform import Rotation

    skewed = np.eye(3)[None] + np.array([[[0.0, 1e-6, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    np.testing.assert_array_equal(frames._quaternions_of_matrices(skewed),
                                  Rotation.from_matrix(skewed).as_quat())
    with pytest.raises(ValueError, match="determinant"):
        frames._quaternions_of_matrices(-np.eye(3)[None])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.5, 2.0))
def test_matrices_of_quaternions_are_scipys_bit_for_bit(seed, scale):
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    q = rng.normal(size=(2000, 4)) * scale  # not normalised: both divide by the norm
    q[:8] = np.vstack([np.eye(4), -np.eye(4)]) * scale
    np.testing.assert_array_equal(frames._matrices_of_quaternions(q),
                                  Rotation.from_quat(q).as_matrix())
