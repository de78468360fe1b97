"""The independent forward model (`missions.rosetta.forward`) against the pipeline's steps,
over every orientation, sign, temperature, filter mode and time the physics allows
(hypothesis).  The forward model shares no code with the pipeline
(tests/missions/test_forward_independence.py), so agreement checks two readings of seed 003.
"""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.rosetta import calib, forward, level_a, level_b

CALS = {s: calib.load_ground_calibration(s) for s in ("OB", "IB")}
NOMINAL = calib.load_nominal_conversion()
SHIFTS = calib.load_time_shift_table()
JUMPS = calib.load_offset_jump_table()
LSB_NT = 30000.0 / (2**20 - 1)  # sec. 4.2.3.1

direction = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v))


@settings(max_examples=200, deadline=None)
@given(v=direction, magnitude=st.floats(0.0, 14000.0), temperature=st.floats(-150.0, 70.0),
       sensor=st.sampled_from(["OB", "IB"]), residual=st.booleans())
def test_ground_calibration_forward_and_back(v, magnitude, temperature, sensor, residual):
    # any direction, both signs, up to the 15000-nT range; both B_RES readings
    cal = CALS[sensor]
    if hasattr(cal, "residual_in_offset"):
        cal = replace(cal, residual_in_offset=residual)
    b_c = magnitude * (np.asarray(v) / np.linalg.norm(v))[None, :] / np.sqrt(3)
    t = np.array([temperature])
    b_raw = forward.raw_field(b_c, t, cal)
    # exact linear algebra both ways (1e-9 of the 15000-nT range)
    np.testing.assert_allclose(level_a.ground_calibrate(b_raw, t, cal), b_c, atol=1.5e-5)


@settings(max_examples=200, deadline=None)
@given(b=st.lists(st.floats(-14999.0, 14999.0), min_size=3, max_size=30))
def test_science_counts_within_half_an_lsb(b):
    raw = np.asarray(b[: len(b) // 3 * 3]).reshape(-1, 3)
    counts = forward.science_counts(raw, NOMINAL)
    assert counts.min() >= -(2**19) and counts.max() < 2**19
    err = level_a.field_counts_to_nt(counts, NOMINAL) - raw
    assert np.abs(err).max() <= 0.5 * LSB_NT * (1 + 1e-9)


@settings(max_examples=200, deadline=None)
@given(t=st.lists(st.floats(-145.0, 145.0), min_size=1, max_size=30),
       sensor=st.sampled_from(["OB", "IB"]))
def test_thermistor_words(t, sensor):
    # The PIU drops 4 bits by a shift (sec. 4.2.2.5): the ADC voltage lies 0..76 uV above
    # the bottom of the word's bin.  The seed's word -> volt, (TLM + 2^15) * 5 V/(2^16 - 1)
    # - 2.5 V, reads 36 uV + 1.1 nV per word above that bottom (its factor is 5/(2^16 - 1),
    # not 16 * 5/(2^20 - 1)): U_read - U in [-40, +61] uV (+2.4 uV ADC rounding).  Times
    # dT/dU <= 650 K/V (the sec. 3.3.3 cubic at +145 C): T_read - T in [-0.026, +0.040] K.
    cal = CALS[sensor]
    temp = np.asarray(t)
    words = forward.thermistor_words(temp, cal, NOMINAL)
    read = level_a.sensor_temperature(words, cal, NOMINAL)
    assert np.all(read - temp >= -0.026) and np.all(read - temp <= 0.040), read - temp


@settings(max_examples=100, deadline=None)
@given(sid=st.lists(st.integers(1, 5), min_size=1, max_size=40),
       sensor=st.sampled_from(["OB", "IB"]), primary=st.sampled_from(["OB", "IB"]))
def test_filter_delay_is_the_time_shift(sid, sensor, primary):
    s = np.asarray(sid)
    expected = level_a.filter_time_shift(s, SHIFTS, sensor=sensor, primary=primary)
    got = forward.filter_delay(s, SHIFTS, secondary=sensor != primary)
    np.testing.assert_array_equal(got, expected)


@settings(max_examples=50, deadline=None)
@given(seconds=st.lists(st.floats(0.0, 3.2e8), min_size=1, max_size=40),
       sensor=st.sampled_from(["OB", "IB"]))
def test_offset_jumps_over_the_mission(seconds, sensor):
    # times from 2004 to 2014-02 and inside/outside/at the edges of Appendix B's intervals
    with KernelPool():
        t0 = utc_to_tt2000(np.array(["2004-01-01T00:00:00"]))[0]
        edges = utc_to_tt2000(np.concatenate([JUMPS.start_utc, JUMPS.end_utc]))
        epoch = np.sort(np.concatenate(
            [t0 + (np.asarray(seconds) * 1e9).astype(np.int64) * 4, edges, edges - 1]))
        expected = level_b.offset_jumps(epoch, JUMPS, sensor)[0]
        got = forward.jump_field(epoch, JUMPS, sensor)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("gap_s", [0.05, 2 * 3600.0, 4 * 3600.0])
def test_extended_offset_shifts_the_next_day(gap_s):
    # sec. 4.2.3.3: across midnight within a campaign, day 2 starts with the offset stored
    # at the end of day 1; after a gap of more than a few hours (3 h) it does not
    days = [np.datetime64("2014-08-01"), np.datetime64("2014-08-02")]
    c1, c2 = np.zeros((6, 3)), np.zeros((6, 3))
    c1[0], c1[1] = [1.0, 2.0, 3.0], [0.01, 0.02, -0.03]
    c2[0], c2[1], c2[2] = [6.0, -1.0, 0.5], [0.02, -0.01, 0.0], [1e-4, 0.0, 2e-4]
    models = {d: calib.DailyOffsetModel(d, "OB", c, "") for d, c in zip(days, (c1, c2),
                                                                          strict=True)}
    with KernelPool():
        midnight = utc_to_tt2000(np.array(["2014-08-02T00:00:00"]))[0]
    stamps = np.array([midnight - 1_000_000_000, midnight - 50_000_000,
                       midnight - 50_000_000 + int(gap_s * 1e9), midnight + 10**10 + int(gap_s
                                                                                   * 1e9)])
    temp = np.array([-20.0, -20.5, -21.0, -40.0])
    with KernelPool():
        off = forward.extended_offset(stamps, temp, models)
    p = lambda c, t: c[0] + c[1] * t + c[2] * t**2  # noqa: E731
    np.testing.assert_allclose(off[:2], [p(c1, -20.0), p(c1, -20.5)])
    if gap_s <= 3 * 3600.0:
        np.testing.assert_allclose(off[2], off[1])
        np.testing.assert_allclose(off[3] - off[2], p(c2, -40.0) - p(c2, -21.0))
    else:
        np.testing.assert_allclose(off[2:], [p(c2, -21.0), p(c2, -40.0)])
