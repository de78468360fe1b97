"""In-flight calibration fit benchmark (issues 13, 21): simulated cruise days through the fit.

    .venv/bin/python benchmarks/messenger_fit.py                  # month at 1 Hz, week at 20 Hz
    .venv/bin/python benchmarks/messenger_fit.py --quick          # 3 days at 1 Hz, 1 at 20 Hz
    FLUXCAL_BENCH_QUICK=1 .venv/bin/python benchmarks/messenger_fit.py
    .venv/bin/python benchmarks/messenger_fit.py --days-1hz 8 --days-20hz 0 --workers 2
    .venv/bin/python benchmarks/messenger_fit.py --estimator zero-mean --json out.json

Each data set is simulated by `fluxcal.missions.messenger.flight_sim` into the batch input
layout (CSV per stream and day, as a user's input folder), then fitted end to end through
the entry point of ``fluxcal messenger fit --input-dir`` (`fit_cli.run_fit`: the days'
chunks, every pass reading and reducing every day's CSVs, merging, fitting; the folder
written), with ``--estimator`` (default ``variance``), first serially, then on a local
Dask cluster of ``--workers`` single-threaded processes (started beforehand, its start-up
printed separately; one untimed warm-up fit over one day per worker first, as
benchmarks/batch.py does).

Prints seconds and input samples per second for both and their ratio, the simulator's
own speed, and for the Dask run the split of its wall time (from the DEBUG timing records
of `fit_passes.fit_days`): the parallel reduce per pass (map over the days and the merge on the
workers), the gather of the merged statistics, and the client's serial part (set-up, the
fit of each pass, the folder written).  That serial share ``f`` of the serial run's time
bounds the speed-up on ``N`` workers by ``1 / (f + (1 - f) / N)`` (Amdahl); the bound is
also given at the parallelism the pure-CPU control measures (`_control.control`).

Both runs are also split per pass for `benchmarks/messenger_fit_amdahl.py` (issue 34,
item 7; docs/decisions/messenger_fit.md entry 53), into the ``--json`` file too:
the serial run's reduce, merge and client fit (`fit_days` logs the same timing records
serially), and the Dask run's workers' compute inside each reduce and client fit, its
idle wall, the wait for the first task and the tail after the last day (Dask's task
stream).  Each in CPU seconds as well (the client process from the records, the workers'
tasks from Dask's metrics), and one day's reduce serially against on a worker.  A fit
that the guards refuse (`fit_guards.check_fit`), or that stops on too little data, is reported
and still timed (serial and Dask do the same work up to there).

A refused fit writes no folder, so the work a written fit does once after its last pass
(the waveform columns' errors, the figure of merit, the folder, the pictures: serial in
both runs) is timed apart, step by step (`once_per_fit`), on one more, untimed pass over
every day on the cluster with the guards off; `benchmarks/messenger_fit_amdahl.py` adds it
to both runs (docs/decisions/messenger_fit_verification.md, section 53).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import importlib
import json
import logging
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# One BLAS/OpenMP thread here as on Dask's workers (see benchmarks/batch.py)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from _control import control  # noqa: E402  (benchmarks/_control.py, beside this script)

from fluxcal.errors import FitRefusedError, FluxcalError  # noqa: E402
from fluxcal.extras import available  # noqa: E402
from fluxcal.missions.messenger.calibration_data import (  # noqa: E402
    MessengerCalibration,
    load_calibration,
)
from fluxcal.missions.messenger.fit import ESTIMATORS, FitResult  # noqa: E402
from fluxcal.missions.messenger.fit_cli import parse_days, run_fit  # noqa: E402
from fluxcal.missions.messenger.fit_merit import ERROR_GOAL_NT, check_merit  # noqa: E402
from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days, judged_at  # noqa: E402
from fluxcal.missions.messenger.fit_pictures import write_fit_pictures  # noqa: E402
from fluxcal.missions.messenger.fit_waveforms import waveform_column_errors  # noqa: E402
from fluxcal.missions.messenger.fit_write import (  # noqa: E402
    report_text,
    write_calibration_folder,
)
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402

START = dt.date(2010, 3, 1)
FIT_LOGGER = "fluxcal.missions.messenger.fit_passes"
#: Seconds for the workers' heartbeats to report their task metrics to the scheduler.
HEARTBEAT_S = 2.0


class _Timings(logging.Handler):
    """Collects the ``fit_timing`` records of `fit_passes.fit_days`'s Dask passes."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.passes: list[dict[str, float]] = []

    def emit(self, record: logging.LogRecord) -> None:
        timing = getattr(record, "fit_timing", None)
        if timing is not None:
            self.passes.append(dict(timing))


