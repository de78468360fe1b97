"""Readers and writers of RPC-MAG EDITED RAW telemetry as CSV files (issue 4 layout).

Science, one file per sensor (seed 003, sec. 4.1.2)::

    time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality

Housekeeping (sec. 4.1.1)::

    time_utc,obt,t_ob,t_ib,stage_a_id,stage_b_id,filter_cfg,ref_voltage,neg_voltage,pos_voltage,bx_ob,by_ob,bz_ob

``time_utc`` is ISO 8601 UTC; ``obt`` the spacecraft clock reading in seconds since
2003-01-01 (sec. 4.1.2).  The time of each record comes from ``obt`` through the Rosetta
SCLK (id -226) when an `SclkKernel` is given, else from ``time_utc``.  Every error names
the file, line and field.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import xarray as xr
from pyarrow import csv as pacsv

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import tt2000_to_utc, utc_to_tt2000
from fluxcal.missions.rosetta.calib import check_sensor
from fluxcal.missions.rosetta.identity import SPACECRAFT_ID
from fluxcal.missions.rosetta.input_checks import report_time_defects
from fluxcal.products.atomic import atomic_path
from fluxcal.textfile import decode_text

SCIENCE_COLUMNS = ("time_utc", "obt", "sid", "bx", "by", "bz", "t_ob", "t_ib", "quality")
HK_COLUMNS = (
    "time_utc",
    "obt",
    "t_ob",
    "t_ib",
    "stage_a_id",
    "stage_b_id",
    "filter_cfg",
    "ref_voltage",
    "neg_voltage",
    "pos_voltage",
    "bx_ob",
    "by_ob",
    "bz_ob",
)
#: Word ranges: science field signed 20 bit, thermistors 16 bit, supplies 8 bit, ref 20 bit.
_RANGES = {
    "bx": (-(2**19), 2**19 - 1),
    "by": (-(2**19), 2**19 - 1),
    "bz": (-(2**19), 2**19 - 1),
    "t_ob": (0, 2**16 - 1),
    "t_ib": (0, 2**16 - 1),
    "quality": (0, 15),
    "sid": (0, 255),
    "ref_voltage": (0, 2**20 - 1),
    "neg_voltage": (0, 255),
    "pos_voltage": (0, 255),
    "bx_ob": (0, 2**16 - 1),
    "by_ob": (0, 2**16 - 1),
    "bz_ob": (0, 2**16 - 1),
    "stage_a_id": (0, 2**16 - 1),
    "stage_b_id": (0, 2**16 - 1),
    "filter_cfg": (0, 2**16 - 1),
}
SCLK_ID = SPACECRAFT_ID


def _read_table(path: Path, columns: tuple[str, ...]) -> np.ndarray:
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputFormatError(f"cannot read: {exc.strerror or exc}", path=str(path)) from None
    # a UTF-8 BOM is dropped; binary bytes are one line naming the file and line
    header, _, body = decode_text(data, path, f"a CSV text file with the columns "
                                              f"{','.join(columns)}").partition("\n")
    del data
    names = tuple(h.strip() for h in header.strip().split(","))
    if names != columns:
        raise InputFormatError(
            f"header {names} differs from the expected {columns}", path=str(path), line=1
        )
    lines = body.splitlines()
    if lines and not lines[-1].strip():
        lines = lines[:-1]
    if not lines:
        raise InputFormatError("no data records", path=str(path), line=2)
    cells = np.char.split(np.array(lines, dtype=str), ",")
    counts = np.fromiter((len(c) for c in cells), dtype=np.int64, count=len(cells))
    bad = np.flatnonzero(counts != len(columns))
    if bad.size:
        i = int(bad[0])
        raise InputFormatError(
            f"{counts[i]} fields, expected {len(columns)}", path=str(path), line=i + 2
        )
    return np.array(cells.tolist(), dtype=str)


class _TextColumn:
    """The UTC text column as pyarrow holds it (~30 bytes a record, not a 104-byte ``<U26``).

    Enough for `_epoch` when times come from the OBT (``sclk``): the text is read only
    to name records in an error message.
    """

    def __init__(self, column) -> None:
        self._column = column

    def __getitem__(self, i: int) -> str:
        return self._column[int(i)].as_py()

    def __len__(self) -> int:
        return len(self._column)


def _read_fast(path: Path, columns: tuple[str, ...], kinds: dict[str, type],
               utc_text: bool = True) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
    """Parse a well-formed CSV with pyarrow (one thread): ``(time_utc, {name: values})``.

    Returns None where anything is unusual (header, BOM, field count, a value pyarrow
    does not parse, a non-finite or out-of-range number): `_read_table` and `_numeric`
    then read the file (or name its defect) as before.  Both give the same arrays: the
    correctly rounded double of each float, the integer of each int, the UTC text as
    written (a `_TextColumn` unless ``utc_text``).  The text path holds ~1.7 GB of
    strings for a 20 Hz day; this one the columns (~170 MB).
    """
    try:
        with open(path, "rb") as fh:
            header = fh.readline()
    except OSError:
        return None
    if header.rstrip(b"\r\n").decode("ascii", "replace").split(",") != list(columns):
        return None
    types = {name: (pa.float64() if kinds[name] is float else pa.int64()) for name in kinds}
    types[columns[0]] = pa.string()
    try:
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(skip_rows=1, column_names=list(columns),
                                           block_size=1 << 24, use_threads=False),
            parse_options=pacsv.ParseOptions(delimiter=",", quote_char=False,
                                             ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(
                column_types=types, null_values=[], strings_can_be_null=False,
                check_utf8=True),
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError, OSError):
        return None
    if table.num_rows == 0:
        return None
    values = {}
    for name, kind in kinds.items():
        col = np.require(table.column(name).to_numpy(), requirements="W")  # writable
        if kind is float and not np.all(np.isfinite(col)):
            return None
        if name in _RANGES and np.any((col < _RANGES[name][0]) | (col > _RANGES[name][1])):
            return None
        values[name] = col
    utc = table.column(columns[0])
    if not utc_text:
        return _TextColumn(utc), values
    return np.asarray(utc.to_numpy(zero_copy_only=False), dtype=str), values


def _read_columns(path: Path, columns: tuple[str, ...], kinds: dict[str, type],
                  utc_text: bool = True) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``(time_utc, {name: values})`` of a raw CSV: `_read_fast`, else the text reader."""
    fast = _read_fast(path, columns, kinds, utc_text)
    if fast is not None:
        return fast
    table = _read_table(path, columns)
    col = {name: j for j, name in enumerate(columns)}
    values = {name: _numeric(table, col[name], name, kind, path) for name, kind in kinds.items()}
    return table[:, 0], values


