from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from fluxcal.cli import main
from fluxcal.products.batch import day_range
from fluxcal.products.synthetic_task import input_path, write_synthetic_inputs


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
