"""Forward model -> pipeline round trip (issue 3 'Tests that must exist')."""

import numpy as np
import pytest

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.simulate import read_truth


@pytest.fixture(scope="module")
def recovered(messenger_kernels, simulated_files, calibration):
    # through the CSV files, as the command runs
    sci = read_science(simulated_files["science"])
    heat = read_heater(simulated_files["heater"])
    temp = read_temperature(simulated_files["temperature"])
    with KernelPool(messenger_kernels):
        ds = calibrate(sci, heat, temp, calibration)
    return ds, read_truth(simulated_files["truth"])


def test_scenario_covers_the_required_cases(recovered):
    ds, truth = recovered
    assert set(np.unique(ds["rate"].values)) >= {6, 8, 9, 10}  # rate changes
    assert set(np.unique(ds["range"].values)) == {0, 1}  # both ranges
    assert ds["heater_applied"].any() and not ds["heater_applied"].all()  # heater on and off
    assert ds.attrs["duty_cycle_changes"] >= 5
    assert ds["temperature"].max() > 0 and ds["temperature"].min() < -49  # excursion


def test_epochs_match_truth(recovered):
    ds, truth = recovered
    # truth et is written with 1 us resolution; TT2000 from the pipeline must agree to < 2 us
    assert np.abs(ds["epoch"].values - truth["epoch"].values).max() < 2000


def test_fine_range_recovered(recovered):
    ds, truth = recovered
    fine = truth["range"].values == 0
    err = ds["b_mso"].values[fine] - truth["b_mso"].values[fine]
    rms = np.sqrt((err**2).mean(axis=0))
    # issue 3: 0.05 nT rms, 0.1 nT max per axis.  Quantisation alone: fine counts of
    # 0.047 nT (Table 4) rounded give 0.047/sqrt(12) = 0.0135 nT rms per sensor axis and
    # <= 0.5 count (0.024 nT) per axis, <= 0.04 nT in MSO
    assert np.all(rms < 0.05), rms
    assert np.all(np.abs(err).max(axis=0) < 0.1), np.abs(err).max(axis=0)


def test_coarse_range_recovered(recovered):
    ds, truth = recovered
    coarse = truth["range"].values == 1
    err = ds["b_mso"].values[coarse] - truth["b_mso"].values[coarse]
    # issue 3: 1.6 nT max (half a coarse count is ~0.8 nT per sensor axis)
    assert np.all(np.abs(err).max(axis=0) < 1.6)


def test_offsets_and_heater_recovered(recovered, simulated):
    ds, _ = recovered
    truth = simulated["truth"]
    # The pipeline finds periods and changes in the heater bits and evaluates eq. 6a-6f; the
    # forward model (fluxcal.missions.messenger.forward) steps the relaxation ODE over the
    # whole history from its block schedule.  While at most six duty-cycle changes lie
    # behind a sample (the schedule's 7th change is 8000 s after the first edge), eq. 6a's
    # zero start is the true quiet start and the two agree up to the linear interpolation of
    # the 10-s temperature samples (< 0.02 counts ~ 1 pT).  Later, the five-change look-back
    # neglects at most 200 exp(-5000/872) = 0.6 DN (sec. 7).
    h = simulated["heater"]
    first_edge_met = float(h["met"].values[0]) + 110.0  # simulate.QUIET_LEAD_S
    u = simulated["science"]["met"].values - first_edge_met
    diff = np.abs(ds["offset"].values - truth["offset"].values)
    assert diff[u < 8000.0].max() < 0.02, diff[u < 8000.0].max(axis=0)
    assert diff.max() < 0.6, diff.max(axis=0)
    # heater waveform: the model uses MET, the pipeline ET; their rates differ by < 1e-6,
    # i.e. < 1e-4 s in a period, times the steepest table slope (< 1 count/s)
    np.testing.assert_allclose(ds["heater_signal"].values, truth["heater_signal"].values,
                               atol=1e-4)


