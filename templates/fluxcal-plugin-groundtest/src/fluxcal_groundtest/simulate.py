"""Forward model of the ground-test fluxgate: a known coil field -> CSV counts (no pipeline code).

The bench values (`BENCH`) are those of ``data/groundtest_calib_v1.txt``, typed in again:
the tests' expected field is `simulate`'s truth, never the pipeline's output.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

BENCH = {"t0": 20.0, "offset": [12.0, -8.0, 5.0], "offset_drift": [0.5, -0.3, 0.2],
         "gain": [0.10, 0.11, 0.095], "gain_drift": [-2.0e-4, 1.5e-4, -1.0e-4],
         "misalignment": [[1.0, 0.002, -0.001], [0.0015, 1.0, 0.003], [-0.002, 0.001, 1.0]]}


def simulate(start: str, seconds: float, rate_hz: float = 1.0):
    """Return (UTC times datetime64[us], counts (n, 3) int, degC (n,), true field (n, 3) nT)."""
    t = np.arange(int(seconds * rate_hz)) / rate_hz
    times = np.datetime64(start, "us") + (t * 1e6).astype("m8[us]")
    b = np.stack([2e4 * np.sin(2 * np.pi * t / 600), -1.5e4 * np.cos(2 * np.pi * t / 900),
                  5e3 + 3e3 * np.sin(2 * np.pi * t / 1300)], axis=1)
    temp = np.round(20.0 + 25.0 * np.sin(2 * np.pi * t / 7200), 3)
    dtemp = temp[:, None] - BENCH["t0"]
    sensor = np.linalg.solve(np.array(BENCH["misalignment"]), b.T).T
    counts = (sensor / (np.array(BENCH["gain"]) * (1 + np.array(BENCH["gain_drift"]) * dtemp))
              + BENCH["offset"] + np.array(BENCH["offset_drift"]) * dtemp)
    return times, np.round(counts).astype(np.int64), temp, b


def write_csv(path: Path, times, counts, temp) -> Path:
    """Write the logger's CSV (``time_utc,cx,cy,cz,temp_c``)."""
    rows = np.column_stack([np.datetime_as_string(times, unit="us"), counts, temp])
    np.savetxt(path, rows, fmt="%s", delimiter=",", header="time_utc,cx,cy,cz,temp_c",
               comments="")
    return Path(path)


def simulate_days(input_dir: Path, days, minutes: float = 60.0) -> None:
    """Write ``GT_<yyyymmdd>.csv`` per day: ``minutes`` at 1 Hz from 23:30 (across midnight)."""
    Path(input_dir).mkdir(parents=True, exist_ok=True)
    for day in days:
        times, counts, temp, _ = simulate(f"{day}T23:30:00", minutes * 60)
        write_csv(Path(input_dir) / f"GT_{day:%Y%m%d}.csv", times, counts, temp)
