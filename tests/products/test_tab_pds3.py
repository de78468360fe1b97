"""Fixed-width TAB + PDS3 label: bytes equal Python's printf, labels load in pvl, tables in pdr.

Oracles: Python's own ``%`` formatting (correctly rounded, ties to even) for every
printed field; `pvl` with the PDS grammar for the labels; `pdr` (the PDS reader) for
the tables, reading with the label's START_BYTE/BYTES.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import hypothesis.extra.numpy as hnp
import numpy as np
import pdr
import pvl
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st
from pvl.decoder import PDSLabelDecoder
from pvl.grammar import PDSGrammar

from fluxcal.errors import InputFormatError
from fluxcal.products import Column, read_tab, write_tab
from fluxcal.products.columns import resolve_columns
from fluxcal.products.tab import format_chunk

from .conftest import make_dataset

_FORTRAN = re.compile(r"^(I\d+(\.\d+)?|F\d+\.\d+|E\d+\.\d+|A\d+)$")


def _printf(fortran: str, zero_pad: bool = False) -> str:
    """The printf form of a FORTRAN descriptor, written independently of the package."""
    code, rest = fortran[0], fortran[1:]
    w, _, d = rest.partition(".")
    if code == "F":
        return f"%{'0' if zero_pad else ''}{w}.{d}f"
    if code == "E":
        return f"%{w}.{d}E"
    if code == "I":
        return f"%{w}.{d}d" if d else f"%{w}d"
    return f"%-{w}s"


def _table(values: dict[str, np.ndarray]) -> xr.Dataset:
    return xr.Dataset({k: ("time", v, {"units": "1"}) for k, v in values.items()},
                      attrs={"creation_time": "2026-01-01T00:00:00Z"})


def _fields(path: Path, label: Mapping[str, Any]) -> list[list[bytes]]:
    """Slice every row by the label's START_BYTE/BYTES (independent of the writer)."""
    table = label["TABLE"]
    row_bytes = table["ROW_BYTES"]
    raw = path.read_bytes()
    assert len(raw) == row_bytes * table["ROWS"] == label["RECORD_BYTES"] * label["FILE_RECORDS"]
    rows = [raw[i:i + row_bytes] for i in range(0, len(raw), row_bytes)]
    cols = table.getall("COLUMN")
    out = []
    for c in cols:
        s, b = c["START_BYTE"] - 1, c["BYTES"]
        out.append([r[s:s + b] for r in rows])
    covered = np.zeros(row_bytes, bool)
    for c in cols:
        covered[c["START_BYTE"] - 1:c["START_BYTE"] - 1 + c["BYTES"]] = True
    for r in rows:  # everything between fields is one blank; rows end CRLF
        assert r.endswith(b"\r\n")
        gaps = bytes(r[i] for i in range(row_bytes - 2) if not covered[i])
        assert gaps == b" " * (len(cols) - 1)
    return out


def _no_repeats(block: Mapping[str, Any], where: str = "") -> None:
    keys = [k for k, v in block.items() if not isinstance(v, Mapping)]
    assert len(keys) == len(set(keys)), (where, sorted(k for k in keys if keys.count(k) > 1))
    for k, v in block.items():
        if isinstance(v, Mapping):
            _no_repeats(v, f"{where}/{k}")


def _load_strict(lbl: Path) -> pvl.PVLModule:
    return pvl.load(str(lbl), grammar=PDSGrammar(), decoder=PDSLabelDecoder())


# --- printf oracle -------------------------------------------------------------------

_SPECIAL = [0.0, -0.0, -1e-9, 1e-9, 0.0005, -0.0005, 0.0015, 0.0625, 1.0005, 2.5, -2.5,
            0.125, 999999.9995, -99999.9995, 123456.7895, 4503599627.370496]


@pytest.mark.parametrize("fmt", ["F10.3", "F17.6", "F8.0", "F12.7", "E15.7", "E24.16",
                                 "E10.3"])
