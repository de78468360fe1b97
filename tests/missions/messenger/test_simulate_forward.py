"""The independent forward model (`missions.messenger.forward`) against the pipeline's
building blocks, step by step, over every orientation, sign, range, temperature and duty
cycle the physics allows (hypothesis).

The forward model shares no code with the pipeline (tests/missions/test_forward_independence.py),
so agreement here checks both readings of seed 000 against each other.
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration.gain_matrix import counts_to_nt, range_conversion
from fluxcal.calibration.heater_signal import heater_waveform
from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.relaxation import relaxed_offset, steady_state_offset
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-06-01T00:00:00")
TABLES = forward.read_tables(CAL.paths)
FULL_SCALE_NT = {0: 1530.0, 1: 51300.0}  # Table 4

unit = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v))


@settings(max_examples=200, deadline=None)
@given(direction=unit, fraction=st.floats(0.0, 0.9), range_flag=st.sampled_from([0, 1]),
       temperature=st.floats(-60.0, 45.0), duty=st.floats(0.0, 60.0),
       since_edge=st.floats(0.0, 99.999))
def test_counts_of_any_field_come_back(direction, fraction, range_flag, temperature, duty,
                                       since_edge):
    # any direction, both signs, up to 90 % of the range's full scale (Table 4)
    v = np.asarray(direction) / np.linalg.norm(direction)
    b = (fraction * FULL_SCALE_NT[range_flag] / np.sqrt(3)) * v[None, :]
    zero = (forward.temperature_offset(np.array([temperature]), TABLES)
            + forward.heater_waveform(np.array([since_edge]), np.array([duty]), TABLES))
    rng = np.array([range_flag])
    counts = forward.counts_from_field(b, zero, rng, TABLES)
    # the pipeline's eq. 1 (offset converted to the range by M_r^-1 M_fine) and eq. 8
    applied = zero if range_flag == 0 else zero @ range_conversion(CAL.matrices)[1].T
    back = counts_to_nt(counts - applied, rng, CAL.matrices)
    # no rounding here: both are exact linear algebra (1e-9 of the full scale)
    np.testing.assert_allclose(back, b, atol=1e-9 * FULL_SCALE_NT[range_flag])


@settings(max_examples=200, deadline=None)
@given(temperature=st.lists(st.floats(-150.0, 60.0), min_size=1, max_size=20))
def test_temperature_offset_is_eq3(temperature):
    t = np.array(temperature)
    np.testing.assert_allclose(forward.temperature_offset(t, TABLES),
                               two_segment_offset(t, CAL.temperature_coefficients),
                               atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(since_edge=st.lists(st.floats(0.0, 99.999), min_size=1, max_size=10),
       duty=st.floats(5.0, 60.0))
def test_heater_waveform_tables_6_8(since_edge, duty):
    # inside the bins and in both extrapolation zones (below 12 %, above 40 %)
    t = np.array(since_edge)
    d = np.full(t.size, duty)
    expected = heater_waveform(t, d, CAL.heater_signal, CAL.heater_duty_bins_percent)
    np.testing.assert_allclose(forward.heater_waveform(t, d, TABLES), expected, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(blocks=st.lists(st.sampled_from([0, 5, 8, 12, 17, 21, 25, 30, 36, 40, 44, 60]),
                       min_size=1, max_size=12),
       samples=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=30))
def test_relaxation_is_eq6_over_the_whole_history(blocks, samples):
    # duty cycles per 1000-s block (up and down: both signs of every step); the ODE stepped
    # by the forward model equals eq. 6a-6f when the look-back reaches the quiet start
    block_s = 1000.0
    span = block_s * len(blocks)
    grid = np.arange(-50.0, span + 200.0, 1.0)
    block = np.floor(grid / block_s).astype(int)
    duty_ppt = np.where((grid >= 0) & (block < len(blocks)),
                        10.0 * np.asarray(blocks)[np.clip(block, 0, len(blocks) - 1)], 0.0)
    state = forward.relaxed_duty_offset(grid, duty_ppt, TABLES)
    # the changes as the pipeline sees them: every block start whose duty differs
    d = np.concatenate([[0], blocks, [0]]) * 10.0
    k = np.flatnonzero(np.diff(d) != 0)
    change_t, change_d = k * block_s, d[k + 1]
    rel = CAL.constants["relaxation"]
    target = steady_state_offset(change_d, CAL.duty_cycle_d0, rel["min_duty_cycle_ppt"])
    t_s = np.round(np.asarray(samples) * (span + 150.0))  # on the 1-s grid
    expected = relaxed_offset(t_s, change_t, target, tau=rel["tau_s"], delay=rel["delay_s"],
                              look_back=max(change_t.size, 1))
    got = state[np.searchsorted(grid, t_s)]
    np.testing.assert_allclose(got, expected, atol=1e-9)
