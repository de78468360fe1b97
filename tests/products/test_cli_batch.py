from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import pytest

from fluxcal.cli import main
from fluxcal.runs.batch import day_range
from fluxcal.runs.synthetic_task import input_path, write_synthetic_inputs


def test_cli_batch_failure_exit_code_and_rerun(tmp_path: Path) -> None:
    days = day_range(dt.date(2024, 2, 27), dt.date(2024, 3, 1))  # crosses a leap day
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, days, n_per_day=50)
    input_path(inp, days[1]).write_text("epoch_ns,cx,cy,cz\n1,2,3\n")  # a short row
    args = ["batch", "synthetic", "--start", "2024-02-27", "--end", "2024-03-01",
            "--input", str(inp), "--out", str(out), "--scheduler", "serial", "--quiet"]
    assert main(args) == 1
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert [d["status"] for d in report["days"]] == ["done", "failed", "done", "done"]
    assert "SYNTH_20240228.csv" in report["days"][1]["error"]
    write_synthetic_inputs(inp, [days[1]], n_per_day=50)
    assert main(args) == 0
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert [d["status"] for d in report["days"]] == ["skipped", "done", "skipped", "skipped"]
    assert main([*args, "--force"]) == 0
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert report["counts"]["done"] == 4


def test_cli_batch_bad_dates(tmp_path: Path) -> None:
    args = ["batch", "synthetic", "--start", "2024-03-02", "--end", "2024-03-01",
            "--input", str(tmp_path), "--out", str(tmp_path / "o"), "--scheduler", "serial"]
    assert main(args) != 0
    assert main([*args[:3], "2024-13-01", *args[4:]]) != 0


def test_cli_batch_unknown_mission(tmp_path: Path) -> None:
    args = ["batch", "voyager", "--start", "2024-03-01", "--end", "2024-03-01",
            "--input", str(tmp_path), "--out", str(tmp_path / "o")]
    assert main(args) == 2


def test_cli_batch_default_local_cluster(tmp_path: Path) -> None:
    days = day_range(dt.date(2024, 3, 1), dt.date(2024, 3, 2))
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, days, n_per_day=20)
    args = ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-02",
            "--input", str(inp), "--out", str(out), "--workers", "1", "--formats", "nc",
            "--quicklook"]
    assert main(args) == 0
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert report["scheduler"].startswith("tcp://") and report["n_workers"] == 1
    assert sorted(p.name for p in out.glob("SYNTH_*")) == [
        "SYNTH_20240301.nc", "SYNTH_20240301_20240301.png",
        "SYNTH_20240302.nc", "SYNTH_20240302_20240302.png"]


def test_cli_batch_progress_and_summary_table(tmp_path: Path, capsys, monkeypatch) -> None:
    """Without --quiet: the rich progress bar, then a table of every day and the counts."""
    monkeypatch.setenv("COLUMNS", "200")  # rich's width when stderr is not a terminal
    monkeypatch.setenv("NO_COLOR", "1")  # plain text whatever the CI environment forces
    for var in ("FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE"):
        monkeypatch.delenv(var, raising=False)
    days = day_range(dt.date(2024, 3, 1), dt.date(2024, 3, 3))
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, days, n_per_day=40)
    input_path(inp, days[2]).write_text("epoch_ns,cx,cy\n1,2,3\n")  # a bad header
    args = ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-03",
            "--input", str(inp), "--out", str(out), "--scheduler", "serial"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "synthetic days" in err and "vectors/s" in err and "failures: 1" in err
    rows = {line.split("│")[1].strip(): line for line in err.splitlines()
            if line.count("│") >= 5 and "2024-03-0" in line}
    assert sorted(rows) == ["2024-03-01", "2024-03-02", "2024-03-03"]
    assert "done" in rows["2024-03-01"] and "40" in rows["2024-03-01"]
    assert "failed" in rows["2024-03-03"] and "InputFormatError" in rows["2024-03-03"]
    assert "2 done, 0 skipped, 0 no_data, 1 failed" in err
    assert str(out / "batch_report_synthetic.json") in err.replace("\n", "")


