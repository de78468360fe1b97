"""Benchmark of the geometry core on one day of 20 Hz samples (1,728,000 epochs).

Times SCLK -> ET and TT2000, the rotation of field vectors MSGR_MAG -> J2000, MSO,
IAU_MERCURY and RTN,
and the positions (Sun/J2000, Mercury/MSO, Mercury/MBF, spherical RTN), against the
per-sample spiceypy oracle timed on a subsample, and prints vectors/s and speed-up.

Run: ``.venv/bin/python benchmarks/geometry.py [--rate 20] [--oracle-samples 20000]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.geometry import frames, positions
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

TARGETS = ["J2000", "MSGR_MSO", "IAU_MERCURY", "MSGR_RTN"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rate", type=float, default=20.0)
    parser.add_argument("--oracle-samples", type=int, default=20000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        meta = write_messenger_like_kernels(Path(tmp), "2012-06-01T00:00:00", 86400.0)
        with KernelPool([meta]):
            run(args.rate, args.oracle_samples)


def run(rate: float, n_oracle: int) -> None:
    clock = SclkKernel.from_pool(-236)
    part, met0 = clock.from_et(np.array([spiceypy.str2et("2012-06-01T00:00:00")]))
    met = met0[0] + np.arange(0.0, 86400.0 - 1.0, 1.0 / rate)
    n = met.size
    partition = np.full(n, part[0])
    print(f"{n} samples ({rate:g} Hz, one day)")

    t = time.perf_counter()
    et, _tt2000 = clock.to_et_and_tt2000(partition, met)
    t_time = time.perf_counter() - t

    b_mag = np.random.default_rng(0).normal(scale=300.0, size=(n, 3))
    t = time.perf_counter()
    rot = frames.Rotator("MSGR_MAG", et)
    for target in TARGETS:
        rot.rotate(target, b_mag)
    t_rot = time.perf_counter() - t

    t = time.perf_counter()
    positions.position("MESSENGER", "SUN", "J2000", et)
    positions.position("MESSENGER", "MERCURY", "MSGR_MSO", et)
    positions.position("MESSENGER", "MERCURY", "IAU_MERCURY", et)
    positions.rtn_spherical("MESSENGER", et)
    t_pos = time.perf_counter() - t

    # oracle on a subsample: scs2e + pxform x4 + spkpos x3 per sample
    idx = np.linspace(0, n - 1, n_oracle).astype(int)
    t = time.perf_counter()
    for i in idx:
        clock_string = f"{part[0]}/{int(met[i])}:{int(round((met[i] % 1) * 1e6)) % 1000000}"
        spiceypy.scs2e(-236, clock_string)
    t_time_o = (time.perf_counter() - t) / idx.size * n
    t = time.perf_counter()
    for i in idx:
        for target in TARGETS:
            spiceypy.mxv(spiceypy.pxform("MSGR_MAG", target, float(et[i])), b_mag[i])
    t_rot_o = (time.perf_counter() - t) / idx.size * n
    t = time.perf_counter()
    for i in idx:
        spiceypy.spkpos("MESSENGER", float(et[i]), "J2000", "NONE", "SUN")
        spiceypy.spkpos("MESSENGER", float(et[i]), "MSGR_MSO", "NONE", "MERCURY")
        spiceypy.spkpos("MESSENGER", float(et[i]), "IAU_MERCURY", "NONE", "MERCURY")
    t_pos_o = (time.perf_counter() - t) / idx.size * n

    rows = [
        ("SCLK -> ET -> TT2000", t_time, t_time_o),
        ("4 rotations (MAG->J2000/MSO/MBF/RTN)", t_rot, t_rot_o),
        ("positions (3 Cartesian + RTN spherical)", t_pos, t_pos_o),
        ("time + 4 rotations", t_time + t_rot, t_time_o + t_rot_o),
    ]
    print(f"{'step':42s} {'fluxcal s':>10s} {'vectors/s':>12s} {'oracle s*':>10s} {'speed-up':>9s}")
    for name, fast, oracle in rows:
        print(f"{name:42s} {fast:10.3f} {n / fast:12.3g} {oracle:10.1f} {oracle / fast:8.0f}x")
    print("* oracle = one spiceypy call per sample, timed on", idx.size, "samples and scaled")


if __name__ == "__main__":
    main()
