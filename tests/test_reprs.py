"""Short, useful reprs of calibration objects and kernel pools (issue 25).

Before: ``MessengerCalibration`` printed hundreds of lines of arrays and ``KernelPool`` an
address. The facts checked come from the procedures (tau = 872 s, MESSENGER procedure
sec. 7; the Normal-mode shift 8.2 s, Rosetta procedure sec. 4.2.3.5) and the file names.
"""

from __future__ import annotations

import pytest

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.rosetta import calib

LIMIT = 300


def _short(obj) -> str:
    text = repr(obj)
    assert len(text) < LIMIT and text.count("\n") <= 2, text
    return text


def test_messenger_calibration_names_tables_versions_and_constants():
    text = _short(load_calibration("2012-06-01"))
    assert text.startswith("MessengerCalibration(v1: latency")
    for table in ("offsets_temperature", "offsets_duty_cycle", "gain_matrix", "processing"):
        assert table in text
    assert "[packaged]" in text and "tau 872.0 s" in text and "heater delay 10.0 s" in text
    assert "valid 2004-08-03 .. 2015-05-01" in text


def test_messenger_calibration_from_another_folder_names_the_folder(tmp_path):
    import shutil

    from fluxcal.missions.messenger.calibration_data import data_dir

    folder = tmp_path / "fitted"
    shutil.copytree(data_dir(), folder)
    assert "[fitted/]" in _short(load_calibration("2012-06-01", folder))


def test_kernel_pool_names_its_kernels_and_counts_them(tmp_path):
    (tmp_path / "a.tls").write_text("")
    assert _short(KernelPool(tmp_path / "a.tls")) == (
        "KernelPool(not entered, 1 user kernels: [a.tls] +generic +fluxcal_frames)")
    with KernelPool([]) as pool:
        text = _short(pool)
        assert f"{len(pool.loaded)} kernels loaded" in text
        assert pool.loaded[0].name in text and "de421.bsp" in text
        if len(pool.loaded) > 4:
            assert f"(+{len(pool.loaded) - 4})" in text


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_rosetta_ground_calibration(sensor):
    text = _short(calib.load_ground_calibration(sensor))
    assert text.startswith(f"GroundCalibration({sensor}, RPCMAG_001_CALIB_FSDPU_FM{sensor}.TXT")
    assert "valid " in text and "B_RES_IN_OFFSET=" in text and "REDUCED_TEMPERATURE=" in text


def test_rosetta_tables():
    assert "SID2 8.2" in _short(calib.load_time_shift_table())
    assert "PLACEHOLDER" in _short(calib.load_alignment())  # the shipped one is a placeholder
    jumps = calib.load_offset_jump_table()
    assert f"{len(jumps.start_utc)} intervals" in _short(jumps)


def test_rosetta_daily_model(tmp_path):
    path = tmp_path / "RPCMAG_140801_006_CALIB_OB.TXT"
    path.write_text("SENSOR = OB\n" + "".join(f"P_{k} = 0.0 0.0 0.0\n" for k in range(6)))
    text = _short(calib.read_daily_offset_model(path))
    assert text == f"DailyOffsetModel(2014-08-01, OB, degree 5, {path.name})"


def test_batch_report_and_day_status():
    from fluxcal.runs.batch import BatchReport, DayStatus

    days = [DayStatus("2012-06-01", "done", ["a.cdf", "b.cdf"], 1000, 2.5),
            DayStatus("2012-06-02", "failed", error="x.csv, line 3, field bx: not a number",
                      traceback="Traceback ...\n" * 200),
            DayStatus("2012-06-03", "skipped")]
    report = BatchReport("messenger", days, 12.34, "local", 2, "/very/long/out/report.json")
    text = _short(report)
    assert text.startswith("BatchReport(messenger: 3 days: 1 done, 1 skipped, 0 no_data, "
                           "1 failed (2012-06-02)")
    assert "1000 vectors in 12.3 s on local, 2 workers; report out/report.json" in text
    failed = _short(days[1])
    assert "2012-06-02 failed" in failed and "field bx: not a number" in failed
    assert "Traceback" not in failed
    assert _short(days[0]) == "DayStatus(2012-06-01 done, 1000 vectors, 2 products, 2.5 s)"
