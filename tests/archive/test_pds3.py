"""Label-driven PDS3 table reader (`fluxcal.archive.pds3`) against `pdr`, and its errors.

Oracles: `pdr` (the PDS reader, an independent implementation) on tables fluxcal writes
and on small hand-written labels (ASCII with a detached and an attached label, record
and byte pointers, ITEMS, a binary table written by numpy in both byte orders); the
values the tests put in (closed form) for special constants and scaling, which pdr does
not mask.  Error messages: one line naming the file, the row (``line``) and the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pdr
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.archive import read_label, read_table, read_table_columns
from fluxcal.archive.fixedparse import parse_ints, parse_reals, pow10
from fluxcal.errors import InputFormatError
from fluxcal.products import Column, write_product


def _label(text: str) -> str:
    """A label from indented lines (CRLF line ends, as PDS3 asks)."""
    return "\r\n".join(line.strip() for line in text.strip().splitlines()) + "\r\n"


def _column(name: str, data_type: str, start: int, nbytes: int, **extra: object) -> str:
    more = "\n".join(f"{k.upper()} = {v}" for k, v in extra.items())
    return (f"OBJECT = COLUMN\nNAME = {name}\nDATA_TYPE = {data_type}\n"
            f"START_BYTE = {start}\nBYTES = {nbytes}\n{more}\nEND_OBJECT = COLUMN\n")


def _assert_same_as_pdr(ds: xr.Dataset, frame, skip: tuple[str, ...] = ()) -> None:
    """Every column of ``ds`` equals pdr's DataFrame column (items as NAME_0, NAME_1...)."""
    for name, var in ds.data_vars.items():
        if name in skip:
            continue
        if var.ndim == 2:
            theirs = np.stack([frame[f"{name}_{i}"].to_numpy() for i in range(var.shape[1])],
                              axis=1)
        else:
            theirs = frame[name].to_numpy()
        if var.dtype.kind == "U" and theirs.dtype.kind in "iuf":
            # pdr infers numbers from a CHARACTER column whose every row is digits ("019" ->
            # 19); the label says text and fluxcal keeps the text (test_digit_only_text...)
            np.testing.assert_array_equal(var.values.astype(theirs.dtype), theirs, err_msg=name)
        elif var.dtype.kind == "U":
            theirs = np.array([t.decode().strip() if isinstance(t, bytes) else str(t).strip()
                               for t in theirs])
            np.testing.assert_array_equal(var.values, theirs, err_msg=name)
        else:
            # both parse the same decimal text / the same bytes: exact equality
            np.testing.assert_array_equal(var.values, theirs.astype(var.dtype), err_msg=name)


# --- tables fluxcal writes ----------------------------------------------------------------


