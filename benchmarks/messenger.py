"""MESSENGER MAG edr2cdr throughput: one simulated day of 20 Hz data.

Runs every step of seed 000 sec. 5-13 on in-memory streams (all five frames, positions,
quality flags, offset validation; no file reading or formatting) and prints vectors/s,
then the same chain with one SPICE call per sample (scs2e, pxform per frame, spkpos per
position) on a subsample, and the ratio of the per-vector costs.

The chain is timed ``--repeat`` times in one process, with user and kernel CPU time per
run; vectors/s is from the median run.  By default freed memory is retained between runs
(`retain_freed_memory`, as a long-lived worker processing day after day would): the first
run pays the first touch of the day's ~1.6 GB (0.1-2.2 s of kernel time on the virtual
machines measured, host-dependent), later runs reuse it.
``--fresh-memory`` measures every run with freshly mapped memory.

Usage: .venv/bin/python benchmarks/messenger.py [--hours 24] [--oracle-samples 2000]
       [--repeat 3] [--fresh-memory]
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

#: glibc ``mallopt`` parameters (malloc.h): M_TRIM_THRESHOLD, M_MMAP_MAX.
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4


def retain_freed_memory() -> bool:
    """Keep memory freed by numpy in this process for the next run (glibc only).

    A day's (n, 3) arrays are ~40 MB each, above glibc's largest mmap threshold, so each
    is a fresh ``mmap`` whose pages fault on first touch and go back to the system when
    freed.  On the virtual machines measured here that first touch costs 0.1-2.2 s of
    kernel time per 20 Hz day (same page-fault count, host-dependent cost) against
    ~0.7 s of computation.  With ``M_MMAP_MAX = 0`` large arrays come from the heap and
    with a huge ``M_TRIM_THRESHOLD`` the heap is kept, so later runs reuse touched memory
    (as a long-lived worker started with ``MALLOC_MMAP_MAX_=0`` would).  Returns True
    when applied.
    """
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))


def oracle_chain(sci, heat, temp, cal):
    """The same chain with per-sample SPICE calls for clock, frames and positions."""
    n = sci.sizes["time"]
    # clock: one scs2e per sample (SPICE's own string path, as the IDL code of sec. 9)
    lag = cal.net_lag_s[sci["rate"].values]
    met = sci["met"].values - lag
    for i in range(n):
        spiceypy.scs2e(-236, f"{int(sci['partition'].values[i])}/{met[i]:.6f}")
    return calibrate(sci, heat, temp, cal, max_offset_step=None, method="oracle")


def breakdown(sci, heat, temp, cal) -> dict[str, float]:
    """Seconds spent in each level function."""
    from fluxcal.missions.messenger import levels

    sclk = SclkKernel.from_pool(-236)
    out = {}
    t = time.perf_counter()
    ds = levels.correct_time(sci, cal, sclk)
    out["time (sec. 5, 9)"] = time.perf_counter() - t
    t = time.perf_counter()
    periods, changes = levels.find_heater_periods(heat, cal, sclk)
    ds = levels.correct_heater_signal(ds, periods, cal)
    out["heater (sec. 6)"] = time.perf_counter() - t
    t = time.perf_counter()
    ds = levels.correct_offsets(ds, temp, changes, cal, sclk)
    out["offsets (sec. 7)"] = time.perf_counter() - t
    t = time.perf_counter()
    ds = levels.counts_to_field(ds, cal)
    out["counts->nT (sec. 8)"] = time.perf_counter() - t
    t = time.perf_counter()
    ds = levels.add_geometry(ds, cal)
    out["frames+positions (sec. 10, 11)"] = time.perf_counter() - t
    t = time.perf_counter()
    ds = levels.assign_quality(ds, cal)
    levels.validate_offsets(ds, 2.0)
    out["quality+validation (sec. 12, 13)"] = time.perf_counter() - t
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--oracle-samples", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=3, help="timed runs of the chain")
    parser.add_argument("--fresh-memory", action="store_true",
                        help="do not retain freed memory (every run pays the first touch)")
    args = parser.parse_args()
    retained = False if args.fresh_memory else retain_freed_memory()
    duration = args.hours * 3600.0
    config = SimulationConfig(duration_s=duration, rate_segments=[(0.0, 10)],
                              coarse_intervals=[(0.5, 0.52)])
    cal = load_calibration(config.start_utc)
    with tempfile.TemporaryDirectory() as tmp:
        mk = write_messenger_like_kernels(Path(tmp), config.start_utc, duration + 2 * 3600.0,
                                          plus_y_sunward=[(0.2 * duration, 0.3 * duration)])
        with KernelPool(mk):
            t0 = time.perf_counter()
            sim = simulate(config, cal, SclkKernel.from_pool(-236))
            t_sim = time.perf_counter() - t0
            sci, heat, temp = sim["science"], sim["heater"], sim["temperature"]
            n = sci.sizes["time"]
            # warm-up: imports and the compiled loops (numba cache or first compilation)
            t0 = time.perf_counter()
            calibrate(sci.isel(time=slice(0, 20000)), heat, temp, cal)
            t_warm = time.perf_counter() - t0
            runs, cpu = [], []
            for _ in range(args.repeat):
                r0 = resource.getrusage(resource.RUSAGE_SELF)
                t0 = time.perf_counter()
                ds = calibrate(sci, heat, temp, cal, max_offset_step=2.0)
                runs.append(time.perf_counter() - t0)
                r1 = resource.getrusage(resource.RUSAGE_SELF)
                cpu.append((r1.ru_utime - r0.ru_utime, r1.ru_stime - r0.ru_stime))
                del ds
            t_fast = float(np.median(runs))
            steps = breakdown(sci, heat, temp, cal)
            ds = calibrate(sci, heat, temp, cal, max_offset_step=2.0)  # for the comparison
            # oracle on a subsample spread over the day (every k-th sample)
            k = max(1, n // args.oracle_samples)
            sub = sci.isel(time=slice(0, None, k))
            t0 = time.perf_counter()
            ref = oracle_chain(sub, heat, temp, cal)
            t_oracle = time.perf_counter() - t0
    m = sub.sizes["time"]
    diff = max(float(np.abs(ds[f"b_{f}"].values[::k] - ref[f"b_{f}"].values).max())
               for f in ("mso", "j2000", "mbf", "rtn", "sc"))
    dpos = float(np.abs(ds["pos_mso"].values[::k] - ref["pos_mso"].values).max())
    fast_rate = n / t_fast
    oracle_rate = m / t_oracle
    print(f"simulated {n} vectors ({args.hours:g} h at 20 Hz) in {t_sim:.1f} s")
    print(f"warm-up on 20000 vectors (imports, compiled loops): {t_warm:.2f} s")
    print(f"freed memory retained between runs: {'yes' if retained else 'no'}")
    print(f"edr2cdr chain (5 frames, positions, flags, validation), {len(runs)} runs:")
    for k, (wall, (user, system)) in enumerate(zip(runs, cpu, strict=True)):
        print(f"  run {k + 1}: {wall:.2f} s (user {user:.2f} s, kernel {system:.2f} s) "
              f"{n / wall:12,.0f} vectors/s")
    print(f"  median {t_fast:.2f} s: {fast_rate:,.0f} vectors/s")
    for name, sec in steps.items():
        print(f"  {name:34s} {sec:6.2f} s  {n / sec:14,.0f} vectors/s")
    print(f"per-sample SPICE oracle chain: {m} vectors in {t_oracle:.2f} s, "
          f"{oracle_rate:,.0f} vectors/s")
    print(f"ratio fast / oracle: {fast_rate / oracle_rate:,.0f}x")
    print(f"max |fast - oracle|: field {diff:.2e} nT, MSO position {dpos:.2e} km")


if __name__ == "__main__":
    main()