def _fit(run, passes: int, scheduler: str, workers: int, out: Path, estimator: str,
         days=None) -> tuple[float, str]:
    """Run ``fluxcal messenger fit --input-dir`` (`run_fit`); return (seconds, outcome)."""
    days = run.days if days is None else days
    t = time.perf_counter()
    try:
        run_fit(sci=[], heater=[], temperature=[], kernels=[], input_dir=run.input_dir,
                days=f"{days[0]}:{days[-1]}", intervals=None, out=out, passes=passes,
                scheduler=scheduler, workers=workers, estimator=estimator)
        outcome = "written"
    except FitRefusedError as exc:  # same work in both runs; the folder is not written
        outcome = f"refused: {exc}"
    except FluxcalError as exc:  # e.g. too little data for a pass: timed up to there
        outcome = f"stopped: {exc}"
    return time.perf_counter() - t, outcome


def _split(t0: float, t1: float, passes: list[dict[str, float]]) -> dict[str, Any]:
    """Wall time of one Dask fit split into parallel reduce, gather and client serial part.

    Without timing records (a `fit_days` that logs none) everything counts as serial.
    """
    if not passes:
        return {"setup_s": 0.0, "reduce_s": [], "gather_s": [], "client_s": [],
                "serial_s": t1 - t0, "parallel_s": 0.0}
    reduce_s = [p["reduced"] - p["start"] for p in passes]
    gather_s = [p["gathered"] - p["reduced"] for p in passes]
    ends = [p["start"] for p in passes[1:]] + [t1]
    client_s = [end - p["gathered"] for p, end in zip(passes, ends, strict=True)]
    setup = passes[0]["start"] - t0
    return {"setup_s": setup, "reduce_s": reduce_s, "gather_s": gather_s,
            "client_s": client_s,
            "serial_s": setup + sum(gather_s) + sum(client_s), "parallel_s": sum(reduce_s)}


def _cpu(passes: list[dict[str, float]], cpu1: float) -> dict[str, list[float]]:
    """This process's CPU seconds per pass: before and after ``reduced``, then its client.

    ``cpu1``: ``time.process_time()`` at the end of `run_fit`.
    """
    ends = [p["start_cpu"] for p in passes[1:]] + [cpu1]
    return {"reduce_cpu_s": [p["reduced_cpu"] - p["start_cpu"] for p in passes],
            "gather_cpu_s": [p["gathered_cpu"] - p["reduced_cpu"] for p in passes],
            "client_cpu_s": [e - p["gathered_cpu"] for p, e in zip(passes, ends, strict=True)]}


def _serial_parts(t0: float, t1: float, cpu1: float,
                  passes: list[dict[str, float]]) -> dict[str, Any]:
    """The serial run's time split per pass: reduce the days, merge them, client fit.

    From the same ``fit_timing`` records `fit_passes.fit_days` logs serially (``reduced``: every
    day reduced, ``gathered``: merged); the client's part runs to the next pass's start
    (the last one to the end of `run_fit`: the figure of merit, the folder, the pictures).
    Wall seconds, and CPU seconds (``*_cpu_s``; on a shared host the wall includes waits
    for a core).
    """
    split = _split(t0, t1, passes)
    cpu = _cpu(passes, cpu1)
    return {"setup_s": split["setup_s"], "reduce_s": split["reduce_s"],
            "merge_s": split["gather_s"], "client_s": split["client_s"],
            "reduce_cpu_s": cpu["reduce_cpu_s"], "merge_cpu_s": cpu["gather_cpu_s"],
            "client_cpu_s": cpu["client_cpu_s"]}