def _messenger_like(n: int) -> xr.Dataset:
    rng = np.random.default_rng(4)
    epoch = 392_040_000_000_000_000 + np.arange(n, dtype=np.int64) * 50_000_000
    return xr.Dataset(
        {
            "year": ("time", np.full(n, 2012)), "doy": ("time", np.full(n, 153)),
            "hour": ("time", np.arange(n) % 24), "minute": ("time", np.arange(n) % 60),
            "second": ("time", (np.arange(n) * 0.05) % 60),
            "met": ("time", 2.4e8 + np.arange(n) * 0.05, {"units": "s"}),
            "position": (("time", "position_component"), rng.normal(0, 3e3, (n, 3)),
                         {"units": "km"}),
            "b": (("time", "b_component"), rng.normal(0, 400, (n, 3)), {"units": "nT"}),
            "quality": ("time", rng.integers(0, 3, n)),
        },
        coords={"epoch": ("time", epoch), "b_component": ["B_X", "B_Y", "B_Z"],
                "position_component": ["X", "Y", "Z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z"})


def test_reads_a_messenger_cdr_table_fluxcal_writes_as_pdr_does(tmp_path: Path) -> None:
    from fluxcal.missions.messenger.products import table_columns

    ds = _messenger_like(500)
    write_product(ds, tmp_path / "MAGMSOSCI12153_V01", ("tab",), table_columns("mso", False),
                  {"START_TIME": "2012-06-01T00:00:00"})
    lbl = tmp_path / "MAGMSOSCI12153_V01.LBL"
    ours = read_table(lbl)
    assert list(ours.data_vars) == ["YEAR", "DAY_OF_YEAR", "HOUR", "MINUTE", "SECOND",
                                    "TIME_TAG", "X", "Y", "Z", "BX", "BY", "BZ"]
    _assert_same_as_pdr(ours, pdr.read(lbl)["TABLE"])
    # printed to 3 decimals (F11.3): within half a unit of the last digit
    np.testing.assert_allclose(ours["BX"].values, ds["b"].values[:, 0], atol=5e-4 + 1e-9)
    assert ours["BX"].attrs["units"] == "nT" and ours["BX"].attrs["format"] == "F11.3"
    assert ours["DAY_OF_YEAR"].dtype == np.int64
    assert ours.attrs["PRODUCT_ID"] == "MAGMSOSCI12153_V01"
    assert ours.attrs["START_TIME"] == "2012-06-01T00:00:00"


def test_reads_a_fluxcal_table_with_strings_and_missing_constant(tmp_path: Path) -> None:
    n = 40
    b = np.linspace(-50, 50, 3 * n).reshape(n, 3)
    b[5, 1] = np.nan
    ds = xr.Dataset(
        {"utc": ("time", np.array([f"2014-08-01T00:00:{i:02d}.000000" for i in range(n)])),
         "b": (("time", "component"), b, {"units": "nT", "description": "field"}),
         "quality": ("time", np.arange(n) % 4)},
        coords={"epoch": ("time", np.arange(n, dtype=np.int64)), "component": ["x", "y", "z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z"})
    cols = [Column("utc", "A26", label="TIME.UTC", data_type="TIME"),
            Column("b", "F11.3", label="B{c}", fill=-99999.999),
            Column("quality", "I2", label="QUALITY")]
    write_product(ds, tmp_path / "T", ("tab",), cols)
    ours = read_table(tmp_path / "T.TAB")  # the data file finds its label beside it
    _assert_same_as_pdr(ours, pdr.read(tmp_path / "T.LBL")["TABLE"], skip=("By",))
    assert np.isnan(ours["By"].values[5]) and np.isfinite(ours["By"].values[:5]).all()
    np.testing.assert_allclose(ours["By"].values[6:], b[6:, 1], atol=5e-4 + 1e-9)
    assert ours["TIME.UTC"].values[3] == "2014-08-01T00:00:03.000000"
    assert ours["Bx"].attrs["description"] == "field"


# --- hand-written labels --------------------------------------------------------------------

_ROWS = [" 1  2.50 AB  10  11  12\r\n", " 2 -3.25 CD -20  21 -99\r\n",
         "-3  1e+2 EF  30 -31  32\r\n"]


def _ascii_label(pointer: str, rows: int = 3, record_bytes: int = 25, extra: str = "") -> str:
    return _label(f"""
        PDS_VERSION_ID = PDS3
        RECORD_TYPE = FIXED_LENGTH
        RECORD_BYTES = {record_bytes}
        FILE_RECORDS = {rows}
        ^TABLE = {pointer}
        PRODUCT_ID = "HAND"
        START_TIME = 2014-08-01T00:00:00.000
        {extra}
        OBJECT = TABLE
        INTERCHANGE_FORMAT = ASCII
        ROWS = {rows}
        COLUMNS = 4
        ROW_BYTES = 25
        {_column("N", "ASCII_INTEGER", 1, 2)}
        {_column("V", "ASCII_REAL", 4, 5, unit='"nT"', description='"a value"',
                 format='"F5.2"')}
        {_column("S", "CHARACTER", 10, 2)}
        {_column("W", "ASCII_INTEGER", 13, 11, items=3, item_bytes=3, item_offset=4,
                 missing_constant=-99, scaling_factor=0.5, offset=1)}
        END_OBJECT = TABLE
        END
    """)


def _check_hand_table(ds: xr.Dataset) -> None:
    np.testing.assert_array_equal(ds["N"].values, [1, 2, -3])
    np.testing.assert_array_equal(ds["V"].values, [2.5, -3.25, 100.0])
    np.testing.assert_array_equal(ds["S"].values, ["AB", "CD", "EF"])
    # W = stored * 0.5 + 1, -99 missing (closed form)
    np.testing.assert_array_equal(ds["W"].values, [[6, 6.5, 7], [-9, 11.5, np.nan],
                                                   [16, -14.5, 17]])
    assert ds["W"].dims == ("row", "W_item")
    assert ds["V"].attrs["units"] == "nT" and ds["V"].attrs["description"] == "a value"
    assert ds.attrs["START_TIME"] == "2014-08-01T00:00:00"


def test_hand_written_detached_label(tmp_path: Path) -> None:
    (tmp_path / "HAND.TAB").write_bytes("".join(_ROWS).encode())
    (tmp_path / "HAND.LBL").write_text(_ascii_label('"HAND.TAB"'), newline="")
    ds = read_table(tmp_path / "HAND.LBL")
    _check_hand_table(ds)
    _assert_same_as_pdr(ds, pdr.read(tmp_path / "HAND.LBL")["TABLE"], skip=("W",))


def test_lower_case_data_file_is_found(tmp_path: Path) -> None:
    (tmp_path / "hand.tab").write_bytes("".join(_ROWS).encode())
    (tmp_path / "HAND.LBL").write_text(_ascii_label('"HAND.TAB"'), newline="")
    _check_hand_table(read_table(tmp_path / "HAND.LBL"))


@pytest.mark.parametrize("form", ["record", "bytes", "file_bytes"])
def test_attached_label_and_pointer_forms(tmp_path: Path, form: str) -> None:
    # label padded to whole 25-byte records, the table from record 41 (byte 1001)
    pointer = {"record": "41", "bytes": "1001 <BYTES>",
               "file_bytes": '("HAND.TAB", 1001 <BYTES>)'}
    text = _ascii_label(pointer[form], record_bytes=25).encode()
    assert len(text) <= 1000
    path = tmp_path / "HAND.TAB"
    path.write_bytes(text + b" " * (1000 - len(text)) + "".join(_ROWS).encode())
    ds = read_table(path)
    _check_hand_table(ds)
    assert read_label(path)["PRODUCT_ID"] == "HAND"
    _assert_same_as_pdr(ds, pdr.read(path)["TABLE"], skip=("W",))


def test_record_pointer_into_a_detached_file(tmp_path: Path) -> None:
    (tmp_path / "HAND.TAB").write_bytes(("#" * 23 + "\r\n" + "".join(_ROWS)).encode())
    (tmp_path / "HAND.LBL").write_text(_ascii_label('("HAND.TAB", 2)'), newline="")
    _check_hand_table(read_table(tmp_path / "HAND.LBL"))


@pytest.mark.parametrize("order", [">", "<"])
def test_binary_table_both_byte_orders(tmp_path: Path, order: str) -> None:
    msb = order == ">"
    dt = np.dtype([("t", f"{order}f8"), ("v", f"{order}i2", (3,)), ("u", f"{order}u4"),
                   ("f", f"{order}f4"), ("c", "S4"), ("i1", "i1")])
    rows = 7
    a = np.zeros(rows, dt)
    a["t"] = np.arange(rows) * 0.5 - 1
    a["v"] = np.arange(3 * rows).reshape(rows, 3) * 1000 - 9000
    a["v"][2, 1] = -32768
    a["u"] = np.arange(rows, dtype=np.uint64) * 600_000_000
    a["f"] = np.linspace(-1e5, 1e5, rows)
    a["c"] = [b"AB  ", b"X   ", b"ABCD", b"    ", b"Q", b"RR", b"S"]
    a["i1"] = np.arange(rows) - 3
    a.tofile(tmp_path / "BIN.DAT")
    ints = "MSB_INTEGER" if msb else "LSB_INTEGER"
    uints = "MSB_UNSIGNED_INTEGER" if msb else "LSB_UNSIGNED_INTEGER"
    reals = "IEEE_REAL" if msb else "PC_REAL"
    (tmp_path / "BIN.LBL").write_text(_label(f"""
        PDS_VERSION_ID = PDS3
        RECORD_TYPE = FIXED_LENGTH
        RECORD_BYTES = {dt.itemsize}
        FILE_RECORDS = {rows}
        ^TABLE = "BIN.DAT"
        OBJECT = TABLE
        INTERCHANGE_FORMAT = BINARY
        ROWS = {rows}
        COLUMNS = 6
        ROW_BYTES = {dt.itemsize}
        {_column("T", reals, 1, 8, unit='"s"')}
        {_column("V", ints, 9, 6, items=3, item_bytes=2, missing_constant=-32768)}
        {_column("U", uints, 15, 4)}
        {_column("F", reals, 19, 4)}
        {_column("C", "CHARACTER", 23, 4)}
        {_column("I1", ints, 27, 1)}
        END_OBJECT = TABLE
        END
    """), newline="")
    ds = read_table(tmp_path / "BIN.LBL")
    np.testing.assert_array_equal(ds["T"].values, a["t"])
    expected_v = a["v"].astype(float)
    expected_v[2, 1] = np.nan
    np.testing.assert_array_equal(ds["V"].values, expected_v)
    np.testing.assert_array_equal(ds["U"].values, a["u"])
    assert ds["U"].dtype == np.uint32 and ds["U"].dtype.isnative
    np.testing.assert_array_equal(ds["F"].values, a["f"])
    np.testing.assert_array_equal(ds["C"].values, ["AB", "X", "ABCD", "", "Q", "RR", "S"])
    np.testing.assert_array_equal(ds["I1"].values, a["i1"])
    _assert_same_as_pdr(ds, pdr.read(tmp_path / "BIN.LBL")["TABLE"], skip=("V",))


def test_read_table_columns_renames_and_requires(tmp_path: Path) -> None:
    (tmp_path / "HAND.TAB").write_bytes("".join(_ROWS).encode())
    (tmp_path / "HAND.LBL").write_text(_ascii_label('"HAND.TAB"'), newline="")
    ds = read_table_columns(tmp_path / "HAND.LBL", {"V": "value", "W": "w"})
    assert list(ds.data_vars) == ["value", "w"] and ds["w"].dims == ("row", "w_item")
    with pytest.raises(InputFormatError) as err:
        read_table_columns(tmp_path / "HAND.LBL", {"V": "value", "BX": "bx"})
    assert err.value.field == "BX" and err.value.path.endswith("HAND.LBL")
    assert "BX" in str(err.value) and "\n" not in str(err.value)


# --- errors: one line naming file, row and column -------------------------------------------


def _hand(tmp_path: Path, table: bytes, label: str | None = None) -> Path:
    (tmp_path / "HAND.TAB").write_bytes(table)
    (tmp_path / "HAND.LBL").write_text(label or _ascii_label('"HAND.TAB"'), newline="")
    return tmp_path / "HAND.LBL"


def _error(lbl: Path, **kw: object) -> InputFormatError:
    with pytest.raises(InputFormatError) as err:
        read_table(lbl, **kw)
    msg = str(err.value)
    assert "\n" not in msg
    assert err.value.path is not None and Path(err.value.path).name in msg
    if err.value.line is not None:
        assert f"line {err.value.line}" in msg
    if err.value.field is not None:
        assert err.value.field in msg
    return err.value


def test_error_malformed_label_names_label_and_line(tmp_path: Path) -> None:
    bad = _ascii_label('"HAND.TAB"').replace("ROWS = 3", "ROWS = (3")
    e = _error(_hand(tmp_path, "".join(_ROWS).encode(), bad))
    assert e.path.endswith("HAND.LBL") and e.line is not None and "not a PDS3 label" in str(e)


def test_error_label_without_end(tmp_path: Path) -> None:
    e = _error(_hand(tmp_path, b"", "PDS_VERSION_ID = PDS3\r\n"))
    assert "END" in str(e)


def test_error_missing_column_keyword(tmp_path: Path) -> None:
    bad = _ascii_label('"HAND.TAB"').replace("START_BYTE = 4\r\n", "")
    e = _error(_hand(tmp_path, "".join(_ROWS).encode(), bad))
    assert e.field == "V" and "START_BYTE" in str(e) and e.path.endswith("HAND.LBL")


def test_error_required_column_missing(tmp_path: Path) -> None:
    e = _error(_hand(tmp_path, "".join(_ROWS).encode()), required=["N", "TIME.UTC"])
    assert e.field == "TIME.UTC" and "HAND.LBL" in str(e)


def test_error_missing_data_file(tmp_path: Path) -> None:
    lbl = tmp_path / "HAND.LBL"
    lbl.write_text(_ascii_label('"HAND.TAB"'), newline="")
    e = _error(lbl)
    assert "HAND.TAB" in str(e) and "not found" in str(e)


def test_error_more_rows_than_rows(tmp_path: Path) -> None:
    e = _error(_hand(tmp_path, "".join(_ROWS + _ROWS[:1]).encode()))
    assert e.path.endswith("HAND.TAB") and e.line == 4
    assert "4 rows" in str(e) and "ROWS = 3" in str(e)


def test_error_fewer_rows_than_rows(tmp_path: Path) -> None:
    e = _error(_hand(tmp_path, "".join(_ROWS[:2]).encode()))
    assert e.line == 3 and "2 rows" in str(e) and "ROWS = 3" in str(e)


def test_error_truncated_in_a_row_names_row_and_column(tmp_path: Path) -> None:
    data = "".join(_ROWS).encode()[:-15]  # row 3 cut inside its S column (bytes 10-11)
    e = _error(_hand(tmp_path, data))
    assert e.line == 3 and e.field == "S" and "truncated" in str(e)


def test_error_record_length_mismatch(tmp_path: Path) -> None:
    rows = list(_ROWS)
    rows[1] = rows[1].replace("-3.25", "-3.2")  # row 2 one byte short
    e = _error(_hand(tmp_path, "".join(rows).encode()))
    assert e.line == 2 and "record length" in str(e) and "24 bytes" in str(e)
    e = _error(_hand(tmp_path, "".join(r.replace("\r\n", "\n") for r in _ROWS).encode()))
    assert e.line == 1 and "record length" in str(e)


def test_error_record_bytes_disagrees_with_row_bytes(tmp_path: Path) -> None:
    e = _error(_hand(tmp_path, "".join(_ROWS).encode(),
                     _ascii_label('"HAND.TAB"', record_bytes=26)))
    assert "RECORD_BYTES = 26" in str(e)


def test_error_non_numeric_field_names_row_and_column(tmp_path: Path) -> None:
    rows = list(_ROWS)
    rows[2] = rows[2].replace("1e+2", "1x+2")
    e = _error(_hand(tmp_path, "".join(rows).encode()))
    assert e.line == 3 and e.field == "V" and "'1x+2'" in str(e)
    rows = list(_ROWS)
    rows[1] = rows[1].replace(" 21 ", " 2. ")  # in the second item of W
    e = _error(_hand(tmp_path, "".join(rows).encode()))
    assert e.line == 2 and e.field == "W"


def test_error_column_outside_the_row(tmp_path: Path) -> None:
    bad = _ascii_label('"HAND.TAB"').replace("START_BYTE = 10", "START_BYTE = 25")
    e = _error(_hand(tmp_path, "".join(_ROWS).encode(), bad))
    assert e.field == "S" and "outside the row" in str(e)


# --- the compiled fixed-width number parser against numpy's exact one -----------------------

_FORMATS = ["%11.3f", "%17.6f", "%24.16E", "%15.7e", "%.17g", "%g", "%+.2f", "%.0f",
            "%25.9E", "%8.1e"]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=False, width=64), min_size=1,
                max_size=30),
       st.sampled_from(_FORMATS))
