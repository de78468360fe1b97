"""Issue 11, "readings with large stakes": both readings of B_res and of the reduced
temperature are calibration-file switches (docs/decisions/rosetta.md, decisions 25, 26)."""

import dataclasses

import numpy as np
import pytest

from fluxcal.errors import CalibrationError
from fluxcal.missions.rosetta import calib, io, level_a
from fluxcal.missions.rosetta.calib import DailyOffsetModel

from ._raw import write_raw_csv


def _switched(cal, tmp_path, **changes):
    """Round trip through the file format: the switch must live in the calibration file."""
    path = calib.write_ground_calibration(
        dataclasses.replace(cal, **changes), tmp_path / calib.GROUND_FILE[cal.sensor]
    )
    return calib.read_ground_calibration(path)


@pytest.mark.parametrize("sensor, z_nt", [("OB", 21.9), ("IB", 16.4)])
def test_b_res_switch(tmp_path, sensor, z_nt):
    """Leaving B_res out (sec. 4.2.3.2 item 2) moves LEVEL_A by -omega sigma B_res:
    21.9 nT (OB z), 16.4 nT (IB z).  Before the switch existed the key was ignored (0 nT)."""
    cal = calib.load_ground_calibration(sensor)
    assert cal.residual_in_offset  # default: sec. 3.3.1.1 / 3.3.2.1 with B_res
    without = _switched(cal, tmp_path, residual_in_offset=False)
    assert not without.residual_in_offset
    t = np.linspace(-140.0, 40.0, 7)
    b = np.tile([[1000.0, -2000.0, 500.0]], (t.size, 1))
    diff = level_a.ground_calibrate(b, t, without) - level_a.ground_calibrate(b, t, cal)
    # written out by hand: B_m grows by -B_res; the z row of omega0 sigma is
    # omega0[2, 2] sigma_z with omega0[2, 2] = 1 within 1e-6 for the flight angles, so
    # diff_z = -sigma_z(T) B_res_z; y gets -sigma_y B_res_y plus omega0[1, 2] (~1e-3) times
    # the 21.9 nT of z, < 0.05 nT
    sigma = cal.sensitivity[0] + cal.sensitivity[1] * t[:, None]
    np.testing.assert_allclose(diff[:, 2], -sigma[:, 2] * cal.residual_field[2], atol=1e-3)
    np.testing.assert_allclose(diff[:, 1], -sigma[:, 1] * cal.residual_field[1], atol=0.05)
    assert np.abs(diff[:, 2]).max() == pytest.approx(z_nt, abs=0.05)


def test_reduced_temperature_switch(tmp_path, pool):
    """T~ = T^c (default) or T^c - T^O: with a daily slope p1 (nT/C) LEVEL_A moves by
    -p1 * (-T^O) = -p1 * 2.7 C for OB.  Before the switch: no change."""
    cal = calib.load_ground_calibration("OB")
    minus = _switched(cal, tmp_path, reduced_temperature="CALIBRATED_MINUS_T_OFF")
    assert minus.reduced_temperature == "CALIBRATED_MINUS_T_OFF"
    assert cal.thermistor_offset == -2.7  # seed 003 sec. 3.3.3, T^O_OB
    coeffs = np.zeros((6, 3))
    coeffs[0] = [3.0, -4.0, 5.0]
    coeffs[1] = [0.2, -0.1, 0.05]  # nT/C
    day = np.datetime64("2014-08-01")
    models = {day: DailyOffsetModel(day, "OB", coeffs, "model")}
    words = np.linspace(9000, 14000, 50).astype(int)  # about -110 .. -40 C
    raw = io.read_science_csv(
        write_raw_csv(tmp_path / "raw.csv", "2014-08-01T10:00:00", 50, 1.0, t_words=words), "OB"
    )
    nom, ts = calib.load_nominal_conversion(), calib.load_time_shift_table()
    a0 = level_a.level_a(raw, cal, ts, nom, daily_models=models)
    a1 = level_a.level_a(raw, minus, ts, nom, daily_models=models)
    np.testing.assert_allclose(
        a1["b"].values - a0["b"].values, np.tile(-coeffs[1] * 2.7, (50, 1)), atol=1e-9
    )
    assert a1.attrs["extended_model_temperature"] == "CALIBRATED_MINUS_T_OFF"


def test_switch_values_are_checked(tmp_path):
    text = calib.default_dir().joinpath(calib.GROUND_FILE["OB"]).read_text()
    bad = tmp_path / "bad.TXT"
    bad.write_text(text + "REDUCED_TEMPERATURE = KELVIN\n")
    with pytest.raises(CalibrationError, match="REDUCED_TEMPERATURE"):
        calib.read_ground_calibration(bad)
    bad.write_text(text + "B_RES_IN_OFFSET = yes\n")
    with pytest.raises(CalibrationError, match="B_RES_IN_OFFSET"):
        calib.read_ground_calibration(bad)
