"""Heater-bit series the V10 controller can produce, against closed forms (issue 11).

Each case builds 1-s heater bits from a declared schedule (duty cycle per 1000-s block, on
for the first ``d`` s of each 100-s period), damages the series as the telemetry does
(a LAC gap, a +-1-bit jitter, a bit that stays on) and compares the heater periods, the
duty-cycle changes, the relaxed offset (eq. 6a-6f) and the heater waveform with what the
schedule implies: the offset in closed form (one or two exponential relaxations), the
waveform from Tables 6-8 at the scheduled periods.  Tolerances are stated per test.
"""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fluxcal.calibration.heater_signal import heater_periods
from fluxcal.calibration.relaxation import duty_cycle_changes, relaxed_offset, steady_state_offset
from tests.calibration._heater_chain import CAL, D0, DT, K_FINE, QUIET, TAU, heater_chain
from tests.calibration._heater_chain import schedule_bits as _bits


def _pipeline(t, b, samples):
    return heater_chain(t, b, samples)[:4]


def _one_step(samples, t0, ppt):
    """Closed form of eq. 6f after a single change from quiet to ``ppt`` at ``t0``."""
    x = np.maximum(samples - t0 - DT, 0.0)
    return np.where(samples >= t0, 1.0, 0.0)[:, None] * (D0 * ppt) * (1 - np.exp(-x / TAU))[:, None]