def test_fields_equal_python_printf(fmt: str) -> None:
    rng = np.random.default_rng(7)
    vals = np.concatenate([
        _SPECIAL,
        rng.normal(0, 300, 3000),
        rng.normal(0, 1, 3000) * 10.0 ** rng.integers(-8, 6, 3000),
        (rng.integers(-10**6, 10**6, 3000) + 0.5) / 10.0 ** rng.integers(0, 8, 3000),  # ties
    ])
    if fmt.startswith("E"):
        vals = np.concatenate([vals, rng.normal(0, 1, 3000) * 10.0 ** rng.integers(-300, 300,
                                                                                   3000),
                               [5e-324, 1e-310, 1.7976931348623157e308, 1e22, 1e23]])
    oracle = _printf(fmt)
    w = int(fmt[1:].split(".")[0])
    keep = np.array([len(oracle % v) <= w for v in vals.tolist()])
    ds = _table({"v": vals[keep]})
    cols = resolve_columns(ds, [Column("v", fmt)])
    buf = format_chunk(ds, cols, 0, int(keep.sum()))
    got = [bytes(r[:w]).decode() for r in buf]
    want = [oracle % v for v in vals[keep].tolist()]
    bad = [(v, g, x) for v, g, x in zip(vals[keep].tolist(), got, want, strict=True) if g != x]
    assert not bad, bad[:5]


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.float64, st.integers(1, 50),
                  elements=st.floats(-1e6, 1e6, allow_nan=False)),
       st.integers(0, 9), st.booleans())
def test_fixed_law(vals: np.ndarray, decimals: int, zero_pad: bool) -> None:
    """Any value, any decimals: the F field is Python's '%w.df' (or '%0w.df')."""
    w = 9 + decimals  # sign, 7 integer digits, point
    fmt = f"%{'0' if zero_pad else ''}{w}.{decimals}f"
    ds = _table({"v": vals})
    buf = format_chunk(ds, resolve_columns(ds, [Column("v", fmt)]), 0, vals.size)
    assert [bytes(r[:w]).decode() for r in buf] == [fmt % v for v in vals.tolist()]


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.int64, st.integers(1, 50), elements=st.integers(-(10**9), 10**9)),
       st.integers(1, 4))
def test_integer_law(vals: np.ndarray, m: int) -> None:
    ds = _table({"v": vals})
    buf = format_chunk(ds, resolve_columns(ds, [Column("v", f"I12.{m}")]), 0, vals.size)
    assert [bytes(r[:12]).decode() for r in buf] == [f"%12.{m}d" % v for v in vals.tolist()]


def test_printf_forms_map_to_fortran() -> None:
    ds = _table({"doy": np.array([5, 153]), "s": np.array([5.1234, 59.9996]),
                 "u": np.array(["a", "bcd"])})
    cols = resolve_columns(ds, [Column("doy", "%03d"), Column("s", "%06.3f"),
                                Column("u", "%-5s"), Column("s", "%15.7e", label="e")])
    assert [c.fmt.fortran for c in cols] == ["I3.3", "F6.3", "A5", "E15.7"]
    rows = [bytes(r).decode() for r in format_chunk(ds, cols, 0, 2)]
    assert rows == ["005 05.123 a       5.1234000E+00\r\n",
                    "153 60.000 bcd     5.9999600E+01\r\n"]


def test_nan_prints_the_fill_and_the_label_says_so(tmp_path: Path) -> None:
    ds = _table({"b": np.array([1.0, np.nan, -2.0])})
    write_tab(ds, tmp_path / "P", [Column("b", "F10.3", fill=-99999.999)])
    assert (tmp_path / "P.TAB").read_bytes().split(b"\r\n")[1] == b"-99999.999"
    col = _load_strict(tmp_path / "P.LBL")["TABLE"]["COLUMN"]
    assert col["MISSING_CONSTANT"] == -99999.999
    back = read_tab(tmp_path / "P.TAB")["b"].values
    assert np.isnan(back[1]) and back[[0, 2]].tolist() == [1.0, -2.0]


@pytest.mark.parametrize(("value", "fmt", "why"), [
    (123456.0, "F8.3", "does not fit the width of F8.3"),
    (np.inf, "F10.3", "is infinite"),
    (-1e31, "F10.3", "too large"),
    (99999.9996, "F9.3", "does not fit"),  # rounds up to 100000.000: 10 characters
])
def test_value_that_does_not_fit_names_column_and_row(value: float, fmt: str, why: str,
                                                      tmp_path: Path) -> None:
    ds = _table({"bz": np.array([1.0, 2.0, value, 3.0])})
    with pytest.raises(InputFormatError, match=why) as exc:
        write_tab(ds, tmp_path / "P", [Column("bz", fmt, label="BZ")])
    assert exc.value.field == "BZ" and "row 2" in str(exc.value)
    assert list(tmp_path.iterdir()) == []  # nothing written, never '*****'


def test_string_longer_than_its_field_is_an_error(tmp_path: Path) -> None:
    ds = _table({"u": np.array(["2014-08-06T00:00:00.123456", "x"])})
    with pytest.raises(InputFormatError, match="row 0 is longer than A20"):
        write_tab(ds, tmp_path / "P", [Column("u", "A20")])


