import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration.heater_signal import heater_periods
from fluxcal.calibration.relaxation import duty_cycle_changes, relaxed_offset, steady_state_offset

TAU, DT = 872.0, 10.0


def brute_force(ts, change_t, cstar, tau=TAU, dt=DT):
    """Eq. 6a-6f written out literally for one sample and one axis (the seed's loop)."""
    prior = [i for i in range(len(change_t)) if change_t[i] <= ts]
    if not prior:
        return 0.0
    i0 = prior[-1]
    # t_0..t_5 and c*_0..c*_5; changes before the data are zero-valued at -infinity
    t = [change_t[i0 - k] if i0 - k >= 0 else -math.inf for k in range(6)]
    c = [cstar[i0 - k] if i0 - k >= 0 else 0.0 for k in range(6)]

    def e(a, b):
        if b == -math.inf:
            return 0.0
        return math.exp(-max(a - b - dt, 0.0) / tau)

    ct4 = c[5] * (1 - e(t[4], t[5]))
    ct3 = c[4] - (c[4] - ct4) * e(t[3], t[4])
    ct2 = c[3] - (c[3] - ct3) * e(t[2], t[3])
    ct1 = c[2] - (c[2] - ct2) * e(t[1], t[2])
    ct0 = c[1] - (c[1] - ct1) * e(t[0], t[1])
    return c[0] - (c[0] - ct0) * e(ts, t[0])


def _changes(n: int, last_sample_s: float) -> dict:
    """Hypothesis strategies: up to ``n`` changes 5..3000 s apart to values of -200..200,
    1..30 samples from -100 s to ``last_sample_s``."""
    return {"gaps": st.lists(st.floats(5.0, 3000.0), min_size=0, max_size=n - 1),
            "values": st.lists(st.floats(-200, 200), min_size=n, max_size=n),
            "samples": st.lists(st.floats(-100.0, last_sample_s), min_size=1, max_size=30)}


@settings(max_examples=60, deadline=None)
@given(**_changes(12, 40000.0))
def test_vectorized_equals_brute_force(gaps, values, samples):
    _check_against(brute_force, gaps, values, samples)


def _check_against(brute, gaps, values, samples, **kwargs):
    """`relaxed_offset` (with ``kwargs``) of changes ``gaps`` s apart to ``values`` equals
    ``brute`` at every sample, to 1e-12 relative (1e-9 absolute near zero)."""
    change_t = np.cumsum(np.array([0.0] + gaps))
    cstar = np.array(values[: change_t.size])
    got = relaxed_offset(np.array(samples), change_t, cstar[:, None], tau=TAU, delay=DT,
                         **kwargs)[:, 0]
    want = [brute(s, change_t, cstar) for s in samples]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


def test_single_step_closed_form():
    # one change to c* at t=0: c(t) = c* (1 - exp(-(t - dt)/tau)) after the delay
    ts = np.array([-5.0, 0.0, 10.0, 100.0, 1000.0])
    got = relaxed_offset(ts, np.array([0.0]), np.array([[50.0]]), tau=TAU, delay=DT)[:, 0]
    want = 50 * (1 - np.exp(-np.maximum(ts - DT, 0) / TAU))
    want[0] = 0.0
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_eq5_threshold():
    s = steady_state_offset(np.array([0, 99, 100, 400]), np.array([0.17885, 0.32851, 0.01477]))
    np.testing.assert_allclose(s[:, 1], [0, 0, 32.851, 131.404])


def test_changes_from_periods():
    # 40 % for ten periods, 25 % for ten (the V10 controller holds a duty cycle for one
    # 1000-s evaluation interval at least), then quiet, then 30 % again
    bits = [0] * 10 + ([1] * 40 + [0] * 60) * 10 + ([1] * 25 + [0] * 75) * 10 + [0] * 500
    bits += ([1] * 30 + [0] * 70) * 10 + [0] * 200
    t = np.arange(len(bits), dtype=float)
    p = heater_periods(t, np.array(bits))
    ch = duty_cycle_changes(p, data_end=t[-1] + 1)
    np.testing.assert_array_equal(ch.time, [10, 1010, 2010, 2510, 3510])
    np.testing.assert_array_equal(ch.duty_cycle_ppt, [400, 250, 0, 300, 0])