def _numeric(table: np.ndarray, j: int, name: str, kind: type, path: Path) -> np.ndarray:
    col = np.char.strip(table[:, j])
    try:
        values = col.astype(np.float64) if kind is float else col.astype(np.int64)
    except (ValueError, OverflowError):
        for i, text in enumerate(col):
            try:
                number = float(text) if kind is float else int(text)
            except ValueError:
                expected = "a number" if kind is float else "an integer"
                raise InputFormatError(
                    f"{str(text)!r} is not {expected}", path=str(path), line=i + 2, field=name
                ) from None
            if kind is int and not -(2**63) <= number < 2**63:
                lo, hi = _RANGES.get(name, (-(2**63), 2**63 - 1))
                raise InputFormatError(f"{number} outside {lo}..{hi}", path=str(path),
                                       line=i + 2, field=name) from None
        raise  # pragma: no cover
    if kind is float and not np.all(np.isfinite(values)):
        i = int(np.flatnonzero(~np.isfinite(values))[0])
        raise InputFormatError(
            f"{str(col[i])!r} is not a finite number", path=str(path), line=i + 2, field=name
        )
    if name in _RANGES:
        lo, hi = _RANGES[name]
        out = np.flatnonzero((values < lo) | (values > hi))
        if out.size:
            i = int(out[0])
            raise InputFormatError(
                f"{values[i]} outside {lo}..{hi}", path=str(path), line=i + 2, field=name
            )
    return values