def test_chunks_are_seamless(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import fluxcal.products.tab as tab_mod

    ds = make_dataset(257)
    cols = [Column("epoch", "I20"), Column("B_mso", "F10.3", label="b{c}"),
            Column("utc", "A23"), Column("quality", "I4")]
    write_tab(ds, tmp_path / "one", cols)
    monkeypatch.setattr(tab_mod, "CHUNK_ROWS", 10)
    write_tab(ds, tmp_path / "many", cols)
    assert (tmp_path / "one.TAB").read_bytes() == (tmp_path / "many.TAB").read_bytes()


# --- labels and tables of several product layouts ---------------------------------------


def _messenger(n: int, averaged: bool) -> tuple[xr.Dataset, list[Column]]:
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 86400, n))
    data = {
        "year": ("time", np.full(n, 2012, np.int16)),
        "doy": ("time", np.full(n, 5, np.int16)),
        "hour": ("time", (t // 3600).astype(np.int8)),
        "minute": ("time", (t // 60 % 60).astype(np.int8)),
        "second": ("time", np.round(t % 60, 3) % 60),
        "met": ("time", 2.4e8 + t),
        "position": (("time", "component"), rng.normal(0, 5000, (n, 3)), {"units": "km"}),
        "b": (("time", "component"), rng.normal(0, 300, (n, 3)), {"units": "nT"}),
    }
    cols = [Column("year", "I4", label="YEAR"), Column("doy", "I3.3", label="DAY_OF_YEAR"),
            Column("hour", "I2.2", label="HOUR"), Column("minute", "I2.2", label="MINUTE"),
            Column("second", "%06.3f", "s", label="SECOND"),
            Column("met", "F17.6", "s", label="TIME_TAG")]
    if averaged:
        data["navg"] = ("time", rng.integers(1, 1200, n).astype(np.int32))
        data["b_std"] = (("time", "component"), rng.uniform(0, 5, (n, 3)), {"units": "nT"})
        cols.append(Column("navg", "I5", label="NAVG"))
    cols += [Column("position", "F14.3", label="{c}"), Column("b", "F11.3", label="B{c}")]
    if averaged:
        cols.append(Column("b_std", "F9.3", label="DB{c}"))
    ds = xr.Dataset(data, coords={"component": ["X", "Y", "Z"]},
                    attrs=make_dataset(1).attrs)
    return ds, cols


def _rosetta(n: int) -> tuple[xr.Dataset, list[Column]]:
    rng = np.random.default_rng(4)
    us = np.sort(rng.integers(0, 86_400_000_000, n))
    utc = np.array([f"2014-08-06T{u // 3_600_000_000:02d}:{u // 60_000_000 % 60:02d}:"
                    f"{u // 1_000_000 % 60:02d}.{u % 1_000_000:06d}" for u in us.tolist()])
    b = rng.normal(0, 50, (n, 3))
    b[n // 2, 1] = np.nan
    ds = xr.Dataset(
        {"time_utc": ("time", utc), "obt": ("time", 3.6e8 + us / 1e6),
         "b": (("time", "component"), b, {"units": "nT"}),
         "temperature": ("time", rng.normal(150, 20, n)),
         "quality": ("time", rng.integers(0, 10, n).astype(np.uint8))},
        coords={"component": ["x", "y", "z"]}, attrs=make_dataset(1).attrs)
    cols = [Column("time_utc", "A26", label="TIME.UTC", data_type="TIME"),
            Column("obt", "F17.6", "s", label="TIME.OBT"),
            Column("b", "F10.3", label="B{c}", fill=-9999.999),
            Column("temperature", "F8.2", "K", label="T"),
            Column("quality", "I2", label="QUALITY")]
    return ds, cols


def _hk(n: int) -> tuple[xr.Dataset, list[Column]]:
    rng = np.random.default_rng(5)
    ds = xr.Dataset(
        {"epoch": ("time", 757_339_269_184_000_123 + np.arange(n, dtype=np.int64) * 10**9),
         "t_ob": ("time", rng.normal(20, 40, n).astype(np.float32)),
         "stage_a_id": ("time", rng.integers(0, 100, n).astype(np.int32)),
         "ref_voltage": ("time", rng.normal(2.5, 0.01, n)),
         "counts": ("time", rng.integers(-2**15, 2**15, n).astype(np.int16))},
        attrs={**make_dataset(1).attrs, "command_line": 'fluxcal rosetta hk --title "HK day"'})
    cols = [Column("epoch", "I20"), Column("t_ob", "F8.2", label="T.OB"),
            Column("stage_a_id", "%6d", label="STAGE_A.ID"),
            Column("ref_voltage", "%9.5f", label="MAG.REF_VOLTAGE"),
            Column("counts", "I6", label="COUNTS"),
            Column("ref_voltage", "E13.6", label="MAG.REF_VOLTAGE_E")]
    return ds, cols


def _value(ds: xr.Dataset, col: Any) -> np.ndarray:
    var = ds[col.variable]
    return var.values if col.index is None else var.values[:, col.index]


PRODUCTS = {
    "messenger_cdr_12": lambda: _messenger(300, averaged=False),
    "messenger_rdr_16": lambda: _messenger(200, averaged=True),
    "rosetta_utc26": lambda: _rosetta(250),
    "hk": lambda: _hk(120),
}


@pytest.mark.parametrize("name", sorted(PRODUCTS))
def test_label_loads_in_pvl_and_table_in_pdr(name: str, tmp_path: Path) -> None:
    ds, cols = PRODUCTS[name]()
    stem = "MAGMSOSCI12005_V01" if name.startswith("messenger") else name.upper()
    tab, lbl = write_tab(ds, tmp_path / stem, cols, label_extra={"PRODUCT_ID": "X_V01",
                                                                 "MISSION_NAME": "M"})
    label = _load_strict(lbl)
    _no_repeats(label)
    text = lbl.read_text(encoding="ascii")
    assert '\\"' not in text and "json:" not in text
    assert text.count("PRODUCT_ID =") == 1 and label["PRODUCT_ID"] == "X_V01"  # caller wins
    assert label["PDS_VERSION_ID"] == "PDS3" and label["RECORD_TYPE"] == "FIXED_LENGTH"
    assert label["^TABLE"] == tab.name
    table = label["TABLE"]
    assert table["INTERCHANGE_FORMAT"] == "ASCII"
    assert table["ROWS"] == label["FILE_RECORDS"] == ds.sizes["time"]
    assert table["ROW_BYTES"] == label["RECORD_BYTES"]
    resolved = resolve_columns(ds, cols)
    columns = table.getall("COLUMN")
    assert table["COLUMNS"] == len(columns) == len(resolved)
    expected_n = {"messenger_cdr_12": 12, "messenger_rdr_16": 16}.get(name)
    assert expected_n is None or len(columns) == expected_n
    fields = _fields(tab, label)
    frame = pdr.read(str(lbl))["TABLE"]
    for c, rc, field in zip(columns, resolved, fields, strict=True):
        assert _FORTRAN.match(c["FORMAT"]), c["FORMAT"]
        assert c["NAME"] == rc.label and c["BYTES"] == len(field[0])
        values = _value(ds, rc)
        fill = c.get("MISSING_CONSTANT")
        printed = values if fill is None else np.where(np.isnan(values), fill, values)
        oracle = _printf(c["FORMAT"], zero_pad=c["NAME"] == "SECOND")
        assert [f.decode() for f in field] == [oracle % v for v in printed.tolist()], c["NAME"]
        got = frame[c["NAME"]].to_numpy()
        if c["DATA_TYPE"] in ("CHARACTER", "TIME"):
            np.testing.assert_array_equal(got.astype(str), values)
        elif c["DATA_TYPE"] == "ASCII_INTEGER":
            np.testing.assert_array_equal(got, values)
        else:
            # to the printed precision: half a unit of the last printed digit, plus
            # float64 rounding of the parsed decimal (1 ulp)
            d = int(c["FORMAT"].split(".")[1])
            if c["FORMAT"].startswith("E"):
                tol = 0.5 * 10.0 ** -d * np.abs(printed) * 10 + 1e-300
            else:
                tol = 0.5 * 10.0 ** -d + np.spacing(np.abs(printed))
            assert np.all(np.abs(got - printed) <= tol), c["NAME"]


def test_provenance_reads_back_without_json(tmp_path: Path) -> None:
    ds, cols = _hk(5)
    write_tab(ds, tmp_path / "HK", cols)
    text = (tmp_path / "HK.LBL").read_text()
    assert "%22HK%20day%22" in text  # the quotes of the command line, percent-encoded
    back = read_tab(tmp_path / "HK.TAB")
    for k, v in ds.attrs.items():
        assert back.attrs[k] == v, k


def test_label_extra_cannot_break_the_structure(tmp_path: Path) -> None:
    ds, cols = _hk(3)
    with pytest.raises(InputFormatError, match="RECORD_BYTES"):
        write_tab(ds, tmp_path / "HK", cols, label_extra={"record_bytes": 10})
    with pytest.raises(InputFormatError, match="30 characters"):
        write_tab(ds, tmp_path / "HK", cols,
                  label_extra={"FLUXCAL_DUPLICATE_EPOCHS_DROPPED": 0})
    with pytest.raises(InputFormatError, match="TITLE"):
        write_tab(ds, tmp_path / "HK", cols, label_extra={"TITLE": 'the "best" day'})
    assert list(tmp_path.iterdir()) == []
