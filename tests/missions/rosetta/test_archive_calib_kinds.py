"""Every calibration-file name of the RPC-MAG archive: recognised, read or refused in one line.

Names from the archive's ``CALIB/CALINFO.TXT`` (AST1 V3.0, ESC4 V6.0, EXT2 V9.0) and the
ESC4 corrigenda (issue 23, item 3).
"""

import shutil

import pytest

from fluxcal.cli import main
from fluxcal.errors import CalibrationError
from fluxcal.missions.rosetta import calib

READ = [
    "RPCMAG_GND_CALIB_FSDPU_FMIB.TXT",
    "RPCMAG_GND_CALIB_FSDPU_FMOB.ASC",
    "RPCMAG_140801_006_CALIB_OB.TXT",
    "RPCMAG_140801_006_CALIB_IB.ASC",
    "RPCMAG_SC_ALIGN.ASC",
]
REFUSED = {
    "RPCMAG_2014_08_PRL_008_CALIB_OB.ASC": "temperature model 008",
    "RPCMAG_2015_01_ESC1_008_CALIB_IB.ASC": "temperature model 008",
    "RPCMAG_phase_008_CALIB_IB.ASC": "temperature model 008",
    "RPCMAG_INFLIGHT_08_CALIB_OB.ASC": "temperature model 008",
    "INFCAL_PARA_OB_20180305_009.ASC": "temperature model 009 parameters",
    "INFCAL_PARA_IB_20180305_009.ASC": "temperature model 009 parameters",
    "INFCAL_OFF__OB_20180305_009.ASC": "temperature model 009 offsets",
    "INFCAL_OFF__IB_20180305_009.ASC": "temperature model 009 offsets",
    "RPCMAG_BOOM_ALIGN_CORR_EF1.ASC": "boom alignment correction",
    "RPCMAG_BOOM_ALIGN_CORR_EF1.TXT": "boom alignment correction",
}


@pytest.mark.parametrize("name", READ)
def test_read_kinds_are_recognised(name):
    kind = calib.archive_kind(name)
    assert kind is not None and kind.read
    assert calib.archive_kind(name.lower()) is kind


@pytest.mark.parametrize("name,kind", sorted(REFUSED.items()))
def test_refused_kinds_are_recognised(name, kind):
    found = calib.archive_kind(name)
    assert found is not None and found.kind == kind and not found.read


def test_labels_and_other_files_are_not_calibration_kinds():
    assert calib.archive_kind("RPCMAG_SC_ALIGN.LBL") is None
    assert calib.archive_kind("CALINFO.TXT") is None


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_folder_with_refused_file_is_one_line_naming_it(tmp_path, name):
    (tmp_path / name).write_text("1 2 3\n")
    with pytest.raises(CalibrationError) as err:
        calib.load_ground_calibration("OB", tmp_path)
    text = str(err.value)
    assert name in text and "not publicly documented" in text and "\n" not in text
    with pytest.raises(CalibrationError, match="not publicly documented"):
        calib.find_daily_offset_models(tmp_path, "IB")


def test_folder_with_only_read_kinds_is_accepted(tmp_path):
    shutil.copy(calib.default_dir() / calib.GROUND_FILE["OB"],
                tmp_path / "RPCMAG_GND_CALIB_FSDPU_FMOB.ASC")
    (tmp_path / "RPCMAG_GND_CALIB_FSDPU_FMOB.LBL").write_text("PDS_VERSION_ID = PDS3\n")
    cal = calib.load_ground_calibration("OB", tmp_path)
    assert cal.source.endswith("RPCMAG_GND_CALIB_FSDPU_FMOB.ASC")


@pytest.mark.parametrize("name", ["INFCAL_OFF__OB_20180305_009.ASC",
                                  "RPCMAG_2014_08_PRL_008_CALIB_OB.ASC",
                                  "RPCMAG_BOOM_ALIGN_CORR_EF1.ASC"])
def test_cli_refuses_with_exit_2_and_one_line(tmp_path, capsys, name):
    sim = tmp_path / "sim"
    assert main(["simulate", "rosetta", "--out", str(sim), "--hours", "0.01", "--seed", "3"]) == 0
    (sim / "calib" / name).write_text("0 0 0\n")
    capsys.readouterr()
    code = main(["rosetta", "calibrate", "--science", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
                 "--sensor", "OB", "--levels", "A", "--calib", str(sim / "calib"),
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and name in err and "not publicly documented" in err
    assert not any((tmp_path / "out").glob("*.TAB"))
