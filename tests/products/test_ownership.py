"""A run owns only what it wrote (issue 22, docs/decisions/products.md decisions 52-57).

Each loss the issue reports, reproduced on small simulated inputs and shown gone:
two commands into one folder; a failing run next to a good product set; SIGINT /
SIGTERM during a run, then a rerun; SIGKILL, then a rerun; a full disk for every
format; Ctrl-C on a batch; a batch day against a single run on a day with samples
recorded just after midnight.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.errors import InputFormatError
from fluxcal.products.staging import LOCK_NAME, OutputFolderBusy, output_lock, owned_run

SRC = str(Path(__file__).resolve().parents[2] / "src")


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    """36 s of simulated Rosetta telemetry (0.01 h, ~700 OB vectors)."""
    folder = tmp_path_factory.mktemp("ownership") / "sim"
    assert main(["simulate", "rosetta", "--out", str(folder), "--hours", "0.01"]) == 0
    return folder


def _calibrate(sim: Path, out: Path, formats: str = "tab,cdf") -> list[str]:
    return ["rosetta", "calibrate", "--science", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
            "--sensor", "OB", "--calib", str(sim / "calib"), "--levels", "A,B,E,F",
            "--formats", formats, "--out", str(out)]


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture()
def good(sim: Path, tmp_path: Path) -> tuple[Path, dict[str, bytes]]:
    """A folder holding a complete, good product set, and its bytes."""
    out = tmp_path / "out"
    assert main(_calibrate(sim, out)) == 0
    snap = _snapshot(out)
    # 24 products and the run's report (index.html)
    assert len(snap) == 25 and "index.html" in snap
    assert not [n for n in snap if n.startswith(".")]
    return out, snap


def _one_line(capsys) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    return lines[0]


def test_a_second_run_into_a_held_folder_refuses_and_touches_nothing(sim, good, capsys):
    """Before: a failing edr2cdr 'cleaned up' (deleted) another run's fresh products."""
    out, snap = good
    with output_lock(out):  # a batch or another single run is writing into the folder
        assert main([*_calibrate(sim, out)[:-1], str(out)]) == 2
        line = _one_line(capsys)
        assert line.startswith("fluxcal: error: --out") and "another fluxcal run" in line
        snap_held = _snapshot(out)
    assert {k: v for k, v in snap_held.items() if k != LOCK_NAME} == snap
    assert _snapshot(out) == snap  # the lock file went with its holder


def test_a_batch_refuses_a_folder_a_single_run_holds(tmp_path):
    from fluxcal.runs.batch import run_batch

    with owned_run(tmp_path), pytest.raises(OutputFolderBusy, match="another fluxcal run"):
        run_batch([], lambda day: None, tmp_path, scheduler="serial")


