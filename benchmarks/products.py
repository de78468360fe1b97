"""MESSENGER ``edr2cdr`` end to end, as a user runs it: CSV inputs -> product files.

Simulates one day of 20 Hz MESSENGER MAG inputs once (science, heater and temperature
CSV files and a synthetic kernel set; the last 2 % of the day at rate setting 8, so the
day has a fast -> slow switch), then runs ``fluxcal messenger edr2cdr`` (the CLI entry
point `fluxcal.cli.main`, each case in a fresh child process pinned to one CPU, with
one thread for BLAS/OpenMP/numba, so its peak RSS is its own and it uses one core) for

(a) CSV -> CDF, frames MSO + RTN, default averages (1, 5, 10, 60 s);
(b) the full default set: TAB + CDF, 5 frames, 4 averages, offsets report.

The baseline, measured in the same run and also in a child process, is the calibration
chain alone on the same inputs (the three CSV files read, then seed 000 sec. 5-13 in
memory, no product).  Printed per case: the child's whole life in wall seconds (interpreter
start-up, imports and all: what a user waits for), vectors/s from it, the ratio to the
baseline's time, peak RSS of the child (`peak_rss_mb`: ``VmHWM``, else ``ru_maxrss``)
CPU seconds (user + system; less sensitive to other load on the machine than the wall
time) and seconds per stage (functions of `fluxcal.missions.messenger.routes`, ``run``,
``products``, ``validation_report`` and of the runner's `fluxcal.products.declared`
wrapped with a timer; nested stages are included in their callers),
system time, page faults, the optional libraries the case loaded, and a write control
(`write_control`).
Every case starts after ``sync`` with the files of the cases before it deleted.

The numba cache and Python's bytecode cache are warmed first (a short ``edr2cdr`` run
of each case), so the figures do not include the one-off compilation.

Usage: .venv/bin/python benchmarks/products.py [--hours 24] [--cases baseline,a,b]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

#: Stages timed in the child: (module, function name).
STAGES = (
    ("fluxcal.missions.messenger.routes", "read_science"),
    ("fluxcal.missions.messenger.routes", "read_heater"),
    ("fluxcal.missions.messenger.routes", "read_temperature"),
    ("fluxcal.missions.messenger.run", "calibrate"),
    ("fluxcal.missions.messenger.run", "split_days"),
    ("fluxcal.runs.driver", "write_declared"),
    ("fluxcal.missions.messenger.validation_report", "report_figure"),
    ("fluxcal.missions.messenger.products", "product_dataset"),
    ("fluxcal.products.declared", "write_product"),
)


#: Libraries a case loads only when it needs them (printed per case).
OPTIONAL_IMPORTS = ("matplotlib", "dask.array", "pvl")


def simulate_inputs(folder: Path, hours: float) -> dict[str, Path]:
    """Write the kernels and the three CSV input streams of ``hours`` of 20 Hz data."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

    duration = hours * 3600.0
    config = SimulationConfig(duration_s=duration, rate_segments=[(0.0, 10), (0.98, 8)],
                              coarse_intervals=[(0.5, 0.52)])
    mk = write_messenger_like_kernels(folder / "kernels", config.start_utc,
                                      duration + 2 * config.lead_s,
                                      plus_y_sunward=[(0.2 * duration, 0.3 * duration)])
    cal = load_calibration(config.start_utc)
    with KernelPool(mk):
        sim = simulate(config, cal, SclkKernel.from_pool(-236))
    paths = write_inputs(sim, folder / "inputs")
    paths["kernels"] = mk
    return paths


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MB).

    ``VmHWM`` of ``/proc/self/status`` (Linux): the high-water mark of this program's own
    memory.  ``getrusage(RUSAGE_SELF).ru_maxrss`` is the fallback; on Linux it also counts
    the parent's memory at ``fork`` (it survives ``exec``), so a child of a big parent
    would report the parent's size.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _argv(paths: dict[str, Path], out: Path, case: str) -> list[str]:
    argv = ["messenger", "edr2cdr", "--sci", str(paths["science"]),
            "--heater", str(paths["heater"]), "--temperature", str(paths["temperature"]),
            "--kernels", str(paths["kernels"]), "--out", str(out)]
    if case == "a":
        argv += ["--frames", "mso,rtn", "--formats", "cdf"]
    return argv


