"""The compiled calibration kernels against their numpy references and brute-force loops.

Every public function that runs a numba kernel (`fluxcal.calibration._compiled`) keeps its
former numpy body as ``*_reference``.  The kernels repeat the reference's floating-point
operations in the same order, so most comparisons below are exact (``assert_array_equal``);
only ``exp`` (libm in the kernel, numpy's own SIMD ``exp`` in the reference: one unit in
the last place apart at most) needs a tolerance, stated where used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fluxcal.calibration.gain_matrix import apply_per_range, apply_per_range_reference
from fluxcal.calibration.heater_signal import (
    HeaterPeriods,
    heater_signal,
    heater_signal_reference,
    heater_waveform,
)
from fluxcal.calibration.offset_steps import largest_steps, largest_steps_reference
from fluxcal.calibration.offsets import two_segment_offset, two_segment_offset_reference
from fluxcal.calibration.rate_latency import per_sample_lag, per_sample_lag_reference
from fluxcal.calibration.relaxation import relaxed_offset, relaxed_offset_reference
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-01-01")
TAB = CAL.heater_signal  # (3, 101, 8), Tables 6-8
BINS = CAL.heater_duty_bins_percent  # 12..40 %


# ----------------------------------------------------------------------------------------
# sec. 6 heater signal
# ----------------------------------------------------------------------------------------
def _periods(rng, k, *, spacing=(100.0, 250.0), length=None):
    """Random heater periods: gaps between them, some not applied, duty 0..60 %."""
    start = np.cumsum(rng.uniform(*spacing, k)) + 50.0
    nxt = np.append(start[1:], np.inf)
    end = np.minimum(start + (100.0 if length is None else length), nxt)
    duty = rng.uniform(0.0, 0.6, k)  # extrapolation zones below 12 % and above 40 %
    duty[::7] = BINS[rng.integers(0, BINS.size, duty[::7].size)] / 100.0  # bin centres
    on = rng.uniform(0.0, 60.0, k)
    return HeaterPeriods(start=start, end=end, duty_cycle=duty, on_duration=on,
                         applied=on >= 10.0)


def _assert_same_signal(got, ref):
    np.testing.assert_array_equal(got[1], ref[1])
    # same operations in the same order: bit-identical (observed); 1e-12 counts only
    # leaves room for a build that contracts a*b + c into one rounding (signals ~10 counts)
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_heater_signal_matches_reference_on_random_samples(seed):
    rng = np.random.default_rng(seed)
    p = _periods(rng, 60)
    # samples before the first period, in gaps, inside, after the last; sorted like a day
    t = np.sort(rng.uniform(p.start[0] - 300.0, p.end[-1] + 300.0, 20000))
    # edges: exactly at starts (cycle time 0), just before the ends, exactly at the ends
    t = np.sort(np.concatenate([t, p.start, np.minimum(p.end, 1e12) - 1e-9, p.end[:-1]]))
    _assert_same_signal(heater_signal(t, p, TAB, BINS), heater_signal_reference(t, p, TAB, BINS))


def test_heater_signal_unsorted_samples_match_reference():
    rng = np.random.default_rng(11)
    p = _periods(rng, 30)
    t = rng.uniform(p.start[0] - 200.0, p.end[-1] + 200.0, 5000)  # random order: bisection
    _assert_same_signal(heater_signal(t, p, TAB, BINS), heater_signal_reference(t, p, TAB, BINS))


def test_heater_kernel_equals_waveform_at_cycle_times_0_to_100_and_beyond():
    # periods longer than the table (end = start + 150) reach cycle times 100 (the last
    # table row, equal to t = 0) and beyond (clipped to 100), as `heater_waveform` does
    rng = np.random.default_rng(3)
    duty = np.array([0.0, 0.05, 0.10, 0.12, 0.14, 0.22, 0.40, 0.41, 0.55, 1.0])
    start = 1000.0 * np.arange(duty.size)
    p = HeaterPeriods(start=start, end=start + 150.0, duty_cycle=duty,
                      on_duration=np.full(duty.size, 40.0), applied=np.ones(duty.size, bool))
    cycle = np.concatenate([[0.0, 0.5, 1.0, 99.0, 99.999, 100.0, 100.5, 149.0],
                            rng.uniform(0.0, 150.0, 200)])
    t = (start[:, None] + cycle[None, :]).ravel()
    sig, applied = heater_signal(t, p, TAB, BINS)
    assert applied.all()
    seen = t - np.repeat(start, cycle.size)  # the cycle times after rounding of t
    expect = heater_waveform(seen, np.repeat(duty * 100.0, cycle.size), TAB, BINS)
    np.testing.assert_allclose(sig, expect, rtol=0, atol=1e-12)  # bit-identical observed
    # t = 100 equals t = 0 (periodic table), the clipped tail equals t = 100
    per = sig.reshape(duty.size, cycle.size, 3)
    np.testing.assert_allclose(per[:, 5], per[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(per[:, 6], per[:, 5])


def test_heater_kernel_against_a_literal_bilinear_loop():
    """Independent of `heater_waveform`: eq. of sec. 6 written per sample in Python."""
    rng = np.random.default_rng(8)
    p = _periods(rng, 12, spacing=(100.0, 100.0))
    t = np.sort(rng.uniform(p.start[0], p.end[-1], 400))
    sig, applied = heater_signal(t, p, TAB, BINS)
    width = BINS[1] - BINS[0]
    for s, ts in enumerate(t):
        k = int(np.searchsorted(p.start, ts, side="right")) - 1
        if k < 0 or ts >= p.end[k] or not p.applied[k]:
            assert not applied[s] and np.all(sig[s] == 0.0)
            continue
        cyc = min(max(ts - p.start[k], 0.0), 100.0)
        i = min(math.floor(cyc), 99)
        d = p.duty_cycle[k] * 100.0
        j = min(max(math.floor((d - BINS[0]) / width), 0), BINS.size - 2)
        fd = (d - BINS[j]) / width  # outside [0, 1]: linear extrapolation of the end bins
        at_i = TAB[:, i, j] + (TAB[:, i, j + 1] - TAB[:, i, j]) * fd
        at_i1 = TAB[:, i + 1, j] + (TAB[:, i + 1, j + 1] - TAB[:, i + 1, j]) * fd
        expect = at_i + (at_i1 - at_i) * (cyc - i)
        # a different but equivalent formula: rounding only (signals ~10 counts)
        np.testing.assert_allclose(sig[s], expect, rtol=0, atol=1e-10)


def test_heater_signal_empty_inputs():
    p = _periods(np.random.default_rng(0), 5)
    sig, applied = heater_signal(np.empty(0), p, TAB, BINS)
    assert sig.shape == (0, 3) and applied.shape == (0,)
    none = HeaterPeriods(*(np.empty(0) for _ in range(4)), applied=np.empty(0, bool))
    t = np.linspace(0.0, 1000.0, 50)
    _assert_same_signal(heater_signal(t, none, TAB, BINS),
                        heater_signal_reference(t, none, TAB, BINS))


def test_heater_signal_nan_samples_are_outside_every_period():
    p = _periods(np.random.default_rng(1), 5)
    t = np.array([np.nan, p.start[0] + 1.0, np.nan])
    _assert_same_signal(heater_signal(t, p, TAB, BINS), heater_signal_reference(t, p, TAB, BINS))


def test_heater_signal_non_finite_duty_defers_to_the_reference():
    # the reference clips floor(NaN) (cast to the smallest int64) to bin 0: NaN signal
    p = _periods(np.random.default_rng(2), 3)
    p = HeaterPeriods(p.start, p.end, np.array([0.3, np.nan, 0.3]), p.on_duration,
                      np.ones(3, bool))
    t = np.concatenate([p.start + 5.0, p.start + 50.0])
    with np.errstate(invalid="ignore"):
        got = heater_signal(t, p, TAB, BINS)
        ref = heater_signal_reference(t, p, TAB, BINS)
    _assert_same_signal(got, ref)  # NaN where the reference has NaN
    assert np.isnan(got[0][[1, 4]]).all()


# ----------------------------------------------------------------------------------------
# sec. 7 offsets
# ----------------------------------------------------------------------------------------
def _changes(rng, m, *, minus_inf=False):
    t = np.cumsum(rng.uniform(5.0, 3000.0, m))
    if minus_inf:
        t[0] = -np.inf
    target = rng.uniform(-200.0, 200.0, (m, 3))
    target[rng.random(m) < 0.2] = 0.0  # duty cycles below 100 ppt
    return t, target


@pytest.mark.parametrize(("m", "minus_inf"), [(1, False), (2, True), (7, False), (40, True)])
def test_relaxed_offset_matches_reference(m, minus_inf):
    rng = np.random.default_rng(m)
    ct, target = _changes(rng, m, minus_inf=minus_inf)
    finite = ct[np.isfinite(ct)]
    lo = finite[0] - 500.0 if finite.size else 0.0
    hi = finite[-1] + 5000.0 if finite.size else 1000.0
    ts = np.concatenate([np.sort(rng.uniform(lo, hi, 20000)), finite, finite + 10.0,
                         rng.uniform(lo, hi, 500)])  # change times, delay ends, unsorted
    got = relaxed_offset(ts, ct, target, tau=872.0, delay=10.0)
    ref = relaxed_offset_reference(ts, ct, target, tau=872.0, delay=10.0)
    # exp: libm (kernel) vs numpy's SIMD exp, <= 1 ulp apart; offsets are <= ~200 counts,
    # so 1e-12 counts is ~100x that rounding
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[ts < (finite[0] if not minus_inf else -np.inf)], 0.0)


def test_relaxed_offset_edges():
    ct = np.array([0.0, 1000.0])
    target = np.array([[50.0, -20.0, 3.0], [10.0, 0.0, 0.0]])
    ts = np.array([-1.0, 0.0, 5.0, 10.0, 1000.0, np.nan, np.inf])
    got = relaxed_offset(ts, ct, target, tau=872.0, delay=10.0)
    ref = relaxed_offset_reference(ts, ct, target, tau=872.0, delay=10.0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)  # exp, as above
    np.testing.assert_array_equal(got[0], 0.0)  # before the first change
    np.testing.assert_array_equal(got[1:4], 0.0)  # within the 10 s heater delay: no change
    assert np.isnan(got[5]).all()  # NaN time, as the reference
    np.testing.assert_allclose(got[6], target[1], rtol=0, atol=1e-12)  # fully relaxed
    assert relaxed_offset(np.empty(0), ct, target, tau=872.0, delay=10.0).shape == (0, 3)
    np.testing.assert_array_equal(
        relaxed_offset(ts, np.empty(0), np.empty((0, 3)), tau=872.0, delay=10.0), 0.0)
    with pytest.raises(ValueError, match="increasing"):
        relaxed_offset(ts, ct[::-1], target, tau=872.0, delay=10.0)


def test_two_segment_offset_matches_reference():
    rng = np.random.default_rng(4)
    coef = CAL.temperature_coefficients
    tm = (coef[:, 0] - coef[:, 2]) / (coef[:, 3] - coef[:, 1])
    t = np.concatenate([rng.uniform(-80.0, 80.0, 10000), tm, np.nextafter(tm, np.inf),
                        [np.nan, np.inf, -np.inf, 0.0, -0.0]])
    got = two_segment_offset(t, coef)
    ref = two_segment_offset_reference(t, coef)
    np.testing.assert_array_equal(got, ref)  # same two operations per element: exact
    assert two_segment_offset(np.empty(0), coef).shape == (0, 3)


# ----------------------------------------------------------------------------------------
# sec. 5 lag, sec. 8 counts -> nT, sec. 13 steps
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("dtype", [np.int8, np.int64, np.uint8])
def test_per_sample_lag_matches_reference(dtype):
    rate = np.random.default_rng(5).integers(0, CAL.net_lag_s.size, 5000).astype(dtype)
    np.testing.assert_array_equal(per_sample_lag(rate, CAL.net_lag_s),
                                  per_sample_lag_reference(rate, CAL.net_lag_s))
    assert per_sample_lag(np.empty(0, dtype), CAL.net_lag_s).shape == (0,)
    bad = rate.copy()
    bad[17] = CAL.net_lag_s.size
    with pytest.raises(ValueError, match="rate_setting"):
        per_sample_lag(bad, CAL.net_lag_s)
    if np.issubdtype(dtype, np.signedinteger):
        bad[17] = -1
        with pytest.raises(ValueError, match="rate_setting"):
            per_sample_lag(bad, CAL.net_lag_s)


@pytest.mark.parametrize("dtype", [np.int8, np.int64])
def test_apply_per_range_matches_reference(dtype):
    rng = np.random.default_rng(6)
    v = rng.uniform(-40000.0, 40000.0, (10000, 3))
    v[:5] = [[np.inf, 1.0, 2.0], [1.0, np.inf, 2.0], [1.0, 2.0, -np.inf], [np.nan, 0, 0],
             [-0.0, -0.0, -0.0]]  # 0 * inf of the zero upper triangle must not appear
    flags = rng.integers(0, 2, v.shape[0]).astype(dtype)
    got = apply_per_range(v, flags, CAL.matrices)
    np.testing.assert_array_equal(got, apply_per_range_reference(v, flags, CAL.matrices))
    # also a full matrix set (no zero terms) with three ranges
    full = rng.normal(size=(3, 3, 3))
    flags3 = rng.integers(0, 3, v.shape[0]).astype(dtype)
    np.testing.assert_array_equal(apply_per_range(v[5:], flags3[5:], full),
                                  apply_per_range_reference(v[5:], flags3[5:], full))
    assert apply_per_range(np.empty((0, 3)), np.empty(0, dtype), CAL.matrices).shape == (0, 3)
    flags[123] = 2
    with pytest.raises(ValueError, match="range_flag"):
        apply_per_range(v, flags, CAL.matrices)


def _steps_equal(got, ref):
    np.testing.assert_array_equal(got.largest_step, ref.largest_step)  # exact: same ops
    np.testing.assert_array_equal(got.index, ref.index)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 1000])
def test_largest_steps_matches_reference(n):
    rng = np.random.default_rng(n)
    off = np.round(rng.normal(size=(n, 3)), 1)  # rounded: ties, the first must win
    seg = np.cumsum(rng.random(n) < 0.05)
    _steps_equal(largest_steps(off, seg), largest_steps_reference(off, seg))
    _steps_equal(largest_steps(off), largest_steps_reference(off))


@pytest.mark.filterwarnings("ignore:invalid value encountered in subtract")
def test_largest_steps_nan_and_flat():
    off = np.zeros((8, 3))
    off[3, 0] = np.nan  # first NaN step wins, as np.argmax
    off[5:, 1] = 4.0
    off[6:, 2] = np.inf
    seg = np.array([0, 0, 0, 0, 0, 1, 1, 1])  # the y step is across segments: ignored
    _steps_equal(largest_steps(off, seg), largest_steps_reference(off, seg))
    _steps_equal(largest_steps(off), largest_steps_reference(off))
    _steps_equal(largest_steps(np.zeros((5, 3))), largest_steps_reference(np.zeros((5, 3))))
