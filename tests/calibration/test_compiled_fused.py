"""Fused calibration kernels: the sec. 7 offset chain, the heater signal from a start time
and the largest offset step split at time gaps, against numpy and brute-force loops.

As in `test_compiled.py`, the kernels repeat the reference's floating-point operations in
the same order, so the comparisons are exact (``assert_array_equal``) unless a tolerance
is stated.
"""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.calibration.heater_signal import (
    HeaterPeriods,
    heater_signal,
    heater_signal_reference,
)
from fluxcal.calibration.offset_steps import largest_steps, largest_steps_reference
from fluxcal.calibration.offsets import breakpoint_temperature, two_segment_offset
from fluxcal.missions.messenger._compiled import offset_chain_kernel
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-01-01")
TAB = CAL.heater_signal
BINS = CAL.heater_duty_bins_percent


# ----------------------------------------------------------------------------------------
# sec. 7: the temperature interpolation of `offset_chain_kernel` is np.interp's
# ----------------------------------------------------------------------------------------
def _chain_temperature(et, xp, fp, margin=60.0):
    """Run the kernel (offsets only, no duty-cycle changes); interpolated T and flag."""
    n = et.size
    coef = np.ascontiguousarray(CAL.temperature_coefficients)
    temp = np.empty(n)
    offset = np.empty((n, 3))
    unused = np.empty((0, 3))
    zero = np.zeros((1, 3))
    outside = offset_chain_kernel(
        et, np.ones(n, dtype=bool), xp, fp, True, margin, -np.inf, 22.4, coef,
        breakpoint_temperature(coef), np.empty(0), zero, zero, 872.0, 10.0, unused,
        np.empty(0, np.int8), np.eye(3), unused, False, temp, offset, np.empty((n, 3)),
        unused, unused,
    )
    return temp, offset, outside


@pytest.mark.parametrize("seed", range(4))
def test_interpolation_equals_np_interp(seed):
    rng = np.random.default_rng(seed)
    xp = np.cumsum(rng.uniform(0.5, 30.0, 400))
    xp[50:53] = xp[50]  # repeated nodes (zero-width intervals)
    xp[53:] += 1.0
    fp = rng.uniform(-60.0, 40.0, xp.size)
    fp[10:12] = [np.inf, np.inf]  # an infinite piece: NaN retried from the other side
    fp[20] = np.nan
    fp[30:32] = [-np.inf, 5.0]
    x = np.concatenate([rng.uniform(xp[0] - 100.0, xp[-1] + 100.0, 20000), xp, xp + 1e-9,
                        [np.nan, np.inf, -np.inf, xp[0], xp[-1]]])
    for et in (np.sort(x), x):  # sorted (moving hint) and unsorted (bisection)
        temp, offset, _ = _chain_temperature(et, xp, fp)
        with np.errstate(invalid="ignore"):
            expect = np.interp(et, xp, fp)
        np.testing.assert_array_equal(temp, expect)
        # and the offset is the two-segment line of that temperature (no changes);
        # a NaN time is outside the model (not t >= -inf): fixed 22.4 C, as before V10
        expect[np.isnan(et)] = 22.4
        with np.errstate(invalid="ignore"):
            ct = two_segment_offset(expect, CAL.temperature_coefficients) + 0.0
        np.testing.assert_array_equal(offset, ct)


def test_interpolation_cover_flag_as_min_max():
    xp = np.array([100.0, 200.0, 300.0])
    fp = np.array([1.0, 2.0, 3.0])
    cases = {
        (40.0, 150.0, 360.0): False,  # exactly at the 60-s margins
        (39.0, 150.0): True,
        (150.0, 360.5): True,
        (np.nan, 10.0): False,  # et.min() is NaN: the reference does not reject
        (): False,
    }
    for et, expect in cases.items():
        assert _chain_temperature(np.array(et, dtype=float), xp, fp)[2] == expect, et


# ----------------------------------------------------------------------------------------
# sec. 6: heater signal from a start time
# ----------------------------------------------------------------------------------------
def _periods(rng, k):
    start = np.cumsum(rng.uniform(100.0, 200.0, k)) + 50.0
    end = np.minimum(start + 100.0, np.append(start[1:], np.inf))
    on = rng.uniform(0.0, 60.0, k)
    return HeaterPeriods(start=start, end=end, duty_cycle=rng.uniform(0.0, 0.6, k),
                         on_duration=on, applied=on >= 10.0)