def test_fast_real_parser_equals_numpy(values: list[float], fmt: str) -> None:
    texts = [fmt % v for v in values]
    width = max(len(t) for t in texts) + 1
    field = np.array([t.rjust(width).encode() for t in texts], dtype=f"S{width}")
    raw = field.view(np.uint8).reshape(len(texts), width)
    ours, ok = parse_reals(raw, pow10())
    expected = field.astype(np.float64)  # numpy's correctly rounded parser
    # the fast path is exact where it claims to be; the rest is numpy's (slow path)
    np.testing.assert_array_equal(ours[ok], expected[ok])
    assert not ok[np.isnan(expected)].any()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(10**18) + 1, 10**18 - 1), min_size=1, max_size=30))
def test_fast_int_parser_equals_python(values: list[int]) -> None:
    field = np.array([f"{v:>20d}".encode() for v in values], dtype="S20")
    ours, ok = parse_ints(field.view(np.uint8).reshape(len(values), 20))
    assert ok.all()
    np.testing.assert_array_equal(ours, np.array(values, dtype=np.int64))


def test_fast_parser_flags_what_it_cannot_read() -> None:
    texts = [b" 1.5D+03", b"   +.25 ", b"  1 5   ", b"    -   ", b"        ", b" 1e400  ",
             b"12345678901234567890", b"  -0.000"]
    width = max(map(len, texts))
    raw = np.array([t.ljust(width) for t in texts], dtype=f"S{width}").view(np.uint8)
    values, ok = parse_reals(raw.reshape(len(texts), width), pow10())
    assert ok.tolist() == [True, True, False, False, False, False, False, True]
    assert values[0] == 1500.0 and values[1] == 0.25
    assert values[7] == 0.0 and np.signbit(values[7])


