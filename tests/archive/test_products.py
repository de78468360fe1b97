"""Archived calibrated products (`fluxcal.archive.products.read_archive_product`).

Tables in the archive layouts are written with fluxcal's table writer and the column
lists of the missions (or hand-written, for the V9 quality string); the expected epochs
come from cdflib (``compute_tt2000``, an outside implementation), the field values from
the values written (within half a unit of the printed last digit).
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.archive.products import read_archive_product as read_with
from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.archive_products import messenger_epoch
from fluxcal.products import Column, write_product
from fluxcal.runs import registry


def read_archive_product(path: Path):
    """The archive reader with every registered mission's readers (as the CLI passes them)."""
    return read_with(path, registry.archived_readers())


def _cdflib_tt2000(parts: list[list[int]]) -> np.ndarray:
    return np.asarray(cdflib.cdfepoch.compute_tt2000(parts), dtype=np.int64).reshape(-1)


def _messenger(n: int, rtn: bool, averaged: bool, sc: bool = False) -> xr.Dataset:
    rng = np.random.default_rng(8)
    second = np.round((np.arange(n) * 0.05 + 0.012) % 60, 3)
    data = {
        "year": ("time", np.full(n, 2012)), "doy": ("time", np.full(n, 153)),
        "hour": ("time", np.full(n, 7)), "minute": ("time", (np.arange(n) * 0.05 // 60)
                                                   .astype(int)),
        "second": ("time", second),
        "met": ("time", 2.4e8 + np.arange(n) * 0.05, {"units": "s"}),
        "b": (("time", "b_component"), rng.normal(0, 400, (n, 3)), {"units": "nT"}),
    }
    if rtn:
        data.update(r=("time", rng.uniform(4e7, 7e7, n), {"units": "km"}),
                    latitude=("time", rng.uniform(-7, 7, n), {"units": "deg"}),
                    azimuth=("time", rng.uniform(-180, 180, n), {"units": "deg"}))
    elif not sc:
        data["position"] = (("time", "position_component"), rng.normal(0, 3e3, (n, 3)),
                            {"units": "km"})
    if averaged:
        data["count"] = ("time", np.full(n, 20))
        data["b_std"] = (("time", "b_component"), rng.uniform(0, 5, (n, 3)), {"units": "nT"})
    labels = ["B_R", "B_T", "B_N"] if rtn else ["B_X", "B_Y", "B_Z"]
    return xr.Dataset(data, coords={"b_component": labels,
                                    "position_component": ["X", "Y", "Z"]},
                      attrs={"creation_time": "2026-01-01T00:00:00Z"})


@pytest.mark.parametrize(("frame", "averaged"), [("mso", False), ("mso", True),
                                                 ("rtn", False), ("rtn", True),
                                                 ("sc", False)])
def test_messenger_cdr_rdr(tmp_path: Path, frame: str, averaged: bool) -> None:
    from fluxcal.missions.messenger.products import product_name, table_columns

    n = 300
    ds = _messenger(n, frame == "rtn", averaged, frame == "sc")
    name = product_name(frame, "12153", 2, 1 if averaged else None)
    write_product(ds, tmp_path / name, ("tab",), table_columns(frame, averaged))
    p = read_archive_product(tmp_path / f"{name}.LBL")
    expected = _cdflib_tt2000([[2012, 6, 1, 7, int(m), int(s), int(round(s * 1000)) % 1000,
                                0, 0] for m, s in zip(ds["minute"].values,
                                                      ds["second"].values, strict=True)])
    np.testing.assert_array_equal(p["epoch"].values, expected)
    assert p["time"].values[0] == np.datetime64("2012-06-01T07:00:00.012")
    # F11.3 in the table: half a unit of the third decimal
    np.testing.assert_allclose(p["b"].values, ds["b"].values, atol=5e-4 + 1e-9)
    np.testing.assert_allclose(p["b_total"].values, np.linalg.norm(p["b"].values, axis=1),
                               rtol=1e-15)
    code = {"mso": "MSO", "rtn": "RTN", "sc": "SC"}[frame]
    assert p["b"].attrs["frame"] == code and p["b"].attrs["units"] == "nT"
    axes = ["B_R", "B_T", "B_N"] if frame == "rtn" else ["B_X", "B_Y", "B_Z"]
    assert p["b_component"].values.tolist() == axes
    assert p.attrs["product_type"] == ("RDR" if averaged else "CDR")
    assert "quality" not in p  # the archived tables have no quality column
    np.testing.assert_allclose(p["met"].values, ds["met"].values, atol=5e-7)
    if frame == "rtn":
        np.testing.assert_allclose(p["r"].values, ds["r"].values, atol=0.05 + 1e-6)
    elif frame == "mso":
        np.testing.assert_allclose(p["position"].values, ds["position"].values, atol=5e-4)
    else:
        assert "position" not in p and "r" not in p
    if averaged:
        assert p.attrs["average_seconds"] == 1.0
        np.testing.assert_array_equal(p["count"].values, 20)
        np.testing.assert_allclose(p["b_std"].values, ds["b_std"].values, atol=5e-4 + 1e-9)


def test_messenger_epoch_leap_second_and_day_of_year() -> None:
    # 2012-06-30 ended with a leap second; day 366 of 2008 (a leap year)
    e = messenger_epoch(np.array([2012, 2012, 2008]), np.array([182, 183, 366]),
                        np.array([23, 0, 12]), np.array([59, 0, 0]),
                        np.array([60.5, 0.25, 1.999]))
    expected = _cdflib_tt2000([[2012, 6, 30, 23, 59, 60, 500, 0, 0],
                               [2012, 7, 1, 0, 0, 0, 250, 0, 0],
                               [2008, 12, 31, 12, 0, 1, 999, 0, 0]])
    np.testing.assert_array_equal(e, expected)


def test_messenger_field_out_of_range_names_row_and_column() -> None:
    with pytest.raises(InputFormatError) as err:
        messenger_epoch(np.full(3, 2012), np.array([1, 2, 367]), np.zeros(3), np.zeros(3),
                        np.zeros(3), Path("X.LBL"))
    assert err.value.line == 3 and err.value.field == "DAY_OF_YEAR"


def _rosetta(n: int, level: str) -> tuple[xr.Dataset, list[str]]:
    rng = np.random.default_rng(9)
    t0 = dt.datetime(2014, 8, 1, 0, 0, 0)
    times = [t0 + dt.timedelta(microseconds=50_000 * i + 7) for i in range(n)]
    utc = np.array([t.strftime("%Y-%m-%dT%H:%M:%S.%f") for t in times])
    ds = xr.Dataset(
        {"time_utc": ("time", utc), "obt": ("time", 3.6e8 + np.arange(n) * 0.05),
         "b": (("time", "component"), rng.normal(0, 50, (n, 3)), {"units": "nT"}),
         "temperature": ("time", rng.uniform(150, 300, n), {"units": "K"}),
         "position": (("time", "component"), rng.normal(0, 1e8, (n, 3)), {"units": "km"}),
         "quality": ("time", np.arange(n) % 2)},
        coords={"component": ["x", "y", "z"]}, attrs={"creation_time": "2026-01-01T00:00:00Z"})
    return ds, [t.strftime("%Y %m %d %H %M %S %f") for t in times]


@pytest.mark.parametrize(("level", "stem"), [("B", "RPCMAG140801T0000_CLB_OB_M3"),
                                             ("C", "RPCMAG140801T0000_CLC_IB_M1"),
                                             ("F", "RPCMAG140801_CLF_OB_A01"),
                                             ("G", "RPCMAG140801_CLG_IB_A60")])
def test_rosetta_calibrated_and_resampled(tmp_path: Path, level: str, stem: str) -> None:
    from fluxcal.missions.rosetta.products import product_columns

    n = 200
    ds, parts = _rosetta(n, level)
    extra = {"COORDINATE_SYSTEM_NAME": "ECLIPJ2000"} if level in ("C", "G") else {}
    write_product(ds, tmp_path / stem, ("tab",), product_columns(level), extra)
    p = read_archive_product(tmp_path / f"{stem}.TAB")
    expected = _cdflib_tt2000([[int(x) for x in s.split()[:6]]
                               + [int(s.split()[6]) // 1000, int(s.split()[6]) % 1000, 0]
                               for s in parts])
    np.testing.assert_array_equal(p["epoch"].values, expected)
    np.testing.assert_allclose(p["b"].values, ds["b"].values, atol=5e-4 + 1e-9)
    np.testing.assert_array_equal(p["quality"].values, ds["quality"].values)
    assert p.attrs["level"] == level and p.attrs["mission"] == "ROSETTA"
    assert p.attrs["sensor"] == stem.split("_")[2]
    frame = {"B": "ROS_SPACECRAFT", "F": "ROS_SPACECRAFT", "C": "ECLIPJ2000",
             "G": "ECLIPJ2000"}[level]
    assert p["b"].attrs["frame"] == frame
    if level in ("C", "G"):
        np.testing.assert_allclose(p["position"].values, ds["position"].values, atol=5e-4)
    elif level == "B":
        np.testing.assert_allclose(p["temperature"].values, ds["temperature"].values,
                                   atol=5e-3 + 1e-9)
    assert p.attrs["product_type"] == ("RESAMPLED" if level in "FG" else "CALIBRATED")
    if level == "G":
        assert p.attrs["average_seconds"] == 60.0
    if level == "B":
        assert p.attrs["filter_mode_sid"] == 3


def test_rosetta_v9_quality_string(tmp_path: Path) -> None:
    """A QUALITY column of 8 digits as text (the V9 deliveries) stays text."""
    n = 5
    ds, _ = _rosetta(n, "F")
    q = np.array(["00000000", "10000000", "00000001", "00000000", "01020000"])
    ds = ds.assign(quality=("time", q))
    cols = [Column("time_utc", "A26", label="TIME.UTC", data_type="TIME"),
            Column("obt", "F17.6", label="TIME.OBT"),
            *[Column("b", "F11.3", label=f"B{c.upper()}", component=c, unit="nT")
              for c in "xyz"],
            Column("quality", "A8", label="QUALITY")]
    stem = "RPCMAG140801_CLE_OB_A01"
    write_product(ds, tmp_path / stem, ("tab",), cols)
    p = read_archive_product(tmp_path / f"{stem}.LBL")
    np.testing.assert_array_equal(p["quality"].values, q)
    assert p["b"].attrs["frame"] == "ROS_RPC_MAG_OB"


def test_missing_field_column_is_named(tmp_path: Path) -> None:
    n = 5
    ds, _ = _rosetta(n, "B")
    cols = [Column("time_utc", "A26", label="TIME.UTC", data_type="TIME"),
            Column("b", "F11.3", label="BX", component="x", unit="nT"),
            Column("b", "F11.3", label="BZ", component="z", unit="nT")]
    write_product(ds, tmp_path / "RPCMAG140801T0000_CLB_OB_M3", ("tab",), cols)
    with pytest.raises(InputFormatError) as err:
        read_archive_product(tmp_path / "RPCMAG140801T0000_CLB_OB_M3.LBL")
    assert err.value.field == "BY" and "RPCMAG140801T0000_CLB_OB_M3.LBL" in str(err.value)


def test_unknown_table_is_refused(tmp_path: Path) -> None:
    ds = xr.Dataset({"v": ("time", np.arange(3.0))}, attrs={"creation_time": "x"})
    write_product(ds, tmp_path / "OTHER", ("tab",))
    with pytest.raises(InputFormatError) as err:
        read_archive_product(tmp_path / "OTHER.LBL")
    assert "OTHER.LBL" in str(err.value) and "TIME.UTC" in str(err.value)
