"""Method 2, stage 1 (seed 003 sec. 4.12.2): heater states and labelled intervals.

Forward model written here: each heater is a PWM switch (its own period, duty cycle
and phase, so it may start on); at the disturbed sensor (ROMAP-like) it adds a fixed
field of 1000-2000 nT in any direction; at RPC-MAG it adds its own 0.3-1.5 nT field.
"""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fluxcal.cleaning.heater_states import intervals_from_states, states_from_steps
from fluxcal.cleaning.steps import remove_labelled_offsets
from fluxcal.errors import InputFormatError
from tests.cleaning._synthetic import red_noise, rotating_field

FS = 10.0


def _schedule(t, periods, duties, phases):
    return np.stack(
        [((t + ph) % p) >= p * (1 - d) for p, d, ph in zip(periods, duties, phases, strict=True)],
        axis=1,
    )


def test_intervals_closed_form():
    t = np.array([0, 10, 20, 30, 40, 50, 60])
    states = [[0, 0], [1, 0], [1, 0], [1, 1], [0, 1], [0, 0], [0, 1]]
    got = intervals_from_states(t, states, ["A", "B"])
    assert got == [(10, 30, "A"), (30, 40, "A+B"), (40, 50, "B"), (60, 70, "B")]
    assert intervals_from_states(t, states, ["A", "B"], stop=65)[-1] == (60, 65, "B")
    with pytest.raises(InputFormatError, match="names"):
        intervals_from_states(t, states, ["A"])
    with pytest.raises(InputFormatError, match="increasing"):
        intervals_from_states(t[::-1], states)
    with pytest.raises(InputFormatError, match="stop"):
        intervals_from_states([5.0], [[1, 0]])  # one sample: its end must be given


@settings(max_examples=40, deadline=None)
@given(states=st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=2, max_size=60))
def test_intervals_label_every_sample(states):
    # law, checked sample by sample: the interval containing t_i carries exactly the
    # heaters on at i, and samples with no heater on are in no interval
    s = np.array(states)
    t = np.arange(s.shape[0]) * 0.5 + 100.0
    got = intervals_from_states(t, s, ["A", "B", "C"])
    for i, ti in enumerate(t):
        inside = [lab for a, b, lab in got if a <= ti < b]
        want = "+".join(n for n, on in zip("ABC", s[i], strict=True) if on)
        assert inside == ([want] if want else [])


@settings(max_examples=25, deadline=None)
@given(
    raw=st.lists(st.floats(-1.0, 1.0), min_size=9, max_size=9),
    strengths=st.lists(st.floats(1000.0, 2000.0), min_size=3, max_size=3),
    duties=st.lists(st.sampled_from([0.2, 0.4, 0.6, 0.8]), min_size=3, max_size=3),
    phases=st.lists(st.floats(0.0, 60.0), min_size=3, max_size=3),
    seed=st.integers(0, 2**31),
)
def test_states_recovered_for_any_signatures(raw, strengths, duties, phases, seed):
    v = np.array(raw).reshape(3, 3)
    assume(np.all(np.linalg.norm(v, axis=1) > 0.1))
    sig = v / np.linalg.norm(v, axis=1)[:, None] * np.array(strengths)[:, None]
    # decomposable: distinct switch patterns give distinct jumps (>> the 0.1 nT noise),
    # and every switch is larger than the detection threshold (half the smallest)
    pats = np.array(np.meshgrid(*[[-1, 0, 1]] * 3)).reshape(3, -1).T
    model = pats @ sig
    dist = np.linalg.norm(model[:, None] - model[None], axis=2) + 1e9 * np.eye(len(pats))
    assume(dist.min() > 50.0)
    smallest = np.min(np.linalg.norm(model[np.any(pats != 0, axis=1)], axis=1))
    assume(smallest > 0.5 * min(strengths) + 20.0)  # threshold + 200x the noise
    rng = np.random.default_rng(seed)
    t = np.arange(int(1800 * FS)) / FS
    truth = _schedule(t, [30.0, 47.0, 61.0], duties, phases)
    romap = 30 * rotating_field(t) / 20 + rng.normal(0, 0.1, (t.size, 3)) + truth @ sig
    res = states_from_steps(romap, {"A": sig[0], "B": sig[1], "C": sig[2]})
    np.testing.assert_array_equal(res.states, truth)
    assert res.undetermined == []


def test_never_switched_heater_is_reported():
    t = np.arange(6000) / FS
    sig = {"A": [1500.0, 0, 0], "B": [0, -1200.0, 300.0]}
    truth = _schedule(t, [30.0], [0.5], [0.0])
    romap = np.zeros((t.size, 3)) + truth[:, :1] * np.array(sig["A"])
    res = states_from_steps(romap, sig)
    assert res.undetermined == ["B"] and not res.states[:, 1].any()
    np.testing.assert_array_equal(res.states[:, 0], truth[:, 0])
    with pytest.raises(InputFormatError, match="combination"):
        states_from_steps(romap + (t > 100)[:, None] * [0, 0, 900.0], sig)


def test_two_stages_remove_the_heaters():
    # stage 1 on ROMAP-like data, stage 2 on RPC-MAG data sampled at the same times
    rng = np.random.default_rng(3)
    t = np.arange(int(3600 * FS)) / FS
    # each label needs intervals with undisturbed samples on both sides (stage 2 estimate)
    truth = _schedule(t, [60.0, 97.0], [0.3, 0.2], [5.0, 20.0])
    romap_sig = np.array([[900.0, -1300.0, 400.0], [-600.0, -200.0, 1700.0]])
    romap = 40 * rotating_field(t) / 20 + rng.normal(0, 0.1, (t.size, 3)) + truth @ romap_sig
    mag_sig = np.array([[0.5, -0.3, 0.6], [-0.2, 0.9, 0.4]])  # at RPC-MAG (nT)
    # quiet background (1e-4 nT^2/Hz at 1 Hz): its wander over a 12-19 s interval is
    # ~0.1 nT, so a label's median over ~30-60 intervals is good to ~0.03 nT
    bg = rotating_field(t, period=3600.0) + red_noise(t.size, FS, 1e-4, rng, floor=1e-5)
    mag = bg + truth @ mag_sig
    states = states_from_steps(romap, {"A": romap_sig[0], "B": romap_sig[1]})
    intervals = intervals_from_states(t, states.states, states.names)
    assert {lab for *_, lab in intervals} == {"A", "B", "A+B"}
    res = remove_labelled_offsets(t, mag, intervals)
    # estimated per label from the data (stage 2); A+B rarely has undisturbed samples
    # on both sides, so only the single heaters are compared
    np.testing.assert_allclose(res.offsets["A"], mag_sig[0], atol=0.1)
    np.testing.assert_allclose(res.offsets["B"], mag_sig[1], atol=0.1)
    residual = np.linalg.norm(res.values - bg, axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.1  # issue 5: residual < 0.1 nT rms