def _epoch(
    utc: np.ndarray,
    obt: np.ndarray,
    path: Path,
    sclk,
    lsk,
    *,
    rows: np.ndarray | None = None,
    names: tuple[str, str] = ("time_utc", "obt"),
) -> tuple[np.ndarray, str]:
    """TT2000 of each record (from ``obt`` with ``sclk``, else from ``utc``), non-decreasing.

    ``rows`` are the record numbers errors name (default: CSV lines, ``i + 2``);
    ``names`` the UTC and OBT field names (the archive tables call them TIME.UTC, TIME.OBT).
    """
    def line_of(i: int) -> int:
        return i + 2 if rows is None else int(rows[i])

    if sclk is not None:  # TT2000 straight from the TDT clock, exact on the OBT tick grid
        epoch = sclk.to_tt2000(np.ones(obt.size, dtype=np.int64), obt)
        field = names[1]
    else:
        try:
            epoch = utc_to_tt2000(utc, lsk)
        except InputFormatError:
            line, text = None, ""
            for i, item in enumerate(np.char.strip(np.asarray(utc, dtype=str))):
                try:
                    utc_to_tt2000(np.array([item]), lsk)
                except InputFormatError:
                    line, text = line_of(i), str(item)
                    break
            raise InputFormatError(
                f"cannot parse UTC time {text!r} (ISO 8601 expected)",
                path=str(path),
                line=line,
                field=names[0],
            ) from None
        field = names[0]
    back = np.flatnonzero(np.diff(epoch) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise InputFormatError(
            f"time goes backwards ({utc[i]} after {utc[i - 1]}, "
            f"obt {obt[i]} after {obt[i - 1]})",
            path=str(path),
            line=line_of(i),
            field=field,
        )
    report_time_defects(epoch, utc, obt, path=path, line_of=line_of, names=names,
                        from_obt=sclk is not None, lsk=lsk)
    return epoch, field


def read_science_csv(path: Path, sensor: str, *, sclk=None, lsk=None) -> xr.Dataset:
    """Read a raw science CSV file into a ``Dataset`` (seed 003, sec. 4.1.2).

    Parameters
    ----------
    path : Path
    sensor : {"OB", "IB"}
        The sensor whose vectors the file holds (recorded in ``attrs["sensor"]``).
    sclk : fluxcal.geometry.time.SclkKernel, optional
        Rosetta SCLK (id -226): times from ``obt``; default: from ``time_utc``.
    lsk : LeapSecondTable, optional

    Returns
    -------
    xarray.Dataset
        ``epoch`` (TT2000 ns), ``obt`` (s), ``sid``, ``b_counts`` (time, component),
        ``t_ob_counts``, ``t_ib_counts``, ``quality``, ``row`` (file line number).

    Raises
    ------
    InputFormatError
        Wrong header, wrong field count, non-numeric field, value out of range, time going
        backwards; naming file, line and field.
    """
    path = Path(path)
    kinds = {"obt": float} | {name: int for name in ("sid", "bx", "by", "bz", "t_ob", "t_ib",
                                                     "quality")}
    # with an SCLK the times come from the OBT: the UTC text only names records in errors
    utc, ints = _read_columns(path, SCIENCE_COLUMNS, kinds, utc_text=sclk is None)
    obt = ints.pop("obt")
    epoch, time_source = _epoch(utc, obt, path, sclk, lsk)
    del utc
    return science_dataset(
        epoch, obt, ints["sid"].astype(np.int16), ints,
        np.arange(2, obt.size + 2), "line in file",
        {"sensor": check_sensor(sensor), "source": str(path), "time_source": time_source},
    )


def science_dataset(epoch: np.ndarray, obt: np.ndarray, sid: np.ndarray, ints: dict,
                    row: np.ndarray, row_description: str, attrs: dict) -> xr.Dataset:
    """Build the raw science Dataset both input layouts give (sec. 4.1.2 columns as counts).

    ``ints`` holds the integer columns ``bx, by, bz, t_ob, t_ib, quality``; ``row`` says
    where each record was read (``row_description``: line in a CSV, row in a table).
    """
    return xr.Dataset(
        {
            "obt": ("time", obt, {"units": "s"}),
            "sid": ("time", sid, {"units": "1"}),
            "b_counts": (
                ("time", "component"),
                np.stack([ints["bx"], ints["by"], ints["bz"]], axis=1).astype(np.int32),
                {"units": "count"},
            ),
            "t_ob_counts": ("time", ints["t_ob"].astype(np.int32), {"units": "count"}),
            "t_ib_counts": ("time", ints["t_ib"].astype(np.int32), {"units": "count"}),
            "quality": ("time", ints["quality"].astype(np.int16), {"units": "1"}),
            "row": ("time", row, {"units": "1", "description": row_description}),
        },
        coords={
            "epoch": ("time", epoch, {"units": "ns", "time_base": "TT2000"}),
            "component": ["x", "y", "z"],
        },
        attrs=attrs,
    )


def read_hk_csv(path: Path, *, sclk=None, lsk=None) -> xr.Dataset:
    """Read a raw HK CSV file into a ``Dataset`` (seed 003, sec. 4.1.1)."""
    path = Path(path)
    table = _read_table(path, HK_COLUMNS)
    obt = _numeric(table, 1, "obt", float, path)
    ints = {
        name: _numeric(table, j, name, int, path) for j, name in enumerate(HK_COLUMNS) if j >= 2
    }
    epoch, time_source = _epoch(table[:, 0], obt, path, sclk, lsk)
    return hk_dataset(epoch, obt, ints, {"source": str(path), "time_source": time_source})


def hk_dataset(epoch: np.ndarray, obt: np.ndarray, ints: dict, attrs: dict) -> xr.Dataset:
    """Build the raw HK Dataset both input layouts give (sec. 4.1.1 words as counts)."""
    data = {
        "obt": ("time", obt, {"units": "s"}),
        "t_ob_counts": ("time", ints["t_ob"], {"units": "count"}),
        "t_ib_counts": ("time", ints["t_ib"], {"units": "count"}),
        "ref_voltage_counts": ("time", ints["ref_voltage"], {"units": "count"}),
        "neg_voltage_counts": ("time", ints["neg_voltage"], {"units": "count"}),
        "pos_voltage_counts": ("time", ints["pos_voltage"], {"units": "count"}),
        "b_ob_counts": (
            ("time", "component"),
            np.stack([ints["bx_ob"], ints["by_ob"], ints["bz_ob"]], axis=1),
            {"units": "count"},
        ),
    }
    for name in ("stage_a_id", "stage_b_id", "filter_cfg"):
        data[name] = ("time", ints[name], {"units": "1"})
    return xr.Dataset(
        data,
        coords={
            "epoch": ("time", epoch, {"units": "ns", "time_base": "TT2000"}),
            "component": ["x", "y", "z"],
        },
        attrs=attrs,
    )


#: Records formatted and written at a time: a day's text (and its temporaries, ~3 GB for
#: 1.7 M records) is never held whole.
WRITE_CHUNK = 1 << 14

#: A column to write: an array (written as ``astype(str)``), or an array and the function
#: that formats a slice of it as text.
Column = np.ndarray | tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]


