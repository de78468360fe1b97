import numpy as np
import pytest

from fluxcal.calibration.heater_signal import heater_periods, heater_signal, heater_waveform
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-01-01")
BINS = CAL.heater_duty_bins_percent
TAB = CAL.heater_signal


@pytest.mark.parametrize("col", range(8))
@pytest.mark.parametrize("t", [0, 1, 17, 50, 99])
def test_bin_centres_reproduce_table(col, t):
    got = heater_waveform(np.array([float(t)]), np.array([BINS[col]]), TAB, BINS)
    np.testing.assert_allclose(got[0], TAB[:, t, col], rtol=0, atol=1e-12)


def test_midpoints_are_averages():
    # half-way in t and in duty cycle: mean of the 4 surrounding table values
    got = heater_waveform(np.array([10.5]), np.array([22.0]), TAB, BINS)[0]
    expect = TAB[:, 10:12, 2:4].mean(axis=(1, 2))
    np.testing.assert_allclose(got, expect, atol=1e-12)


@pytest.mark.parametrize("duty", [0.0, 5.0, 10.0])
def test_extrapolation_below_12(duty):
    t = 30
    slope = (TAB[:, t, 1] - TAB[:, t, 0]) / 4.0
    expect = TAB[:, t, 0] + slope * (duty - 12.0)
    got = heater_waveform(np.array([float(t)]), np.array([duty]), TAB, BINS)[0]
    np.testing.assert_allclose(got, expect, atol=1e-12)


@pytest.mark.parametrize("duty", [41.0, 45.0, 60.0])
def test_extrapolation_above_40(duty):
    t = 12
    slope = (TAB[:, t, 7] - TAB[:, t, 6]) / 4.0
    expect = TAB[:, t, 7] + slope * (duty - 40.0)
    got = heater_waveform(np.array([float(t)]), np.array([duty]), TAB, BINS)[0]
    np.testing.assert_allclose(got, expect, atol=1e-12)


def test_t100_equals_t0():
    a = heater_waveform(np.array([0.0, 100.0]), np.array([23.0, 23.0]), TAB, BINS)
    np.testing.assert_allclose(a[0], a[1])


def _bits(pattern):
    """pattern: list of (on_seconds, period_seconds) repeated periods."""
    out = [0] * 50
    for on, per in pattern:
        out += [1] * on + [0] * (per - on)
    out += [0] * 300
    return np.arange(len(out), dtype=float), np.array(out)


def test_periods_duty_and_persistence():
    # persistence=1: every bit change taken as it comes; the 5-s on-run is a period whose
    # signal is not applied (on < 10 s)
    t, b = _bits([(40, 100), (40, 100), (25, 100), (5, 100)])
    p = heater_periods(t, b, persistence=1)
    np.testing.assert_array_equal(p.start, [50, 150, 250, 350])
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.40, 0.25, 0.05])
    np.testing.assert_allclose(p.on_duration, [40, 40, 25, 5])
    np.testing.assert_array_equal(p.applied, [True, True, True, False])
    np.testing.assert_array_equal(p.end, [150, 250, 350, 450])
    # the default 10-count persistence (sec. 6): the spacecraft ignored the 5-s request,
    # no heater period there (duty cycle 0 % rather than 5 %)
    q = heater_periods(t, b)
    np.testing.assert_array_equal(q.start, [50, 150, 250])
    np.testing.assert_allclose(q.duty_cycle, [0.40, 0.40, 0.25])


def test_signal_only_in_applied_periods():
    t, b = _bits([(30, 100), (5, 100)])
    p = heater_periods(t, b)
    ts = np.array([10.0, 50.0, 80.5, 160.0, 300.0])
    sig, applied = heater_signal(ts, p, TAB, BINS)
    np.testing.assert_array_equal(applied, [False, True, True, False, False])
    assert np.all(sig[~applied] == 0)
    expect = heater_waveform(np.array([30.5]), np.array([30.0]), TAB, BINS)[0]
    np.testing.assert_allclose(sig[2], expect)


