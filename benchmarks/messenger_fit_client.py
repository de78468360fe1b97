"""Where the MESSENGER fit's client spends its serial time, per pass (issue 34, item 7).

    .venv/bin/python benchmarks/messenger_fit_client.py --days 4
    .venv/bin/python benchmarks/messenger_fit_client.py --days 6 --passes 3 --json out.json

Simulates ``--days`` cruise days at 1 Hz (`flight_sim.simulate_flight`, as
benchmarks/messenger_fit.py does), then runs ``fluxcal messenger fit --input-dir``
(`fit_cli.run_fit`) serially, once plainly and once under `cProfile`, and prints the
seconds of each part (calls, total, per call, share of the profiled run).

On a Dask cluster `fit_passes.fit_days` maps `fit_passes.reduce_chunk`, the merges and the
bootstrap's resamples (`fit_breaks.resample_fits`, one block per worker) onto the
workers; everything else is the client's serial part (in this serial run the resamples
are on the client too, printed as their own line): the fit of each pass
(`fit.fit_variance_calibration`) with its bootstrap (`fit_variance.solve_variance`)
with its break choices (`fit_breaks.choose_breaks`, in the solution and in every
resample) and the resamples' steps (`fit_variance.apply_steps`), and its heater
waveforms (`fit_waveforms.fit_waveforms`; before entry 33 each pass also fitted the four folds
for the column errors), the pass bookkeeping
(`fit_passes.pass_changes`, `fit_guards.check_fit`), and after the passes the last pass's waveform
column errors (`fit_waveforms.waveform_column_errors`; its own `fit_waveforms` call is also
counted on that line), the figure of merit (`fit_merit.assess`,
`fit_passes.merit_inside_range`, `fit_merit.check_merit`), the folder written
(`fit_write.write_calibration_folder`) and its pictures
(`fit_pictures.write_fit_pictures`).

Each time is cProfile's cumulative time of the function (inclusive: the bootstrap and
the waveforms lie inside the fit of a pass).  cProfile slows Python-heavy code more than
NumPy-heavy code, so compare shares, not seconds; the plain run's wall time is printed.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import datetime as dt
import json
import logging
import os
import pstats
import shutil
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from fluxcal.errors import FluxcalError  # noqa: E402
from fluxcal.missions.messenger.fit_cli import run_fit  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402

START = dt.date(2010, 3, 1)

#: (label, module file suffix, function name[, calling function: only its calls]) of the
#: parts timed.
PARTS = (
    ("map: reduce_chunk (workers)", "messenger/fit_passes.py", "reduce_chunk"),
    ("merge (workers on Dask)", "messenger/fit_passes.py", "_merge_all"),
    ("fit of a pass", "messenger/fit.py", "fit_variance_calibration"),
    ("  bootstrap (solve_variance)", "messenger/fit_variance.py", "solve_variance"),
    ("    resamples (workers on Dask)", "messenger/fit_breaks.py", "resample_fits"),
    ("    break choices (choose_breaks)", "messenger/fit_breaks.py", "choose_breaks"),
    ("      of the solution (client)", "messenger/fit_breaks.py", "choose_breaks",
     "solve_variance"),
    ("      their breaks in their cells", "messenger/fit_breaks.py", "refine_breaks",
     "resample_fits"),
    ("    the solution's break in its cell", "messenger/fit_breaks.py", "refine_breaks",
     "solve_variance"),
    ("    resampled sums (einsum)", "numpy/_core/einsumfunc.py", "einsum", "solve_variance"),
    ("  resample steps (apply_steps)", "messenger/fit_variance.py", "apply_steps"),
    ("  waveforms (fit_waveforms)", "messenger/fit_waveforms.py", "fit_waveforms"),
    ("waveform column errors, once", "messenger/fit_waveforms.py", "waveform_column_errors"),
    ("pass_changes", "messenger/fit_passes.py", "pass_changes"),
    ("check_fit", "messenger/fit_guards.py", "check_fit"),
    ("merit: assess", "messenger/fit_merit.py", "assess"),
    ("merit: merit_inside_range", "messenger/fit_passes.py", "merit_inside_range"),
    ("merit: check_merit", "messenger/fit_merit.py", "check_merit"),
    ("write folder", "messenger/fit_write.py", "write_calibration_folder"),
    ("pictures", "messenger/fit_pictures.py", "write_fit_pictures"),
)


def _cumulative(stats: pstats.Stats) -> dict[str, tuple[int, float]]:
    """(primitive calls, cumulative s) of each part (`PARTS`); (0, 0) if never called."""
    out = {}
    for label, suffix, name, *caller in PARTS:
        calls, cum = 0, 0.0
        for (path, _line, func), (cc, _nc, _tt, ct, callers) in stats.stats.items():
            if func == name and path.replace("\\", "/").endswith(suffix):
                if not caller:
                    calls, cum = calls + cc, cum + ct
                    continue
                for (_p, _l, f), c in callers.items():  # only the calls from ``caller``
                    if f == caller[0]:
                        calls, cum = calls + c[0], cum + c[3]
        out[label] = (calls, cum)
    return out


def _run(input_dir: Path, days: list[str], out: Path, passes: int) -> tuple[float, str]:
    t = time.perf_counter()
    try:
        run_fit(sci=[], heater=[], temperature=[], kernels=[], input_dir=input_dir,
                days=f"{days[0]}:{days[-1]}", intervals=None, out=out, passes=passes)
        outcome = "written"
    except FluxcalError as exc:
        outcome = f"{type(exc).__name__}: {str(exc).splitlines()[0][:100]}"
    return time.perf_counter() - t, outcome


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=4, help="days at 1 Hz (default 4)")
    ap.add_argument("--passes", type=int, default=3, help="most passes (default 3, as "
                    "benchmarks/messenger_fit.py)")
    ap.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()
    logging.getLogger("fluxcal").setLevel(logging.ERROR)
    work = Path(tempfile.mkdtemp(prefix="fluxcal-bench-client-"))
    try:
        run = simulate_flight(work / "sim", FlightConfig(start=str(START), days=args.days,
                                                         seed=args.seed), truth=False)
        with contextlib.suppress(FluxcalError):  # warm-up: imports, first-call costs
            _run(run.input_dir, run.days[:1], work / "warm", 1)
        wall, outcome = _run(run.input_dir, run.days, work / "plain", args.passes)
        prof = cProfile.Profile()
        prof.enable()
        wall_p, outcome_p = _run(run.input_dir, run.days, work / "profiled", args.passes)
        prof.disable()
        parts = _cumulative(pstats.Stats(prof))
        n_pass = max(parts["fit of a pass"][0], 1)
        mapped = parts["map: reduce_chunk (workers)"][1] + parts["merge (workers on Dask)"][1]
        client = wall_p - mapped
        print(f"{args.days} day(s) at 1 Hz, {run.n_samples:,} samples, at most "
              f"{args.passes} passes: {outcome}")
        print(f"  wall {wall:.2f} s without the profiler, {wall_p:.2f} s with it"
              + ("" if outcome_p == outcome else f" [{outcome_p}]"))
        print(f"  client (wall less map and merge): {client:.2f} s = "
              f"{client / wall_p:.1%} of the serial run; {n_pass} fit call(s)")
        print(f"  {'part':34s} {'calls':>5s} {'total s':>8s} {'per call':>8s} "
              f"{'of client':>9s} {'of run':>7s}")
        for label, (calls, cum) in parts.items():
            of_client = "" if label.startswith(("map", "merge")) else f"{cum / client:9.1%}"
            print(f"  {label:34s} {calls:5d} {cum:8.3f} {cum / max(calls, 1):8.3f} "
                  f"{of_client:>9s} {cum / wall_p:7.1%}")
        if args.json is not None:
            args.json.write_text(json.dumps({
                "days": args.days, "samples": run.n_samples, "passes": args.passes,
                "outcome": outcome, "wall_s": wall, "wall_profiled_s": wall_p,
                "client_s": client, "parts": parts}, indent=1) + "\n")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