def test_cli_batch_rosetta_placeholder_alignment_warns(tmp_path: Path, capsys) -> None:
    """Before: the batch used the placeholder alignment without a word."""
    inp, out = tmp_path / "in", tmp_path / "out"
    inp.mkdir()
    args = ["batch", "rosetta", "--start", "2014-08-01", "--end", "2014-08-01",
            "--input", str(inp), "--out", str(out), "--scheduler", "serial", "--quiet",
            "--formats", "cdf"]
    assert main(args) == 0  # no data that day: nothing to compute, but the warning stands
    err = capsys.readouterr().err
    assert "PLACEHOLDER" in err and "RPCMAG_SC_ALIGN.TXT" in err
    missing = tmp_path / "no_calib"
    assert main([*args, "--calib", str(missing)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "--calib" in line and str(missing) in line


def test_second_batch_into_the_same_folder_refuses(tmp_path: Path, capsys) -> None:
    """Before: two batches deleted each other's temporaries ([Errno 2] ... .tmp.LBL)."""
    from fluxcal.runs.batch import LOCK_NAME, output_lock

    days = day_range(dt.date(2024, 3, 1), dt.date(2024, 3, 1))
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, days, n_per_day=20)
    args = ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-01",
            "--input", str(inp), "--out", str(out), "--scheduler", "serial", "--quiet"]
    out.mkdir()
    with output_lock(out):  # another run holds the folder (a second open file: flock refuses)
        assert main(args) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert "another fluxcal run" in line and str(out) in line
        assert not list(out.glob("SYNTH_*"))
    assert not (out / LOCK_NAME).exists()  # released and removed
    assert main(args) == 0
    assert not (out / LOCK_NAME).exists()


def test_temporaries_of_a_running_process_are_spared(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    from fluxcal.products.atomic import atomic_path, temporary_owner
    from fluxcal.runs.batch import clean_stale_temporaries

    with atomic_path(tmp_path / "P.TAB") as tmp:
        assert temporary_owner(tmp) == os.getpid()  # pid + random: unique per run
        tmp.write_text("x")
    assert temporary_owner(tmp_path / "P.TAB") is None
    alive = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    try:
        running = tmp_path / f".A.TAB.{alive.pid}.abcd1234.fluxcal-tmp.TAB"
        stale = tmp_path / f".B.TAB.{int(dead.stdout)}.abcd1234.fluxcal-tmp.TAB"
        # not fluxcal's pattern (a user's file, or a pre-0.x name): never removed
        other = tmp_path / ".C.TAB.abcd1234.tmp.TAB"
        for p in (running, stale, other):
            p.write_text("x")
        removed = clean_stale_temporaries(tmp_path)
        assert removed == [stale]
        assert running.exists() and other.exists()
    finally:
        alive.kill()
        alive.wait()


def test_simulate_rosetta_batch_layout_is_read_by_batch(tmp_path: Path, capsys) -> None:
    """Before: simulate wrote a layout that 'fluxcal batch' could not read."""
    sim, out = tmp_path / "sim", tmp_path / "out"
    assert main(["simulate", "rosetta", "--layout", "batch", "--days", "2", "--start",
                 "2014-08-01T10:00:00", "--hours", "0.03", "--out", str(sim)]) == 0
    assert "fluxcal batch rosetta" in capsys.readouterr().out
    assert (sim / "20140802" / "science_OB.csv").is_file() and (sim / "kernels.tm").is_file()
    assert main(["batch", "rosetta", "--start", "2014-08-01", "--end", "2014-08-02",
                 "--input", str(sim), "--out", str(out), "--scheduler", "serial",
                 "--quiet"]) == 0
    report = json.loads((out / "batch_report_rosetta.json").read_text())
    assert report["counts"]["done"] == 2
    # a day crossing midnight is refused before anything is written
    assert main(["simulate", "rosetta", "--layout", "batch", "--start",
                 "2014-08-01T23:00:00", "--hours", "2", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_batch_formats_png_is_messenger_only_and_checked_first(tmp_path: Path, capsys) -> None:
    """``png`` (the MESSENGER offset report's figure) is a format of messenger batches only."""
    from fluxcal.missions.messenger.batch_task import make_day_task
    from fluxcal.missions.messenger.options import MessengerOptions
    from fluxcal.runs.options import from_command_line

    out = tmp_path / "out"
    for mission in ("rosetta", "synthetic"):
        args = ["batch", mission, "--start", "2024-03-01", "--end", "2024-03-01",
                "--input", str(tmp_path), "--out", str(out), "--scheduler", "serial",
                "--formats", "cdf,png"]
        assert main(args) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert "'png'" in line and "--formats" in line
    from fluxcal.products.writer import FORMATS
    from fluxcal.runs.batch import accepted_formats

    assert accepted_formats("rosetta") == accepted_formats("synthetic") == FORMATS
    assert accepted_formats("messenger") == (*FORMATS, "png")
    assert from_command_line(MessengerOptions, {"formats": "CDF, png"}).formats == ("cdf", "png")
    assert MessengerOptions().formats == ("tab", "cdf", "png")  # the task's default
    assert make_day_task(tmp_path, out).options.formats == ("tab", "cdf", "png")
    assert make_day_task(tmp_path, out, formats=["cdf"]).options.formats == ("cdf",)
    # the task itself refuses an unknown format before looking for the day's files
    from fluxcal.errors import InputFormatError

    with pytest.raises(InputFormatError, match="pgn"):
        make_day_task(tmp_path, out, formats=["pgn"])(dt.date(2024, 3, 1))