def test_stream_ending_inside_the_on_phase():
    # 40 % periods; the series ends 15 s into the third period's on-phase: that period
    # keeps the 40 % (and the >= 10 s persistence) of the contiguous period before it
    t, b = _bits([(40, 100), (40, 100)])
    b = np.concatenate([b[:250], np.ones(15, dtype=b.dtype)])
    t = np.arange(b.size, dtype=float)
    p = heater_periods(t, b)
    np.testing.assert_array_equal(p.start, [50, 150, 250])
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.40, 0.40])
    np.testing.assert_array_equal(p.applied, [True, True, True])


def test_stream_ending_after_the_on_phase_is_complete():
    # the cut period's bit went off at 25 s before the end: its duty cycle is known (25 %)
    t, b = _bits([(40, 100), (40, 100)])
    b = np.concatenate([b[:250], np.ones(25, dtype=b.dtype), np.zeros(10, dtype=b.dtype)])
    t = np.arange(b.size, dtype=float)
    p = heater_periods(t, b)
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.40, 0.25])


def test_unfinished_period_without_predecessor_keeps_what_was_seen():
    b = np.array([0] * 20 + [1] * 5)
    p = heater_periods(np.arange(b.size, dtype=float), b)
    np.testing.assert_allclose(p.duty_cycle, [0.05])
    np.testing.assert_array_equal(p.applied, [False])


def test_short_gap_inside_the_on_phase():
    # 40 % periods; 20 bits missing (a gap < one period) inside the third on-phase:
    # 20 bits seen on, up to 40 possible -> keeps the previous 40 %
    t, b = _bits([(40, 100)] * 4)
    keep = (t < 260) | (t >= 280)
    p = heater_periods(t[keep], b[keep])
    np.testing.assert_array_equal(p.start, [50, 150, 250, 350])
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.40, 0.40, 0.40])
    np.testing.assert_array_equal(p.applied, [True] * 4)


def test_gap_after_the_fall_keeps_the_seen_duty_cycle():
    # the bit was seen going off at 25 s, the gap is in the off-phase: 25 % is known
    t, b = _bits([(40, 100), (40, 100), (25, 100), (25, 100)])
    keep = (t < 290) | (t >= 320)
    p = heater_periods(t[keep], b[keep])
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.40, 0.25, 0.25])


def test_gap_duty_outside_the_bounds_is_not_inherited():
    # 10 bits missing in a 25 % on-phase following a 40 % period: seen 15, at most 25
    # (< 40): the previous duty cycle is impossible, the seen lower bound stays
    t, b = _bits([(40, 100), (25, 100)])
    keep = (t < 165) | (t >= 175)
    p = heater_periods(t[keep], b[keep])
    np.testing.assert_allclose(p.duty_cycle, [0.40, 0.15])


@pytest.mark.parametrize("rate_error", [-1e-5, -5e-8, 0.0, 5e-8, 1e-5])
@pytest.mark.parametrize("on_bits, applied", [(9, False), (10, True), (11, True)])
def test_persistence_counts_bits_whatever_the_clock_rate(rate_error, on_bits, applied):
    # sec. 6: the signal is applied when the bit persisted for at least 10 s (ten 1-s bits).
    # Bit times in ET from a clock running fast or slow by `rate_error`: the on-time is
    # on_bits * (1 + rate_error) s, so ten bits may last 9.9999995 s and still count.
    n_periods = 5
    b = np.tile(np.r_[np.ones(on_bits), np.zeros(100 - on_bits)], n_periods).astype(np.int8)
    t = 1000.0 + np.arange(b.size) * (1.0 + rate_error)
    p = heater_periods(np.r_[t[0] - (1.0 + rate_error), t], np.r_[0, b], persistence=1)
    assert p.start.size == n_periods
    assert (p.applied == applied).all()
    # the 10-count persistence of the bit itself counts records too: 9 bits are no
    # heater change at all, 10 and 11 are, whatever the clock rate
    q = heater_periods(np.r_[t[0] - (1.0 + rate_error), t], np.r_[0, b])
    assert q.start.size == (n_periods if applied else 0)
    assert q.applied.all()