def _structure_label(pointer: str) -> str:
    return _label(f"""
        PDS_VERSION_ID = PDS3
        RECORD_TYPE = FIXED_LENGTH
        RECORD_BYTES = 25
        FILE_RECORDS = 3
        ^TABLE = {pointer}
        OBJECT = TABLE
        INTERCHANGE_FORMAT = ASCII
        ROWS = 3
        COLUMNS = 4
        ROW_BYTES = 25
        {_column("N", "ASCII_INTEGER", 1, 2)}
        ^STRUCTURE = "HAND.FMT"
        END_OBJECT = TABLE
        END
    """)


_FMT = _label(f"""
    {_column("V", "ASCII_REAL", 4, 5, unit='"nT"', description='"a value"', format='"F5.2"')}
    ^STRUCTURE = "MORE.FMT"
""")
_MORE = _label(f"""
    {_column("S", "CHARACTER", 10, 2)}
    {_column("W", "ASCII_INTEGER", 13, 11, items=3, item_bytes=3, item_offset=4,
             missing_constant=-99, scaling_factor=0.5, offset=1)}
""")


def test_structure_file_beside_the_label_and_in_a_label_folder(tmp_path: Path) -> None:
    """^STRUCTURE: format files (nested) beside the label or in LABEL/ of the volume."""
    data = tmp_path / "DATA" / "2014"
    data.mkdir(parents=True)
    (data / "HAND.TAB").write_bytes("".join(_ROWS).encode())
    (data / "HAND.LBL").write_text(_structure_label('"HAND.TAB"'), newline="")
    (data / "HAND.FMT").write_text(_FMT, newline="")
    (tmp_path / "LABEL").mkdir()
    (tmp_path / "LABEL" / "MORE.FMT").write_text(_MORE, newline="")
    ds = read_table(data / "HAND.LBL")
    assert list(ds.data_vars) == ["N", "V", "S", "W"]
    _check_hand_table(ds.assign_attrs(START_TIME="2014-08-01T00:00:00"))
    (tmp_path / "LABEL" / "MORE.FMT").unlink()
    e = _error(data / "HAND.LBL")
    assert "MORE.FMT" in str(e) and "^STRUCTURE" in str(e)