def _scheduled_wave(samples, starts, duty_percent):
    """Tables 6-8 at the scheduled periods (bilinear, as sec. 6), written out here."""
    tab, bins = CAL.heater_signal, CAL.heater_duty_bins_percent
    k = np.searchsorted(starts, samples, side="right") - 1
    out = np.zeros((samples.size, 3))
    inside = (k >= 0) & (samples < starts[np.maximum(k, 0)] + 100.0)
    for i in np.flatnonzero(inside):
        c = samples[i] - starts[k[i]]
        j = min(int((duty_percent - bins[0]) // 4), bins.size - 2)
        fd = (duty_percent - bins[j]) / 4.0
        i0 = min(int(c), 99)
        ft = c - i0
        for a in range(3):
            lo = tab[a, i0, j] * (1 - fd) + tab[a, i0, j + 1] * fd
            hi = tab[a, i0 + 1, j] * (1 - fd) + tab[a, i0 + 1, j + 1] * fd
            out[i, a] = lo * (1 - ft) + hi * ft
    return out


def _nt(counts):
    return np.abs(counts) * K_FINE


# --- a LAC gap shorter than a period hides a rising edge --------------------------------
# before the fix: the 0 -> 1 step across the gap was an edge at the first record after the
# gap, 120 s after the previous edge: a fake "heater quiet" change, a change to a 20 % duty
# cycle and one back to 40 % (0.60 nT of offset, 0.53 nT of waveform for about an hour)
def _gap_case(gap_from, gap_to):
    t, b = _bits([40] * 108)  # 3 h at 40 %
    keep = (t < gap_from) | (t >= gap_to)
    samples = np.arange(0.0, t[-1], 0.5)
    return _pipeline(t[keep], b[keep], samples), samples


@pytest.mark.parametrize(("gap_from", "gap_to"), [
    # a 30-s gap from 10 s before an edge: the bit is on after it
    (QUIET + 100 * 20 - 10, QUIET + 100 * 20 + 20),
    # a 65-s gap from 5 s before an edge: the whole 40-s on-phase is missing, the first
    # record after the gap is off; the next edge, one period after the grid point,
    # shows the heater kept cycling
    (QUIET + 100 * 30 - 5, QUIET + 100 * 30 + 60),
], ids=["edge_with_the_bit_on_after_it", "whole_on_phase"])
def test_gap_hiding_an_edge(gap_from, gap_to):
    (p, ch, delta, wave), s = _gap_case(gap_from, gap_to)
    starts = QUIET + 100.0 * np.arange(108)
    np.testing.assert_array_equal(p.start, starts)
    np.testing.assert_allclose(p.duty_cycle, 0.40)
    np.testing.assert_array_equal(ch.time, [QUIET, starts[-1] + 100])
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [400, 0])
    in_heat = s < starts[-1] + 100
    # 1e-9 counts: the same exponential, evaluated the same way up to rounding
    np.testing.assert_allclose(delta[in_heat], _one_step(s, QUIET, 400)[in_heat], atol=1e-9)
    # waveform: the scheduled periods outside the gap (inside it no bit tells the phase,
    # but the grid does: same waveform), 1e-9 counts
    np.testing.assert_allclose(wave, _scheduled_wave(s, starts, 40.0), atol=1e-9)


# --- +-1 s jitter of the on-count in every third period ---------------------------------
# before: 72 spurious changes in 3 h, the five-change look-back shrank to ~500 s and the
# offset stayed 1.6/2.9/0.14 nT short of D0 * 400
def test_jitter_of_single_periods_is_no_change():
    on = [40] * 108
    for k in range(2, 108, 3):
        on[k] = 41 if (k // 3) % 2 else 39
    t, b = _bits(on)
    s = np.arange(0.0, t[-1], 1.0)
    p, ch, delta, _ = _pipeline(t, b, s)
    np.testing.assert_array_equal(ch.time, [QUIET, QUIET + 100 * 108])
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [400, 0])
    in_heat = s < QUIET + 100 * 108
    np.testing.assert_allclose(delta[in_heat], _one_step(s, QUIET, 400)[in_heat], atol=1e-9)


def test_jitter_does_not_hide_real_changes():
    # 40 % for 2000 s, 25 % for 1000 s, 36 % for 3000 s, each block with jitter in every
    # third period (also the first period of the 25 % block): changes at the block starts
    blocks = [40] * 20 + [25] * 10 + [36] * 30
    on = list(blocks)
    for k in range(0, 60, 3):
        on[k] += 1 if (k // 3) % 2 else -1
    t, b = _bits(on)
    p = heater_periods(t, b)
    ch = duty_cycle_changes(p, data_end=t[-1] + 1.0, data_start=t[0])
    np.testing.assert_array_equal(ch.time, [QUIET, QUIET + 2000, QUIET + 3000, QUIET + 6000])
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [400, 250, 360, 0])


# --- a bit that stays on (100 % duty cycle) ---------------------------------------------
# before: one period at the edge, then "heater quiet" 100 s later: the offset relaxed to 0
# instead of D0 * 1000 (8.4/15.3/0.7 nT after two hours)
def test_bit_that_stays_on_is_a_100_percent_duty_cycle():
    t, b = _bits([100] * 72 + [40] * 30)  # 2 h always on, then 40 %
    s = np.arange(0.0, t[-1], 1.0)
    p, ch, delta, wave = _pipeline(t, b, s)
    starts = QUIET + 100.0 * np.arange(102)
    np.testing.assert_array_equal(p.start, starts)
    np.testing.assert_allclose(p.duty_cycle, [1.0] * 72 + [0.4] * 30)
    # no off phase: no heater-cycle waveform; the 40 % periods get it
    np.testing.assert_array_equal(p.applied, [False] * 72 + [True] * 30)
    np.testing.assert_array_equal(ch.time, [QUIET, QUIET + 7200, QUIET + 10200])
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [1000, 400, 0])
    # closed form: D0 * 1000 relaxing from zero, then toward D0 * 400
    t2 = QUIET + 7200.0
    c1 = D0 * 1000 * (1 - math.exp(-(t2 - QUIET - DT) / TAU))
    want = _one_step(s, QUIET, 1000)
    after = s >= t2
    x = np.maximum(s[after] - t2 - DT, 0.0)[:, None]
    want[after] = D0 * 400 - (D0 * 400 - c1) * np.exp(-x / TAU)
    in_heat = s < QUIET + 10200
    np.testing.assert_allclose(delta[in_heat], want[in_heat], atol=1e-9)
    assert np.all(_nt(delta[s == t2 - 1][0] - D0 * 1000) < 0.01)  # steady after 2 h
    on_part = s < t2
    assert np.all(wave[on_part] == 0.0)