def _worker_metrics(client) -> dict[str, float]:
    """The workers' cumulative CPU and non-CPU (waiting for a core) seconds per task name.

    Dask's fine performance metrics, as the workers' heartbeats last reported them.
    """
    def read(dask_scheduler):
        return {f"{k[1]}:{k[2]}": v for k, v in dask_scheduler.cumulative_worker_metrics.items()
                if isinstance(k, tuple) and len(k) == 4 and k[0] == "execute"
                and k[2] in ("thread-cpu", "thread-noncpu")}

    return client.run_on_scheduler(read)


def _tasks(records: list[dict[str, Any]], offset: float) -> list[dict[str, Any]]:
    """The Dask task stream's records as (name, worker, compute start/stop, transfer s).

    ``offset`` turns the workers' ``time.time()`` into this process's ``perf_counter``.
    """
    from dask.utils import key_split

    out = []
    for r in records:
        compute = [s for s in r["startstops"] if s["action"] == "compute"]
        if not compute:
            continue
        out.append({"name": key_split(r["key"]), "worker": r["worker"],
                    "start": compute[0]["start"] - offset,
                    "stop": compute[-1]["stop"] - offset,
                    "compute_s": sum(s["stop"] - s["start"] for s in compute),
                    "transfer_s": sum(s["stop"] - s["start"] for s in r["startstops"]
                                      if s["action"] == "transfer")})
    return out


def _union(spans: list[tuple[float, float]]) -> float:
    """Seconds covered by the union of ``spans`` (start, stop)."""
    total, end = 0.0, -float("inf")
    for a, b in sorted(spans):
        if b > end:
            total += b - max(a, end)
            end = b
    return total


def _dask_parts(t1: float, passes: list[dict[str, float]], tasks: list[dict[str, Any]],
                n_workers: int) -> list[dict[str, Any]]:
    """Per Dask pass: the workers' compute inside its reduce and inside its client fit.

    Window of the reduce: the pass's ``start`` to ``gathered`` (the merges after the last
    day run while the client waits for the merged object); of the client fit: from
    ``gathered`` to the next pass's start (the bootstrap's resamples, `resample_fits`, run
    on the workers then).  ``idle_s``: worker-seconds of the reduce window in which no
    task computed, divided by the workers (the wall the reduce lost to scheduling,
    transfers, the merge tree's tail and uneven days).
    """
    ends = [p["start"] for p in passes[1:]] + [t1]
    out = []
    for p, end in zip(passes, ends, strict=True):
        red = [t for t in tasks if p["start"] <= t["start"] < p["gathered"]]
        cli = [t for t in tasks if p["gathered"] <= t["start"] < end]
        days = [t["compute_s"] for t in red if t["name"] == "reduce_chunk"]
        merges = [t["compute_s"] for t in red if t["name"] == "merge_parts"]
        wall = p["gathered"] - p["start"]
        busy = sum(t["compute_s"] for t in red)
        first = min((t["start"] for t in red), default=p["gathered"])
        last_day = max((t["stop"] for t in red if t["name"] == "reduce_chunk"),
                       default=p["start"])
        rs = [t for t in cli if t["name"] == "resample_fits"]
        out.append({
            "days": len(days), "day_s": days, "day_compute_s": sum(days),
            "merges": len(merges), "merge_compute_s": sum(merges),
            "transfer_s": sum(t["transfer_s"] for t in red), "reduce_wall_s": wall,
            "idle_s": wall - busy / n_workers, "first_task_s": first - p["start"],
            "tail_s": p["gathered"] - last_day,
            "client_wall_s": end - p["gathered"], "resamples": len(rs),
            "resample_compute_s": sum(t["compute_s"] for t in rs),
            "resample_union_s": _union([(t["start"], t["stop"]) for t in rs])})
    return out


