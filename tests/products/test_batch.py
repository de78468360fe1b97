"""Batch runner on a real 2-worker LocalCluster (one per module, ~5 s to start)."""

from __future__ import annotations

import datetime as dt
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from fluxcal.products import read_product
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.runs import registry
from fluxcal.runs.batch import (
    BatchReport,
    DayResult,
    day_range,
    is_up_to_date,
    make_local_cluster,
    manifest_path,
    run_batch,
    task_factory,
)
from fluxcal.runs.synthetic_task import (
    SyntheticDayTask,
    input_path,
    write_synthetic_inputs,
)

DAYS = day_range(dt.date(2024, 3, 1), dt.date(2024, 3, 5))
BAD = dt.date(2024, 3, 3)


@pytest.fixture(scope="module")
def cluster():
    c = make_local_cluster(2)
    yield c
    c.close()


def _corrupt(path: Path, line: int) -> None:
    lines = path.read_text().splitlines()
    lines[line - 1] = lines[line - 1].replace(",", ",1e", 1)  # '1e' is not an integer
    path.write_text("\n".join(lines) + "\n")


def _products(out: Path) -> list[str]:
    return sorted(p.name for p in out.glob("SYNTH_*.cdf"))


def _expected_field(input_dir: Path, day: dt.date) -> np.ndarray:
    # Independent of the task: counts from the CSV through the calibration written above.
    raw = np.loadtxt(input_path(input_dir, day), delimiter=",", skiprows=1)
    return 0.05 * (raw[:, 1:] - np.array([12.0, -7.0, 3.0]))


def test_five_days_one_corrupted(cluster, tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, DAYS, n_per_day=500)
    _corrupt(input_path(inp, BAD), line=7)
    task = SyntheticDayTask(inp, out)
    seen = []
    rep = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address, on_day_done=seen.append)
    assert isinstance(rep, BatchReport)
    assert [d.status for d in rep.days] == ["done", "done", "failed", "done", "done"]
    assert len(seen) == 5
    assert _products(out) == [f"SYNTH_{d:%Y%m%d}_v01.cdf" for d in DAYS if d != BAD]
    bad = rep.days[2]
    assert "SYNTH_20240303.csv" in bad.error and "line 7" in bad.error and "cx" in bad.error
    assert not list(out.glob("SYNTH_20240303*"))
    assert not manifest_path(out, "synthetic", BAD).exists()
    # products are complete and correct
    for d in DAYS:
        if d != BAD:
            back = read_product(out / f"SYNTH_{d:%Y%m%d}_v01.cdf")
            np.testing.assert_allclose(back["B"].values, _expected_field(inp, d), atol=1e-9)
    # JSON report of every day
    report = json.loads(Path(rep.report_path).read_text())
    assert report["counts"] == {"done": 4, "skipped": 0, "no_data": 0, "failed": 1}
    assert report["days"][2]["status"] == "failed" and "line 7" in report["days"][2]["error"]
    assert rep.n_vectors == 4 * 500

    # Rerun: the four are skipped, the bad one retried (and fails again).
    rep2 = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address)
    assert [d.status for d in rep2.days] == ["skipped", "skipped", "failed", "skipped", "skipped"]

    # Fix the input: the rerun does only that day.
    write_synthetic_inputs(inp, [BAD], n_per_day=500)
    rep3 = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address)
    assert [d.status for d in rep3.days] == ["skipped", "skipped", "done", "skipped", "skipped"]
    assert rep3.ok

    # A changed input or calibration invalidates the manifest; --force redoes everything.
    write_synthetic_inputs(inp, [DAYS[0]], n_per_day=400, seed=9)
    assert not is_up_to_date(task, DAYS[0], out, "synthetic")
    assert is_up_to_date(task, DAYS[1], out, "synthetic")
    (inp / "synthetic_calib.txt").write_text("offset = 0 0 0\ngain = 0.05\n")
    assert not is_up_to_date(task, DAYS[1], out, "synthetic")
    rep4 = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address, force=True)
    assert [d.status for d in rep4.days] == ["done"] * 5


def test_killed_worker_loses_no_product(cluster, tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, DAYS, n_per_day=300)
    # Day 2 kills its worker process (SIGKILL) once, after leaving a half-written temporary.
    task = SyntheticDayTask(inp, out, delay=0.3, crash_once_on=DAYS[1])
    rep = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address)
    assert (out / ".crashed-SYNTH_20240302").exists()  # the worker really was killed
    assert not list(out.glob("*fluxcal-tmp*"))  # its half-written temporary was removed
    statuses = {d.day: d.status for d in rep.days}
    # Every product that exists is complete; none is partial.
    for d in DAYS:
        cdf = out / f"SYNTH_{d:%Y%m%d}_v01.cdf"
        if statuses[d.isoformat()] == "done":
            back = read_product(cdf)
            np.testing.assert_allclose(back["B"].values, _expected_field(inp, d), atol=1e-9)
            assert manifest_path(out, "synthetic", d).exists()
    # Rerun completes every day (the interrupted one, if Dask did not already retry it).
    rep2 = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address)
    assert rep2.ok
    assert {d.status for d in rep2.days} <= {"done", "skipped"}
    assert _products(out) == [f"SYNTH_{d:%Y%m%d}_v01.cdf" for d in DAYS]


