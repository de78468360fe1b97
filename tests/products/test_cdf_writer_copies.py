"""The CDF writer hands numeric arrays to cdflib without copies, and writes cdflib's bytes.

Expected values: the file cdflib's own writer (`cdflib.cdfwrite.CDF`, its conversion
with ``np.array`` + ``tobytes``) produces from the same dataset, byte for byte.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from cdflib.cdfwrite import CDF as CdflibWriter

from fluxcal.products import cdf

from .conftest import make_dataset


class CdflibWriterOfLists(CdflibWriter):
    """cdflib's own writer, given text as the list of str `cdf._payload` handed it before.

    fluxcal's writer takes text as a fixed-width ``S`` array (issue 22: no Python list of
    a day's 1.7 M strings); cdflib's own conversion takes the list.
    """

    def write_var(self, var_spec, var_attrs=None, var_data=None):  # noqa: D102
        if isinstance(var_data, np.ndarray) and var_data.dtype.kind == "S":
            var_data = [s.decode("ascii") for s in var_data.tolist()]
        return super().write_var(var_spec, var_attrs=var_attrs, var_data=var_data)


def _mixed(n: int) -> xr.Dataset:
    """Every numeric CDF type, NaN and a non-contiguous array."""
    ds = make_dataset(n, seed=3)
    rng = np.random.default_rng(4)
    b = ds["B_mso"].values.copy()
    b[::7, 1] = np.nan  # NaN -> FILLVAL (a converted copy, then the no-copy path)
    wide = rng.normal(0, 1, (n, 6))
    kw = {"units": "1", "description": "test", "valid_min": -1e3, "valid_max": 1e3}
    return ds.assign(
        B_mso=(("time", "component"), b, ds["B_mso"].attrs),
        strided=(("time", "component"), wide[:, ::2], kw),  # not C-contiguous
        i8=("time", rng.integers(-100, 100, n).astype(np.int8), kw),
        i16=("time", rng.integers(-100, 100, n).astype(np.int16), kw),
        i64=("time", rng.integers(-100, 100, n).astype(np.int64), kw),
        u8=("time", rng.integers(0, 100, n).astype(np.uint8), kw),
        u16=("time", rng.integers(0, 100, n).astype(np.uint16), kw),
        u32=("time", rng.integers(0, 100, n).astype(np.uint32), kw),
        flag=("time", rng.integers(0, 2, n).astype(bool), kw),
        one=(("component",), np.array([1.0, 2.0, 3.0]), kw),  # not record-varying
    )


@pytest.mark.parametrize("n", [1, 2, 257])
def test_bytes_equal_cdflibs_own_conversion(tmp_path: Path, monkeypatch, n: int) -> None:
    ds = _mixed(n)
    ours = cdf.write_cdf(ds, tmp_path / "ours.cdf")
    monkeypatch.setattr(cdf, "_Writer", CdflibWriterOfLists)
    theirs = cdf.write_cdf(ds, tmp_path / "theirs.cdf")
    assert ours.read_bytes() == theirs.read_bytes()


def test_a_text_column_is_not_a_python_list(tmp_path: Path) -> None:
    """A day of 26-character UTC strings: fixed-width bytes, not 1.7 M Python strings."""
    n = 100_000
    text = np.array([f"2014-08-01T00:00:{i % 60:02d}.{i:06d}" for i in range(n)])
    ds = xr.Dataset({"time_utc": ("time", text, {"units": "UTC", "description": "UTC"})},
                    coords={"epoch": ("time", 757_339_269_184_000_123
                                      + np.arange(n, dtype=np.int64) * 50_000_000)})
    cdf.write_cdf(ds.isel(time=slice(0, 10)), tmp_path / "warm.cdf")
    tracemalloc.start()
    try:
        path = cdf.write_cdf(ds, tmp_path / "text.cdf")
        _current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 0.5 * text.nbytes, peak  # the U26 column is 10.4 MB; its S26 copy 2.6 MB
    np.testing.assert_array_equal(cdf.read_cdf(path)["time_utc"].values.astype(str), text)


def test_a_large_vector_is_not_copied(tmp_path: Path) -> None:
    # 2e5 x 3 float64 = 4.8 MB per vector: cdflib's conversion allocates two more
    # (np.array, tobytes), 9.6 MB; the writer may allocate small bookkeeping only.
    # tracemalloc sees numpy's buffers; the limit 2 MB leaves room for attributes.
    n = 200_000
    rng = np.random.default_rng(5)
    ds = xr.Dataset(
        {"B_mso": (("time", "component"), rng.normal(0, 300, (n, 3)),
                   {"units": "nT", "description": "Magnetic field, MSO"})},
        coords={"epoch": ("time", 757_339_269_184_000_123 + np.arange(n, dtype=np.int64)
                          * 50_000_000),
                "component": ("component", np.array(["x", "y", "z"]))},
    )
    cdf.write_cdf(ds.isel(time=slice(0, 10)), tmp_path / "warm.cdf")  # load the tables
    tracemalloc.start()
    try:
        cdf.write_cdf(ds, tmp_path / "big.cdf")
        _current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2e6, peak
