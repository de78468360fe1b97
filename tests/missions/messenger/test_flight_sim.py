"""The flight-like forward model (issue 13 verification): its tables, statistics, streams.

The pipeline with the *true* tables must give back the simulated field to the rounding
of the counts: the forward model (flight_sim + forward) and the pipeline share no code
(tests/missions/test_forward_independence.py), so this checks both.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.flight_sim import (
    BLOCK_S,
    CalibrationChanges,
    FlightConfig,
    HeaterModel,
    RealisticWindModel,
    SolarWindModel,
    heater_schedule,
    read_flight_truth,
    simulate_flight,
    solar_wind,
    wind_model,
    write_true_calibration,
)
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature

DAY = np.datetime64("2010-03-01")
#: Fine-range nT per count (Table 4): rounding to integer counts leaves 1/sqrt(12) count.
NT_PER_COUNT = 1530.0 / 32768.0


def test_true_tables_load_and_differ_from_the_seed_as_asked(tmp_path):
    ch = CalibrationChanges()
    write_true_calibration(tmp_path, ch)
    true = load_calibration(DAY, tmp_path)
    seed = load_calibration(DAY)
    assert {v for _, v in true.files} == {1, ch.version}
    tc, sc = true.temperature_coefficients, seed.temperature_coefficients
    np.testing.assert_allclose(tc[:, 0] / sc[:, 0], ch.a0, rtol=1e-6)
    np.testing.assert_allclose(tc[:, 1] / sc[:, 1], ch.b0, rtol=1e-5)
    np.testing.assert_allclose(tc[:, 3] / sc[:, 3], ch.b1, rtol=1e-5)
    # eq. 4 holds for the printed T_m, moved by the asked shift
    tm = (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1])
    np.testing.assert_allclose(tm, true.breakpoint_temperature_c, atol=1e-5)
    np.testing.assert_allclose(tm - seed.breakpoint_temperature_c, ch.tm_shift_c, atol=2e-3)
    # Table 3: C0 is the new Table 2 at -50 C (the seed's constraint), D0 scaled
    c50 = np.maximum(tc[:, 0] - 50 * tc[:, 1], tc[:, 2] - 50 * tc[:, 3])
    np.testing.assert_allclose(true.duty_cycle_c0, c50, atol=1e-5)
    np.testing.assert_allclose(true.duty_cycle_d0 / seed.duty_cycle_d0, ch.d0, rtol=1e-5)
    assert true.constants["relaxation"]["tau_s"] == pytest.approx(872.0 * ch.tau, abs=1e-3)
    ratio = true.heater_signal / np.where(seed.heater_signal == 0, np.nan, seed.heater_signal)
    for k in range(3):  # 5-decimal values: ratio exact to 1e-5 / |value|
        big = np.abs(seed.heater_signal[k]) > 0.5
        np.testing.assert_allclose(ratio[k][big], ch.waveform[k], rtol=1e-4)
    # the simulator reads the same values with its own reader
    fw = forward.read_tables(true.paths)
    np.testing.assert_allclose(fw.d0, true.duty_cycle_d0)
    np.testing.assert_allclose(fw.heater, true.heater_signal)


def test_controller_schedule_and_temperatures():
    rng = np.random.default_rng(7)
    n_blocks = 4 * 87  # four days
    model = HeaterModel()
    s = heater_schedule(rng, n_blocks, 2, model)
    d = s.duty_percent
    # duty cycles: 0 or 10..45 %, changed only between 1000-s blocks (by construction of
    # the per-block array), lead blocks off
    assert set(np.unique(d)) <= {0} | set(range(10, 46))
    assert (d[:2] == 0).all() and (d > 0).any() and (d[2:] == 0).any()
    assert np.abs(np.diff(d[d > 0])).max() <= max(model.duty_step_percent, 45)
    # eq. 2: the temperature varies only with the heater off
    block = (np.arange(s.temperature_c.size) // BLOCK_S).astype(int)
    warm = s.temperature_c != -50.0
    assert (d[block[warm]] == 0).all()
    # excursions span -60..+40 C, enough for every 10-C bin of the temperature law
    assert s.temperature_c.min() < -60.0 and s.temperature_c.max() > 40.0
    hist, _ = np.histogram(s.temperature_c, bins=np.arange(-65.0, 46.0, 10.0))
    assert hist.min() >= 1000, hist


def test_the_default_wind_is_the_realistic_one_and_quiet_is_an_option():
    assert isinstance(wind_model(FlightConfig().solar_wind), RealisticWindModel)
    assert wind_model("realistic").b_median_nt == 18.0
    assert isinstance(wind_model("quiet"), SolarWindModel)
    with pytest.raises(ValueError, match="choose one of realistic, quiet"):
        wind_model("calm")
    # the quiet name draws the same field as the quiet model (today's, issue 13)
    a = solar_wind(np.random.default_rng(1), 5000, "quiet")
    np.testing.assert_array_equal(a, solar_wind(np.random.default_rng(1), 5000,
                                                SolarWindModel()))


def test_quiet_solar_wind_statistics():
    rng = np.random.default_rng(3)
    model = SolarWindModel()
    n = 40 * 86_400
    b = solar_wind(rng, n, model)
    mag = np.linalg.norm(b, axis=1)
    lo, hi = np.percentile(mag, [5, 95])
    assert 4.5 < lo < 6.0 and 8.5 < hi < 11.0  # |B| ~ 5-10 nT
    # Alfvenic: within 1-h windows the components rotate by ~2-3 nT (correlation 0.27 at
    # 1 h) while |B| varies by its compressive 3 % (0.2 nT) and its slow part: > 4x
    w = b[: n // 3600 * 3600].reshape(-1, 3600, 3)
    m = mag[: n // 3600 * 3600].reshape(-1, 3600)
    mag_std = np.median(m.std(axis=1))
    comp_std = np.median(w.std(axis=1))
    assert mag_std < 0.05 * model.b_median_nt and comp_std > 4 * mag_std, (mag_std, comp_std)
    # sector changes: the field's component along the Parker direction changes sign
    # every 2-6 days: 40 days hold 7-20 sector boundaries (daily means change sign)
    p = np.asarray(model.parker_direction) / np.linalg.norm(model.parker_direction)
    daily = (b @ p)[: 40 * 86_400].reshape(40, -1).mean(axis=1)
    assert 5 <= np.count_nonzero(np.diff(np.sign(daily))) <= 25
    # the long-term mean tends to zero: over 40 days (~10 sectors, each ~3 nT along p)
    # the mean along p is ~3 nT / sqrt(10) ~ 1 nT; 3 sigma = 3 nT
    assert abs((b @ p).mean()) < 3.0


def _calibrated_rms(inp, day, folder):
    from fluxcal.missions.messenger.chain import calibrate

    one = dt.timedelta(days=1)

    def f(code, d):
        return inp / f"MAG{code}_{d:%Y%j}.csv"

    sci = read_science([f("SCI", day)])
    htr = read_heater([p for p in (f("HTR", day - one), f("HTR", day)) if p.exists()])
    tmp = read_temperature([p for p in (f("TMP", day - one), f("TMP", day),
                                        f("TMP", day + one)) if p.exists()])
    with KernelPool(inp / "kernels.tm"):
        ds = calibrate(sci, htr, tmp, load_calibration(np.datetime64(str(day)), folder),
                       frames=("sc",), max_offset_step=None)
    truth = read_flight_truth(inp, day)
    assert np.array_equal(ds["met"].values, truth["met"])
    err = ds["b_sensor"].values - truth["b_sensor"]
    return np.sqrt((err**2).mean(axis=0)), np.abs(err).max(axis=0), ds, truth


def _check_field(tmp_path, config):
    run = simulate_flight(tmp_path, config)
    day = run.days[-1]
    rms, _, ds, truth = _calibrated_rms(run.input_dir, day, run.calibration_dir)
    # fine range: rounding leaves 0.047 / sqrt(12) = 0.0135 nT rms; eq. 6's five-change
    # look-back differs from the model's infinite memory by <= 0.6 count (sec. 7)
    fine = truth["range"] == 0
    err = ds["b_sensor"].values - truth["b_sensor"]
    fine_rms = np.sqrt((err[fine] ** 2).mean(axis=0))
    assert fine_rms.max() < 0.02, fine_rms
    assert np.abs(err[fine]).max() < (0.5 * 1.01 + 0.6) * NT_PER_COUNT, np.abs(err).max(0)
    return run, day, rms, ds, truth


def test_pipeline_with_the_true_tables_gives_back_the_field(tmp_path):
    # day 2 of a run, with a 20-Hz hour, a coarse-range half hour, a science gap, a
    # 60-s heater gap and a 300-s temperature gap.  Duty cycles 11-45 %: at exactly 10 %
    # see the strict xfail below.
    h = 86_400.0
    config = FlightConfig(
        days=2, seed=11, heater=HeaterModel(duty_percent=(11, 45)),
        rate_changes=[(h + 3600.0, 10), (h + 7200.0, 6)],
        coarse_intervals=[(h + 20_000.0, h + 21_800.0)],
        science_gaps=[(h + 30_000.0, h + 31_000.0)],
        heater_gaps=[(h + 40_000.0, h + 40_060.0)],
        temperature_gaps=[(h + 50_000.0, h + 50_300.0)])
    run, day, rms, ds, truth = _check_field(tmp_path, config)
    assert set(np.unique(ds["rate"].values)) == {6, 10} and truth["range"].any()
    # coarse-range samples (2 % of the day) round 30x coarser (1.4 nT / sqrt(12) = 0.40
    # nT): sqrt(0.02 * 0.40^2) = 0.057 nT on the day's rms
    assert rms.max() < 0.08, rms
    # the seed's own tables miss the altered offsets by several nT
    shipped, _, _, _ = _calibrated_rms(run.input_dir, day, None)
    assert shipped.max() > 1.0, shipped


def test_ten_percent_duty_cycle_gets_its_waveform(tmp_path):
    _check_field(tmp_path, FlightConfig(days=1, seed=5, heater=HeaterModel(
        duty_percent=(10, 10))))