def test_label_decoding_equals_pvl_default(tmp_path: Path) -> None:
    """The faster decoder gives pvl's own values: dates, times, symbols, numbers, units."""
    import pvl

    from fluxcal.archive.pds3 import parse_label_text
    from fluxcal.missions.messenger.products import table_columns

    extra = _label("""
        A = 2014-08-01T00:00:00.000
        B = 2014-213T12:30:00
        C = 2014-08-01
        D = 12:30:00.5
        E = ASCII_REAL
        F = 16#FF#
        G = 1.5 <nT>
        H = (1, "x", N/A)
        I = 2014-08-01T00:00:00Z
        END
    """)
    assert parse_label_text(extra) == pvl.loads(extra)
    write_product(_messenger_like(3), tmp_path / "MAGMSOSCI12153_V01", ("tab",),
                  table_columns("mso", False))
    text = (tmp_path / "MAGMSOSCI12153_V01.LBL").read_text()
    assert parse_label_text(text) == pvl.loads(text)


def test_digit_only_text_columns_stay_text(tmp_path: Path) -> None:
    """A CHARACTER column of digits keeps its leading zeros; pdr's inference reads numbers.

    The random table test below draws such columns now and then (strings from "ABCXYZ019");
    this case pins the difference so that the comparison above is shown to be about pdr.
    """
    ds = xr.Dataset({"C0": ("time", np.array(["019", "7", "00000"]))},
                    attrs={"creation_time": "2026-01-01T00:00:00Z"})
    write_product(ds, tmp_path / "R", ("tab",), [Column("C0", "A5")])
    assert read_table(tmp_path / "R.LBL")["C0"].values.tolist() == ["019", "7", "00000"]
    assert pdr.read(tmp_path / "R.LBL")["TABLE"]["C0"].tolist() == [19, 7, 0]