def _write_atomic(path: Path, header: tuple[str, ...], columns: Sequence[Column]) -> Path:
    """Write a CSV (header, then one line per record) atomically, `WRITE_CHUNK` rows at a time.

    The bytes are those of formatting every column whole and joining all lines at once.
    """
    path = Path(path)
    cols = [c if isinstance(c, tuple) else (c, None) for c in columns]
    n = len(cols[0][0])
    with atomic_path(path, now=True) as tmp:
        with open(tmp, "w", encoding="ascii") as fh:
            fh.write(",".join(header) + "\n")
            if n == 0:
                fh.write("\n")
            for a in range(0, n, WRITE_CHUNK):
                part = slice(a, a + WRITE_CHUNK)
                text = [values[part].astype(str) if fmt is None else fmt(values[part])
                        for values, fmt in cols]
                rows = text[0]
                for c in text[1:]:
                    rows = np.char.add(np.char.add(rows, ","), c)
                fh.write("\n".join(rows.tolist()) + "\n")
    return path


def _utc(epoch: np.ndarray, lsk) -> np.ndarray:
    return tt2000_to_utc(epoch, digits=6, lsk=lsk)


def _obt_text(obt: np.ndarray) -> np.ndarray:
    return np.char.mod("%.6f", obt)


def write_science_csv(raw: xr.Dataset, path: Path, *, lsk=None) -> Path:
    """Write a raw science dataset (as `read_science_csv` returns) to CSV, atomically."""
    b = raw["b_counts"].values
    cols = [
        (raw["epoch"].values, lambda e: _utc(e, lsk)),
        (raw["obt"].values, _obt_text),
        raw["sid"].values,
        b[:, 0],
        b[:, 1],
        b[:, 2],
        raw["t_ob_counts"].values,
        raw["t_ib_counts"].values,
        raw["quality"].values,
    ]
    return _write_atomic(path, SCIENCE_COLUMNS, cols)


def write_hk_csv(raw: xr.Dataset, path: Path, *, lsk=None) -> Path:
    """Write a raw HK dataset (as `read_hk_csv` returns) to CSV, atomically."""
    b = raw["b_ob_counts"].values
    cols = [
        (raw["epoch"].values, lambda e: _utc(e, lsk)),
        (raw["obt"].values, _obt_text),
        raw["t_ob_counts"].values,
        raw["t_ib_counts"].values,
        raw["stage_a_id"].values,
        raw["stage_b_id"].values,
        raw["filter_cfg"].values,
        raw["ref_voltage_counts"].values,
        raw["neg_voltage_counts"].values,
        raw["pos_voltage_counts"].values,
        b[:, 0],
        b[:, 1],
        b[:, 2],
    ]
    return _write_atomic(path, HK_COLUMNS, cols)