# --- the look-back spans 5000 s (sec. 7) ------------------------------------------------
def test_look_back_spans_5000_s():
    # eight changes within 2400 s (the heater going quiet and starting again): the
    # look-back reaches back to the first (all within 5000 s), i.e. the full recursion
    # from zero; with five changes only, the state would start from zero at the third
    change_t = np.array([0.0, 300.0, 600.0, 900.0, 1200.0, 1500.0, 1800.0, 2100.0, 2400.0])
    ppt = np.array([400, 0, 400, 0, 400, 0, 400, 0, 400], dtype=float)
    target = steady_state_offset(ppt, D0)
    ts = np.array([2400.0, 2500.0, 3000.0])
    got = relaxed_offset(ts, change_t, target, tau=TAU, delay=DT, look_back=5,
                         look_back_s=5000.0)
    state = np.zeros(3)
    for i in range(change_t.size - 1):  # eq. 6a-6e over every change, from zero
        e = math.exp(-max(change_t[i + 1] - change_t[i] - DT, 0.0) / TAU)
        state = target[i] - (target[i] - state) * e
    want = np.array([target[-1] - (target[-1] - state) * math.exp(-max(x - 2400 - DT, 0) / TAU)
                     for x in ts])
    np.testing.assert_allclose(got, want, rtol=1e-12)
    five = relaxed_offset(ts, change_t, target, tau=TAU, delay=DT, look_back=5)
    assert np.max(_nt(five - want)) > 0.1  # what the five-change look-back lost


# --- all of it at once: random schedules, jitter, short gaps ----------------------------
@settings(max_examples=40, deadline=None)
@given(
    blocks=st.lists(st.sampled_from([0, 12, 25, 36, 40, 44, 100]), min_size=2, max_size=8),
    jitter_seed=st.integers(0, 2**31 - 1),
    gaps=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(2, 99)), max_size=3),
)
def test_changes_follow_the_block_schedule(blocks, jitter_seed, gaps):
    # duty cycle per 1000-s block (0: heater quiet), +-1 s jitter in up to a third of the
    # periods (never two within three, never in a 100 % or a quiet block), LAC gaps of
    # 2-99 s:
    # the changes are the schedule's, at the block starts
    rng = np.random.default_rng(jitter_seed)
    on = []
    for d in blocks:
        on += [d] * 10
    jitter = rng.random(len(on)) < 0.33
    for k in range(len(on)):  # at most one period in three (a minority in any window)
        jitter[k] &= not jitter[max(k - 2, 0):k].any()
    for k in np.flatnonzero(jitter):
        if 0 < on[k] < 100:
            on[k] += 1 if rng.random() < 0.5 else -1
    t, b = _bits(on)
    keep = np.ones(t.size, dtype=bool)
    spans = []
    for where, length in gaps:
        g0 = int(QUIET + where * (len(on) * 100 - length))
        assume(all(abs(g0 - a) > 200 for a, _ in spans))  # gaps apart (a gap each)
        spans.append((g0, length))
        keep[g0:g0 + length] = False
        # undecidable, left out: a gap hiding the whole on-phase of the first period after
        # the heater was quiet (it may have started there or one period later) or of the
        # last one before it goes quiet (it may have stopped one period earlier)
        for i, d in enumerate(blocks):
            for first, k in ((True, 10 * i), (False, 10 * i + 9)):
                ps = QUIET + 100 * k
                quiet = blocks[i - 1] == 0 if first else i + 1 == len(blocks) or blocks[
                    i + 1] == 0
                if d and (quiet or (first and i == 0)):
                    assume(not (g0 <= ps and g0 + length >= ps + on[k]))
    # known limit, left out here and pinned by test_lone_start_then_hidden_on_phase: a gap
    # hiding the edge that starts a run after quiet (its periods then start at the first
    # on-bit, late by up to the gap) and a later gap hiding a whole on-phase
    starts = [QUIET + 100 * k for k, d in enumerate(on) if d and (k == 0 or not on[k - 1])]
    shifted = any(g0 <= ps < g0 + length for ps in starts for g0, length in spans)
    hidden = any(d and g0 <= QUIET + 100 * k and g0 + length >= QUIET + 100 * k + d
                 for k, d in enumerate(on) for g0, length in spans)
    assume(not (shifted and hidden))
    p = heater_periods(t[keep], b[keep])
    ch = duty_cycle_changes(p, data_end=t[-1] + 1.0, data_start=t[0])
    # expected from the schedule: a change at each block start where the duty cycle
    # changes (quiet: at the end of the last heater period, i.e. the block start too)
    want_t, want_d, prev = [], [], 0
    for i, d in enumerate(blocks):
        if d != prev:
            want_t.append(QUIET + 1000.0 * i)
            want_d.append(10 * d)
        prev = d
    if prev != 0:
        want_t.append(QUIET + 1000.0 * len(blocks))
        want_d.append(0)
    # exact, except after an edge a gap hid with no grid point to place it (the heater
    # starting in the gap and staying on to the end): the run starts at the first on-bit
    # after the gap and its periods (and its end) shift by less than the gap
    slack = np.zeros(len(want_t))
    for w in want_t:
        for g0, length in spans:
            if g0 <= w < g0 + length:
                slack[:] = np.maximum(slack, g0 + length - w)
    assert ch.time.size == len(want_t), (ch.time, want_t)
    assert np.all(np.abs(ch.time - want_t) <= slack), (ch.time, want_t)
    np.testing.assert_array_equal(ch.duty_cycle_ppt, want_d)


