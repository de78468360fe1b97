"""Heater streams that start or end inside heater operation (day boundaries).

A day's LAC file ends wherever the day ends, often inside the heater-on part of a period,
and a day processed without the previous day's file starts inside heater operation.
Neither boundary may turn into a spurious duty-cycle change.
"""

import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.chain import calibrate


def _truncate_heater(simulated, end_rel):
    """Keep heater records up to ``end_rel`` s after the simulated heater schedule start."""
    heat = simulated["heater"]
    h_zero = float(simulated["science"]["met"].values[0]) - 1200.0  # SimulationConfig.lead_s
    return heat.isel(heater_time=heat["met"].values <= h_zero + end_rel)


def test_stream_ending_inside_the_on_phase(messenger_kernels, simulated, calibration):
    # the science ends 8400 s after the schedule start; the 8300-s period (block 8, 30 %)
    # is on for 8300-8330 s: the heater file ends 15 s into it (a day's last LAC record)
    heat = _truncate_heater(simulated, 8315.0)
    sci = simulated["science"]
    truth = simulated["truth"]
    with KernelPool(messenger_kernels):
        ds = calibrate(sci, heat, simulated["temperature"], calibration)
    # same heater signal and offsets as the independent forward model (its declarative
    # schedule): waveform to the MET/ET clock-rate difference (< 1e-4 counts), offsets to
    # the sec. 7 look-back bound 0.6 DN (see test_round_trip.py)
    np.testing.assert_allclose(ds["heater_signal"].values, truth["heater_signal"].values,
                               atol=1e-4)
    np.testing.assert_allclose(ds["offset"].values, truth["offset"].values, atol=0.6)


def test_stream_starting_inside_heater_operation(messenger_kernels, simulated, calibration,
                                                 caplog):
    # the heater file starts 5 s into an on-phase (block 1, 36 %): the duty cycle before
    # it is unknown -> taken as steady (a change at -inf), and a warning names the stream
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger import levels

    heat = simulated["heater"]
    h_zero = float(simulated["science"]["met"].values[0]) - 1200.0
    heat = heat.isel(heater_time=heat["met"].values >= h_zero + 1105.0)
    with KernelPool(messenger_kernels), caplog.at_level("WARNING"):
        periods, changes = levels.find_heater_periods(heat, calibration,
                                                      SclkKernel.from_pool(-236))
    assert np.isneginf(changes.time[0]) and changes.duty_cycle_ppt[0] == 360
    assert np.all(np.isfinite(changes.time[1:]))
    # the warning (chain.warn_unseen_duty_cycle) needs science samples within the
    # 5000-s look-back of the stream start: the simulated science starts 95 s after it
    from fluxcal.missions.messenger.chain import warn_unseen_duty_cycle

    with KernelPool(messenger_kernels), caplog.at_level("WARNING"):
        sclk = SclkKernel.from_pool(-236)
        ds = levels.correct_time(simulated["science"], calibration, sclk)
        assert warn_unseen_duty_cycle(ds, heat, changes, calibration, sclk)
        # the same stream 5000 s or more before every sample: quiet (the batch case)
        # (+10 s: the science ET is lag-corrected, up to 2.4 s earlier than recorded)
        late = ds.isel(time=ds["et"].values >= ds["et"].values[0] - 95.0 + 5010.0)
        assert late.sizes["time"] > 0
        assert not warn_unseen_duty_cycle(late, heat, changes, calibration, sclk)
    assert caplog.text.count("starts inside heater operation") == 1
    assert ";" not in caplog.text.split("first file")[1].split(")")[0]
    # the full simulated stream starts quiet (110 s of zeros): no such assumption
    with KernelPool(messenger_kernels):
        _, full = levels.find_heater_periods(simulated["heater"], calibration,
                                             SclkKernel.from_pool(-236))
    assert np.all(np.isfinite(full.time)) and full.duty_cycle_ppt[0] == 400