def _fail_on_second_level(monkeypatch, action) -> None:
    """Make `level_products` run ``action`` after the first level of the run is written."""
    from fluxcal.missions.rosetta import products as rosetta_products

    original = rosetta_products.level_products
    calls = []

    def level_products(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            action()
        return original(*args, **kwargs)

    monkeypatch.setattr(rosetta_products, "level_products", level_products)


def test_a_failing_run_leaves_a_good_product_set_byte_equal(sim, good, capsys, monkeypatch):
    """Before: a rejected run replaced the LEVEL_A products, leaving old and new mixed."""
    out, snap = good

    def reject():
        raise InputFormatError("rejected half-way", path="x.csv", field="bx")

    _fail_on_second_level(monkeypatch, reject)
    assert main(_calibrate(sim, out)) == 2  # LEVEL_A is written (staged), then B fails
    assert "rejected half-way" in _one_line(capsys)
    assert _snapshot(out) == snap  # byte-equal, nothing new, no temporary, no lock


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_cleans_up_then_a_rerun_completes(sim, good, capsys, monkeypatch, sig):
    """Before: Ctrl-C skipped the clean-up (typer returned 130 first), SIGTERM had none."""
    out, snap = good
    _fail_on_second_level(monkeypatch, lambda: os.kill(os.getpid(), sig))
    assert main(_calibrate(sim, out)) == 128 + sig
    line = _one_line(capsys)
    assert line.startswith(f"fluxcal: interrupted: {signal.Signals(sig).name}")
    assert _snapshot(out) == snap
    fresh = out.parent / "fresh"  # a folder the interrupted run created goes entirely
    monkeypatch.undo()
    _fail_on_second_level(monkeypatch, lambda: os.kill(os.getpid(), sig))
    assert main(_calibrate(sim, fresh)) == 128 + sig
    assert not fresh.exists()
    monkeypatch.undo()
    assert main(_calibrate(sim, out)) == 0  # the rerun: a complete set, nothing else
    assert sorted(_snapshot(out)) == sorted(snap)


@pytest.mark.slow
def test_sigkill_leaves_temporaries_that_the_next_run_removes(sim, good, caplog):
    """Before: an OOM-killed edr2cdr left hidden .*.tmp.* files that no run removed."""
    out, snap = good
    script = textwrap.dedent(f"""
        import os, signal
        from fluxcal.missions.rosetta import products as rosetta_products
        from fluxcal.cli import main
        original, calls = rosetta_products.level_products, []
        def level_products(*args, **kwargs):
            calls.append(1)
            if len(calls) == 3:  # LEVEL_A and B staged under temporary names
                os.kill(os.getpid(), signal.SIGKILL)
            return original(*args, **kwargs)
        rosetta_products.level_products = level_products
        main({_calibrate(sim, out)!r})
    """)
    proc = subprocess.run([sys.executable, "-c", script], env={**os.environ, "PYTHONPATH": SRC},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    stale = [n for n in _snapshot(out) if n.startswith(".") and "fluxcal-tmp" in n]
    assert len(stale) >= 4, stale  # the killed run's staged products
    assert {k: v for k, v in _snapshot(out).items() if k in snap} == snap  # old set intact
    assert main(_calibrate(sim, out)) == 0
    assert sorted(_snapshot(out)) == sorted(snap)  # no temporary, no lock file left
    assert f"removed {len(stale)} stale temporary file(s) of an earlier, killed run" \
        in caplog.text


def _tmpfs(folder: Path, size: str) -> Path:
    folder.mkdir(parents=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                          capture_output=True)
    if done.returncode != 0:
        pytest.skip("a small tmpfs needs root (mount); the ENOSPC paths are also covered "
                    "by tests/test_cli_errors.py::test_full_disk_during_simulate_leaves_nothing")
    return folder


@pytest.fixture()
def full_disk(tmp_path):
    disk = _tmpfs(tmp_path / "disk", "1m")
    yield disk
    subprocess.run(["umount", str(disk)], check=False)


def _fill(disk: Path, leave: int) -> None:
    """Fill ``disk`` up to ``leave`` free bytes."""
    import shutil

    free = shutil.disk_usage(disk).free
    (disk / "filler").write_bytes(b"\0" * max(free - leave, 0))


@pytest.mark.parametrize("fmt", ["tab", "cdf", "nc", "zarr"])
def test_a_full_disk_is_one_line_and_keeps_the_old_products(sim, full_disk, capsys, fmt):
    """Before: a full disk while writing netCDF ended in a segmentation fault (exit 139)."""
    if fmt == "zarr":
        pytest.importorskip("zarr")
    out = full_disk / "out"
    assert main(_calibrate(sim, out, formats="tab,cdf")) == 0
    snap = _snapshot(out)
    _fill(full_disk, leave=16_384)
    assert main(_calibrate(sim, out, formats=fmt)) == 2
    line = _one_line(capsys)
    assert "No space left on device" in line and "free space" in line and str(out) in line
    assert _snapshot(out) == snap


@pytest.mark.slow
def test_a_full_disk_writing_netcdf_does_not_crash_the_process(sim, full_disk):
    """The segfault came at exit, after the error line: only a process shows it."""
    out = full_disk / "out"
    _fill(full_disk, leave=16_384)
    proc = subprocess.run([sys.executable, "-m", "fluxcal.cli", *_calibrate(sim, out, "nc")],
                          env={**os.environ, "PYTHONPATH": SRC}, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert "No space left on device" in line and ".nc" in line
    assert not out.exists()


@pytest.mark.slow
def test_ctrl_c_on_a_batch_prints_the_summary_and_writes_the_report(tmp_path):
    """Before: 64 lines of Dask worker tracebacks, no summary, no report."""
    import datetime as dt
    import json

    from fluxcal.runs.batch import day_range
    from fluxcal.runs.synthetic_task import write_synthetic_inputs

    days = day_range(dt.date(2024, 3, 1), dt.date(2024, 3, 30))
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, days, n_per_day=20_000)
    proc = subprocess.Popen(
        [sys.executable, "-m", "fluxcal.cli", "batch", "synthetic", "--start", "2024-03-01",
         "--end", "2024-03-30", "--input", str(inp), "--out", str(out), "--workers", "1",
         "--quiet"], env={**os.environ, "PYTHONPATH": SRC}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 90
    while not list(out.glob("SYNTH_*.cdf")) and proc.poll() is None:
        assert time.monotonic() < deadline, "no day finished in 90 s"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: the whole group
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the batch finished before the signal arrived")
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "distributed" not in err, err
    lines = err.strip().splitlines()
    assert "interrupted; report:" in lines[-2], err
    assert lines[-1].startswith("fluxcal: interrupted: SIGINT"), err
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert report["counts"]["interrupted"] >= 1  # a day done on the worker may not have
    # reached the report yet: its products stay, without a manifest, and a rerun redoes it
    assert sum(report["counts"].values()) == len(days)
    assert not list(out.rglob("*fluxcal-tmp*")) and not (out / LOCK_NAME).exists()


@pytest.mark.slow
def test_a_batch_day_equals_a_single_run_with_samples_after_midnight(tmp_path):
    """Before: the batch dropped the 2 samples recorded just after midnight (9,820 of 9,822)."""
    import datetime as dt
    import shutil

    from fluxcal.missions.messenger.batch_task import day_file, make_day_task
    from fluxcal.products import read_fluxcal_product
    from fluxcal.runs.batch import run_batch

    sim = tmp_path / "sim"
    assert main(["simulate", "messenger", "--out", str(sim), "--start", "2012-06-01T23:50:00",
                 "--duration", "600"]) == 0
    kernels = sim / "kernels" / "messenger_synthetic.tm"
    day = dt.date(2012, 6, 1)
    batch_in = tmp_path / "batch_in"
    batch_in.mkdir()
    for stream, code in (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP")):
        shutil.copy(sim / "inputs" / f"MAG_{stream}.csv", day_file(batch_in, code, day))
    n_science = len((sim / "inputs" / "MAG_science.csv").read_text().splitlines()) - 1

    single = tmp_path / "single"
    assert main(["messenger", "edr2cdr", "--sci", str(sim / "inputs" / "MAG_science.csv"),
                 "--heater", str(sim / "inputs" / "MAG_heater.csv"),
                 "--temperature", str(sim / "inputs" / "MAG_temperature.csv"),
                 "--kernels", str(kernels), "--out", str(single), "--formats", "tab",
                 "--average", "60", "--frames", "mso"]) == 0
    batch = tmp_path / "batch"
    task = make_day_task(batch_in, batch, kernels=kernels, formats=("tab",), frames=("mso",),
                         averages=(60,))
    report = run_batch([day], task, batch, scheduler="serial")
    assert report.days[0].status == "done" and report.n_vectors == n_science

    names = sorted(p.name for p in single.glob("*.TAB"))
    assert names == sorted(p.name for p in batch.glob("*.TAB"))
    for name in names:
        a, b = read_fluxcal_product(single / name), read_fluxcal_product(batch / name)
        assert a.sizes == b.sizes
        for var in a.data_vars:
            np.testing.assert_array_equal(a[var].values, b[var].values, err_msg=name)
    assert read_fluxcal_product(batch / "MAGMSOSCI12153_V01.TAB").sizes["time"] == n_science


def test_calibrate_f_and_clean_f_have_distinct_names():
    """Before: clean --level F (from K) replaced calibrate's F (from B) of the same day."""
    from fluxcal.missions.rosetta.products import logical_source, made_from, resampled_tab_stem

    day = np.datetime64("2014-08-01")
    assert made_from({}, "F") is None and made_from({"averaged_from": "LEVEL_B"}, "F") is None
    assert made_from({"averaged_from": "LEVEL_K"}, "F") == "K"
    assert made_from({"averaged_from": "LEVEL_L"}, "G") == "L"
    names = {resampled_tab_stem(day, "F", "OB", 1.0, made_from(a, "F"))
             for a in ({}, {"averaged_from": "LEVEL_K"})}
    assert names == {"RPCMAG140801_CLF_OB_A01", "RPCMAG140801_CLF_OB_A01_FROMK"}
    assert logical_source("F", "OB", 1.0, "K") == "rosetta_rpcmag_clf-ob-a01-fromk"
    assert logical_source("F", "OB", 1.0) == "rosetta_rpcmag_clf-ob-a01"


def test_enospc_names_the_product_not_the_temporary(tmp_path):
    from fluxcal.products.atomic import atomic_path

    with pytest.raises(OSError) as info, atomic_path(tmp_path / "P.TAB") as tmp:
        tmp.write_text("x")
        raise OSError(errno.ENOSPC, "Can't close file (HDF5 says a lot)")
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "P.TAB")
    assert info.value.strerror == os.strerror(errno.ENOSPC)
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_serial_batch_writes_its_report(tmp_path):
    import datetime as dt
    import json

    from fluxcal.products.staging import Interrupted, interrupt_signals
    from fluxcal.runs.batch import DayResult, run_batch

    days = [dt.date(2024, 3, d) for d in (1, 2, 3)]

    def task(day):
        if day == days[1]:
            os.kill(os.getpid(), signal.SIGTERM)
        return DayResult(day, [])

    with interrupt_signals(), pytest.raises(Interrupted) as info:
        run_batch(days, task, tmp_path, scheduler="serial", name="t")
    assert info.value.signum == signal.SIGTERM
    statuses = [d.status for d in info.value.batch_report.days]
    assert statuses == ["done", "interrupted", "interrupted"]
    report = json.loads((tmp_path / "batch_report_t.json").read_text())
    assert report["counts"]["interrupted"] == 2 and report["counts"]["done"] == 1
    assert not (tmp_path / LOCK_NAME).exists()
