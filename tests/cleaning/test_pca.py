import numpy as np
import pytest

from fluxcal.cleaning.pca import two_sensor_pca
from fluxcal.errors import InputFormatError
from tests.cleaning._synthetic import red_noise, rotating_field

FS = 1.0  # LEVEL_J works on 1 s averages
N = 200_000
SIGMA_OB = np.array([0.2, 0.15, 0.25])  # nT, local disturbance at the outboard sensor
SIGMA_IB = np.array([0.5, 0.6, 0.4])  # nT, larger at the inboard sensor (closer to s/c)


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(21)
    t = np.arange(N) / FS
    # external field: slow rotation + red-noise fluctuations (a few nT rms); the
    # sampling error of psi is ~ sigma_e * sigma_n / sqrt(N), so sigma_e stays modest
    external = rotating_field(t, magnitude=5.0, period=1e6) + red_noise(N, FS, 3e-6, rng)
    n_ob = rng.normal(size=(N, 3)) * SIGMA_OB
    n_ib = rng.normal(size=(N, 3)) * SIGMA_IB
    res = two_sensor_pca(external + n_ob, external + n_ib)
    return dict(external=external, n_ob=n_ob, n_ib=n_ib, res=res)


def test_noise_variances_recovered(case):
    res = case["res"]
    # psi_a = C_aa - C_ab = var(n_a) + cov(e, n_a) - cov(e, n_b) - cov(n_a, n_b): its
    # sampling standard deviation follows from those terms; allow 4 of them
    se2 = case["external"].var(axis=0)
    pa, pb = SIGMA_OB**2, SIGMA_IB**2
    for k, p_true in enumerate((pa, pb)):
        std = np.sqrt(se2 * (pa + pb) + pa * pb + 2 * p_true**2) / np.sqrt(N)
        assert np.all(np.abs(res.noise_variance[:, k] - p_true) < 4 * std)
        np.testing.assert_allclose(res.noise_variance[:, k], p_true, rtol=0.15)


def test_external_field_error_is_the_closed_form_minimum(case):
    res = case["res"]
    pa, pb = SIGMA_OB**2, SIGMA_IB**2
    expected = np.sqrt(pa * pb / (pa + pb))  # rms error of the inverse-variance mean
    err = np.sqrt(np.mean((res.external - case["external"]) ** 2, axis=0))
    np.testing.assert_allclose(err, expected, rtol=0.05)
    assert np.all(err < SIGMA_OB)  # better than the better sensor alone


def test_uncorrelated_parts(case):
    res = case["res"]
    pa, pb = SIGMA_OB**2, SIGMA_IB**2
    # closed form: uncorrelated_a = w_b (n_a - n_b), rms = w_b sqrt(psi_a + psi_b), with
    # w_b -> psi_a / (psi_a + psi_b) for the true variances (1 % sampling tolerance on
    # the rms of N samples; the weights themselves are checked against the ideal below)
    rms_a = np.sqrt(np.mean(res.uncorrelated_a**2, axis=0))
    rms_b = np.sqrt(np.mean(res.uncorrelated_b**2, axis=0))
    np.testing.assert_allclose(rms_a, res.weights[:, 1] * np.sqrt(pa + pb), rtol=0.01)
    np.testing.assert_allclose(rms_b, res.weights[:, 0] * np.sqrt(pa + pb), rtol=0.01)
    np.testing.assert_allclose(res.weights[:, 1], pa / (pa + pb), atol=0.05)
    # each part is correlated with its own sensor's disturbance as the closed form
    # corr(w (n_b - n_a), n_b) = sigma_b / sqrt(sigma_a^2 + sigma_b^2) says
    for c in range(3):
        expected = SIGMA_IB[c] / np.hypot(SIGMA_OB[c], SIGMA_IB[c])
        got = np.corrcoef(res.uncorrelated_b[:, c], case["n_ib"][:, c])[0, 1]
        assert got == pytest.approx(expected, abs=0.01)
    # the split is exact: correlated + uncorrelated = measured
    np.testing.assert_allclose(
        res.external + res.uncorrelated_a, case["external"] + case["n_ob"], atol=1e-9
    )


def test_leading_eigenvector_is_common_mode_for_equal_noise():
    rng = np.random.default_rng(3)
    e = rng.normal(size=(50_000, 3)) * 5
    a = e + rng.normal(size=e.shape) * 0.3
    b = e + rng.normal(size=e.shape) * 0.3
    res = two_sensor_pca(a, b)
    np.testing.assert_allclose(res.eigenvectors[:, :, 0], np.full((3, 2), 2**-0.5), atol=1e-3)
    proj = two_sensor_pca(a, b, method="projection")
    # with equal noise the literal projection and the common-mode split coincide
    assert np.sqrt(np.mean((proj.external - res.external) ** 2)) < 0.01
    # psi sampling error here ~ 5 * 0.42 / sqrt(5e4) = 0.01 (10 % of 0.09) -> weights +-0.05
    np.testing.assert_allclose(res.weights, 0.5, atol=0.05)


def test_shape_errors():
    with pytest.raises(InputFormatError, match="resample"):
        two_sensor_pca(np.zeros((10, 3)), np.zeros((11, 3)))
    with pytest.raises(InputFormatError, match="method"):
        two_sensor_pca(np.ones((10, 3)), np.ones((10, 3)), method="ica")
