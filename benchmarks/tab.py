"""TAB writing speed: compiled fixed-width formatting against the old printf (``%``) path.

One 20 Hz MESSENGER day (1,728,000 rows) in the archive CDR layout, 12 columns
``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG X Y Z BX BY BZ``, written with
`fluxcal.products.write_tab` (label included), and the same rows formatted by the
former path (one Python ``%`` over 20,000-row chunks, ~0.4 us per value) in the same
run.  Prints rows/s of each and their ratio; the bytes of both are compared.

Run: ``.venv/bin/python benchmarks/tab.py [rows]``
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.products import Column, write_tab
from fluxcal.products.columns import resolve_columns
from fluxcal.products.tab import format_chunk

PRINTF = ["%4d", "%03d", "%02d", "%02d", "%06.3f", "%17.6f", "%14.3f", "%14.3f", "%14.3f",
          "%11.3f", "%11.3f", "%11.3f"]


def day(n: int) -> xr.Dataset:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.05
    return xr.Dataset(
        {
            "year": ("time", np.full(n, 2012, np.int32)),
            "doy": ("time", np.full(n, 153, np.int32)),
            "hour": ("time", (t // 3600).astype(np.int32)),
            "minute": ("time", (t // 60 % 60).astype(np.int32)),
            "second": ("time", t % 60),
            "met": ("time", 2.4e8 + t),
            "position": (("time", "component"), rng.normal(0, 5000, (n, 3))),
            "b": (("time", "component"), rng.normal(0, 300, (n, 3))),
        },
        coords={"component": ["x", "y", "z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z"},
    )


def columns() -> list[Column]:
    return [Column("year", "I4"), Column("doy", "I3.3"), Column("hour", "I2.2"),
            Column("minute", "I2.2"), Column("second", "%06.3f"), Column("met", "F17.6"),
            Column("position", "F14.3", label="{c}"), Column("b", "F11.3", label="b{c}")]


def old_printf(ds: xr.Dataset, chunk: int = 20_000) -> bytes:
    """The former formatting path: one ``%`` over the flattened values of each chunk."""
    cols = resolve_columns(ds, columns())
    values = [ds[c.variable].values if c.index is None else ds[c.variable].values[:, c.index]
              for c in cols]
    line = " ".join(PRINTF) + "\r\n"
    n = ds.sizes["time"]
    out = []
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        block = np.empty((stop - start, len(cols)), dtype=object)
        for j, v in enumerate(values):
            block[:, j] = v[start:stop].tolist()
        out.append((line * (stop - start)) % tuple(block.ravel().tolist()))
    return "".join(out).encode("ascii")


def main(n: int = 1_728_000) -> None:
    ds = day(n)
    cols = resolve_columns(ds, columns())
    format_chunk(ds, cols, 0, min(n, 10))  # compile (or load the numba cache) first
    with tempfile.TemporaryDirectory() as d:
        w0, c0 = time.perf_counter(), time.process_time()
        tab, _ = write_tab(ds, Path(d) / "MAGMSOSCI12153_V01", columns())
        w_new, c_new = time.perf_counter() - w0, time.process_time() - c0
        new = tab.read_bytes()
    c0 = time.process_time()
    arrays = [ds[c.variable].values if c.index is None else ds[c.variable].values[:, c.index]
              for c in cols]
    out = None
    for start in range(0, n, 100_000):
        out = format_chunk(ds, cols, start, min(n, start + 100_000), arrays, out)
    c_fmt = time.process_time() - c0
    w0, c0 = time.perf_counter(), time.process_time()
    old = old_printf(ds)
    w_old, c_old = time.perf_counter() - w0, time.process_time() - c0
    print(f"rows: {n:,}  columns: {len(cols)}  bytes: {len(new):,}  (wall / CPU of this process)")
    print(f"write_tab (compiled, to disk, label incl.): {w_new:6.2f} s / {c_new:6.2f} s CPU  "
          f"{n / c_new:12,.0f} rows/s CPU")
    print(f"  of which formatting only (no disk):                {c_fmt:6.2f} s CPU  "
          f"{n / c_fmt:12,.0f} rows/s CPU")
    print(f"old printf path (formatting only):          {w_old:6.2f} s / {c_old:6.2f} s CPU  "
          f"{n / c_old:12,.0f} rows/s CPU")
    print(f"speed-up (CPU): {c_old / c_new:.1f}x   identical bytes: {old == new}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_728_000)
