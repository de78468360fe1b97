"""The CDF writer uses cdflib's public writer only, in the forms that cost least memory.

Expected values: the file cdflib's writer (`cdflib.cdfwrite.CDF`) produces from the same
dataset with text given as a list of str (cdflib's list conversion: each string padded
with NUL to the width), byte for byte; memory bounds from cdflib's numeric conversion
(``np.array`` of the array, then ``tobytes``: two copies of it) and its ``bytes`` path
(``struct.unpack`` + ``pack`` of one ``<N>s`` item: two copies of the text's bytes).
"""

from __future__ import annotations

import ast
import tracemalloc
from pathlib import Path

import cdflib
import numpy as np
import pytest
import xarray as xr
from cdflib.cdfwrite import CDF as CdflibWriter

from fluxcal.products import cdf

from .conftest import make_dataset

CDF_CHAR = 51  # CDF data type number (CDF User's Guide, sec. 2.5)


def cdflib_writer_of_lists(ds: xr.Dataset) -> type:
    """cdflib's writer, given each text variable of ``ds`` as a list of str, not ``bytes``.

    fluxcal hands ASCII text over as one ``bytes`` of NUL-padded fixed-width values
    (issue 22: no Python list of a day's 1.7 M strings); cdflib's list conversion pads
    each string of the list with NUL to ``Num_Elements`` itself.  The list is made from
    the dataset's own strings, not from fluxcal's bytes.
    """

    class CdflibWriterOfLists(CdflibWriter):
        def write_var(self, var_spec, var_attrs=None, var_data=None):  # noqa: D102
            name = var_spec["Variable"]
            if isinstance(var_data, bytes) and name in ds.data_vars:
                assert var_spec["Data_Type"] == CDF_CHAR
                var_data = ds[name].values.astype(str).ravel().tolist()
            return super().write_var(var_spec, var_attrs=var_attrs, var_data=var_data)

    return CdflibWriterOfLists


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
        column=("time", wide[:, 1], kw),  # a strided 1-D view
        fortran=(("time", "component"), np.asfortranarray(wide[:, 3:]), kw),
        i8=("time", rng.integers(-100, 100, n).astype(np.int8), kw),
        i16=("time", rng.integers(-100, 100, n).astype(np.int16), kw),
        i64=("time", rng.integers(-100, 100, n).astype(np.int64), kw),
        u8=("time", rng.integers(0, 100, n).astype(np.uint8), kw),
        u16=("time", rng.integers(0, 100, n).astype(np.uint16), kw),
        u32=("time", rng.integers(0, 100, n).astype(np.uint32), kw),
        flag=("time", rng.integers(0, 2, n).astype(bool), kw),
        one=(("component",), np.array([1.0, 2.0, 3.0]), kw),  # not record-varying
        note=("time", np.array(["ok", "data gap", "", "x"] * n)[:n],  # padded to 8 with NUL
              {"units": " ", "description": "note"}),
    )


@pytest.mark.parametrize("n", [1, 2, 257])
def test_bytes_equal_cdflibs_own_conversion(tmp_path: Path, monkeypatch, n: int) -> None:
    ds = _mixed(n)
    ours = cdf.write_cdf(ds, tmp_path / "ours.cdf")
    monkeypatch.setattr(cdf, "CDFWriter", cdflib_writer_of_lists(ds))
    theirs = cdf.write_cdf(ds, tmp_path / "theirs.cdf")
    assert ours.read_bytes() == theirs.read_bytes()


@pytest.mark.parametrize("n", [1, 257])
def test_every_value_reads_back_with_cdflib(tmp_path: Path, n: int) -> None:
    """Row-major values of every type and memory layout; NaN as the ISTP fill -1e31."""
    ds = _mixed(n)
    got = cdflib.CDF(str(cdf.write_cdf(ds, tmp_path / "x.cdf")))
    np.testing.assert_array_equal(got.varget("Epoch").reshape(-1), ds["epoch"].values)
    for name, var in ds.data_vars.items():
        expected = var.values
        if expected.dtype.kind == "f":
            expected = np.where(np.isnan(expected), -1e31, expected)
        elif expected.dtype.kind == "U":
            expected = expected.astype(str)
        raw = np.asarray(got.varget(name)).reshape(var.shape)
        np.testing.assert_array_equal(raw.astype(expected.dtype) if expected.dtype == bool
                                      else raw, expected, err_msg=name)


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
    # the U26 column is 10.4 MB; its S26 bytes 2.6 MB, which cdflib's bytes path copies
    # twice (7.8 MB in all); through a list of 100,000 str it was 17.6 MB
    assert peak < text.nbytes, peak
    np.testing.assert_array_equal(cdf.read_cdf(path)["time_utc"].values.astype(str), text)


def test_a_large_vector_costs_cdflibs_two_copies_only(tmp_path: Path) -> None:
    # 2e5 x 3 float64 = 4.8 MB per vector: cdflib's conversion allocates two copies
    # (np.array, tobytes), 9.6 MB; the writer itself none (no ascontiguousarray, NaN
    # or type copy of a clean float64 vector).  tracemalloc sees numpy's buffers; the
    # limit leaves 2 MB for attributes.
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
    assert peak < 2 * 4.8e6 + 2e6, peak


def test_the_writer_uses_no_private_name_of_cdflib() -> None:
    """Project rule: no other library's private internals (decision 77).

    The module defines no class (no subclass of cdflib's writer) and reads no attribute
    whose name starts with one underscore on any object.
    """
    tree = ast.parse(Path(cdf.__file__).read_text())
    private = sorted({node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)
                      and node.attr.startswith("_") and not node.attr.startswith("__")})
    assert private == []
    assert not [n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]
