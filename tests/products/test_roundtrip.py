"""One round-trip suite shared by every product writer (write, read back, compare)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fluxcal.products.atomic as atomic_mod
from fluxcal.errors import InputFormatError
from fluxcal.products import Column, read_fluxcal_product, write_product, zarr_available
from fluxcal.products.label import find_objects
from fluxcal.products.tab import read_label
from fluxcal.products.timeindex import with_time_index

from .conftest import EPOCH0, make_dataset

FORMATS = [
    "tab",
    "cdf",
    "nc",
    pytest.param("zarr", marks=pytest.mark.skipif(not zarr_available(),
                                                  reason="optional zarr not installed")),
]
MAIN_FILE = {"tab": ".TAB", "cdf": ".cdf", "nc": ".nc", "zarr": ".zarr"}


def _roundtrip(ds: xr.Dataset, fmt: str, tmp: Path, **kw) -> tuple[xr.Dataset, list[Path]]:
    paths = write_product(ds, tmp / "PROD", formats=(fmt,), **kw)
    return read_fluxcal_product(tmp / f"PROD{MAIN_FILE[fmt]}"), paths


def _assert_same_science(ds: xr.Dataset, back: xr.Dataset) -> None:
    # Times to the nanosecond: int64 TT2000 compared exactly.
    assert back["epoch"].dtype == np.int64
    np.testing.assert_array_equal(back["epoch"].values, ds["epoch"].values)
    for name in ds.data_vars:
        assert back[name].dims == ds[name].dims, name
        assert back[name].dtype == ds[name].dtype, name
        np.testing.assert_array_equal(back[name].values, ds[name].values, err_msg=name)
        assert back[name].attrs["units"] == ds[name].attrs["units"]
    np.testing.assert_array_equal(back["component"].values, ds["component"].values)


def _assert_attrs_kept(ds: xr.Dataset, back: xr.Dataset) -> None:
    # Every dataset attribute (provenance included) comes back equal; formats may add more
    # (ISTP global attributes in CDF).
    for k, v in ds.attrs.items():
        assert back.attrs[k] == v, k


@pytest.mark.parametrize("fmt", FORMATS)
def test_roundtrip_exact(fmt: str, dataset: xr.Dataset, tmp_path: Path) -> None:
    back, paths = _roundtrip(dataset, fmt, tmp_path)
    assert all(p.exists() for p in paths)
    _assert_same_science(dataset, back)
    _assert_attrs_kept(dataset, back)
    for name in dataset.data_vars:
        assert back[name].attrs.get("description") == dataset[name].attrs["description"]


@pytest.mark.parametrize("fmt", FORMATS)
def test_roundtrip_empty_day(fmt: str, tmp_path: Path) -> None:
    ds = make_dataset(0)
    back, _ = _roundtrip(ds, fmt, tmp_path)
    assert back.sizes.get("time", 0) == 0


@pytest.mark.parametrize("fmt", [f for f in FORMATS if f != "tab"])
def test_roundtrip_keeps_nan(fmt: str, dataset: xr.Dataset, tmp_path: Path) -> None:
    ds = dataset.copy(deep=True)
    ds["B_mso"].values[3, 1] = np.nan
    back, _ = _roundtrip(ds, fmt, tmp_path)
    assert np.isnan(back["B_mso"].values[3, 1])
    np.testing.assert_array_equal(back["B_mso"].values, ds["B_mso"].values)


def test_tab_printed_precision(dataset: xr.Dataset, tmp_path: Path) -> None:
    cols = [Column("epoch", "%d"), Column("utc", "%s"), Column("position", "%11.2f", label="{c}"),
            Column("B_mso", "%10.3f", label="b{c}"), Column("temperature", "%7.2f"),
            Column("quality", "%3d")]
    write_product(dataset, tmp_path / "P", formats=("tab",), columns=cols)
    back = read_fluxcal_product(tmp_path / "P.TAB")
    # "%10.3f" rounds to the nearest 0.001 nT: error <= 0.0005 (+ binary rounding slack).
    np.testing.assert_allclose(back["B_mso"].values, dataset["B_mso"].values, rtol=0,
                               atol=0.0005 + 1e-9)
    np.testing.assert_allclose(back["position"].values, dataset["position"].values, rtol=0,
                               atol=0.005 + 1e-9)
    np.testing.assert_allclose(back["temperature"].values, dataset["temperature"].values,
                               rtol=0, atol=0.005 + 1e-6)
    np.testing.assert_array_equal(back["epoch"].values, dataset["epoch"].values)
    np.testing.assert_array_equal(back["utc"].values, dataset["utc"].values)
    np.testing.assert_array_equal(back["quality"].values, dataset["quality"].values)


def test_tab_label_describes_fixed_width_columns(dataset: xr.Dataset, tmp_path: Path) -> None:
    cols = [Column("utc", "%-22s"), Column("B_mso", "%10.3f", label="b{c}"),
            Column("quality", "%4d")]
    write_product(dataset, tmp_path / "P", formats=("tab",), columns=cols)
    label = read_label(tmp_path / "P.LBL")
    table = find_objects(label, "TABLE")[0]
    columns = [dict(c) for c in find_objects(table, "COLUMN")]
    assert [c["NAME"] for c in columns] == ["utc", "bx", "by", "bz", "quality"]
    assert [c["UNIT"] for c in columns] == ["N/A", "nT", "nT", "nT", "1"]  # PDS3: no unit
    row_bytes = dict(table)["ROW_BYTES"]
    raw = (tmp_path / "P.TAB").read_bytes()
    assert len(raw) == row_bytes * dataset.sizes["time"]
    # Independent check: slice each row by the label's byte positions and parse.
    row7 = raw[7 * row_bytes:8 * row_bytes].decode()
    bx = columns[1]
    value = float(row7[bx["START_BYTE"] - 1:bx["START_BYTE"] - 1 + bx["BYTES"]])
    assert value == pytest.approx(dataset["B_mso"].values[7, 0], abs=0.0005 + 1e-9)
    assert row7.endswith("\r\n")


def test_tab_label_has_provenance(dataset: xr.Dataset, tmp_path: Path) -> None:
    write_product(dataset, tmp_path / "P", formats=("tab",),
                  label_extra={"MISSION_NAME": "MESSENGER"})
    text = (tmp_path / "P.LBL").read_text()
    for needle in ("SOFTWARE_VERSION_ID = \"0.1.0\"", "INPUT_FILE_SHA256", "ab" * 32,
                   "CALIBRATION_NAME = (\"table2\")", "KERNEL_NAME", "COMMAND_LINE",
                   "PRODUCT_CREATION_TIME = \"2026-01-01T00:00:00Z\"",
                   "MISSION_NAME = \"MESSENGER\""):
        assert needle in text, needle


def test_same_run_twice_same_science_bytes(dataset: xr.Dataset, tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    ds2 = dataset.copy()
    ds2.attrs = {**dataset.attrs, "creation_time": "2026-06-30T12:00:00Z"}
    write_product(dataset, a / "P", formats=("tab", "cdf", "nc"))
    write_product(ds2, b / "P", formats=("tab", "cdf", "nc"))
    assert (a / "P.TAB").read_bytes() == (b / "P.TAB").read_bytes()
    la = (a / "P.LBL").read_text().splitlines()
    lb = (b / "P.LBL").read_text().splitlines()
    diff = [(x, y) for x, y in zip(la, lb, strict=True) if x != y]
    assert diff and all("2026-" in x and "creation" in x.lower() for x, _ in diff)
    for fmt in (".cdf", ".nc"):
        ra, rb = read_fluxcal_product(a / f"P{fmt}"), read_fluxcal_product(b / f"P{fmt}")
        xr.testing.assert_equal(ra.drop_attrs(), rb.drop_attrs())


# --- atomicity ---------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
def test_failed_rename_leaves_nothing(fmt: str, dataset: xr.Dataset, tmp_path: Path,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[int] = []

    def broken_replace(src, dst):
        # The temporary file was fully written before the crash.
        p = Path(src)
        seen.append(p.stat().st_size if p.is_file() else 1)
        raise OSError("simulated crash before rename")

    # Only fluxcal's final rename fails: patching os.replace process-wide would also break
    # the writers' own renames (zarr renames every chunk it writes, from its I/O thread).
    class OsWithBrokenReplace:
        replace = staticmethod(broken_replace)

        def __getattr__(self, name: str):
            return getattr(os, name)

    monkeypatch.setattr(atomic_mod, "os", OsWithBrokenReplace())
    with pytest.raises(OSError, match="simulated crash"):
        write_product(dataset, tmp_path / "P", formats=(fmt,))
    assert seen and seen[0] > 0
    assert list(tmp_path.iterdir()) == []


def test_cdf_crash_mid_write_leaves_nothing(dataset: xr.Dataset, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    from cdflib.cdfwrite import CDF

    original = CDF.write_var
    calls = {"n": 0}

    def flaky(self, *a, **kw):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("disk full")
        return original(self, *a, **kw)

    monkeypatch.setattr(CDF, "write_var", flaky)
    with pytest.raises(RuntimeError, match="disk full"):
        write_product(dataset, tmp_path / "P", formats=("cdf",))
    assert list(tmp_path.iterdir()) == []


def test_nc_crash_mid_write_keeps_older_product(dataset: xr.Dataset, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    write_product(dataset, tmp_path / "P", formats=("nc",))
    before = (tmp_path / "P.nc").read_bytes()

    def half_written(self, path, *a, **kw):
        Path(path).write_bytes(b"CDF\x01" + b"\0" * 100)  # a partial netCDF header
        raise OSError("killed")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", half_written)
    with pytest.raises(OSError, match="killed"):
        write_product(dataset.isel(time=slice(0, 3)), tmp_path / "P", formats=("nc",))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["P.nc"]
    assert (tmp_path / "P.nc").read_bytes() == before


def test_tab_bad_string_is_an_error_and_writes_nothing(dataset: xr.Dataset,
                                                       tmp_path: Path) -> None:
    ds = dataset.copy(deep=True)
    ds["utc"] = ds["utc"].str.replace("T", " ")
    with pytest.raises(InputFormatError, match="whitespace") as exc:
        write_product(ds, tmp_path / "P", formats=("tab",))
    assert "utc" in str(exc.value)
    assert list(tmp_path.iterdir()) == []


def test_unknown_column_names_the_variable(dataset: xr.Dataset, tmp_path: Path) -> None:
    with pytest.raises(InputFormatError, match="B_rtn"):
        write_product(dataset, tmp_path / "P", formats=("tab",), columns=[Column("B_rtn")])


def test_unknown_format(dataset: xr.Dataset, tmp_path: Path) -> None:
    with pytest.raises(InputFormatError, match="hdf9"):
        write_product(dataset, tmp_path / "P", formats=("hdf9",))


# --- round-trip law (hypothesis) ----------------------------------------------------------

#: Any finite or NaN value but the CDF fill value -1e31, which the CDF writer refuses
#: out loud (a reader would take it for a missing value; test_cdf_attribute_links).
_floats = hnp.arrays(np.float64, st.integers(0, 20).map(lambda n: (n, 3)),
                     elements=st.floats(allow_nan=True, allow_infinity=False, width=64)
                     .filter(lambda x: x != -1e31))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(b=_floats, offset=st.integers(-(2**62), 2**62 - 10**12),
       fmt=st.sampled_from(["tab", "cdf", "nc", *(["zarr"] if zarr_available() else [])]))
def test_roundtrip_law(b: np.ndarray, offset: int, fmt: str) -> None:
    """read(write(ds)) == ds for any finite/NaN field but -1e31, any TT2000 epoch, every format.

    +-2**62 ns is +-146 years around J2000, inside the UTC datetime64[ns] range of the
    ``time`` index (1678-2262) that netCDF and Zarr store beside the int64 epoch.
    """
    n = b.shape[0]
    epoch = offset + np.arange(n, dtype=np.int64) * 1_000_000_007
    ds = xr.Dataset(
        {"B": (("time", "component"), b, {"units": "nT", "description": "field"})},
        coords={"epoch": ("time", epoch, {"units": "ns"}), "component": ["x", "y", "z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z", "note": "law"},
    )
    with tempfile.TemporaryDirectory() as d:
        back, _ = _roundtrip(ds, fmt, Path(d))
        np.testing.assert_array_equal(back["epoch"].values, epoch)
        np.testing.assert_array_equal(back["B"].values, b)
        assert back.attrs["note"] == "law"


def test_epoch_precision_nanosecond(tmp_path: Path) -> None:
    ds = make_dataset(3)
    ds = ds.assign_coords(epoch=("time", np.array([EPOCH0, EPOCH0 + 1, EPOCH0 + 2], np.int64)))
    for fmt in ("tab", "cdf", "nc"):
        back, _ = _roundtrip(ds, fmt, tmp_path / fmt)
        assert np.diff(back["epoch"].values).tolist() == [1, 1], fmt


def test_no_stray_temporary_files(dataset: xr.Dataset, tmp_path: Path) -> None:
    write_product(dataset, tmp_path / "P", formats=("tab", "cdf", "nc"))
    assert sorted(os.listdir(tmp_path)) == ["P.LBL", "P.TAB", "P.cdf", "P.nc"]


def test_failing_format_leaves_no_file_of_the_product(dataset: xr.Dataset, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """TAB and CDF succeed, netCDF fails: none of the three appears (all-or-nothing)."""
    write_product(dataset, tmp_path / "P", formats=("tab", "cdf", "nc"))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def broken(self, *a, **kw):
        raise OSError("no space left")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError, match="no space"):
        write_product(dataset.isel(time=slice(0, 5)), tmp_path / "P",
                      formats=("tab", "cdf", "nc"))
    with pytest.raises(OSError, match="no space"):
        write_product(dataset, tmp_path / "Q", formats=("tab", "cdf", "nc"))
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


# --- the time index ------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
def test_writers_accept_a_time_index_and_readers_return_it(fmt: str, dataset: xr.Dataset,
                                                           tmp_path: Path) -> None:
    indexed = with_time_index(dataset)
    assert indexed["time"].dtype == np.dtype("M8[ns]") and "time" in indexed.indexes
    back, _ = _roundtrip(indexed, fmt, tmp_path)
    _assert_same_science(dataset, back)
    np.testing.assert_array_equal(back["time"].values, indexed["time"].values)
    assert "time" in back.indexes
    back2, _ = _roundtrip(dataset, fmt, tmp_path / "plain")  # without the index too
    np.testing.assert_array_equal(back2["time"].values, indexed["time"].values)


def test_time_index_is_cdflibs_utc_and_selects(dataset: xr.Dataset) -> None:
    import cdflib

    ds = with_time_index(dataset)
    # an outside maintained conversion (cdflib's own leap-second table), to the nanosecond
    np.testing.assert_array_equal(ds["time"].values,
                                  cdflib.cdfepoch.to_datetime(dataset["epoch"].values))
    assert ds["epoch"].dtype == np.int64  # the exact time stays
    one = ds.sel(time="2024-01-01T00:00:01.000000143")
    assert one["epoch"].item() == dataset["epoch"].values[20]
    # pandas partial-string slicing: "...:01" ends after the whole second 01
    part = ds.sel(time=slice("2024-01-01T00:00:00.5", "2024-01-01T00:00:01"))
    assert part.sizes["time"] == 30  # samples 10..39 (50 ms steps)
    assert part["epoch"].values[0] == dataset["epoch"].values[10]
    assert ds.resample(time="1s").mean()["B_mso"].shape == (3, 3)


def test_time_index_across_a_leap_second() -> None:
    import cdflib

    # 2016-12-31T23:59:60 is a leap second: UTC datetime64 has no :60, the index clamps
    # it to 23:59:59.999999999 (sorted, never in the next day)
    t60 = int(cdflib.cdfepoch.compute_tt2000([2016, 12, 31, 23, 59, 60, 0, 0, 0]))
    epoch = t60 + np.array([-10**9, 0, 5 * 10**8, 10**9], dtype=np.int64)
    ds = with_time_index(xr.Dataset({"b": ("time", np.arange(4.0))},
                                    coords={"epoch": ("time", epoch)}))
    assert [str(t) for t in ds["time"].values] == [
        "2016-12-31T23:59:59.000000000", "2016-12-31T23:59:59.999999999",
        "2016-12-31T23:59:59.999999999", "2017-01-01T00:00:00.000000000"]
    assert ds.indexes["time"].is_monotonic_increasing


def test_time_index_needs_an_int64_epoch() -> None:
    ds = xr.Dataset({"b": ("time", [1.0])}, coords={"epoch": ("time", [1.5])})
    with pytest.raises(InputFormatError, match="epoch"):
        with_time_index(ds)
    assert with_time_index(xr.Dataset({"c": ("x", [1])})).identical(
        xr.Dataset({"c": ("x", [1])}))


def test_cf_time_is_what_xarrays_encoder_writes(dataset: xr.Dataset, tmp_path: Path) -> None:
    write_product(dataset, tmp_path / "P", formats=("nc",))
    ref = xr.Dataset(coords={"time": with_time_index(dataset)["time"].values})
    ref["time"].encoding = {"units": "nanoseconds since 1970-01-01T00:00:00",
                            "calendar": "proleptic_gregorian", "dtype": "int64"}
    ref.to_netcdf(tmp_path / "ref.nc", engine="h5netcdf")
    with xr.open_dataset(tmp_path / "P.nc", decode_times=False) as a, \
            xr.open_dataset(tmp_path / "ref.nc", decode_times=False) as b:
        assert a["time"].dtype == b["time"].dtype == np.int64
        np.testing.assert_array_equal(a["time"].values, b["time"].values)
        for key in ("units", "calendar"):
            assert a["time"].attrs[key] == b["time"].attrs[key]
    with xr.open_dataset(tmp_path / "P.nc") as plain:  # and decodes to the index
        np.testing.assert_array_equal(plain["time"].values,
                                      with_time_index(dataset)["time"].values)