# --- a gap that cuts an on-run -----------------------------------------------------------
# Found by the hypothesis test above.  The on-run cut by the gap is unseen (bounds 0.91..1 in
# a 100 % block; 0.12..0.25 in the first 25 % period); before the fix the 100 % block was
# lost (about D0 * 880: ~7 nT) or the change landed one period late (100 s).  Expected from
# the schedule: each block holds ten periods (one 1000-s evaluation, sec. 7), so the change
# is at the block start, 1200 s.
@pytest.mark.parametrize("blocks, g0, length, want_t", [
    ([12, 100, 0, 0, 0], 1291, 10, [200.0, 1200.0, 2200.0]),
    ([12, 25, 0, 0, 0], 1212, 13, [200.0, 1200.0, 2200.0]),
])
def test_gap_cutting_an_on_run(blocks, g0, length, want_t):
    on = [d for d in blocks for _ in range(10)]
    t, b = _bits(on)
    keep = np.ones(t.size, dtype=bool)
    keep[g0:g0 + length] = False
    p = heater_periods(t[keep], b[keep])
    ch = duty_cycle_changes(p, data_end=t[-1] + 1.0, data_start=t[0])
    np.testing.assert_array_equal(ch.time, want_t)
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [10 * blocks[0], 10 * blocks[1], 0])


# --- known limit: a lone start, then a gap hiding a whole on-phase -----------------------
# The first gap hides the edge that starts the 100 % run after quiet: its periods start at
# the first on-bit (2 s late).  The second gap hides the fall of the run and the whole
# on-phase of the first 12 % period: its grid point (1202) misses the next seen edge (1300)
# by 2 s > tolerance, so no period is placed there and the change lands at 1300 (100 s late).
@pytest.mark.xfail(strict=True, reason="grid phase from a lone start is off by the gap")
def test_lone_start_then_hidden_on_phase():
    on = [d for d in [100, 12, 0, 0] for _ in range(10)]
    t, b = _bits(on)
    keep = np.ones(t.size, dtype=bool)
    keep[200:202] = False
    keep[1196:1212] = False
    p = heater_periods(t[keep], b[keep])
    ch = duty_cycle_changes(p, data_end=t[-1] + 1.0, data_start=t[0])
    # slack: the run start may be late by the first gap (2 s), the change by the second
    assert ch.time.size == 3
    assert np.all(np.abs(ch.time - [200.0, 1200.0, 2200.0]) <= [2.0, 12.0, 2.0])