_COLUMN_KINDS = st.sampled_from([("I6", "i"), ("I3.3", "i"), ("F10.3", "f"), ("F12.6", "f"),
                                 ("E15.7", "f"), ("E24.16", "f"), ("A5", "s")])


@settings(max_examples=10, deadline=None)  # each example parses two labels (~1 s)
@given(st.lists(_COLUMN_KINDS, min_size=1, max_size=6), st.integers(1, 15),
       st.integers(0, 2**32 - 1))
def test_random_fluxcal_tables_read_as_pdr_reads_them(tmp_path_factory, kinds, rows: int,
                                                      seed: int) -> None:
    rng = np.random.default_rng(seed)
    data, cols = {}, []
    for i, (fmt, kind) in enumerate(kinds):
        name = f"C{i}"
        if kind == "i":
            values = rng.integers(0, 999, rows)
        elif kind == "f":
            values = rng.uniform(-999, 999, rows)
        else:
            values = np.array(["".join(rng.choice(list("ABCXYZ019"), rng.integers(1, 6)))
                               for _ in range(rows)])
        data[name] = ("time", values)
        cols.append(Column(name, fmt))
    folder = tmp_path_factory.mktemp("random_table")
    ds = xr.Dataset(data, attrs={"creation_time": "2026-01-01T00:00:00Z"})
    write_product(ds, folder / "R", ("tab",), cols)
    ours = read_table(folder / "R.LBL")
    _assert_same_as_pdr(ours, pdr.read(folder / "R.LBL")["TABLE"])
    for name, (fmt, kind) in zip(data, kinds, strict=True):
        if kind == "f":  # printed decimals: half a unit of the last printed digit
            digits = int(fmt.split(".")[1])
            scale = 10.0 ** (3 - digits) if fmt[0] == "E" else 10.0 ** -digits
            np.testing.assert_allclose(ours[name].values, ds[name].values,
                                       atol=0.5 * scale * (1 + 1e-9), rtol=0)
        else:
            np.testing.assert_array_equal(ours[name].values, ds[name].values)
