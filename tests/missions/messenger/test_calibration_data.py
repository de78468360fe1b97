"""Every seed table reproduced from its data file (spot values typed from the seed)."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from fluxcal.calibration.offsets import breakpoint_temperature, two_segment_offset
from fluxcal.errors import CalibrationError, CalibrationRangeError
from fluxcal.missions.messenger.calibration_data import load_calibration, resolve_table

SEED = Path(__file__).resolve().parents[3] / ".." / "shared" / "seeds" / "000_dc13c776705c8c22.txt"


@pytest.fixture(scope="module")
def cal():
    return load_calibration("2012-06-01")


# Table 1 (sec. 5): rate setting -> (sample rate, net lag)
@pytest.mark.parametrize(
    ("rate", "hz", "lag"),
    [(0, 0.01, 2.358), (3, 0.10, 2.358), (6, 1.0, 2.358), (7, 2.0, 1.186), (8, 5.0, 0.477),
     (9, 10.0, 0.223), (10, 20.0, 0.042)],
)
def test_table1(cal, rate, hz, lag):
    assert cal.sample_rate_hz[rate] == pytest.approx(hz)
    assert cal.net_lag_s[rate] == pytest.approx(lag)


# Table 2 (sec. 7)
@pytest.mark.parametrize(
    ("axis", "a0", "b0", "a1", "b1", "tm"),
    [(0, -10.802, 1.2043, 2.8435, 2.5445, -10.1817), (1, -76.138, 2.042, -18.176, 6.6181, -12.6662),
     (2, 432.27, 0.45175, 455.4, 2.016, -14.7866)],
)
def test_table2_and_eq4(cal, axis, a0, b0, a1, b1, tm):
    np.testing.assert_array_equal(cal.temperature_coefficients[axis], [a0, b0, a1, b1])
    assert cal.breakpoint_temperature_c[axis] == tm
    # eq. 4 reproduces the printed T_m to its last printed digit (1e-4 degC)
    assert breakpoint_temperature(cal.temperature_coefficients)[axis] == pytest.approx(tm, abs=1e-4)


def test_two_segment_continuous_at_tm(cal):
    tm = breakpoint_temperature(cal.temperature_coefficients)
    for axis in range(3):
        lo = two_segment_offset(np.array([tm[axis] - 1e-9]), cal.temperature_coefficients)[0, axis]
        hi = two_segment_offset(np.array([tm[axis] + 1e-9]), cal.temperature_coefficients)[0, axis]
        assert lo == pytest.approx(hi, abs=1e-6)


# Table 3 and eq. 5a: the intercept C0 equals cT(-50 C) of Table 2.
# cT(-50) = A0 - 50 B0 = -71.017, -178.238, 409.6825; Table 3 prints -71.0, -178.2, 409.7,
# i.e. the same numbers rounded to 0.1 count: tolerance 0.05 count (half the last digit).
@pytest.mark.parametrize(("axis", "c0", "d0"), [(0, -71.0, 0.17885), (1, -178.2, 0.32851),
                                                (2, 409.7, 0.01477)])
def test_table3_intercept_is_ct_minus50(cal, axis, c0, d0):
    assert cal.duty_cycle_c0[axis] == c0
    assert cal.duty_cycle_d0[axis] == d0
    ct = two_segment_offset(np.array([-50.0]), cal.temperature_coefficients)[0, axis]
    assert ct == pytest.approx(c0, abs=0.05)


# sec. 7: the duty-cycle law is anchored at the regulated -50 C (C0 = cT(-50 C)); the
# packaged processing file states it, a file that leaves it out gets the seed's value
def test_reference_temperature_is_the_seeds_minus50(cal):
    assert cal.reference_temperature_c == -50.0
    rel = {k: v for k, v in cal.constants["relaxation"].items()
           if k != "reference_temperature_c"}
    bare = dataclasses.replace(cal, constants={**cal.constants, "relaxation": rel})
    assert bare.reference_temperature_c == -50.0
    moved = dataclasses.replace(cal, constants={
        **cal.constants, "relaxation": {**rel, "reference_temperature_c": -45.0}})
    assert moved.reference_temperature_c == -45.0


# Table 4 (sec. 8)
def test_table4(cal):
    fine, coarse = cal.matrices
    assert fine[0, 0] == 0.046769 and fine[1, 1] == 0.046673 and fine[2, 2] == 0.047997
    assert coarse[0, 0] == 1.56513 and coarse[1, 1] == 1.56419 and coarse[2, 2] == 1.61029
    assert fine[1, 0] == pytest.approx(-0.00462 * 0.046769)
    assert fine[2, 0] == pytest.approx(0.00053 * 0.046769)
    assert coarse[2, 1] == pytest.approx(-0.00736 * 1.56419)
    np.testing.assert_array_equal(cal.prelaunch_offsets[0], [-1017, -2520, -544])
    np.testing.assert_array_equal(cal.prelaunch_offsets[1], [-30.4, -75.2, -16.2])
    assert np.all(np.triu(fine, 1) == 0)


# Tables 6-8 (Appendix): spot values typed from the seed
@pytest.mark.parametrize(
    ("axis", "t", "col", "value"),
    [(0, 0, 0, -0.70727), (0, 4, 7, -0.04287), (0, 100, 7, 0.21793), (0, 83, 6, 1.80303),
     (1, 18, 0, -10.40830), (2, 99, 7, 0.70759), (1, 0, 3, -0.81213), (2, 75, 2, 0.87512)],
)
def test_heater_tables(cal, axis, t, col, value):
    assert cal.heater_signal[axis, t, col] == value


@pytest.mark.skipif(not SEED.is_file(), reason=f"seed document not found at {SEED}: put the "
                    "shared folder beside the checkout (../shared, see README)")
def test_heater_tables_match_seed_text(cal):
    """All 3 x 101 x 8 values equal the seed's, parsed independently (regex on the text)."""
    text = SEED.read_text()
    for axis, title in enumerate(["Table 6:", "Table 7:", "Table 8:"]):
        block = text[text.index(title):].split("t-sec", 1)[1].splitlines()[1:]
        rows = [ln.split() for ln in block if len(ln.split()) == 9]
        rows = [list(map(float, r[1:])) for r in rows[:101]]
        np.testing.assert_array_equal(cal.heater_signal[axis], np.array(rows))
    np.testing.assert_array_equal(cal.heater_duty_bins_percent, np.arange(12, 41, 4))
    # t = 100 repeats t = 0 (the waveform is periodic)
    np.testing.assert_array_equal(cal.heater_signal[:, 100], cal.heater_signal[:, 0])


