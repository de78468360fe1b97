"""Calibration files: shipped defaults match the seed tables; bad files fail clearly."""

from pathlib import Path

import numpy as np
import pytest

from fluxcal.errors import CalibrationError
from fluxcal.missions.rosetta import calib

DATA = calib.default_dir()


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_default_ground_files_parse(sensor):
    cal = calib.load_ground_calibration(sensor)
    assert cal.sensor == sensor
    assert cal.offset.shape == (2, 3) and cal.k_inverse.shape == (3, 3)
    assert cal.version == "001"


# seed 003 sec. 3.3.1 (IB) and 3.3.2 (OB) tables, copied by hand from the document
SEED = {
    "OB": dict(
        a0=[214.5, -79.9, 384.7],
        a1=[-1.053, 0.073, -1.657],
        res=[0.0, 4.0, -20.0],
        s00=[1.09100, 1.09352, 1.09289],
        s01=[-1.18e-5, -8.21e-6, -6.97e-6],
        xi0=[90.0666, 90.0366, 90.0370],
        xi1=[-6.04e-5, -1.11e-4, -8.12e-5],
        kinv=[[1, -0.00010, 0.00028], [0, 1, -0.00038], [0, 0, 1]],
        toff=-2.7,
    ),
    "IB": dict(
        a0=[114.3, -119.8, 494.0],
        a1=[-0.565, 0.731, -1.673],
        res=[-2.0, 2.0, -15.0],
        s00=[1.09070, 1.09434, 1.09413],
        s01=[-1.42e-5, -9.30e-6, -8.55e-6],
        xi0=[90.0348, 89.9587, 89.9433],
        xi1=[8.54e-5, 3.71e-5, 1.20e-4],
        kinv=[[1, -0.00017, 0.00031], [0, 1, -0.00008], [0, 0, 1]],
        toff=-1.5,
    ),
}


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_default_values_are_the_seed_tables(sensor):
    cal = calib.load_ground_calibration(sensor)
    s = SEED[sensor]
    np.testing.assert_array_equal(cal.offset, [s["a0"], s["a1"]])
    np.testing.assert_array_equal(cal.residual_field, s["res"])
    np.testing.assert_array_equal(cal.sensitivity, [s["s00"], s["s01"]])
    np.testing.assert_array_equal(cal.angles, [s["xi0"], s["xi1"]])
    np.testing.assert_array_equal(cal.k_inverse, s["kinv"])
    np.testing.assert_array_equal(cal.thermistor, [-368.61072, 458.49304, -356.02890, 180.00644])
    assert cal.thermistor_offset == s["toff"]