@pytest.mark.parametrize("where", [0.0, 0.37, 0.5, 1.1])
def test_heater_signal_applies_from_matches_reference_and_masking(where):
    rng = np.random.default_rng(int(where * 100))
    p = _periods(rng, 50)
    t = np.sort(rng.uniform(p.start[0] - 300.0, p.end[-1] + 300.0, 20000))
    t0 = float(p.start[0] - 300.0 + where * (p.end[-1] - p.start[0] + 600.0))
    t = np.sort(np.concatenate([t, [t0, np.nextafter(t0, -np.inf)]]))
    t[::1000] = np.nan
    got = heater_signal(t, p, TAB, BINS, applies_from=t0)
    ref = heater_signal_reference(t, p, TAB, BINS, applies_from=t0)
    np.testing.assert_array_equal(got[1], ref[1])
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-12)  # as test_compiled.py
    # the same as the signal everywhere, masked afterwards (the former caller)
    sig, applied = heater_signal(t, p, TAB, BINS)
    applied &= t >= t0
    sig[~applied] = 0.0
    np.testing.assert_array_equal(got[1], applied)
    np.testing.assert_array_equal(got[0], sig)
    assert not got[1][~(t >= t0)].any()


def test_heater_signal_applies_from_none_and_minus_inf_are_no_limit():
    rng = np.random.default_rng(1)
    p = _periods(rng, 20)
    t = np.sort(rng.uniform(p.start[0] - 300.0, p.end[-1] + 300.0, 3000))
    base = heater_signal(t, p, TAB, BINS)
    for lim in (None, -np.inf):
        got = heater_signal(t, p, TAB, BINS, applies_from=lim)
        np.testing.assert_array_equal(got[0], base[0])
        np.testing.assert_array_equal(got[1], base[1])
    assert heater_signal(np.empty(0), p, TAB, BINS, applies_from=0.0)[0].shape == (0, 3)


# ----------------------------------------------------------------------------------------
# sec. 13: largest step split at time gaps
# ----------------------------------------------------------------------------------------
def _steps_equal(got, ref):
    np.testing.assert_array_equal(got.largest_step, ref.largest_step)
    np.testing.assert_array_equal(got.index, ref.index)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 2000])
@pytest.mark.parametrize("time_dtype", [np.float64, np.int64])
def test_largest_steps_with_gaps_matches_reference_and_segments(n, time_dtype):
    rng = np.random.default_rng(n)
    off = np.round(rng.normal(size=(n, 3)), 1)  # ties: the first maximum wins
    times = np.cumsum(np.where(rng.random(n) < 0.02, rng.integers(11, 100, n), 1))
    times = times.astype(time_dtype)
    seg = np.cumsum(rng.random(n) < 0.03)
    got = largest_steps(off, times=times, max_gap=10.0)
    _steps_equal(got, largest_steps_reference(off, times=times, max_gap=10.0))
    # = segments from diff/cumsum (the former offset_step_report)
    gap_seg = np.concatenate([[0], np.cumsum(np.diff(times) > 10.0)])[:n]
    _steps_equal(got, largest_steps_reference(off, gap_seg))
    both = largest_steps(off, seg, times=times, max_gap=10.0)
    _steps_equal(both, largest_steps_reference(off, seg, times=times, max_gap=10.0))
    if n > 1:
        _steps_equal(both, largest_steps_reference(off, seg * (n + 1) + gap_seg))


def test_largest_steps_against_a_loop():
    rng = np.random.default_rng(3)
    n = 500
    off = rng.normal(size=(n, 3))
    times = np.cumsum(rng.choice([0.05, 0.05, 0.05, 20.0], n))
    got = largest_steps(off, times=times, max_gap=10.0)
    for j in range(3):
        best, at = -1.0, 1
        for i in range(1, n):
            step = 0.0 if times[i] - times[i - 1] > 10.0 else abs(off[i, j] - off[i - 1, j])
            if step > best:
                best, at = step, i
        assert got.largest_step[j] == best and got.index[j] == at


def test_largest_steps_needs_times_and_max_gap_together():
    off = np.zeros((4, 3))
    with pytest.raises(ValueError, match="both or neither"):
        largest_steps(off, times=np.arange(4.0))
    with pytest.raises(ValueError, match="both or neither"):
        largest_steps(off, max_gap=1.0)