def test_quality_dates(cal):
    assert cal.date("boom_deployment") == np.datetime64("2005-03-08T00:00:00")
    assert cal.date("heater_mode_v10") == np.datetime64("2007-03-09T00:00:00")


def test_outside_validity_raises():
    with pytest.raises(CalibrationRangeError, match="outside every validity interval"):
        load_calibration("2003-01-01")
    with pytest.raises(CalibrationRangeError):
        resolve_table("latency", "2016-01-01")


def test_highest_version_wins(tmp_path):
    from fluxcal.missions.messenger.calibration_data import data_dir

    src = (data_dir() / "latency_v1.csv").read_text()
    (tmp_path / "latency_v1.csv").write_text(src)
    v2 = src.replace("# version: 1", "# version: 2").replace(
        "# valid_from: 2004-08-03T00:00:00", "# valid_from: 2010-01-01T00:00:00"
    ).replace("10,20.0,0.0,0.042", "10,20.0,0.0,0.050")
    (tmp_path / "latency_v2.csv").write_text(v2)
    assert resolve_table("latency", "2009-01-01", tmp_path).version == 1
    assert resolve_table("latency", "2011-01-01", tmp_path).version == 2


# Table 4's pre-launch offsets: the calibration-file switch (issue 11, decision in
# docs/decisions/messenger.md)
def _with_reading(tmp_path, reading):
    import shutil

    from fluxcal.missions.messenger.calibration_data import data_dir

    for p in data_dir().iterdir():
        if p.suffix in (".csv", ".toml"):
            shutil.copy(p, tmp_path / p.name)
    src = (tmp_path / "processing_v1.toml").read_text()
    assert 'prelaunch_offsets = "not_applied"' in src
    v2 = src.replace("version = 1", "version = 2").replace(
        'prelaunch_offsets = "not_applied"', f'prelaunch_offsets = "{reading}"')
    (tmp_path / "processing_v2.toml").write_text(v2)
    return load_calibration("2012-06-01", tmp_path)


def test_prelaunch_offsets_not_applied_by_default(cal):
    assert cal.prelaunch_offsets_reading == "not_applied"
    np.testing.assert_array_equal(cal.offset_coefficients(), cal.temperature_coefficients)


def test_prelaunch_offsets_switch(tmp_path, cal):
    import xarray as xr

    from fluxcal.calibration.relaxation import DutyCycleChanges
    from fluxcal.missions.messenger import levels

    alt = _with_reading(tmp_path, "added_to_table2")
    assert alt.prelaunch_offsets_reading == "added_to_table2"

    class Clock:  # the temperature stream's met is already ET
        @staticmethod
        def to_et(partition, met):
            return np.asarray(met, dtype=float)

    et = np.array([4.0e8, 4.0e8 + 10.0, 4.0e8 + 20.0, 4.0e8 + 30.0])  # 2012-09 (V10)
    temps = np.array([-60.0, -10.0, 20.0, 35.0])  # both segments of every axis
    ds = xr.Dataset({"et": ("time", et), "counts": (("time", "component"), np.zeros((4, 3))),
                     "range": ("time", np.array([0, 0, 1, 1], dtype=np.int8)),
                     "heater_signal": (("time", "component"), np.zeros((4, 3)))})
    temp = xr.Dataset({"partition": ("t", np.ones(4)), "met": ("t", et),
                       "temperature_c": ("t", temps)})
    none = DutyCycleChanges(np.empty(0), np.empty(0))
    from fluxcal.geometry.kernels import KernelPool

    with KernelPool([]):  # the leapseconds kernel, for the V10 date
        a = levels.correct_offsets(ds, temp, none, cal, Clock())
        b = levels.correct_offsets(ds, temp, none, alt, Clock())
    # fine range: Table 4's fine counts exactly (closed form: A0/A1 + offset)
    np.testing.assert_allclose(b["offset_applied"].values[:2] - a["offset_applied"].values[:2],
                               np.tile([-1017.0, -2520.0, -544.0], (2, 1)), rtol=0, atol=1e-9)
    # coarse range: Table 4's coarse counts, to their printed 0.1-count rounding
    np.testing.assert_allclose(b["offset_applied"].values[2:] - a["offset_applied"].values[2:],
                               np.tile([-30.4, -75.2, -16.2], (2, 1)), rtol=0, atol=0.05)
    # in nT (eq. 8): Table 4's -48/-118/-26 nT (printed to 1 nT)
    fine = alt.matrices[0] @ np.array([-1017.0, -2520.0, -544.0])
    np.testing.assert_allclose(fine, [-48.0, -118.0, -26.0], atol=0.8)


