"""Products declared by a mission and written by the runner (`fluxcal.products.declared`).

Expected values never come from fluxcal's code: the UTC day of each sample is counted
with numpy ``datetime64`` on the UTC times the test draws, and those times are turned
into TT2000 by cdflib (`cdflib.cdfepoch.compute_tt2000`), not by fluxcal.  The days
used (2024-03-12/13) hold no leap second, so UTC and the TT2000 count differ by a fixed
69.184 s throughout.  File names are the templates and ISTP rule spelled out by hand.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.products.declared import Product, Quicklook, write_declared

DAY1, DAY2 = dt.date(2024, 3, 12), dt.date(2024, 3, 13)
MIDNIGHT = np.datetime64("2024-03-13T00:00:00", "ns")
PROVENANCE = {"software": "fluxcal", "software_version": "9.9.9",
              "inputs": [{"name": "in.csv", "sha256": "ab" * 32}], "calibration": {},
              "kernels": [], "command_line": "fluxcal test",
              "creation_time": "2024-01-01T00:00:00Z"}


def _utc_times(seed: int = 1) -> np.ndarray:
    """Irregular UTC times from 21:00 on the 12th to 03:00 on the 13th, one at midnight."""
    rng = np.random.default_rng(seed)
    start = np.datetime64("2024-03-12T21:00:00", "ns")
    steps = rng.integers(1, 300_000_000_000, 150)  # up to 5 min apart (ns)
    times = start + np.cumsum(steps).astype("m8[ns]")
    times = np.sort(np.r_[times[times < start + np.timedelta64(6, "h")], MIDNIGHT])
    return np.unique(times)


def _tt2000(times: np.ndarray) -> np.ndarray:
    """cdflib's UTC -> TT2000 (independent of fluxcal's conversion)."""
    parts = []
    for t in times:
        s = str(t)  # 'YYYY-MM-DDTHH:MM:SS.nnnnnnnnn'
        ns = int(s[20:29].ljust(9, "0")) if len(s) > 19 else 0
        parts.append([int(s[0:4]), int(s[5:7]), int(s[8:10]), int(s[11:13]), int(s[14:16]),
                      int(s[17:19]), ns // 1_000_000, ns // 1000 % 1000, ns % 1000])
    return np.asarray(cdflib.cdfepoch.compute_tt2000(parts), dtype=np.int64)


def _dataset(times: np.ndarray | None = None) -> xr.Dataset:
    times = _utc_times() if times is None else times
    n = times.size
    b = np.column_stack([np.arange(n), -np.arange(n), np.full(n, 7.0)]).astype(float)
    return xr.Dataset(
        {"b": (("time", "component"), b, {"units": "nT", "description": "Magnetic field"})},
        coords={"epoch": ("time", _tt2000(times)), "component": ["x", "y", "z"]},
        attrs={"mission": "TEST"})


def _provenance(product: Product) -> dict:
    return dict(PROVENANCE)


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_an_undated_product_over_midnight_is_one_file_per_utc_day(tmp_path: Path) -> None:
    times = _utc_times()
    before, after = int((times < MIDNIGHT).sum()), int((times >= MIDNIGHT).sum())
    assert before > 10 and after > 10 and times.size == before + after
    written = write_declared([Product("TST_{day:%Y%m%d}", _dataset(times), formats=("cdf",))],
                             tmp_path, _provenance)
    assert sorted(p.name for p in written) == ["TST_20240312.cdf", "TST_20240313.cdf"]
    for name, count, first in (("TST_20240312.cdf", before, times[0]),
                               ("TST_20240313.cdf", after, MIDNIGHT)):
        epoch = np.asarray(cdflib.CDF(str(tmp_path / name)).varget("Epoch"))
        assert epoch.size == count
        assert cdflib.cdfepoch.to_datetime(epoch[:1])[0] == first  # midnight opens the 13th


def test_only_day_writes_that_day_only(tmp_path: Path) -> None:
    times = _utc_times()
    written = write_declared([Product("TST_{day:%Y%m%d}", _dataset(times), formats=("cdf",))],
                             tmp_path, _provenance, only_day=DAY2)
    assert [p.name for p in written] == ["TST_20240313.cdf"]
    assert _names(tmp_path) == ["TST_20240313.cdf"]
    epoch = np.asarray(cdflib.CDF(str(written[0])).varget("Epoch"))
    assert epoch.size == int((times >= MIDNIGHT).sum())


def test_provenance_is_set_and_attrs_override_it(tmp_path: Path) -> None:
    product = Product("TST_{day:%Y%m%d}", _dataset(), formats=("nc",),
                      attrs={"command_line": "declared by the mission", "extra": "yes"})
    written = write_declared([product], tmp_path, _provenance, only_day=DAY1)
    with xr.open_dataset(written[0]) as ds:
        attrs = dict(ds.attrs)
    for key in ("software", "software_version", "inputs", "calibration", "kernels",
                "creation_time"):
        assert key in attrs, key
    assert attrs["software_version"] == "9.9.9"
    assert attrs["creation_time"] == "2024-01-01T00:00:00Z"
    assert attrs["command_line"] == "declared by the mission"  # attrs after the provenance
    assert attrs["extra"] == "yes" and attrs["mission"] == "TEST"


def test_an_istp_named_product_names_the_cdf_by_istp_and_the_table_by_its_name(
        tmp_path: Path) -> None:
    product = Product("TSTTAB_{day:%Y%m%d}", _dataset(), formats=("tab", "cdf"),
                      logical_source="tst_mag_l2", version=1)
    written = write_declared([product], tmp_path, _provenance)
    # ISTP: <logical_source>_<yyyymmdd>_v<NN>, the version on two digits at least
    assert sorted(p.name for p in written) == [
        "TSTTAB_20240312.LBL", "TSTTAB_20240312.TAB", "TSTTAB_20240313.LBL",
        "TSTTAB_20240313.TAB", "tst_mag_l2_20240312_v01.cdf", "tst_mag_l2_20240313_v01.cdf"]
    cdf = cdflib.CDF(str(tmp_path / "tst_mag_l2_20240313_v01.cdf"))
    assert cdf.globalattsget()["Logical_file_id"] == ["tst_mag_l2_20240313_v01"]


def test_a_failure_in_the_second_product_leaves_no_file_of_the_first(tmp_path: Path) -> None:
    def broken() -> xr.Dataset:
        raise RuntimeError("the second product's maker fails")

    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="second product"):
        write_declared([Product("P1_{day:%Y%m%d}", _dataset(), formats=("cdf", "tab")),
                        Product("P2", broken, day=DAY1, formats=("cdf",))], out, _provenance)
    assert _names(out) == []  # neither the first product nor a temporary file


def test_a_generator_is_consumed_one_product_at_a_time(tmp_path: Path) -> None:
    out = tmp_path / "out"
    seen: dict[str, list[str]] = {}

    def maker(name: str) -> xr.Dataset:
        seen[name] = _names(out)  # what is on disk when this product is made
        return _dataset()

    def declarations():
        yield Product("P1", lambda: maker("P1"), day=DAY1, formats=("cdf",))
        seen["generator resumed"] = _names(out)
        yield Product("P2", lambda: maker("P2"), day=DAY1, formats=("cdf",))

    written = write_declared(declarations(), out, _provenance, only_day=DAY1)
    assert [p.name for p in written] == ["P1.cdf", "P2.cdf"]
    assert seen["P1"] == []
    # P1 is complete (under its temporary name until the group commits) before the
    # generator is asked for P2 and before P2's data are made
    for key in ("generator resumed", "P2"):
        assert any("P1.cdf" in name for name in seen[key]), seen[key]
        assert not any("P2" in name for name in seen[key]), seen[key]
    assert _names(out) == ["P1.cdf", "P2.cdf"]


def test_a_quicklook_draws_only_the_batch_day(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    ql = Quicklook("TSTQL", _dataset(), field="b", frame="test frame")
    written = write_declared([ql], tmp_path / "one", _provenance, only_day=DAY2)
    assert [p.name for p in written] == ["TSTQL_20240313.png"]
    written = write_declared([ql], tmp_path / "all", _provenance)
    assert sorted(p.name for p in written) == ["TSTQL_20240312.png", "TSTQL_20240313.png"]
    assert write_declared([ql], tmp_path / "none", _provenance, only_day=dt.date(2024, 3, 14)
                          ) == []


@pytest.mark.parametrize("name", ["../x", "a/b", ".hidden", ""])
def test_a_name_that_is_not_a_plain_file_name_is_refused(tmp_path: Path, name: str) -> None:
    out = tmp_path / "out"
    with pytest.raises(InputFormatError, match="product name"):  # one line, exit code 2
        write_declared([Product(name, _dataset(), day=DAY1, formats=("cdf",))], out,
                       _provenance)
    assert _names(out) == [] and _names(tmp_path) == ["out"]  # nothing written anywhere


def _own_layout(part: xr.Dataset, provenance: dict) -> xr.Dataset:
    """An archive-like layout: its own variable names and ISTP attributes."""
    epoch = part["epoch"].values
    ds = xr.Dataset(
        {"field_vectors": (("epoch", "axis"), part["b"].values, {
            "CATDESC": "Field", "DEPEND_0": "epoch", "DEPEND_1": "axis", "FIELDNAM": "Field",
            "FILLVAL": -1e31, "FORMAT": "F12.5", "LABL_PTR_1": "axis_label", "UNITS": "nT",
            "VALIDMIN": -1e9, "VALIDMAX": 1e9, "VAR_TYPE": "data", "DISPLAY_TYPE":
            "time_series"})},
        coords={"epoch": ("epoch", epoch, {"CATDESC": "Time", "FIELDNAM": "epoch",
                                           "FILLVAL": np.int64(-9223372036854775808),
                                           "FORMAT": " ", "UNITS": "ns", "VAR_TYPE":
                                           "support_data", "VALIDMIN": np.int64(0),
                                           "VALIDMAX": np.int64(2**62)}),
                "axis": ("axis", np.arange(3), {"CATDESC": "Axis", "FIELDNAM": "axis",
                                                "FORMAT": "I1", "VAR_TYPE": "support_data",
                                                "UNITS": " ", "FILLVAL": np.int64(-1),
                                                "VALIDMIN": np.int64(0),
                                                "VALIDMAX": np.int64(2)}),
                "axis_label": ("axis", np.array(["x", "y", "z"]), {
                    "CATDESC": "Axis label", "FIELDNAM": "axis label", "FORMAT": "A1",
                    "VAR_TYPE": "metadata"})},
        attrs={"Logical_source": "arc_mag", "Parents": [i["name"] for i in
                                                         provenance["inputs"]]})
    return ds


def test_a_product_with_a_layout_of_its_own_is_written_as_it_is(tmp_path: Path) -> None:
    times = _utc_times()
    product = Product("ARC_{day:%Y%m%d}", _dataset(times), formats=("cdf",),
                      layout=_own_layout, attrs={"Mission_group": "TEST"})
    written = write_declared([product], tmp_path, _provenance)
    assert sorted(p.name for p in written) == ["ARC_20240312.cdf", "ARC_20240313.cdf"]
    cdf = cdflib.CDF(str(tmp_path / "ARC_20240313.cdf"))
    assert set(cdf.cdf_info().zVariables) >= {"epoch", "field_vectors"}
    assert cdf.varget("field_vectors").shape == (int((times >= MIDNIGHT).sum()), 3)
    g = cdf.globalattsget()
    assert g["Parents"] == ["in.csv"] and g["Mission_group"] == ["TEST"]
    assert g["software_version"] == ["9.9.9"]
    # provenance lists and dicts are JSON with fluxcal's prefix (sorted keys)
    assert g["inputs"] == ['json:[{"name": "in.csv", "sha256": "' + "ab" * 32 + '"}]']
    with pytest.raises(FluxcalError, match="CDF only"):
        write_declared([Product("ARC", _dataset(), day=DAY1, formats=("cdf", "nc"),
                                layout=_own_layout)], tmp_path / "x", _provenance)
    assert _names(tmp_path / "x") == []
