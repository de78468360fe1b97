import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.cleaning.minimum_variance import minimum_variance
from fluxcal.errors import InputFormatError


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _constructed(rng, sigmas, n=20000, mean=(0.0, 0.0, 0.0)):
    """Independent components of known standard deviations along the columns of a rotation."""
    axes = _random_rotation(rng)
    comps = rng.normal(size=(n, 3)) * np.asarray(sigmas)
    comps -= comps.mean(axis=0)
    # decorrelate exactly so the sample covariance is diagonal in the constructed frame
    comps = comps @ np.linalg.inv(np.linalg.cholesky(np.cov(comps.T, bias=True))).T
    comps *= np.asarray(sigmas)
    return comps @ axes.T + np.asarray(mean), axes


def test_known_axes_and_eigenvalues():
    rng = np.random.default_rng(1)
    sigmas = (3.0, 1.0, 0.2)
    b, axes = _constructed(rng, sigmas, mean=(5.0, -2.0, 1.0))
    mva = minimum_variance(b)
    # the sample covariance was made exactly diag(sigma^2) in the constructed frame:
    np.testing.assert_allclose(mva.eigenvalues, np.square(sigmas), rtol=1e-10)
    for k in range(3):
        # axes agree up to sign (checked separately below)
        assert abs(abs(axes[:, k] @ mva.eigenvectors[:, k]) - 1) < 1e-10
    np.testing.assert_allclose(mva.ratio, 1.0 / 0.04, rtol=1e-10)
    np.testing.assert_allclose(mva.max_ratio, 9.0, rtol=1e-10)


def test_sign_convention():
    rng = np.random.default_rng(2)
    b, _ = _constructed(rng, (2.0, 1.0, 0.1), mean=(0.0, 0.0, 10.0))
    mva = minimum_variance(b)
    e = mva.eigenvectors
    assert e[:, 2] @ mva.mean > 0  # e_min along the mean field
    assert e[np.argmax(np.abs(e[:, 0])), 0] > 0  # largest component of e_max positive
    np.testing.assert_allclose(np.cross(e[:, 0], e[:, 1]), e[:, 2], atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(e), 1.0, atol=1e-12)


def test_planar_rotation_example():
    # whole periods: sample covariance is exactly diag(8, 2, 0) (closed form: A^2 / 2)
    t = np.linspace(0, 6 * np.pi, 6000, endpoint=False)
    b = np.stack([np.cos(t) * 4, np.sin(t) * 2, np.full_like(t, 7.0)], axis=1)
    mva = minimum_variance(b)
    np.testing.assert_allclose(mva.eigenvalues, [8.0, 2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(mva.eigenvectors, np.eye(3), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_frame_round_trip_preserves_vectors_and_norms(seed):
    rng = np.random.default_rng(seed)
    b = rng.normal(size=(50, 3)) * [5, 2, 1] + rng.normal(size=3)
    mva = minimum_variance(b)
    c = mva.to_frame(b)
    np.testing.assert_allclose(mva.from_frame(c), b, atol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(c, axis=1), np.linalg.norm(b, axis=1), rtol=1e-10)
    # variances of the components are the eigenvalues, in descending order
    np.testing.assert_allclose(c.var(axis=0), mva.eigenvalues, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("bad", [np.zeros((2, 3)), np.zeros((10, 2)), np.full((5, 3), np.nan)])
def test_rejects_bad_input(bad):
    with pytest.raises(InputFormatError, match="vectors"):
        minimum_variance(bad)