def test_prelaunch_offsets_unknown_reading_is_an_error(tmp_path):
    with pytest.raises(CalibrationError, match="prelaunch_offsets"):
        _with_reading(tmp_path, "subtracted_twice")


# --- the generic calibration store (issue 20 item 5) -----------------------------------
def test_user_folder_overrides_one_table_and_keeps_the_packaged_others(tmp_path, cal):
    """A folder holding only Table 3 as v2 (D0 doubled by hand) changes only Table 3."""
    from fluxcal.missions.messenger.calibration_data import data_dir

    text = (data_dir() / "offsets_duty_cycle_v1.csv").read_text()
    text = text.replace("# version: 1", "# version: 2").replace("0.17885", "0.3577")
    (tmp_path / "offsets_duty_cycle_v2.csv").write_text(text)
    mine = load_calibration("2012-06-01", tmp_path)
    assert mine.duty_cycle_d0[0] == 0.3577 and mine.duty_cycle_d0[1] == 0.32851
    np.testing.assert_array_equal(mine.temperature_coefficients, cal.temperature_coefficients)
    assert ("offsets_duty_cycle_v2.csv", 2) in mine.files and ("latency_v1.csv", 1) in mine.files
    assert sum(p.parent == tmp_path for p in mine.paths) == 1


def test_environment_variable_names_the_user_folder(tmp_path, monkeypatch):
    from fluxcal.missions.messenger.calibration_data import data_dir

    text = (data_dir() / "latency_v1.csv").read_text().replace("# version: 1", "# version: 3")
    (tmp_path / "latency_v3.csv").write_text(text)
    monkeypatch.setenv("FLUXCAL_CALIBRATION_DIR", str(tmp_path))
    assert resolve_table("latency", "2012-06-01").path == tmp_path / "latency_v3.csv"
    monkeypatch.delenv("FLUXCAL_CALIBRATION_DIR")
    assert resolve_table("latency", "2012-06-01").path == data_dir() / "latency_v1.csv"


def test_list_calibration_command(tmp_path, capsys):
    from fluxcal.cli import main

    assert main(["messenger", "list-calibration", "--day", "2012-06-01"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 8 and all(line.startswith("* ") for line in lines)
    assert "offsets_temperature" in lines[1] and "v1" in lines[1] and "Table 2" in lines[1]
    assert main(["messenger", "list-calibration", "--calib", str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"fluxcal: error: {tmp_path / 'nope'}: the user calibration folder does not exist "
        "or is not a folder")


@pytest.mark.parametrize("cell", ["abc", "nan", "inf", ""])
def test_a_table_value_that_is_no_finite_number_is_one_error(tmp_path, capsys, cell):
    """A garbled number in a ``--calib`` table: one line naming file, line and column, exit
    2, before any input is read (entry 62; before, the column was kept as words and the
    run ended in an internal error, exit 1, when the law was evaluated)."""
    import shutil

    from fluxcal.cli import main
    from fluxcal.missions.messenger.calibration_data import data_dir

    calib = tmp_path / "calib"
    calib.mkdir()
    for p in data_dir().glob("*_v1.*"):
        shutil.copy(p, calib / p.name)
    table = calib / "offsets_temperature_v1.csv"
    lines = table.read_text().splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith("y,"))
    fields = lines[row].split(",")
    fields[3] = cell  # A1
    lines[row] = ",".join(fields)
    table.write_text("\n".join(lines) + "\n")
    with pytest.raises(CalibrationError, match=rf"line {row + 1}, column 'A1': "):
        load_calibration("2012-06-01", calib)
    out = tmp_path / "out"
    assert main(["messenger", "fit", "--input-dir", str(tmp_path / "missing"), "--calib",
                 str(calib), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fluxcal: error: "), err
    assert f"offsets_temperature_v1.csv: line {row + 1}, column 'A1': {cell!r}" in err, err
    assert not out.exists()
