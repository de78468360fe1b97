"""In-flight calibration fit benchmark (issue 13): simulated cruise days through the fit.

    .venv/bin/python benchmarks/messenger_fit.py                  # month at 1 Hz, week at 20 Hz
    .venv/bin/python benchmarks/messenger_fit.py --quick          # 3 days at 1 Hz, 1 at 20 Hz
    FLUXCAL_BENCH_QUICK=1 .venv/bin/python benchmarks/messenger_fit.py
    .venv/bin/python benchmarks/messenger_fit.py --days-1hz 10 --days-20hz 0 --workers 2

Each data set is simulated by `fluxcal.missions.messenger.flight_sim` into the batch input
layout (CSV per stream and day, as a user's input folder), then fitted end to end the way
``fluxcal messenger fit`` does it: `fit.day_chunks` + `fit.fit_days` (every pass reads
and reduces every day's CSVs, merges, fits) + `fit_write.write_calibration_folder`,
first serially, then on a local Dask cluster of ``--workers`` single-threaded processes
(started beforehand, its start-up printed separately; one untimed warm-up pass over one
day per worker first, as benchmarks/batch.py does).  Prints seconds and input samples
per second for both and their ratio, plus the simulator's own speed.
"""

from __future__ import annotations

import argparse
import datetime as dt
import logging
import os
import shutil
import tempfile
import time
from pathlib import Path

# One BLAS/OpenMP thread here as on Dask's workers (see benchmarks/batch.py)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from _control import control  # noqa: E402  (benchmarks/_control.py, beside this script)

from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402

START = dt.date(2010, 3, 1)


def _fit(run, passes: int, scheduler: str | None, out: Path, days=None) -> float:
    from fluxcal.missions.messenger import fit, fit_write

    days = run.days if days is None else days
    t = time.perf_counter()
    chunks = fit.day_chunks(run.input_dir, days)
    base = load_calibration(np.datetime64(str(days[0])))
    # speed only: the guards (check_fit) may refuse a zero-mean fit of this wind
    result = fit.fit_days(chunks, base, passes=passes, scheduler=scheduler, guard=False)
    fit_write.write_calibration_folder(result, out, None, {
        "inputs": {}, "intervals": "all data", "days": f"{days[0]}..{days[-1]}",
        "command": "benchmarks/messenger_fit.py"})
    return time.perf_counter() - t


def _case(label: str, days: int, rate_setting: int, passes: int, cluster, work: Path) -> None:
    t, cpu = time.perf_counter(), time.process_time()
    run = simulate_flight(work / label, FlightConfig(start=str(START), days=days,
                                                     rate_setting=rate_setting), truth=False)
    sim_s, sim_cpu = time.perf_counter() - t, time.process_time() - cpu
    n = run.n_samples
    # warm-up (imports, numba cache loads, first-call costs) in this process and on every
    # worker: one pass over one day per worker, not timed
    warm = run.days[: len(cluster.workers)]
    _fit(run, 1, "serial", work / label / "warm_serial", warm)
    _fit(run, 1, cluster.scheduler_address, work / label / "warm_parallel", warm)
    cpu = time.process_time()
    serial = _fit(run, passes, "serial", work / label / "fit_serial")
    serial_cpu = time.process_time() - cpu
    parallel = _fit(run, passes, cluster.scheduler_address, work / label / "fit_parallel")
    print(f"{label}: {days} day(s), {n:,} samples, {passes} passes")
    print(f"  simulate:            {sim_s:8.2f} s  {n / sim_s:12,.0f} samples/s"
          f"  (CPU {sim_cpu:.1f} s)")
    print(f"  fit serial:          {serial:8.2f} s  {n / serial:12,.0f} samples/s"
          f"  (CPU {serial_cpu:.1f} s)")
    print(f"  fit Dask x{len(cluster.workers)} workers: {parallel:8.2f} s  "
          f"{n / parallel:12,.0f} samples/s")
    print(f"  speed-up serial/parallel: {serial / parallel:.2f}x "
          f"(ideal {len(cluster.workers)}x; load average {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores)")
    print(f"  control: a pure-CPU task reaches {control(cluster, 2 * len(cluster.workers)):.2f}x"
          " on this cluster right now (the parallelism the machine offers)")
    shutil.rmtree(work / label, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    quick = os.environ.get("FLUXCAL_BENCH_QUICK", "") not in ("", "0")
    ap.add_argument("--quick", action="store_true", default=quick,
                    help="3 days at 1 Hz and 1 day at 20 Hz (also FLUXCAL_BENCH_QUICK=1)")
    ap.add_argument("--days-1hz", type=int, default=None, help="days at 1 Hz (default 30)")
    ap.add_argument("--days-20hz", type=int, default=None, help="days at 20 Hz (default 7)")
    ap.add_argument("--passes", type=int, default=3, help="fit passes (default 3)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    d1 = args.days_1hz if args.days_1hz is not None else (3 if args.quick else 30)
    d20 = args.days_20hz if args.days_20hz is not None else (1 if args.quick else 7)
    logging.getLogger("fluxcal").setLevel(logging.ERROR)  # look-back warnings of day 1

    from distributed import Client

    from fluxcal.runs.batch import make_local_cluster

    work = Path(tempfile.mkdtemp(prefix="fluxcal-bench-fit-"))
    t = time.perf_counter()
    cluster = make_local_cluster(args.workers)
    with Client(cluster) as client:
        client.run(lambda: logging.getLogger("fluxcal").setLevel(logging.ERROR))
    print(f"local Dask cluster: {args.workers} workers, start-up {time.perf_counter() - t:.1f} s"
          " (not included below)")
    try:
        for label, days, rate in (("1 Hz", d1, 6), ("20 Hz", d20, 10)):
            if days > 0:
                _case(label, days, rate, args.passes, cluster, work)
    finally:
        cluster.close()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