def test_day_without_input_is_no_data(tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, DAYS[:2], n_per_day=10)
    rep = run_batch(DAYS[:3], SyntheticDayTask(inp, out), out, scheduler="serial")
    assert [d.status for d in rep.days] == ["done", "done", "no_data"]
    assert rep.ok


def test_task_factory_registry() -> None:
    assert task_factory("synthetic").__module__ == "fluxcal.runs.synthetic_task"
    from fluxcal.errors import FluxcalError

    with pytest.raises(FluxcalError, match="no mission 'voyager' is registered"):
        task_factory("voyager")


def test_worker_processes_are_single_threaded(cluster) -> None:
    from distributed import Client

    with Client(cluster.scheduler_address) as client:
        # a worker killed by an earlier test in this module is restarted by its nanny:
        # wait for it to register again before counting
        client.wait_for_workers(2, timeout=60)
        info = client.scheduler_info()["workers"]
        assert len(info) == 2
        assert all(w["nthreads"] == 1 for w in info.values())
        pids = client.run(os.getpid)
        assert len(set(pids.values())) == 2 and os.getpid() not in pids.values()


def test_worker_loads_kernels_once(cluster) -> None:
    from distributed import Client

    def probe(_: int) -> tuple[int, int, int]:
        import os

        import spiceypy

        from fluxcal.runs.batch import worker_kernel_pool

        pool = worker_kernel_pool([])
        again = worker_kernel_pool([])
        assert again is pool
        return os.getpid(), id(pool), spiceypy.ktotal("ALL")

    with Client(cluster.scheduler_address) as client:
        results = client.gather(client.map(probe, range(8), pure=False))
    by_pid: dict[int, set] = {}
    for pid, pool_id, n_kernels in results:
        by_pid.setdefault(pid, set()).add((pool_id, n_kernels))
    # one pool object and one kernel count per worker process, however many days it ran
    assert all(len(v) == 1 for v in by_pid.values())
    assert all(n > 0 for v in by_pid.values() for _, n in v)


def test_worker_kernel_pool_switches_lists() -> None:
    import spiceypy

    from fluxcal.geometry.kernels import frame_kernel_path
    from fluxcal.runs.batch import release_worker_kernel_pool, worker_kernel_pool

    # an earlier in-process (serial) batch test may have left its pool cached here
    release_worker_kernel_pool()
    before = spiceypy.ktotal("ALL")
    try:
        a = worker_kernel_pool([])
        n_a = spiceypy.ktotal("ALL")
        b = worker_kernel_pool([frame_kernel_path("MSGR_MSO", registry.frame_kernels())])
        assert b is not a
        assert spiceypy.ktotal("ALL") >= n_a
        assert worker_kernel_pool([frame_kernel_path("MSGR_MSO", registry.frame_kernels())]) is b
    finally:
        release_worker_kernel_pool()
    assert spiceypy.ktotal("ALL") == before


def test_cli_batch_on_existing_scheduler(cluster, tmp_path: Path) -> None:
    from fluxcal.cli import main

    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, DAYS[:2], n_per_day=30)
    args = ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-02", "--input",
            str(inp), "--out", str(out), "--scheduler", cluster.scheduler_address]
    assert main(args) == 0
    report = json.loads((out / "batch_report_synthetic.json").read_text())
    assert report["scheduler"] == cluster.scheduler_address
    assert report["counts"]["done"] == 2


@dataclass(frozen=True)
class KernelDayTask:
    """A day task that loads kernels through `worker_kernel_pool`, as the mission tasks do."""

    out_dir: Path
    name: str = "kernels"

    def __call__(self, day: dt.date) -> DayResult:
        import spiceypy

        from fluxcal.geometry.kernels import frame_kernel_path
        from fluxcal.runs.batch import worker_kernel_pool

        worker_kernel_pool([frame_kernel_path("MSGR_MSO", registry.frame_kernels())])
        path = atomic_write_bytes(Path(self.out_dir) / f"K_{day:%Y%m%d}.txt",
                                  str(spiceypy.ktotal("ALL")).encode())
        return DayResult(day, [path])


