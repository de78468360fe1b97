"""Two sensors on a common time base (`fluxcal.cleaning.resample`) and PCA after it.

The main case is built so that every expected number is a closed form: all signals are
sums of tones at whole numbers of cycles over the window (the FFT grid), so distinct
tones are exactly orthogonal over the samples, and IB is tagged half a sample after
OB, so linear interpolation of IB onto an OB tag is the mean of its two neighbours
and scales a tone of frequency f by exactly ``cos(pi f h)``.
"""

import numpy as np
import pytest

from fluxcal.cleaning.pca import two_sensor_pca
from fluxcal.cleaning.resample import (
    common_time_base,
    interpolate_linear,
    resample_two_sensors,
)
from fluxcal.errors import InputFormatError

H_NS = 1_000_000_000  # 1 s sampling: LEVEL_J works on 1 s averages
T0 = 460_000_000_000_000_000  # a TT2000 value in 2014 (ns): float64 ns would resolve 64 ns
N = 2**17  # samples (36 h): the tones' common period
SIGMA_OB = np.array([0.2, 0.15, 0.25])  # nT, local disturbance at the outboard sensor
SIGMA_IB = np.array([0.5, 0.6, 0.4])  # nT, larger at the inboard sensor


def _tones(half_samples, ks, amps, phases):
    """Sum of tones ``A cos(2 pi k t / (N h) + phi)`` at t = half_samples * h / 2.

    The phase is reduced modulo 2 pi in integers, so it is exact for any t.
    """
    out = np.zeros(half_samples.size)
    for k, a, p in zip(ks, amps, phases, strict=True):
        out += a * np.cos(2 * np.pi * ((int(k) * half_samples) % (2 * N)) / (2 * N) + p)
    return out


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(5)
    k_ob = np.arange(N, dtype=np.int64)  # OB at t = k h
    k_ib = np.arange(N + 1, dtype=np.int64)  # IB at t = (k - 1/2) h: spans every OB tag
    hs_ob, hs_ib = 2 * k_ob, 2 * k_ib - 1  # times in half samples
    e_ob, e_ib, a, b = (np.zeros((n, 3)) for n in (N, N + 1, N, N + 1))
    b_interp = np.zeros((N, 3))  # IB interpolated onto OB tags, in closed form
    terms = {"loss_a": np.zeros(3), "psi_b": np.zeros(3), "eta2": np.zeros(3)}
    for c in range(3):
        # disjoint wavenumbers per component: external (red, below 0.01 Hz), then the
        # two sensors' band-limited disturbances (0.002-0.05 Hz)
        k_ext = rng.choice(np.arange(2, 1300), 40, replace=False)
        rest = np.setdiff1d(np.arange(250, 6500), k_ext)
        k_dist = rng.choice(rest, 160, replace=False)
        k_a, k_b = k_dist[:80], k_dist[80:]
        amp_ext = 0.5 * (100.0 / k_ext) ** 0.5  # red: amplitude ~ f^-1/2
        # the slow rotation of `rotating_field` (magnitude 5 nT) is the k = 1 tone
        rot = {0: (4.0, 0.0), 1: (4.0, -np.pi / 2), 2: (0.0, 0.0)}[c]
        k_ext, amp_ext = np.append(k_ext, 1), np.append(amp_ext, rot[0])
        ph_ext = np.append(rng.uniform(0, 2 * np.pi, 40), rot[1])
        amp_a = np.full(80, SIGMA_OB[c] * np.sqrt(2 / 80))  # sum A^2 / 2 = sigma^2
        amp_b = np.full(80, SIGMA_IB[c] * np.sqrt(2 / 80))
        ph_a, ph_b = rng.uniform(0, 2 * np.pi, (2, 80))
        const = 3.0 if c == 2 else 0.0
        e_ob[:, c] = const + _tones(hs_ob, k_ext, amp_ext, ph_ext)
        e_ib[:, c] = const + _tones(hs_ib, k_ext, amp_ext, ph_ext)
        a[:, c] = e_ob[:, c] + _tones(hs_ob, k_a, amp_a, ph_a)
        b[:, c] = e_ib[:, c] + _tones(hs_ib, k_b, amp_b, ph_b)
        g_ext, g_b = np.cos(np.pi * k_ext / N), np.cos(np.pi * k_b / N)  # cos(pi f h)
        b_interp[:, c] = (
            const
            + _tones(hs_ob, k_ext, amp_ext * g_ext, ph_ext)
            + _tones(hs_ob, k_b, amp_b * g_b, ph_b)
        )
        # closed forms of the covariances of a = e + n_a and b' = e' + n_b' (primes:
        # interpolated) over whole periods:
        terms["loss_a"][c] = np.sum(amp_ext**2 * (1 - g_ext)) / 2  # C_aa - C_ab - sigma_a^2
        terms["psi_b"][c] = (
            np.sum(amp_b**2 * g_b**2) / 2 - np.sum(amp_ext**2 * g_ext * (1 - g_ext)) / 2
        )
        terms["eta2"][c] = np.sum(amp_ext**2 * (1 - g_ext) ** 2) / 2  # var(e' - e)
        terms.setdefault("sigma_b2_interp", np.zeros(3))[c] = np.sum(amp_b**2 * g_b**2) / 2
    t_ob = T0 + k_ob * H_NS
    t_ib = T0 + k_ib * H_NS - H_NS // 2
    res = resample_two_sensors(t_ob, a, t_ib, b)
    pca = two_sensor_pca(res.a, res.b, method="common-mode")  # the closed forms are its
    return dict(res=res, pca=pca, e=e_ob, a=a, b_interp=b_interp, **terms)