def _write(tmp_path, text, name="RPCMAG_001_CALIB_FSDPU_FMOB.TXT"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _default_text(sensor="OB"):
    return (DATA / calib.GROUND_FILE[sensor]).read_text()


def test_missing_key_is_named(tmp_path):
    text = "\n".join(
        line for line in _default_text().splitlines() if not line.startswith("SIGMA_01")
    )
    with pytest.raises(CalibrationError, match="missing key SIGMA_01"):
        calib.read_ground_calibration(_write(tmp_path, text))


def test_wrong_count_names_line(tmp_path):
    text = _default_text().replace("A_1 = -1.053 0.073 -1.657", "A_1 = -1.053 0.073")
    with pytest.raises(CalibrationError, match=r"line \d+: key A_1 has 2 value\(s\), expected 3"):
        calib.read_ground_calibration(_write(tmp_path, text))


def test_non_numeric_value(tmp_path):
    text = _default_text().replace("T_OFF = -2.7", "T_OFF = cold")
    with pytest.raises(CalibrationError, match="T_OFF has a non-numeric"):
        calib.read_ground_calibration(_write(tmp_path, text))


def test_unknown_sensor(tmp_path):
    text = _default_text().replace("SENSOR = OB", "SENSOR = MID")
    with pytest.raises(CalibrationError, match="unknown RPC-MAG sensor 'MID'"):
        calib.read_ground_calibration(_write(tmp_path, text))
    with pytest.raises(CalibrationError, match="unknown RPC-MAG sensor"):
        calib.load_ground_calibration("XB")


def test_sensor_mismatch(tmp_path):
    with pytest.raises(CalibrationError, match="SENSOR = OB, but sensor IB"):
        calib.read_ground_calibration(_write(tmp_path, _default_text()), "IB")


def test_dotted_keys_accepted(tmp_path):
    # the seed names the keys both A.0 and A_0 (sec. 3.3.1.1 vs 3.3.2.1)
    text = _default_text().replace("A_0 =", "A.0 =").replace("XI_10 =", "XI.10 =")
    cal = calib.read_ground_calibration(_write(tmp_path, text))
    assert cal.offset[0, 0] == 214.5 and cal.angles[0, 0] == 90.0666


def test_user_dir_overrides_default(tmp_path):
    text = _default_text().replace("A_0 = 214.5", "A_0 = 200.0")
    _write(tmp_path, text)
    assert calib.load_ground_calibration("OB", tmp_path).offset[0, 0] == 200.0
    assert calib.load_ground_calibration("IB", tmp_path).offset[0, 0] == 114.3  # default


def test_ground_round_trip_writer(tmp_path):
    cal = calib.load_ground_calibration("IB")
    back = calib.read_ground_calibration(calib.write_ground_calibration(cal, tmp_path / "x.TXT"))
    np.testing.assert_array_equal(back.angles, cal.angles)
    np.testing.assert_array_equal(back.k_inverse, cal.k_inverse)


def test_daily_file(tmp_path):
    coeffs = np.arange(18.0).reshape(6, 3)
    model = calib.DailyOffsetModel(np.datetime64("2014-08-01"), "OB", coeffs)
    path = calib.write_daily_offset_model(model, tmp_path)
    assert path.name == "RPCMAG_140801_006_CALIB_OB.TXT"
    found = calib.find_daily_offset_models(tmp_path, "OB")
    assert list(found) == [np.datetime64("2014-08-01")]
    np.testing.assert_array_equal(found[np.datetime64("2014-08-01")].coefficients, coeffs)
    assert calib.find_daily_offset_models(tmp_path, "IB") == {}


def test_daily_file_missing_p5(tmp_path):
    path = tmp_path / "RPCMAG_140801_006_CALIB_IB.TXT"
    path.write_text("\n".join(f"P_{k} = 0 0 0" for k in range(5)))
    with pytest.raises(CalibrationError, match="missing key P_5"):
        calib.read_daily_offset_model(path)


def test_alignment_default_is_placeholder_rotation():
    al = calib.load_alignment()
    assert al.placeholder
    for sensor in ("OB", "IB"):
        for boom in ("deployed", "stowed"):
            np.testing.assert_array_equal(al.matrix(sensor, boom), np.eye(3))


def test_alignment_rejects_non_rotation(tmp_path):
    path = tmp_path / calib.ALIGN_FILE
    rows = {f"{s}_{b}": "1 0 0 0 1 0 0 0 1" for s in ("OB", "IB") for b in ("DEPLOYED", "STOWED")}
    rows["IB_STOWED"] = "2 0 0 0 1 0 0 0 1"
    path.write_text("\n".join(f"{k} = {v}" for k, v in rows.items()))
    with pytest.raises(CalibrationError, match="IB_STOWED is not a rotation"):
        calib.read_alignment(path)
    rows["IB_STOWED"] = "1 0 0 0 1 0 0 0"
    path.write_text("\n".join(f"{k} = {v}" for k, v in rows.items()))
    with pytest.raises(CalibrationError, match="IB_STOWED has 8 value"):
        calib.read_alignment(path)


def test_time_shift_table_is_the_seed_table():
    t = calib.load_time_shift_table()
    # seed 003 sec. 4.2.3.5, both tables
    np.testing.assert_array_equal(t.sid, [1, 2, 3, 4, 5, 6])
    np.testing.assert_array_equal(t.primary, [223.7, 8.2, 0, 1.35, 27.7, 0])
    np.testing.assert_array_equal(t.secondary[:5], [1023.95, 31.95, 15.95, 31.95, 127.95])
    assert np.isnan(t.secondary[5])


# Seed 003 Appendix B, transcribed verbatim: OFFSET_JUMP (identical in B.1 and B.2) and the
# JUMP_SUM_{OB,IB}_{X,Y,Z} lists (nT), one value per interval.
APPENDIX_B_INTERVALS = [
    ("2004-01-01T00:00:00", "2012-01-01T00:00:00"),
    ("2014-01-01T00:00:00", "2014-03-27T05:00:00"),
    ("2014-04-16T22:00:00", "2014-04-17T07:00:00"),
    ("2014-05-09T15:00:00", "2014-05-20T11:00:00"),
    ("2014-05-23T14:00:00", "2014-06-03T10:00:00"),
    ("2014-06-06T03:00:00", "2014-06-17T10:00:00"),
    ("2014-06-20T02:00:00", "2014-07-01T08:00:00"),
    ("2014-07-04T02:00:00", "2014-07-08T08:00:00"),
    ("2014-07-11T02:00:00", "2014-07-15T02:00:00"),
    ("2014-07-18T02:00:00", "2014-07-22T02:00:00"),
    ("2014-07-25T02:00:00", "2014-09-13T03:00:00"),
    ("2014-09-15T14:00:00", "2014-10-01T15:00:00"),
    ("2014-10-02T08:00:00", "2014-10-30T02:00:00"),
    ("2014-10-30T04:00:00", "2014-11-12T08:35:00"),
    ("2014-11-12T08:35:00", "2014-11-13T00:00:00"),
    ("2014-11-13T00:00:00", "2015-01-14T09:00:00"),
    ("2015-01-17T00:00:00", "2015-01-18T10:00:00"),
    ("2015-01-18T11:00:00", "2015-02-14T13:10:00"),
    ("2015-02-14T13:10:00", "2018-01-01T00:00:00"),
]
# fmt: off
APPENDIX_B_JUMPS = {
    "OB": [
        [0.000, -0.6443, -0.6443, 0.5954, -2.0896, -1.3826, 0.6297, -0.1665, -0.5286, -0.4732,
         -1.4364, 9.0744, 8.4542, 8.2876, -7.8000, -8.5240, -8.5240, -8.5240, -4.52],
        [0.000, 0.7116, -1.2884, 0.6396, -3.3906, 0.1758, 4.5775, 7.3484, 7.3515, -3.6564,
         -0.2041, 12.3533, 14.9331, 13.2751, 8.9000, 9.2652, 9.2652, 9.2652, 25.26],
        [0.000, -2.2752, 1.7248, 3.3307, 1.8250, 0.7866, 1.4086, 1.0691, -1.7854, -0.0780,
         -0.6965, -5.1818, -2.3597, -4.4664, -15.7000, -9.5247, -9.5247, -9.5247, -5.52],
    ],
    "IB": [
        [0.000, 0.4322, 0.4322, 2.3403, 0.0904, 0.0904, 0.2279, 3.0616, 3.0616, 1.1037,
         -1.0137, 2.1689, 2.1689, 2.1689, -7.5000, -8.7412, -8.7412, -8.7412, -13.74],
        [0.000, 0.8046, 1.9944, 12.9253, 6.7833, 0.7486, 4.3631, 16.1721, 8.0264, 3.2022,
         -9.8093, 8.6587, 4.3783, 4.3783, 3.8000, 7.5576, 7.5576, 7.5576, -0.4424],
        [0.000, -0.4443, -0.7393, -4.5484, -4.5484, -2.0144, -2.0144, -4.1340, -3.1969,
         -3.1718, 1.1286, -6.5916, -6.5916, -12.3560, -13.3000, -19.2265, -19.2265, -19.2265,
         0.7735],
    ],
}
# fmt: on


def test_offset_jump_table_is_appendix_b():
    t = calib.load_offset_jump_table()
    # every interval and every value of seed 003 Appendix B.1 (OB) and B.2 (IB); the last
    # JUMP_SUM_IB_Z value (0.7735) is on the document's final line
    assert list(zip(t.start_utc, t.end_utc, strict=True)) == APPENDIX_B_INTERVALS
    for sensor in ("OB", "IB"):
        np.testing.assert_array_equal(t.jumps[sensor], np.transpose(APPENDIX_B_JUMPS[sensor]))
    assert np.isfinite(t.jumps["IB"]).all() and np.isfinite(t.jumps["OB"]).all()


def test_missing_file_in_both_places(tmp_path):
    with pytest.raises(CalibrationError, match="found neither"):
        calib.resolve("NOPE.TXT", tmp_path)


def test_repeated_key(tmp_path):
    path = _write(tmp_path, _default_text() + "\nA_0 = 1 2 3\n")
    with pytest.raises(CalibrationError, match="key A_0 repeated"):
        calib.read_ground_calibration(path)


def test_validity(tmp_path):
    cal = calib.load_ground_calibration("OB")
    cal.validity.check(np.datetime64("2014-08-01"), np.datetime64("2014-08-02"))
    from fluxcal.errors import CalibrationRangeError

    with pytest.raises(CalibrationRangeError):
        cal.validity.check(np.datetime64("2017-01-01"), np.datetime64("2017-01-02"))


def test_data_files_have_header_citation():
    for name in (
        *calib.GROUND_FILE.values(),
        calib.ALIGN_FILE,
        calib.TIMESHIFT_FILE,
        calib.JUMPS_FILE,
    ):
        head = Path(DATA / name).read_text()[:1500]
        assert "seed 003" in head and "version" in head.lower() and "valid" in head.lower(), name


# --- the generic calibration store (issue 20 item 5) -----------------------------------
def test_shipped_files_carry_the_store_header():
    """Every shipped file gives the store a version and a validity (one header format)."""
    store = calib.calibration_store()
    for header in store.tables()[: len(store.names)]:
        assert header.version is not None and header.valid_from is not None, header
        assert header.valid_to is not None, header
        assert header.path.parent == DATA


def test_environment_folder_and_list_command(tmp_path, monkeypatch, capsys):
    import shutil

    from fluxcal.cli import main

    shutil.copy(DATA / calib.GROUND_FILE["OB"], tmp_path / "RPCMAG_GND_CALIB_FSDPU_FMOB.ASC")
    monkeypatch.setenv("FLUXCAL_CALIBRATION_DIR", str(tmp_path))
    assert calib.load_ground_calibration("OB").source == str(
        tmp_path / "RPCMAG_GND_CALIB_FSDPU_FMOB.ASC")
    assert calib.load_ground_calibration("IB").source == str(DATA / calib.GROUND_FILE["IB"])
    assert main(["rosetta", "list-calibration"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("* RPCMAG_001_CALIB_FSDPU_FMOB.TXT")
    assert f"{tmp_path.name}/RPCMAG_GND_CALIB_FSDPU_FMOB.ASC" in out[0]
    assert out[-1].startswith("  RPCMAG_001_CALIB_FSDPU_FMOB.TXT")  # the hidden default