def test_quality_flags_of_the_day(recovered):
    ds, _ = recovered
    q = ds["quality"].values
    # after V10 (H = 2); +Y sunward in 1000-2500 s gives S = 1, else S = 2
    assert set(np.unique(q // 10 % 10)) == {2}
    assert set(np.unique(q // 100)) == {1, 2}
    c = q % 10
    # C = 2 where the heater waveform or a duty-cycle offset of >= 1 count was removed
    # (issue 11: also in the relaxation hour after the heater stops)
    duty = (np.abs(ds["duty_cycle_offset"].values) >= 1.0).any(axis=1)
    np.testing.assert_array_equal(c == 2, ds["heater_applied"].values | duty)
    assert (duty & ~ds["heater_applied"].values).any()


def test_frames_are_rotations(recovered):
    ds, _ = recovered
    n = np.linalg.norm(ds["b_sensor"].values, axis=1)
    for f in ("mso", "j2000", "mbf", "rtn", "sc"):
        np.testing.assert_allclose(np.linalg.norm(ds[f"b_{f}"].values, axis=1), n, rtol=1e-12)


def test_heater_stream_must_cover_the_samples(messenger_kernels, simulated, calibration):
    from fluxcal.errors import InputFormatError

    short = simulated["heater"].isel(heater_time=slice(0, 3000))
    with KernelPool(messenger_kernels), pytest.raises(InputFormatError, match="does not cover"):
        calibrate(simulated["science"], short, simulated["temperature"], calibration)


def test_vso_on_request(messenger_kernels, simulated, calibration):
    sci = simulated["science"].isel(time=slice(0, 2000))
    with KernelPool(messenger_kernels):
        ds = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                       frames=("vso", "mso"))
    np.testing.assert_allclose(np.linalg.norm(ds["b_vso"].values, axis=1),
                               np.linalg.norm(ds["b_mso"].values, axis=1), rtol=1e-12)
    assert "b_j2000" not in ds


def _simulated_and_calibrated(tmp_path, duration_s, kernel_s, **schedule):
    """A forward-model run from 2012-06-01 of ``duration_s`` at rate setting 6, fine range
    only, with the heater ``schedule`` (SimulationConfig fields), and the pipeline's
    calibration of it; (calibrated, truth)."""
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.simulate import SimulationConfig, simulate
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

    cfg = SimulationConfig(start_utc="2012-06-01T00:00:00", duration_s=duration_s,
                           rate_segments=[(0.0, 6)], coarse_intervals=[], **schedule)
    mk = write_messenger_like_kernels(tmp_path, cfg.start_utc, kernel_s)
    cal = load_calibration(cfg.start_utc)
    with KernelPool(mk):
        sim = simulate(cfg, cal, SclkKernel.from_pool(-236))
        ds = calibrate(sim["science"], sim["heater"], sim["temperature"], cal)
    return ds, sim["truth"]


def test_heater_always_on_round_trip(tmp_path):
    # a bit that stays on (100 % duty, sec. 6-7: no rising edge inside the run) keeps the
    # steady state D0 * 1000 (8.4/15.3/0.7 nT if read as the heater stopping); the forward
    # model puts no cyclic waveform there (no on/off cycle)
    ds, truth = _simulated_and_calibrated(tmp_path, 4000.0, 6000.0,
                                          duty_cycles_percent=[40, 100, 100, 40, 30, 20])
    # six changes at most behind every sample: eq. 6a-6f is exact (see above)
    np.testing.assert_allclose(ds["offset"].values, truth["offset"].values, atol=0.02)
    err = np.abs(ds["b_mso"].values - truth["b_mso"].values)
    assert err.max() < 0.1, err.max(axis=0)  # fine range, issue 3's bound


@pytest.mark.parametrize("bits", [
    # +-1 s in the on-time of every third period (the 1-s command iteration): no duty-cycle
    # change (the V10 controller changes it only every 1000 s); issue 11 saw 72 spurious
    # changes in 3 h and 1.6/2.9/0.14 nT errors
    {"jitter_every": 3},
    # a 60-s LAC gap from 30 s before a rising edge to 10 s after it: a 0 -> 1 step across
    # the gap is no edge (issue 11: up to 0.6 nT for an hour)
    {"heater_gaps": [(3050.0, 3110.0)]},
])
def test_heater_bits_with_jitter_or_gap_round_trip(tmp_path, bits):
    ds, truth = _simulated_and_calibrated(tmp_path, 7200.0, 9000.0,
                                          duty_cycles_percent=[40, 36, 25, 30, 21, 40], **bits)
    # the schedule's changes over the heater stream (8600 s): 40 36 25 30 21 40 | 40 36 25
    assert ds.attrs["duty_cycle_changes"] == 8
    # waveform at each period's actual duty cycle (sec. 6), offsets within sec. 7's 0.6 DN
    np.testing.assert_allclose(ds["heater_signal"].values, truth["heater_signal"].values,
                               atol=1e-4)
    np.testing.assert_allclose(ds["offset"].values, truth["offset"].values, atol=0.6)
    err = np.abs(ds["b_mso"].values - truth["b_mso"].values)
    assert err.max() < 0.1, err.max(axis=0)  # fine range, issue 3's bound


def test_calibrate_without_intermediates(messenger_kernels, simulated, calibration):
    """``keep_intermediates=False`` (what ``edr2cdr`` uses) drops exactly the unwritten steps.

    Reference: the same call keeping every intermediate; every variable left must be
    identical (same bits, same attributes), since the drop only frees memory.
    """
    from fluxcal.missions.messenger.chain import (
        UNWRITTEN_AFTER_QUALITY,
        UNWRITTEN_BEFORE_GEOMETRY,
    )

    sci = simulated["science"].isel(time=slice(0, 4000))
    with KernelPool(messenger_kernels):
        full = calibrate(sci, simulated["heater"], simulated["temperature"], calibration)
        lean = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                         keep_intermediates=False)
    dropped = set(UNWRITTEN_BEFORE_GEOMETRY) | set(UNWRITTEN_AFTER_QUALITY)
    assert set(full.variables) - set(lean.variables) == dropped
    assert lean.identical(full.drop_vars(sorted(dropped)))