def test_serial_run_leaves_the_callers_spice_pool_as_found(tmp_path: Path) -> None:
    """In-process runs must not leak a task's kernels into the caller (or the next test)."""
    from fluxcal.geometry.kernels import loaded_kernels
    from fluxcal.runs import batch as batch_mod

    batch_mod.release_worker_kernel_pool()  # whatever an earlier test may have cached
    before = loaded_kernels()
    rep = run_batch(DAYS[:2], KernelDayTask(tmp_path), tmp_path, scheduler="serial")
    assert [d.status for d in rep.days] == ["done", "done"]
    assert int((tmp_path / "K_20240301.txt").read_text()) > len(before)  # kernels were loaded
    assert loaded_kernels() == before
    assert "pool" not in batch_mod._KERNEL_CACHE
    # a caller that keeps a worker pool itself (a worker running a nested serial batch) keeps it
    try:
        pool = batch_mod.worker_kernel_pool([])
        run_batch(DAYS[:1], KernelDayTask(tmp_path), tmp_path, scheduler="serial", force=True)
        assert batch_mod._KERNEL_CACHE.get("pool") is not None
        assert batch_mod._KERNEL_CACHE["pool"] is not pool  # replaced by the task's list
    finally:
        batch_mod.release_worker_kernel_pool()
    assert loaded_kernels() == before


def test_cluster_and_serial_give_identical_science(cluster, tmp_path: Path) -> None:
    """Worker processes and this process write the same bytes (same run, another place)."""
    from .test_reproducible import science_content

    inp = tmp_path / "in"
    write_synthetic_inputs(inp, DAYS[:2], n_per_day=400)
    runs = {}
    for where, scheduler in (("serial", "serial"), ("cluster", cluster.scheduler_address)):
        out = tmp_path / where
        rep = run_batch(DAYS[:2], SyntheticDayTask(inp, out, formats=("tab", "cdf", "nc")), out,
                        scheduler=scheduler)
        assert rep.ok, [d.error for d in rep.days]
        runs[where] = {Path(p).name: out / p for d in rep.days for p in d.products}
    assert sorted(runs["serial"]) == sorted(runs["cluster"]) and len(runs["serial"]) == 8
    for name, path in runs["serial"].items():
        assert science_content(path) == science_content(runs["cluster"][name]), name


def test_worker_killed_from_outside_mid_run(cluster, tmp_path: Path) -> None:
    """The test SIGKILLs a worker process while it runs a day: no partial product, rerun ok."""
    import signal

    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, DAYS, n_per_day=300)
    task = SyntheticDayTask(inp, out, delay=0.5)
    killed: list[int] = []

    def kill_a_busy_worker(st) -> None:
        # the worker that just finished a day has already started its next one
        if not killed and st.status == "done" and st.worker:
            pid = int(st.worker.split()[-1])
            assert pid != os.getpid()
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    rep = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address,
                    on_day_done=kill_a_busy_worker)
    assert killed
    with pytest.raises(ProcessLookupError):
        os.kill(killed[0], 0)  # the worker process really is gone
    assert not list(out.glob("*fluxcal-tmp*"))
    assert {d.status for d in rep.days} <= {"done", "failed"}
    assert all("KilledWorker" in (d.error or "") for d in rep.days if d.status == "failed")
    for day in DAYS:  # every product present is complete (even one whose manifest is missing)
        cdf = out / f"SYNTH_{day:%Y%m%d}_v01.cdf"
        if cdf.exists():
            np.testing.assert_allclose(read_product(cdf)["B"].values,
                                       _expected_field(inp, day), atol=1e-9)
    rep2 = run_batch(DAYS, task, out, scheduler=cluster.scheduler_address)
    assert rep2.ok and {d.status for d in rep2.days} <= {"done", "skipped"}
    assert _products(out) == [f"SYNTH_{d:%Y%m%d}_v01.cdf" for d in DAYS]
    for d in DAYS:
        np.testing.assert_allclose(read_product(out / f"SYNTH_{d:%Y%m%d}_v01.cdf")["B"].values,
                                   _expected_field(inp, d), atol=1e-9)


def test_clean_stale_temporaries_files_and_store_directories(tmp_path: Path) -> None:
    from fluxcal.runs.batch import clean_stale_temporaries

    (tmp_path / "P.zarr" / "B").mkdir(parents=True)  # a finished store: kept
    (tmp_path / "P.zarr" / "B" / "0.0").write_bytes(b"x")
    # a Zarr store a killed worker (pid 2**22 + 1: above Linux's pid_max) was writing
    stale_dir = tmp_path / f".P.zarr.{2**22 + 1}.k3j2ab12.fluxcal-tmp.zarr"
    (stale_dir / "B").mkdir(parents=True)
    (stale_dir / "B" / "0.0.abc.partial").write_bytes(b"x")
    (stale_dir / ".zgroup").write_text("{}")
    stale_file = tmp_path / "sub" / f".P.TAB.{2**22 + 1}.x1y2ab12.fluxcal-tmp.TAB"
    stale_file.parent.mkdir()
    stale_file.write_text("partial")
    (tmp_path / "P.TAB").write_text("done")
    removed = clean_stale_temporaries(tmp_path)
    assert sorted(removed) == sorted([stale_dir, stale_file])
    assert not stale_dir.exists() and not stale_file.exists()
    assert (tmp_path / "P.zarr" / "B" / "0.0").exists() and (tmp_path / "P.TAB").exists()
