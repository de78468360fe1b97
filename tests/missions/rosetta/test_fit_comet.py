"""``fluxcal rosetta fit`` at a comet: written tables meet the goal or the fit refuses (issue 34).

Data: the independent comet forward model of `_comet_field` (|B| of the day 18 nT with a
slow 10 % compressive modulation, f^-2 from 6 h to 2 min; f^-5/3 rotations about a draped
direction; 40-mHz wave packets of 1-2 nT; a daily temperature swing of 20 C) through the
seed's instrument model (`fluxcal.missions.rosetta.forward`); the offset is the daily
cubic of the extended temperature model (sec. 4.2.3.3), and in the jump case an
Appendix B offset jump of (1.5, -1.0, 0.8) nT from noon (issue 34's case).

Expected values come from the forward model: the curve's truth is the offset the
LEVEL_A data carry (``B_A - B_true``), the unseen stretch's truth is its field.  The goal
is the issue's 0.2 nT rms per axis for the curve over the day and for an unseen 6 h.
0.25 Hz keeps a day at 21 600 vectors (a fit takes about 2 s).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.errors import FitRefusedError
from fluxcal.missions.rosetta import calib, forward, io, level_a

from . import _comet_field as comet

DAY = "2015-03-10"
GOAL = 0.2  # nT rms per axis (issue 34)
JUMP = np.array([1.5, -1.0, 0.8])
RATE = 0.25


def _level_a(raw, models=None):
    from fluxcal.missions.rosetta.fit import reduced_temperature

    cal = calib.load_ground_calibration("OB")
    a = level_a.level_a(raw, cal, calib.load_time_shift_table(),
                        calib.load_nominal_conversion(), daily_models=models)
    return a, reduced_temperature(a, cal)


def _judge(fit, a, b, tt, seed, **day):
    """Curve rms over the day and unseen-6-h rms (x y z, nT) of a written fit."""
    curve = np.sqrt(((fit.offset(tt) - (a["b"].values - b)) ** 2).mean(axis=0))
    raw_u, b_u, _, _ = comet.comet_day(DAY, seed=seed + 1000, rate_hz=RATE, start_s=50_000.0,
                                       hours=6.0, **day)
    a_u, _ = _level_a(raw_u, {np.datetime64(DAY): fit.to_model()})
    return curve, np.sqrt(((a_u["b"].values - b_u) ** 2).mean(axis=0))


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_comet_day_is_written_within_the_goal_or_refused(seed, pool):
    """Before issue 34 (one constant |B| per 1200-s interval, 1-nT limit) the 18-nT day
    was written off by more than the goal; now every written table is within it."""
    from fluxcal.missions.rosetta.fit_variance import (
        VarianceSettings,
        fit_extended_model_variance,
    )

    day = {"b0": 18.0, "swing_c": 20.0}
    raw, b, _, _ = comet.comet_day(DAY, seed=seed, rate_hz=RATE, **day)
    a, tt = _level_a(raw)
    before = fit_extended_model_variance(
        a, tt, settings=VarianceSettings(segment_s=1200.0, goal=99.0, max_sigma=99.0))
    curve_before, _ = _judge(before, a, b, tt, seed, **day)
    assert curve_before.max() > GOAL, curve_before  # the failure: 0.3-0.7 nT
    try:
        fit = fit_extended_model_variance(a, tt)
    except FitRefusedError as exc:
        assert re.search(r"predicted error of the recalibrated day .* above the goal 0.2 nT",
                         str(exc)), exc
        return
    curve, unseen = _judge(fit, a, b, tt, seed, **day)
    assert np.all(curve < GOAL) and np.all(unseen < GOAL), (curve, unseen)
    assert re.match(r"\d+ Gauss-Newton steps; stopped: the curve moved \S+ nT < 0.0001 nT "
                    r"with the selection unchanged", fit.notes["convergence"])
    assert "60-s segments" in fit.notes["segments"]


def test_an_offset_jump_inside_the_day_is_refused_naming_time_and_size(pool):
    """(1.5, -1.0, 0.8) nT from noon: named within one 1200-s interval of 12:00, its size
    within 3 stated sigma; the same day without the jump is not called a jump."""
    from fluxcal.missions.rosetta.fit_variance import fit_extended_model_variance

    raw, _, _, _ = comet.comet_day(DAY, seed=21, rate_hz=RATE, jump=JUMP)
    a, tt = _level_a(raw)
    with pytest.raises(FitRefusedError, match="an offset jump of") as info:
        fit_extended_model_variance(a, tt)
    text = str(info.value)
    m = re.search(r"jump of (\S+) (\S+) (\S+) \+- (\S+) (\S+) (\S+) nT \(x y z\) between "
                  r"(\S+) and (\S+) UTC", text)
    assert m, text
    step, sigma = np.array(m.groups()[:3], float), np.array(m.groups()[3:6], float)
    start, end = (np.datetime64(v) for v in m.groups()[6:])
    noon = np.datetime64(f"{DAY}T12:00:00")
    assert start - np.timedelta64(1200, "s") <= noon <= end + np.timedelta64(1200, "s"), text
    assert np.all(np.abs(step - JUMP) < 3 * sigma), (step, sigma)
    clean, _, _, _ = comet.comet_day(DAY, seed=21, rate_hz=RATE)
    a, tt = _level_a(clean)
    try:
        fit_extended_model_variance(a, tt)
    except FitRefusedError as exc:
        assert "offset jump" not in str(exc), exc


def test_cli_records_range_and_error_and_calibrate_flags_extrapolation(tmp_path, caplog):
    """The daily file states where it was fitted and its error; a stretch 4 C warmer than
    the fitted day is calibrated with a warning saying how far outside it is."""
    from fluxcal.geometry.kernels import KernelPool

    day = {"b0": 12.0, "swing_c": 20.0}
    with KernelPool():
        raw, _, temp, _ = comet.comet_day(DAY, seed=31, rate_hz=RATE, **day)
        io.write_science_csv(raw, tmp_path / "day.csv")
        warm, _, temp_w, _ = comet.comet_day(DAY, seed=32, rate_hz=RATE, start_s=16_000.0,
                                             hours=6.0, temperature_shift_c=4.0, **day)
        io.write_science_csv(warm, tmp_path / "warm.csv")
    fitted = tmp_path / "fitted"
    assert main(["rosetta", "fit", "--science", str(tmp_path / "day.csv"), "--sensor", "OB",
                 "--out", str(fitted)]) == 0
    model = calib.read_daily_offset_model(fitted / "RPCMAG_150310_006_CALIB_OB.TXT")
    cal = calib.load_ground_calibration("OB")
    true_tt = forward.reduced_temperature(temp, cal)
    # the range is the day's, to the thermistor word (0.02 C)
    np.testing.assert_allclose(model.temperature_range, [true_tt.min(), true_tt.max()],
                               atol=0.03)
    assert np.all(model.curve_sigma > 0) and np.all(model.curve_sigma < 2 * GOAL)
    text = (fitted / "RPCMAG_150310_006_CALIB_OB.TXT").read_text()
    assert "# figure of merit: predicted error of the recalibrated day" in text
    assert "goal 0.2 nT" in text and "# curve error: 1-sigma x y z" in text
    assert "# convergence:" in text
    caplog.clear()
    assert main(["rosetta", "calibrate", "--science", str(tmp_path / "warm.csv"), "--sensor",
                 "OB", "--levels", "A", "--formats", "cdf", "--out", str(tmp_path / "out"),
                 "--calib", str(fitted)]) == 0
    far = float(forward.reduced_temperature(temp_w, cal).max() - model.temperature_range[1])
    assert far > 3.0
    m = re.search(r"(\d+) of \d+ vectors at reduced temperatures outside the range .* \(up to "
                  r"(\S+) C outside", caplog.text)
    assert m, caplog.text
    assert float(m.group(2)) == pytest.approx(far, abs=0.03)


def test_cli_goal_accepts_a_worse_table_and_says_so(tmp_path, capsys):
    """A 40-nT day whose rotations stop at 2 min, where its compression stops (little
    rotation left within the 60-s segments): refused at the 0.2-nT goal naming it; --goal 1
    writes the table and its header says the goal was raised."""
    from fluxcal.geometry.kernels import KernelPool

    with KernelPool():
        raw, _, _, _ = comet.comet_day(DAY, seed=41, rate_hz=RATE, b0=40.0,
                                       rotation_cut_s=120.0)
        io.write_science_csv(raw, tmp_path / "day.csv")
    args = ["rosetta", "fit", "--science", str(tmp_path / "day.csv"), "--sensor", "OB"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert "above the goal 0.2 nT" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "b"), "--goal", "1"]) == 0
    out = capsys.readouterr().out
    assert "fitted on T~" in out and "curve error (1 sigma" in out
    text = (tmp_path / "b" / "RPCMAG_150310_006_CALIB_OB.TXT").read_text()
    assert "goal 1 nT (ACCEPTED ABOVE THE DEFAULT GOAL 0.2 nT by --goal)" in text
    assert main([*args, "--out", str(tmp_path / "c"), "--goal", "0"]) == 2


def test_appendix_b_jumps_at_a_comet_within_the_goal(pool):
    """Two 2-day Appendix B intervals of the 18-nT comet field under a slow attitude: the
    variance jump fit with 60-s segments is within 0.1 nT and its stated errors cover it;
    with one constant |B| per 1200-s sub-interval (before issue 34) it was off by 0.34 nT
    and its errors (0.1-0.15 nT) fail the goal."""
    from fluxcal.missions.rosetta.fit_variance import (
        VarianceSettings,
        fit_offset_jumps_variance,
    )

    from . import _daily_mean_wind as wind

    epoch, b_sc, _, _ = wind.jump_data(
        0, rate_hz=0.1, field=lambda secs, rng: comet.comet_field(secs, 18.0, rng))
    start, end = (np.array(c) for c in zip(*wind.JUMP_INTERVALS, strict=True))
    fit = fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB")
    err = fit.jumps - wind.TRUE_JUMPS
    assert np.all(np.abs(err) < GOAL / 2), err  # measured 0.051 nT at most
    assert np.all(np.abs(err) < 3 * fit.sigma + 0.01), (err, fit.sigma)
    assert np.all(2 * fit.sigma <= GOAL)
    before = fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB",
                                       settings=VarianceSettings(segment_s=1200.0, goal=99.0))
    assert np.abs(before.jumps - wind.TRUE_JUMPS).max() > GOAL  # measured 0.34 nT
    with pytest.raises(FitRefusedError, match="twice the error is above the goal 0.2 nT"):
        fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB",
                                  settings=VarianceSettings(segment_s=1200.0))


def test_a_jump_inside_an_appendix_b_interval_is_refused_naming_where_to_split(pool):
    """(1.5, -1.0, 0.8) nT more from 12:00 of the first interval's first day: one constant
    per interval would spread it; the fit names the time (within one 1200-s sub-interval)
    and the size (within 3 sigma) and asks for the interval to be split there."""
    from fluxcal.geometry.time import utc_to_tt2000
    from fluxcal.missions.rosetta.fit_variance import fit_offset_jumps_variance

    from . import _daily_mean_wind as wind

    epoch, b_sc, _, _ = wind.jump_data(
        1, rate_hz=0.1, field=lambda secs, rng: comet.comet_field(secs, 18.0, rng))
    noon = np.datetime64("2014-08-01T12:00:00")
    jumped = ((epoch >= utc_to_tt2000(np.array([str(noon)]))[0])
              & (epoch < utc_to_tt2000(np.array([wind.JUMP_INTERVALS[1][0]]))[0]))
    b_sc = b_sc + np.where(jumped[:, None], JUMP, 0.0)
    start, end = (np.array(c) for c in zip(*wind.JUMP_INTERVALS, strict=True))
    with pytest.raises(FitRefusedError, match="inside the interval") as info:
        fit_offset_jumps_variance(epoch, b_sc, start, end, sensor="OB")
    text = str(info.value)
    m = re.search(r"jump of (\S+) (\S+) (\S+) \+- (\S+) (\S+) (\S+) nT \(x y z\) inside the "
                  r"interval, between (\S+) and (\S+) UTC .* split the interval at about", text)
    assert m and "2014-08-01T00:00:00 .. 2014-08-03T00:00:00" in text, text
    step, sigma = np.array(m.groups()[:3], float), np.array(m.groups()[3:6], float)
    first, last = (np.datetime64(v) for v in m.groups()[6:])
    one = np.timedelta64(1200, "s")
    assert first - one <= noon <= last + one, text
    # + 0.05 nT: the step is one linearised solve from the fit without it
    assert np.all(np.abs(step - JUMP) < 3 * sigma + 0.05), (step, sigma)
