"""Batch scale benchmark: N simulated days serially vs on a LocalCluster of 2 workers.

    .venv/bin/python benchmarks/batch.py [--days 8] [--workers 2]   # MESSENGER day task
    .venv/bin/python benchmarks/batch.py --task synthetic [--vectors 200000]
    .venv/bin/python benchmarks/batch.py --task messenger --input DIR --start 2012-06-01

Prints days/s, vectors/s and the speed-up, then extrapolates the wall time of the whole
MESSENGER orbital mission (2011-03-18 .. 2015-04-30, 1505 days, up to 20 vectors/s =
1,728,000 vectors/day) on a cluster of 100 such workers from the measured cost per
vector.  The cluster start-up is timed separately (a long batch amortises it).
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib
import logging
import math
import os
import shutil
import tempfile
import time
from pathlib import Path

# One BLAS/OpenMP thread in this process too: Dask's nanny gives each worker one thread
# (OMP/MKL/OPENBLAS_NUM_THREADS=1), so the serial run must not use both cores through
# OpenBLAS, or the comparison measures BLAS threading instead of day parallelism.
# (Set before numpy is imported.)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from _control import control  # noqa: E402  (benchmarks/_control.py, beside this script)
from distributed import Client  # noqa: E402

from fluxcal.errors import FluxcalError  # noqa: E402
from fluxcal.runs.batch import (  # noqa: E402
    day_range,
    make_local_cluster,
    run_batch,
    task_factory,
)

MESSENGER_DAYS = (dt.date(2015, 4, 30) - dt.date(2011, 3, 18)).days + 1
VECTORS_PER_DAY_20HZ = 20 * 86_400


def _quiet_fluxcal_logs() -> None:
    """Keep the pipelines' data warnings (e.g. heater look-back) out of the timing output."""
    logging.getLogger("fluxcal").setLevel(logging.ERROR)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=8)
    ap.add_argument("--vectors", type=int, default=200_000, help="vectors per synthetic day")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--task", default="auto",
                    help="messenger (default when its day task exists), synthetic or rosetta")
    ap.add_argument("--input", type=Path, help="input folder (mission tasks)")
    ap.add_argument("--start", default=None, help="first day (default 2024-01-01, "
                    "MESSENGER 2012-06-01)")
    ap.add_argument("--formats", default=None,
                    help="product formats (default: the task's own, as `fluxcal batch`)")
    ap.add_argument("--verbose", action="store_true", help="keep the pipelines' warnings")
    args = ap.parse_args()
    if not args.verbose:
        _quiet_fluxcal_logs()
    if args.task == "auto":
        try:
            task_factory("messenger")
            args.task = "messenger"
        except FluxcalError:
            args.task = "synthetic"

    start = args.start or ("2012-06-01" if args.task == "messenger" else "2024-01-01")
    days = day_range(dt.date.fromisoformat(start),
                     dt.date.fromisoformat(start) + dt.timedelta(days=args.days - 1))
    work = Path(tempfile.mkdtemp(prefix="fluxcal-bench-"))
    options = {} if args.formats is None else {"formats": tuple(args.formats.split(","))}
    try:
        if args.task == "synthetic":
            from fluxcal.runs.synthetic_task import write_synthetic_inputs

            inp = work / "in"
            write_synthetic_inputs(inp, days, n_per_day=args.vectors)
        elif args.input is None and args.task == "messenger":
            from fluxcal.missions.messenger.batch_task import simulate_messenger_days

            inp = work / "in"
            start = dt.datetime.combine(days[0], dt.time())
            days = simulate_messenger_days(inp, duration_s=args.days * 86_400.0, start=start,
                                           rate_setting=6)  # Table 1: 1 vector/s
        else:
            if args.input is None:
                ap.error("--input is required for this task")
            inp = args.input
        factory = task_factory(args.task)

        serial_out = work / "serial"
        task = factory(inp, serial_out, **options)
        run_batch(days[:1], task, serial_out, scheduler="serial", force=True)  # warm-up
        rep_s = run_batch(days, task, serial_out, scheduler="serial", force=True)

        t0 = time.perf_counter()
        cluster = make_local_cluster(args.workers)
        with Client(cluster) as client:  # import the task's modules on every worker
            client.run(importlib.import_module, type(task).__module__)
            if not args.verbose:
                client.run(_quiet_fluxcal_logs)
        startup = time.perf_counter() - t0
        try:
            par_out = work / "parallel"
            task = factory(inp, par_out, **options)
            # warm-up (first-call costs on each worker), as for the serial run
            run_batch(days[: args.workers], task, par_out, scheduler=cluster.scheduler_address,
                      force=True)
            rep_p = run_batch(days, task, par_out, scheduler=cluster.scheduler_address,
                              force=True)
            ctrl = control(cluster, 2 * args.workers)
        finally:
            cluster.close()
    finally:
        shutil.rmtree(work, ignore_errors=True)

    for rep in (rep_s, rep_p):
        if not rep.ok:
            raise SystemExit(f"{len(rep.failed)} day(s) failed: {rep.failed[0].error}")
    n = len(days)
    vec = rep_s.n_vectors
    print(f"task={args.task} days={n} vectors/day={vec // n:,} formats={','.join(task.formats)}")
    print(f"serial:           {rep_s.wall_seconds:7.2f} s  {n / rep_s.wall_seconds:6.3f} days/s"
          f"  {vec / rep_s.wall_seconds:12,.0f} vectors/s")
    print(f"LocalCluster x{args.workers}: {rep_p.wall_seconds:7.2f} s  "
          f"{n / rep_p.wall_seconds:6.3f} days/s  {vec / rep_p.wall_seconds:12,.0f} vectors/s"
          f"  (cluster start-up {startup:.1f} s, not included)")
    speedup = rep_s.wall_seconds / rep_p.wall_seconds
    print(f"control: a pure-CPU task reaches {ctrl:.2f}x on this cluster right now "
          "(the parallelism the machine offers)")
    print(f"load average during the runs: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
          "(other processes on the machine lower the speed-up)")
    print(f"speed-up: {speedup:.2f}x  (ideal {args.workers}x)")
    per_vector = rep_s.wall_seconds / vec
    day_cost = per_vector * VECTORS_PER_DAY_20HZ
    waves = math.ceil(MESSENGER_DAYS / 100)
    wall = waves * day_cost
    print(f"extrapolation: one 20 Hz MESSENGER day ~ {day_cost:.1f} s on one worker; "
          f"{MESSENGER_DAYS} orbital days on 100 workers = {waves} waves ~ {wall / 60:.1f} min "
          f"(+ scheduler overhead; assumes this task's cost per vector)")


if __name__ == "__main__":
    main()