def test_interpolation_matches_the_closed_form(case):
    res = case["res"]
    assert res.times.size == N and res.dropped == 0
    assert res.interpolated == (0, N)  # OB on its own tags, every IB value interpolated
    np.testing.assert_array_equal(res.a, case["a"])  # the primary is not touched
    # rounding only: sums of ~120 tones of <= 4 nT, relative precision 1e-16
    np.testing.assert_allclose(res.b, case["b_interp"], rtol=0, atol=1e-11)


def test_noise_variances_recovered_within_the_interpolation_error(case):
    psi = case["pca"].noise_variance
    # exact predictions (whole periods: no sampling error; 1e-9 relative for rounding)
    np.testing.assert_allclose(psi[:, 0], SIGMA_OB**2 + case["loss_a"], rtol=1e-9)
    np.testing.assert_allclose(psi[:, 1], case["psi_b"], rtol=1e-9)
    # against the known amplitudes: OB gains the external field's interpolation loss,
    # IB loses the attenuation of its own disturbance and the external cross term
    tol_a = case["loss_a"]
    tol_b = SIGMA_IB**2 - case["sigma_b2_interp"] + case["loss_a"]
    assert np.all(np.abs(psi[:, 0] - SIGMA_OB**2) <= tol_a * (1 + 1e-6))
    assert np.all(np.abs(psi[:, 1] - SIGMA_IB**2) <= tol_b * (1 + 1e-6))
    # the bounds are small: < 1 % of the OB and < 3 % of the IB variance here
    assert np.all(tol_a < 0.01 * SIGMA_OB**2) and np.all(tol_b < 0.03 * SIGMA_IB**2)


def test_external_field_recovered(case):
    pca, e = case["pca"], case["e"]
    w_a, w_b = pca.weights[:, 0], pca.weights[:, 1]
    err = np.sqrt(np.mean((pca.external - e) ** 2, axis=0))
    # closed form: external - e = w_a n_a + w_b (n_b' + e' - e), orthogonal terms
    expected = np.sqrt(w_a**2 * SIGMA_OB**2 + w_b**2 * (case["sigma_b2_interp"] + case["eta2"]))
    np.testing.assert_allclose(err, expected, rtol=1e-6)
    # and the noise-limited optimum of the known amplitudes (no interpolation), within
    # the relative change the interpolation error terms can cause (< 1 % here)
    pa, pb = SIGMA_OB**2, SIGMA_IB**2
    optimum = np.sqrt(pa * pb / (pa + pb))
    rel = np.abs(err / optimum - 1)
    bound = (case["loss_a"] + SIGMA_IB**2 - case["sigma_b2_interp"]) / pa + np.sqrt(
        case["eta2"] / pb
    )
    assert np.all(rel <= bound) and np.all(rel < 0.01), (rel, bound)
    # uncorrelated parts: u_a = w_b (a - b'), u_b = w_a (b' - a), rms in closed form
    d2 = SIGMA_OB**2 + case["sigma_b2_interp"] + case["eta2"]
    np.testing.assert_allclose(
        np.sqrt(np.mean(pca.uncorrelated_a**2, axis=0)), w_b * np.sqrt(d2), rtol=1e-6
    )
    np.testing.assert_allclose(
        np.sqrt(np.mean(pca.uncorrelated_b**2, axis=0)), w_a * np.sqrt(d2), rtol=1e-6
    )


def test_white_noise_is_attenuated_by_midpoint_interpolation():
    """Documented limit: broadband noise of the resampled sensor keeps (1-u)^2 + u^2."""
    rng = np.random.default_rng(8)
    n = 200_000
    t_b = np.arange(n + 1, dtype=np.int64) * H_NS
    t_a = t_b[:-1] + H_NS // 2  # u = 1/2
    noise = rng.normal(size=(n + 1, 1))
    res = resample_two_sensors(t_a, np.zeros((n, 1)), t_b, noise)
    # var of (x_k + x_k+1)/2: 1/2; standard error of the sample variance of this MA(1)
    # series sqrt(2 (1 + 2 rho^2) / n) * 1/2 with rho = 1/2; allow 5 of them
    se = 0.5 * np.sqrt(2 * 1.5 / n)
    assert abs(res.b.var() - 0.5) < 5 * se