def _clocked(f, *args, **kwargs) -> tuple[Any, list[float]]:
    """``f(*args, **kwargs)`` and its [wall, CPU] seconds in this process."""
    w, c = time.perf_counter(), time.process_time()
    out = f(*args, **kwargs)
    return out, [time.perf_counter() - w, time.process_time() - c]


def once_per_fit(result: FitResult, base: MessengerCalibration, out: Path,
                 goal: float | None = None) -> dict[str, Any]:
    """Time the work a written fit does once, after its last pass, step by step.

    What `fit_passes.fit_days` and `fit_cli.run_fit` do after the last pass of a fit that
    is written (docs/decisions/messenger_fit.md entry 33; section 53 of
    docs/decisions/messenger_fit_verification.md), on ``result`` (a `fit_days` result of
    one pass from ``base``, so that its column errors are stated from ``base``) in their
    order, each [wall, CPU] seconds of this process:

    * ``column_errors``: `fit_waveforms.waveform_column_errors` (the waveform columns'
      jackknife);
    * ``merit``: `fit_passes.judged_at` (`fit_merit.assess` and `merit_inside_range`,
      as `fit_days` judges a fit) and `fit_merit.check_merit` (its refusal caught);
    * ``folder``: `fit_write.write_calibration_folder` (the tables and reports; as a
      study, so that a fit that has not converged is written);
    * ``report``: `fit_write.report_text`, which `run_fit` returns;
    * ``pictures``: `fit_pictures.write_fit_pictures` (the PNGs and ``index.html``).

    ``import_plot``: matplotlib's first import (`fluxcal.products.fit_plots`), once per
    process, timed before the pictures and not in ``total_cpu_s`` (0 when imported
    already).  The variance estimator only (``merit`` needs it).
    """
    steps: dict[str, list[float]] = {}
    _, steps["column_errors"] = _clocked(waveform_column_errors, result.stats, base)

    def merit():
        judged = judged_at(result, ERROR_GOAL_NT if goal is None else goal)
        with contextlib.suppress(FitRefusedError):
            check_merit(judged, rejudge=judged_at)
        return judged

    judged, steps["merit"] = _clocked(merit)
    provenance = {"inputs": judged.stats.inputs, "intervals": "all data",
                  "days": ", ".join(judged.stats.days), "command": "messenger_fit.py"}
    _, steps["folder"] = _clocked(write_calibration_folder, judged, out, None, provenance,
                                  study=True)
    _, steps["report"] = _clocked(report_text, judged, provenance)
    imported = "fluxcal.products.fit_plots" in sys.modules or not available("plot")
    _, import_plot = _clocked(lambda: imported or importlib.import_module(
        "fluxcal.products.fit_plots"))
    _, steps["pictures"] = _clocked(write_fit_pictures, judged, out)
    return {"steps": steps, "total_s": sum(v[0] for v in steps.values()),
            "total_cpu_s": sum(v[1] for v in steps.values()),
            "import_plot": [0.0, 0.0] if imported else import_plot}


def _once_per_fit(run, address: str, n_workers: int, out: Path,
                  estimator: str) -> dict[str, Any] | None:
    """`once_per_fit` of one untimed pass over every day of ``run`` on the cluster.

    The passes of the timed fits are refused as not converged at 3 passes (section 47),
    so neither fit writes its folder; this pass has the guards off (`fit_days`,
    ``guard=False``) and is fitted on the cluster's workers.  None for an estimator other
    than ``variance``, or when the pass stops (too little data).
    """
    if estimator != "variance":
        return None
    chunks = day_chunks(run.input_dir, parse_days("", run.input_dir))
    base = load_calibration(chunks[0].label, None)
    try:
        result = fit_days(chunks, base, passes=1, scheduler=address, n_workers=n_workers,
                          estimator=estimator, guard=False)
    except FluxcalError:
        return None
    return once_per_fit(result, base, out)


