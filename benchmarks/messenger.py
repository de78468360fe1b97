"""MESSENGER MAG edr2cdr throughput: one simulated day of 20 Hz data.

Runs every step of seed 000 sec. 5-13 on in-memory streams (all five frames, positions,
quality flags, offset validation; no file reading or formatting) and prints vectors/s,
then the same chain with one SPICE call per sample (scs2e, pxform per frame, spkpos per
position) on a subsample, and the ratio of the per-vector costs.

Usage: .venv/bin/python benchmarks/messenger.py [--hours 24] [--oracle-samples 2000]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import write_messenger_like_kernels
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.pipeline import calibrate
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate


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
    args = parser.parse_args()
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
            calibrate(sci.isel(time=slice(0, 20000)), heat, temp, cal)  # warm-up (imports)
            t0 = time.perf_counter()
            ds = calibrate(sci, heat, temp, cal, max_offset_step=2.0)
            t_fast = time.perf_counter() - t0
            steps = breakdown(sci, heat, temp, cal)
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
    print(f"edr2cdr chain (5 frames, positions, flags, validation): {t_fast:.2f} s, "
          f"{fast_rate:,.0f} vectors/s")
    for name, sec in steps.items():
        print(f"  {name:34s} {sec:6.2f} s  {n / sec:14,.0f} vectors/s")
    print(f"per-sample SPICE oracle chain: {m} vectors in {t_oracle:.2f} s, "
          f"{oracle_rate:,.0f} vectors/s")
    print(f"ratio fast / oracle: {fast_rate / oracle_rate:,.0f}x")
    print(f"max |fast - oracle|: field {diff:.2e} nT, MSO position {dpos:.2e} km")


if __name__ == "__main__":
    main()