def _wrap_stages(times: dict[str, float]) -> None:
    import importlib

    for module_name, name in STAGES:
        module = importlib.import_module(module_name)
        func = getattr(module, name, None)
        if func is None:
            continue

        def timed(*args, __f=func, __n=name, **kwargs):
            t0 = time.perf_counter()
            try:
                return __f(*args, **kwargs)
            finally:
                times[__n] += time.perf_counter() - t0

        setattr(module, name, timed)


def child(case: str, paths: dict[str, Path], out: Path) -> dict:
    """Run one case in this process; return wall time, stages, RSS and vector count.

    Nothing numerical is imported before the command runs, as with the ``fluxcal``
    script (`fluxcal.cli.main` sets numpy's import-time options first).
    """
    times: dict[str, float] = defaultdict(float)
    start = resource.getrusage(resource.RUSAGE_SELF)
    cpu0 = start.ru_utime + start.ru_stime
    t0 = time.perf_counter()
    if case == "baseline":
        from fluxcal.geometry.kernels import KernelPool
        from fluxcal.missions.messenger.calibration_data import load_calibration
        from fluxcal.missions.messenger.chain import calibrate, day_of
        from fluxcal.missions.messenger.readers import (
            read_heater,
            read_science,
            read_temperature,
        )

        t = time.perf_counter()
        sci = read_science([paths["science"]])
        heat = read_heater([paths["heater"]])
        temp = read_temperature([paths["temperature"]])
        times["read inputs"] = time.perf_counter() - t
        with KernelPool(paths["kernels"]):
            t = time.perf_counter()
            ds = calibrate(sci, heat, temp, load_calibration(day_of(sci)),
                           max_offset_step=2.0)
            times["calibrate"] = time.perf_counter() - t
        n = int(ds.sizes["time"])
        code = 0
    else:
        t = time.perf_counter()
        from fluxcal.cli import main

        times["import fluxcal.cli"] = time.perf_counter() - t
        # the stage timers import the modules they wrap, and with them numpy, before
        # `main` would set numpy's import-time option: set it first, as `main` does
        from fluxcal.process import numpy_allocation_defaults

        numpy_allocation_defaults()
        _wrap_stages(times)
        code = main(_argv(paths, out, case))
    wall = time.perf_counter() - t0
    if case != "baseline":
        n = 0  # counted by the parent, outside the timed process (`count_vectors`)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    rss_mb = peak_rss_mb()
    cpu = usage.ru_utime + usage.ru_stime - cpu0
    files = sorted(out.iterdir()) if out.exists() else []
    size = sum(p.stat().st_size for p in files if p.is_file())
    return {"case": case, "code": code, "wall": wall, "cpu": cpu, "stages": dict(times), "n": n,
            "system": usage.ru_stime - start.ru_stime,
            "page_faults": usage.ru_minflt + usage.ru_majflt,
            "rss_mb": rss_mb, "files": len(files), "bytes": size,
            "loaded": [m for m in OPTIONAL_IMPORTS if m in sys.modules],
            "numpy": sys.modules["numpy"].__version__}


def write_control(total_bytes: int, files: int, out: Path) -> dict:
    """Write ``total_bytes`` into ``files`` new files by plain 8 MiB writes; time them.

    The machine's own cost of putting that many new bytes into the page cache, for
    comparison with a case that wrote them.  It runs right after the case's files are
    deleted, so it can reuse the memory they held: on the development VM, whose first
    touch of memory is expensive, that makes it a lower bound of what the case paid
    (1.5 s for 1.7 GB there, against 5.6-7.3 s for the same writes after a case whose
    files were kept).
    """
    import numpy as np

    out.mkdir(parents=True, exist_ok=True)
    block = memoryview(np.random.default_rng(0).integers(0, 256, 8 << 20, dtype=np.uint8))
    per_file = total_bytes // max(files, 1)
    start = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    for k in range(files):
        with open(out / f"control_{k}", "wb") as fh:
            left = per_file
            while left > 0:
                left -= fh.write(block[:min(left, len(block))])
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return {"case": "write control", "code": 0, "wall": wall,
            "system": usage.ru_stime - start.ru_stime}


def count_vectors(science: Path) -> int:
    """Number of data records of the science CSV (lines minus the header)."""
    with open(science, "rb") as fh:
        return sum(chunk.count(b"\n") for chunk in iter(lambda: fh.read(1 << 24), b"")) - 1