def _amdahl(f: float, n: float) -> float:
    return 1.0 / (f + (1.0 - f) / n)


def _case(label: str, days: int, rate_setting: int, passes: int, cluster, work: Path,
          estimator: str) -> dict[str, Any]:
    n_workers = len(cluster.workers)
    t, cpu = time.perf_counter(), time.process_time()
    run = simulate_flight(work / label, FlightConfig(start=str(START), days=days,
                                                     rate_setting=rate_setting), truth=False)
    sim_s, sim_cpu = time.perf_counter() - t, time.process_time() - cpu
    n = run.n_samples
    # warm-up (imports, numba cache loads, first-call costs) in this process and on every
    # worker: one fit over one day here, over one day per worker on the cluster, not timed
    address = cluster.scheduler_address
    with contextlib.suppress(FluxcalError):  # a day or a few may be too little to fit
        _fit(run, 1, "serial", n_workers, work / label / "warm_serial", estimator,
             run.days[:1])
    with contextlib.suppress(FluxcalError):
        _fit(run, 1, address, n_workers, work / label / "warm_parallel", estimator,
             run.days[:n_workers])
    from distributed import Client, get_task_stream

    log = logging.getLogger(FIT_LOGGER)
    serial_timing = _Timings()
    log.addHandler(serial_timing)
    log.setLevel(logging.DEBUG)
    try:
        cpu, s0 = time.process_time(), time.perf_counter()
        serial, outcome = _fit(run, passes, "serial", n_workers, work / label / "fit_serial",
                               estimator)
        s1, s1_cpu = time.perf_counter(), time.process_time()
        serial_cpu = s1_cpu - cpu
    finally:
        log.removeHandler(serial_timing)
    handler = _Timings()
    log.addHandler(handler)
    try:
        # the workers' task stream (the scheduler's record of every task's compute and
        # transfers) during the Dask fit: what of its reduce the workers spent computing
        with Client(cluster) as watcher:
            time.sleep(HEARTBEAT_S)
            before = _worker_metrics(watcher)
            with get_task_stream(client=watcher) as stream:
                t0 = time.perf_counter()
                parallel, outcome_p = _fit(run, passes, address, n_workers,
                                           work / label / "fit_parallel", estimator)
                t1, cpu1 = time.perf_counter(), time.process_time()
                offset = time.time() - time.perf_counter()
            time.sleep(HEARTBEAT_S)
            after = _worker_metrics(watcher)
    finally:
        log.removeHandler(handler)
        log.setLevel(logging.NOTSET)
    ctrl = control(cluster, 2 * n_workers)
    once = _once_per_fit(run, address, n_workers, work / label / "once", estimator)
    split = _split(t0, t1, handler.passes)
    serial_parts = _serial_parts(s0, s1, s1_cpu, serial_timing.passes)
    dask_parts = _dask_parts(t1, handler.passes, _tasks(stream.data, offset), n_workers)
    dask_cpu = _cpu(handler.passes, cpu1)
    worker_cpu = {k: after[k] - before.get(k, 0.0) for k in after}
    f = min(split["serial_s"] / serial, 1.0)
    speed_up = serial / parallel
    print(f"{label}: {days} day(s), {n:,} samples, estimator {estimator}, at most {passes} "
          f"passes ({len(handler.passes)} run)")
    print(f"  simulate:            {sim_s:8.2f} s  {n / sim_s:12,.0f} samples/s"
          f"  (CPU {sim_cpu:.1f} s)")
    print(f"  fit serial:          {serial:8.2f} s  {n / serial:12,.0f} samples/s"
          f"  (CPU {serial_cpu:.1f} s)  [{outcome.splitlines()[0][:100]}]")
    print(f"  fit Dask x{n_workers} workers: {parallel:8.2f} s  {n / parallel:12,.0f} samples/s"
          + ("" if outcome_p == outcome else f"  [{outcome_p.splitlines()[0][:100]}]"))
    print(f"    split: set-up {split['setup_s']:.3f} s; per pass: parallel reduce (map over "
          "the days + merge on the workers) / gather / client fit (and, last, write):")
    for p, (r, g, c) in enumerate(zip(split["reduce_s"], split["gather_s"], split["client_s"],
                                      strict=True)):
        print(f"      pass {p + 1}: {r:7.3f} s / {g:6.3f} s / {c:6.3f} s")
    print(f"    client serial part {split['serial_s']:.2f} s = {f:.1%} of the serial run; "
          f"Amdahl bound {_amdahl(f, n_workers):.2f}x on {n_workers} workers, "
          f"{_amdahl(f, ctrl):.2f}x at the control's {ctrl:.2f}x")
    print("    parts per pass (s): serial reduce / merge / client | Dask reduce wall = "
          "day compute / workers + idle (tail after the last day) | merges | client wall "
          "(resamples on the workers: compute, wall)")
    for p, (r, m, c) in enumerate(zip(serial_parts["reduce_s"], serial_parts["merge_s"],
                                      serial_parts["client_s"], strict=True)):
        d = dask_parts[p] if p < len(dask_parts) else None
        dask = ("" if d is None else
                f" | {d['reduce_wall_s']:.3f} = {d['day_compute_s']:.3f} / {n_workers} + "
                f"{d['idle_s']:.3f} ({d['tail_s']:.3f}) | {d['merges']} "
                f"{d['merge_compute_s']:.3f} | {d['client_wall_s']:.3f} "
                f"({d['resamples']} {d['resample_compute_s']:.3f}, "
                f"{d['resample_union_s']:.3f})")
        print(f"      pass {p + 1}: {r:.3f} / {m:.3f} / {c:.3f}{dask}")
    print("    CPU s per pass: serial reduce / merge / client | Dask client process during "
          "the reduce / gather / its fit: "
          + "; ".join(f"{a:.2f} / {b:.2f} / {c:.2f} | {d:.2f} / {e:.2f} / {g:.2f}"
                      for a, b, c, d, e, g in zip(
                          serial_parts["reduce_cpu_s"], serial_parts["merge_cpu_s"],
                          serial_parts["client_cpu_s"], dask_cpu["reduce_cpu_s"],
                          dask_cpu["gather_cpu_s"], dask_cpu["client_cpu_s"], strict=False)))
    print("    workers' task seconds (CPU / waiting for a core): " + ", ".join(
        f"{name} {worker_cpu.get(name + ':thread-cpu', 0.0):.2f} / "
        f"{worker_cpu.get(name + ':thread-noncpu', 0.0):.2f}"
        for name in ("reduce_chunk", "merge_parts", "resample_fits")))
    day_serial = sum(serial_parts["reduce_s"]) / max(days * len(serial_parts["reduce_s"]), 1)
    day_dask = [t for p in dask_parts for t in p["day_s"]]
    if day_dask:
        per_day = sum(day_dask) / len(day_dask)
        slow = per_day / day_serial
        print(f"    one day's reduce: {day_serial:.3f} s serially, {per_day:.3f} s on a worker "
              f"({slow:.2f}x; the control's task {n_workers / ctrl:.2f}x: the reduce slows "
              f"{slow * ctrl / n_workers:.2f}x as much when the workers run together)")
    if once is not None:
        st = once["steps"]
        z = once["total_cpu_s"]
        with_z = serial_cpu + (0.0 if outcome == "written" else z)
        print("    once per fit (after the last pass of a written fit; timed apart on one "
              "untimed pass with the guards off), CPU s: " + " / ".join(
                  f"{k.replace('_', ' ')} {v[1]:.3f}" for k, v in st.items())
              + f"; total {z:.3f} CPU s, {once['total_s']:.3f} s wall: "
              f"{z / with_z:.1%} of the serial run's CPU with it"
              + (" (in it already: the fits were written)" if outcome == "written" else "")
              + f"; matplotlib's first import {once['import_plot'][1]:.3f} CPU s (once per "
              "process, not counted)")
    print(f"  speed-up serial/parallel: {speed_up:.2f}x (ideal {n_workers}x; load average "
          f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores)")
    print(f"  control: a pure-CPU task reaches {ctrl:.2f}x on this cluster right now (the "
          "parallelism the machine offers)")
    print(f"  speed-up / control: {speed_up / ctrl:.0%}")
    shutil.rmtree(work / label, ignore_errors=True)
    return {"label": label, "days": days, "samples": n, "estimator": estimator,
            "workers": n_workers, "passes_run": len(handler.passes), "simulate_s": sim_s,
            "serial_s": serial, "parallel_s": parallel, "speed_up": speed_up,
            "control": ctrl, "ratio_to_control": speed_up / ctrl, "serial_share": f,
            "amdahl_workers": _amdahl(f, n_workers), "amdahl_control": _amdahl(f, ctrl),
            "split": split, "serial_parts": serial_parts, "dask_parts": dask_parts,
            "dask_client_cpu": dask_cpu, "worker_cpu": worker_cpu, "once_per_fit": once,
            "serial_cpu_s": serial_cpu,
            "outcome": outcome, "outcome_parallel": outcome_p,
            "cpu_count": os.cpu_count(), "load_average": os.getloadavg()[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    quick = os.environ.get("FLUXCAL_BENCH_QUICK", "") not in ("", "0")
    ap.add_argument("--quick", action="store_true", default=quick,
                    help="3 days at 1 Hz and 1 day at 20 Hz (also FLUXCAL_BENCH_QUICK=1)")
    ap.add_argument("--days-1hz", type=int, default=None, help="days at 1 Hz (default 30)")
    ap.add_argument("--days-20hz", type=int, default=None, help="days at 20 Hz (default 7)")
    ap.add_argument("--passes", type=int, default=3, help="most fit passes (default 3)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--estimator", choices=ESTIMATORS, default="variance",
                    help="the fit's --estimator (default variance)")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    ap.add_argument("--scheduler-process", action="store_true",
                    help="the scheduler in a process of its own (distributed's experimental "
                    "SubprocessCluster) instead of the LocalCluster's scheduler in this "
                    "process, to measure the client without the scheduler's CPU "
                    "(docs/decisions/messenger_fit.md entries 53 and 54); its workers "
                    "keep Dask's default environment")
    args = ap.parse_args()
    d1 = args.days_1hz if args.days_1hz is not None else (3 if args.quick else 30)
    d20 = args.days_20hz if args.days_20hz is not None else (1 if args.quick else 7)
    logging.getLogger("fluxcal").setLevel(logging.ERROR)  # look-back warnings of day 1

    from distributed import Client

    from fluxcal.runs.batch import make_local_cluster

    work = Path(tempfile.mkdtemp(prefix="fluxcal-bench-fit-"))
    t = time.perf_counter()
    if args.scheduler_process:
        from distributed.deploy.subprocess import SubprocessCluster

        # its processes unpickle this folder's `_control.burn`: give them the folder
        os.environ["PYTHONPATH"] = os.pathsep.join(
            [str(Path(__file__).resolve().parent), *filter(None, [os.environ.get("PYTHONPATH")])])
        cluster = SubprocessCluster(n_workers=args.workers, threads_per_worker=1,
                                    dashboard_address=":0", silence_logs=logging.ERROR)
    else:
        cluster = make_local_cluster(args.workers)
    with Client(cluster) as client:
        client.run(lambda: logging.getLogger("fluxcal").setLevel(logging.ERROR))
    print(f"local Dask cluster: {args.workers} workers, start-up {time.perf_counter() - t:.1f} s"
          " (not included below)")
    results = []
    try:
        for label, days, rate in (("1 Hz", d1, 6), ("20 Hz", d20, 10)):
            if days > 0:
                results.append(_case(label, days, rate, args.passes, cluster, work,
                                     args.estimator))
    finally:
        cluster.close()
        shutil.rmtree(work, ignore_errors=True)
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