def test_stream_starting_inside_heater_operation():
    # 40 % from the first bit on (no quiet period seen before the first edge): the duty
    # cycle before the data is unknown and taken as steady (change at -inf), so the
    # offset is D0 d at once instead of relaxing from zero; then 25 % for one 1000-s
    # evaluation interval
    bits = ([1] * 40 + [0] * 60) * 5 + ([1] * 25 + [0] * 75) * 10 + [0] * 300
    bits = bits[5:]  # the series starts 5 s into an on-phase: first edge at 95 s
    t = np.arange(len(bits), dtype=float)
    p = heater_periods(t, np.array(bits))
    ch = duty_cycle_changes(p, data_end=t[-1] + 1, data_start=t[0])
    assert ch.time[0] == -np.inf and ch.duty_cycle_ppt[0] == 400
    np.testing.assert_array_equal(ch.time[1:], [495, 1495])
    np.testing.assert_array_equal(ch.duty_cycle_ppt[1:], [250, 0])
    d0 = np.array([0.32851])
    target = steady_state_offset(ch.duty_cycle_ppt, d0)
    ts = np.array([0.0, 300.0, 500.0, 600.0, 1550.0])
    got = relaxed_offset(ts, ch.time, target, tau=TAU, delay=DT)[:, 0]
    # closed form: steady 400 * D0 until 495 + dt, then toward 250 * D0, then toward 0
    c400, c250 = 400 * d0[0], 250 * d0[0]
    at1495 = c250 - (c250 - c400) * math.exp(-(1495 - 495 - DT) / TAU)
    want = [c400, c400, c400, c250 - (c250 - c400) * math.exp(-(600 - 495 - DT) / TAU),
            at1495 * math.exp(-(1550 - 1495 - DT) / TAU)]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # the brute-force 6a-6f agrees with the change at -inf
    brute = [brute_force(s, list(ch.time), list(target[:, 0])) for s in ts]
    np.testing.assert_allclose(got, brute, rtol=1e-12)


def test_quiet_start_is_seen():
    # more than one heater period of zeros before the first edge: quiet before, relax
    # from zero as before
    bits = [0] * 102 + [1] * 40 + [0] * 60 + [0] * 300
    t = np.arange(len(bits), dtype=float)
    ch = duty_cycle_changes(heater_periods(t, np.array(bits)), data_end=t[-1] + 1,
                            data_start=t[0])
    np.testing.assert_array_equal(ch.time, [102, 202])


def brute_force_span(ts, change_t, cstar, span=5000.0, tau=TAU, dt=DT):
    """Eq. 6a-6f with a look-back of at least five changes and at least ``span`` s.

    Written as a plain recursion: the state is zero at ``t_D``, the deepest of the fifth
    change back and the last change at least ``span`` before ``t_0`` (the first change
    if there is none that old), then relaxes change by change.
    """
    prior = [i for i in range(len(change_t)) if change_t[i] <= ts]
    if not prior:
        return 0.0
    i0 = prior[-1]
    old = [i for i in range(i0 + 1) if change_t[i] <= change_t[i0] - span]
    first = max(min(i0 - 5, old[-1] if old else -1), 0)
    state = 0.0  # zero at t_D (or before the first change)
    for i in range(first, i0):  # eq. 6a-6e: relax from change i to change i + 1
        e = math.exp(-max(change_t[i + 1] - change_t[i] - dt, 0.0) / tau)
        state = cstar[i] - (cstar[i] - state) * e
    return cstar[i0] - (cstar[i0] - state) * math.exp(-max(ts - change_t[i0] - dt, 0.0) / tau)


@settings(max_examples=60, deadline=None)
@given(**_changes(15, 60000.0))
def test_look_back_span_equals_brute_force(gaps, values, samples):
    _check_against(brute_force_span, gaps, values, samples, look_back_s=5000.0)