def test_identical_tags_give_the_input_back():
    rng = np.random.default_rng(1)
    t = T0 + np.arange(500, dtype=np.int64) * H_NS
    a, b = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    res = resample_two_sensors(t, a, t, b)
    np.testing.assert_array_equal(res.a, a)
    np.testing.assert_array_equal(res.b, b)
    np.testing.assert_array_equal(res.times, t)
    np.testing.assert_array_equal(res.primary_index, np.arange(500))
    assert res.interpolated == (0, 0) and res.dropped == 0


def _ramp(t):
    """A linear field (nT) of the time: reproduced exactly by linear interpolation."""
    s = (t - T0) / 1e9
    return np.stack([0.5 * s + 1.0, -0.2 * s, np.full(s.shape, 7.0)], axis=1)


def test_gaps_are_not_bridged_and_are_counted():
    t_ob = T0 + np.arange(1000, dtype=np.int64) * H_NS
    t_ib = t_ob + H_NS // 2
    keep_ib = np.ones(1000, bool)
    keep_ib[100:105] = False  # IB gap 99.5 s -> 105.5 s (6 s > 2 samples)
    keep_ib[300] = False  # one missing vector: 2 s, bridged
    t_ib = t_ib[keep_ib]
    res = resample_two_sensors(t_ob, _ramp(t_ob), t_ib, _ramp(t_ib))
    # overlap [0.5 s, 999 s]: OB tags 1..999; inside the IB gap: OB 100..105
    assert res.base_size == 999
    assert res.dropped_in_gaps == (0, 6) and res.dropped == 6
    assert not np.any(np.isin(res.times, T0 + np.arange(100, 106) * H_NS))
    assert np.isin(T0 + np.array([300, 301]) * H_NS, res.times).all()  # bridged
    assert res.max_gap_ns == (2 * H_NS, 2 * H_NS)
    np.testing.assert_allclose(res.b, _ramp(res.times), rtol=0, atol=1e-12)
    # configurable: 6 samples bridge the gap; 1 sample leaves the single hole open too
    assert (
        resample_two_sensors(t_ob, _ramp(t_ob), t_ib, _ramp(t_ib), max_gap_samples=6).dropped == 0
    )
    assert (
        resample_two_sensors(t_ob, _ramp(t_ob), t_ib, _ramp(t_ib), max_gap_samples=1).dropped == 8
    )
    # an OB gap does not drop anything on the OB tags but does on a regular grid
    t_ob2 = np.delete(t_ob, np.arange(500, 510))  # 11 s gap: OB tags 499 -> 510
    t_ib2 = t_ob + H_NS // 2
    res2 = resample_two_sensors(t_ob2, _ramp(t_ob2), t_ib2, _ramp(t_ib2))
    assert res2.dropped == 0 and res2.times.size == 989
    grid = resample_two_sensors(t_ob2, _ramp(t_ob2), t_ib2, _ramp(t_ib2), step_ns=H_NS)
    # grid from the overlap start (0.5 s) every 1 s: 0.5 ... 998.5; OB gap 499-510 s
    # holds 499.5 ... 509.5 (11 times)
    assert grid.base_size == 999 and grid.dropped_in_gaps == (11, 0)
    assert np.all(grid.primary_index == -1)  # no grid time is an OB tag
    np.testing.assert_allclose(grid.a, _ramp(grid.times), rtol=0, atol=1e-12)
    np.testing.assert_allclose(grid.b, _ramp(grid.times), rtol=0, atol=1e-12)


def test_int64_times_keep_nanoseconds():
    # a ramp of 1 nT per ns, tags 37 ns after the targets at ~4.6e17 ns: float64
    # nanoseconds (spacing 64 ns there) cannot resolve that, int64 differences can
    t = T0 + np.arange(10, dtype=np.int64) * H_NS + 37
    targets = T0 + np.arange(1, 10, dtype=np.int64) * H_NS
    values = (t - T0).astype(float)
    out, valid, on = interpolate_linear(t, values, targets)
    assert valid.all() and not on.any()
    np.testing.assert_allclose(out, (targets - T0).astype(float), rtol=0, atol=1e-3)
    naive = np.interp(targets.astype(float), t.astype(float), values)
    assert np.max(np.abs(naive - (targets - T0))) > 10.0  # what the rule protects against


def test_common_time_base_and_errors():
    t_a = np.array([0, 10, 20, 30], dtype=np.int64)
    t_b = np.array([15, 25, 35], dtype=np.int64)
    np.testing.assert_array_equal(common_time_base(t_a, t_b), [20, 30])
    np.testing.assert_array_equal(common_time_base(t_a, t_b, step_ns=4), [15, 19, 23, 27])
    assert common_time_base(t_a, t_b + 100).size == 0
    with pytest.raises(InputFormatError, match="int64"):
        common_time_base(t_a.astype(float), t_b)
    with pytest.raises(InputFormatError, match="increase strictly"):
        resample_two_sensors([0, 10, 10], np.zeros((3, 3)), t_b, np.zeros((3, 3)))
    with pytest.raises(InputFormatError, match="step_ns"):
        common_time_base(t_a, t_b, step_ns=0)
    with pytest.raises(InputFormatError, match="components"):
        resample_two_sensors(t_a, np.zeros((4, 3)), t_b, np.zeros((3, 2)))
