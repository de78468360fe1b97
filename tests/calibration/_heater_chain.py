"""Heater-bit schedules and the heater chain they run through, for the heater-bit tests.

`schedule_bits` writes the V10 controller's 1-s heater bits from a declared schedule (on
for the first ``d`` s of each 100-s period) by hand; `heater_chain` runs the code under
test on them (heater periods, duty-cycle changes, relaxed offset eq. 6a-6f, waveform
Tables 6-8).  Expected values stay in the tests (closed forms, or the clean schedule's
own chain).
"""

from __future__ import annotations

import numpy as np

from fluxcal.calibration.heater_signal import heater_periods, heater_signal
from fluxcal.calibration.relaxation import duty_cycle_changes, relaxed_offset, steady_state_offset
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-06-01")
TAU, DT = 872.0, 10.0  # sec. 7
D0 = np.array([0.17885, 0.32851, 0.01477])  # Table 3, counts per ppt
K_FINE = np.array([0.046769, 0.046673, 0.047997])  # Table 4, nT per fine count
QUIET = 200  # seconds of zero bits before the schedule (more than one period)


def schedule_bits(on_seconds: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """1-s times and bits: QUIET zeros, then one 100-s period per entry (on for the first
    d s), then 300 s of zeros."""
    out = [0] * QUIET
    for d in on_seconds:
        out += [1] * d + [0] * (100 - d)
    out += [0] * 300
    return np.arange(len(out), dtype=float), np.array(out, dtype=np.int8)


def heater_chain(t: np.ndarray, b: np.ndarray, samples: np.ndarray) -> tuple:
    """Heater periods, duty-cycle changes, relaxed offset and waveform (with the applied
    mask) of the bits ``b`` at ``t``, at the sample times ``samples``."""
    p = heater_periods(t, b)
    ch = duty_cycle_changes(p, data_end=t[-1] + 1.0, data_start=t[0])
    target = steady_state_offset(ch.duty_cycle_ppt, D0)
    delta = relaxed_offset(samples, ch.time, target, tau=TAU, delay=DT, look_back=5,
                           look_back_s=5000.0)
    wave, applied = heater_signal(samples, p, CAL.heater_signal, CAL.heater_duty_bins_percent)
    return p, ch, delta, wave, applied