def _one_core() -> None:
    """Pin the child to one CPU (the targets are for one core; no thread may use a second)."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {max(os.sched_getaffinity(0))})


def run_case(case: str, paths: dict[str, Path], out: Path) -> dict:
    """Run ``case`` in a fresh child pinned to one core; ``process_wall`` is its whole life.

    ``process_wall`` (interpreter start to exit, measured here) is the end-to-end time a
    user sees; ``wall`` (measured in the child) leaves out the interpreter start-up.
    """
    spec = json.dumps({k: str(v) for k, v in paths.items()})
    os.sync()  # every case starts with no other case's writes pending
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
               NUMBA_NUM_THREADS="1")
    # as on a user's machine, Python keeps its compiled bytecode (the warm-up run writes it;
    # some sandboxes set PYTHONDONTWRITEBYTECODE, recompiling every module on every run)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, __file__, "--child", case, "--paths", spec,
                           "--out", str(out)], capture_output=True, text=True, check=False,
                          env=env, preexec_fn=_one_core)
    process_wall = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines or json.loads(lines[-1])["code"] != 0:
        raise RuntimeError(f"case {case} failed:\n{proc.stdout}\n{proc.stderr}")
    res = {**json.loads(lines[-1]), "process_wall": process_wall}
    if case in ("a", "b"):
        res["n"] = count_vectors(paths["science"])
    return res


def report(res: dict, base: dict | None) -> None:
    n, wall = res["n"], res["process_wall"]
    ratio = f", {wall / base['process_wall']:.1f}x the baseline time" if base else ""
    print(f"case {res['case']}: {wall:.2f} s end to end (process), {n / wall:,.0f} vectors/s"
          f"{ratio}, "
          f"CPU {res['cpu']:.2f} s ({n / res['cpu']:,.0f} vectors per CPU second; system "
          f"{res['system']:.2f} s, {res['page_faults']:,} page faults), "
          f"peak RSS {res['rss_mb']:.0f} MB, {res['files']} files, "
          f"{res['bytes'] / 1e6:.0f} MB written; loaded: "
          f"{', '.join(res.get('loaded', [])) or 'none of ' + ', '.join(OPTIONAL_IMPORTS)}")
    for name, sec in res["stages"].items():
        print(f"    {name:18s} {sec:7.2f} s")
    sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--cases", default="baseline,a,b")
    parser.add_argument("--inputs", default=None,
                        help="folder for the simulated inputs, reused when present")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--paths", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--out", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        paths = {k: Path(v) for k, v in json.loads(args.paths).items()}
        if args.child.startswith("write:"):
            _, total, files = args.child.split(":")
            res = write_control(int(total), int(files), Path(args.out))
        else:
            res = child(args.child, paths, Path(args.out))
        print(json.dumps(res), flush=True)
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t0 = time.perf_counter()
        sim = Path(args.inputs) if args.inputs else folder / "sim"
        saved = sim / "paths.json"
        if saved.is_file():
            paths = {k: Path(v) for k, v in json.loads(saved.read_text()).items()}
            print(f"inputs reused from {sim}", flush=True)
        else:
            paths = simulate_inputs(sim, args.hours)
            saved.write_text(json.dumps({k: str(v) for k, v in paths.items()}))
            print(f"simulated {args.hours:g} h of inputs in {time.perf_counter() - t0:.1f} s",
                  flush=True)
        warm = simulate_inputs(folder / "warm", 0.25)
        t0 = time.perf_counter()
        for case in ("a", "b"):  # each case's kernels (their signatures differ)
            run_case(case, warm, folder / f"warm_{case}")
        print(f"warm-up runs (numba cache, bytecode): {time.perf_counter() - t0:.1f} s",
              flush=True)
        base = None
        for case in args.cases.split(","):
            res = run_case(case, paths, folder / f"out_{case}")
            if case == "baseline":
                base = res
            report(res, base if case != "baseline" else None)
            shutil.rmtree(folder / f"out_{case}", ignore_errors=True)  # (its page cache too)
            if res["bytes"]:
                ctl = run_case(f"write:{res['bytes']}:{res['files']}", paths,
                               folder / f"control_{case}")
                shutil.rmtree(folder / f"control_{case}", ignore_errors=True)
                print(f"    write control: the same {res['bytes'] / 1e6:.0f} MB in "
                      f"{res['files']} new files by plain 8 MiB writes took "
                      f"{ctl['wall']:.2f} s here (system {ctl['system']:.2f} s), just after "
                      f"the case's own files were deleted", flush=True)


if __name__ == "__main__":
    main()
