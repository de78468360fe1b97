"""Readers of the three MESSENGER MAG input streams (CSV with a header line).

* science: ``partition,met,rate,range,cx,cy,cz``
* heater (the LAC stream): ``partition,met,heater``
* sensor temperature: ``partition,met,temperature_c``

Several files per stream are concatenated in time order.  Every defect (unknown or
missing column, non-numeric field, rate or range out of range, counts beyond the
range's limits) raises `fluxcal.errors.InputFormatError` naming the file, line and
field.  A heater gap longer than a heater period or a temperature gap longer than 600 s
is recorded in ``attrs["stream_gaps"]`` and the span flagged
(`fluxcal.missions.messenger.defects`; ``on_gap="raise"`` refuses it instead).  Records
whose MET breaks the clock's order (a jump back, a spike) are dropped, counted in
``attrs["clock_jumps"]`` and their span flagged (``on_clock_jump="raise"`` refuses them
instead); a stream with fewer than half its records in order is refused.  The format is
documented in ``docs/formats/messenger.md``.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 2 (EDR content), sec. 5 Table 1,
   sec. 6 (LAC heater bit).
"""

from __future__ import annotations

import mmap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import xarray as xr
from numba import njit
from pyarrow import csv as pacsv

from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.defects import clock_jumps, ordered_records
from fluxcal.textfile import csv_header, decode_text

SCIENCE_COLUMNS = ("partition", "met", "rate", "range", "cx", "cy", "cz")
HEATER_COLUMNS = ("partition", "met", "heater")
TEMPERATURE_COLUMNS = ("partition", "met", "temperature_c")
#: Signed 16-bit sensor counts (both ranges).
COUNT_LIMITS = (-32768, 32767)
MAX_RATE_SETTING = 10
HEATER_PERIOD_S = 100.0
#: Longest gap (s) between temperature records the linear interpolation may bridge
#: (docs/decisions/messenger.md, "Temperature gaps").
TEMPERATURE_MAX_GAP_S = 600.0


def _read_table(path: Path, expected: Sequence[str]) -> np.ndarray:
    """Return a (len(expected), n) float array: the CSV's columns in ``expected`` order."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            first = fh.readline()
    except OSError as exc:
        raise InputFormatError(f"cannot read file: {exc}", path=str(path)) from exc
    # a UTF-8 BOM is dropped (not part of the first name); binary bytes are an error
    header = decode_text(first, path, f"a CSV text file with the columns {','.join(expected)}")
    names = csv_header(header)  # RFC 4180: a spreadsheet export quotes the names
    for name in names:
        if name not in expected:
            raise InputFormatError(
                f"unknown column {name!r}; expected the columns {','.join(expected)}",
                path=str(path), line=1, field=name,
            )
    for name in expected:
        if name not in names:
            raise InputFormatError(
                f"missing column {name!r}; expected {','.join(expected)}",
                path=str(path), line=1, field=name,
            )
    if len(set(names)) != len(names):
        raise InputFormatError("duplicate column names", path=str(path), line=1)
    order = [names.index(n) for n in expected]
    data = _parse_plain(path, len(names), order)
    if data is None:  # not plain decimal numbers: the general parser decides
        data = _parse_numbers(path, names, order)
        bad = ~np.isfinite(data)
        if bad.any():
            row, col = np.argwhere(bad.T)[0]
            raise InputFormatError(
                "non-finite value; expected a finite number", path=str(path),
                line=int(row) + 2, field=expected[col],
            )
    return data


#: Exact powers of ten (10**22 is the largest double that is one).
_POW10 = np.array([10.0**e for e in range(23)])
#: Largest mantissa whose conversion to double is exact.
_MAX_MANTISSA = 2**53


@njit(cache=True, nogil=True)
def _parse_plain_kernel(buf, start, column, pow10, max_mantissa, out):  # pragma: no cover
    """Parse lines of ``-?digits[.digits]`` fields separated by ``,`` into ``out``.

    Field ``f`` of record ``r`` goes to ``out[column[f], r]`` (``out`` has room for
    every record of ``buf[start:]``).  A field is ``mantissa / 10**fraction_digits``
    (negated after a ``-``): one correctly rounded division of two exact doubles
    (mantissa <= 2**53, at most 18 digits), so the value is the correctly rounded one,
    as a full decimal parser gives.

    Returns
    -------
    int
        The number of records, or -1 at the first record not in that form (any other
        byte, an empty field or line, a field count other than ``column.size``, more
        digits); the loop stops there.
    """
    k = column.size
    size = buf.size
    i = start
    row = 0
    while i < size:
        if row == out.shape[1]:
            return -1
        for f in range(k):
            neg = i < size and buf[i] == 45  # "-"
            if neg:
                i += 1
            mant = 0
            digits = 0
            while i < size:
                c = np.int64(buf[i]) - 48
                if c < 0 or c > 9:
                    break
                mant = mant * 10 + c
                digits += 1
                i += 1
            frac = 0
            if digits and i < size and buf[i] == 46:  # "."
                i += 1
                while i < size:
                    c = np.int64(buf[i]) - 48
                    if c < 0 or c > 9:
                        break
                    mant = mant * 10 + c
                    frac += 1
                    i += 1
                if frac == 0:
                    return -1
            if digits == 0 or digits + frac > 18 or mant > max_mantissa:
                return -1
            v = float(mant)
            if frac:
                v = v / pow10[frac]
            out[column[f], row] = -v if neg else v
            if f < k - 1:  # a comma, then the next field
                if i >= size or buf[i] != 44:
                    return -1
            elif i < size and buf[i] != 10:  # the line (or the file) ends
                return -1
            i += 1
        row += 1
    return row


def _parse_plain(path: Path, n_fields: int, order: list[int]) -> np.ndarray | None:
    """Parse a body of plain decimal numbers, shape ``(len(order), n)``; None otherwise.

    Fields of ``-?digits[.digits]`` with LF line ends (every file fluxcal writes)
    are parsed in one compiled pass over the memory-mapped file (`_parse_plain_kernel`);
    anything else (other number forms, CR line ends, defects) returns None for
    `_parse_numbers`, which parses or names the defect.  Both give the correctly
    rounded double of each field.
    """
    with path.open("rb") as fh:
        try:
            mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):  # an empty file, a pipe: the general reader decides
            return None
        with mm:
            size = len(mm)
            start = mm.find(b"\n") + 1
            if start == 0 or mm.find(b"\r", 0, start) >= 0:
                return None  # the header line is read as text (universal newlines)
            buf = np.frombuffer(mm, dtype=np.uint8)
            try:
                # room for the most records the body can hold (2 bytes a field at
                # least); pages past the records read are never touched
                out = np.empty((len(order), (size - start) // (2 * n_fields) + 1))
                column = np.full(n_fields, -1, dtype=np.int64)
                column[order] = np.arange(len(order))
                n = _parse_plain_kernel(buf, start, column, _POW10, _MAX_MANTISSA, out)
            finally:
                del buf  # releases the map
    return out[:, :n] if n >= 0 else None


def _parse_numbers(path: Path, names: list[str], order: list[int]) -> np.ndarray:
    """Parse the CSV body as float64, shape (len(order), n), columns ``names[order]``.

    The general reader (any number form ``float`` takes), for files `_parse_plain`
    does not take.  Uses pyarrow's CSV reader on one thread.

    Empty fields are not taken as missing values and empty lines are not skipped, so
    every defect fails the parse; the slow line-by-line `_diagnose` then names the
    file, line and field.
    """
    try:
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(skip_rows=1, column_names=names,
                                           block_size=1 << 24, use_threads=False),
            parse_options=pacsv.ParseOptions(delimiter=",", ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(
                column_types={n: pa.float64() for n in names}, null_values=[],
                strings_can_be_null=False, quoted_strings_can_be_null=False),
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        _diagnose(path, names)  # raises naming the line and field of a defect
        # every line parses with Python's float: numpy's more lenient parser decides
        try:
            full = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float)
        except ValueError as exc:
            raise InputFormatError(f"malformed CSV: {exc}", path=str(path)) from None
        return np.ascontiguousarray(full.reshape(-1, len(names))[:, order].T)
    data = np.empty((len(order), table.num_rows))
    for j, k in enumerate(order):
        column = table.column(k)
        if column.null_count:  # pragma: no cover - null_values=[] leaves none
            raise InputFormatError("missing value", path=str(path), field=names[k])
        data[j] = column.to_numpy()
    return data


def _diagnose(path: Path, names: list[str]) -> None:
    """Find the first malformed line (slow path, only after a parse failure) and raise.

    Returns without raising when every line has the right number of fields, each of
    which Python's ``float`` accepts.
    """
    with path.open("rb") as fh:
        fh.readline()
        for lineno, raw in enumerate(fh, start=2):
            line = decode_text(raw, path, "a CSV text file of numbers",
                               first_line=lineno).replace("\r", "")
            if not line.strip():
                raise InputFormatError("empty line", path=str(path), line=lineno)
            fields = line.rstrip("\n").split(",")
            if len(fields) != len(names):
                raise InputFormatError(
                    f"expected {len(names)} fields, got {len(fields)}", path=str(path), line=lineno
                )
            for name, value in zip(names, fields, strict=True):
                try:
                    float(value)
                except ValueError:
                    raise InputFormatError(
                        f"non-numeric value {value.strip()!r}; expected a number",
                        path=str(path), line=lineno, field=name,
                    ) from None


@njit(cache=True, nogil=True)
def _first_outside(values, lo, hi):  # pragma: no cover - compiled
    """Index of the first value that is not a whole number in ``[lo, hi]``, or -1."""
    for i in range(values.size):
        v = values[i]
        if np.floor(v) != v or v < lo or v > hi:  # NaN: floor(NaN) != NaN
            return i
    return -1


def plain_number(value: float) -> str:
    """``value`` as a user wrote it: ``12``, ``12.5``, ``1.2345678901234567e+19``, ``nan``."""
    v = float(value)
    if v.is_integer() and abs(v) < 2**53:
        return str(int(v))
    return repr(v)


def _check_integer(
    path: Path, values: np.ndarray, name: str, lo: float, hi: float, what: str
) -> None:
    row = _first_outside(np.ascontiguousarray(values, dtype=np.float64), float(lo), float(hi))
    if row >= 0:
        v = float(values[row])
        problem = "is not an integer" if np.isfinite(v) and not v.is_integer() \
            else f"outside {what}"
        raise InputFormatError(f"value {plain_number(v)} {problem}", path=str(path),
                               line=row + 2, field=name)


@njit(cache=True, nogil=True)
def _first_backwards(partition, met):  # pragma: no cover - compiled
    """First ``i`` whose (partition, MET) step goes back, or -1.

    A step goes back when ``partition[i] - partition[i-1] < 0``, or when that difference
    is zero and ``met[i] - met[i-1] < 0`` (NaN differences do not).
    """
    for i in range(1, partition.size):
        dp = partition[i] - partition[i - 1]
        if dp < 0.0 or (dp == 0.0 and met[i] - met[i - 1] < 0.0):
            return i
    return -1


def _check_order(paths: list[Path], tables: list[np.ndarray], stream: str) -> None:
    """MET (within the clock partition order) must never go backwards, across files too."""
    prev: tuple[float, float, Path, int] | None = None
    for path, data in zip(paths, tables, strict=True):
        if data.shape[1] == 0:
            continue
        key_p, key_m = data[0], data[1]
        row = _first_backwards(key_p, key_m)
        if row >= 0:
            raise InputFormatError(
                f"{stream}: MET goes backwards ({plain_number(key_m[row - 1])} -> "
                f"{plain_number(key_m[row])})",
                path=str(path), line=row + 2, field="met",
            )
        if prev is not None and (key_p[0], key_m[0]) < prev[:2]:
            raise InputFormatError(
                f"{stream}: MET goes backwards across files ({plain_number(prev[1])} at "
                f"the end of {prev[2]} -> {plain_number(key_m[0])})", path=str(path), line=2,
                field="met",
            )
        prev = (key_p[-1], key_m[-1], path, data.shape[1] + 1)


def _read_stream(
    paths: Sequence[str | Path], columns: Sequence[str], stream: str,
    on_clock_jump: str = "raise",
) -> tuple[list[Path], list[np.ndarray]]:
    if isinstance(paths, (str, Path)):
        paths = [paths]
    plist = [Path(p) for p in paths]
    if not plist:
        raise InputFormatError(f"no {stream} file given")
    tables = [_read_table(p, columns) for p in plist]
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[0], "partition", 1, 2, "the clock partitions 1..2")
    # files in time order of their first record
    order = sorted(
        range(len(plist)),
        key=lambda i: (tuple(tables[i][:2, 0]) if tables[i].shape[1] else (np.inf, np.inf)),
    )
    plist = [plist[i] for i in order]
    tables = [tables[i] for i in order]
    if on_clock_jump not in ("raise", "drop"):
        raise ValueError(f"on_clock_jump: 'raise' or 'drop', not {on_clock_jump!r}")
    if on_clock_jump == "raise":
        _check_order(plist, tables, stream)
    return plist, tables


def _drop_clock_jumps(plist: list[Path], tables: list[np.ndarray], data: np.ndarray,
                      stream: str, on_clock_jump: str) -> tuple[np.ndarray, dict]:
    """Drop the records off the longest time-ordered run (issue 23); return the attrs.

    ``{"clock_jumps": [[partition, met_before, met_after, n], ...]}`` when records were
    dropped (`fluxcal.missions.messenger.defects.clock_jumps`), else nothing.
    """
    if on_clock_jump == "raise" or data.shape[1] < 2:
        return data, {}
    keep = ordered_records(data[0], data[1], strict=stream == "science")
    if keep.all():
        return data, {}
    first = int(np.flatnonzero(~keep)[0])
    sizes = np.cumsum([t.shape[1] for t in tables])
    where = str(plist[int(np.searchsorted(sizes, first, side="right"))])
    jumps = clock_jumps(data[0], data[1], keep, stream=f"{stream} stream", where=where)
    return data[:, keep], {"clock_jumps": jumps}


def read_science(
    paths: Sequence[str | Path] | str | Path, *, on_clock_jump: str = "drop"
) -> xr.Dataset:
    """Read science-sample CSV files into a raw dataset on dimension ``time``.

    Parameters
    ----------
    paths : path or sequence of paths
    on_clock_jump : {"drop", "raise"}
        Samples off the longest run in (partition, MET) order (MET going back, a time
        spike, files that overlap): dropped and listed in ``attrs["clock_jumps"]``
        (``[[partition, met_before, met_after, n], ...]``, the kept samples around each
        run; `fluxcal.missions.messenger.defects`), or an error naming the line.

    Returns
    -------
    xarray.Dataset
        ``partition`` (int8), ``met`` (s), ``rate`` (int8), ``range`` (int8), ``counts``
        (time, component) int32; attrs ``inputs`` (and ``clock_jumps``).

    Raises
    ------
    InputFormatError
        For every defect listed in the module docstring.
    """
    plist, tables = _read_stream(paths, SCIENCE_COLUMNS, "science", on_clock_jump)
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[2], "rate", 0, MAX_RATE_SETTING,
                       f"the rate settings 0..{MAX_RATE_SETTING} (Table 1)")
        _check_integer(path, data[3], "range", 0, 1, "the range flags 0 (fine) and 1 (coarse)")
        for j, name in enumerate(("cx", "cy", "cz")):
            _check_integer(path, data[4 + j], name, *COUNT_LIMITS,
                           f"the signed 16-bit count limits {COUNT_LIMITS}")
    data = tables[0] if len(tables) == 1 else np.concatenate(tables, axis=1)
    data, jumps = _drop_clock_jumps(plist, tables, data, "science", on_clock_jump)
    return xr.Dataset(
        {
            "partition": ("time", data[0].astype(np.int8), {"units": "1"}),
            # a copy: a view would keep the whole (7, n) parsed table (95 MB a 20 Hz day)
            "met": ("time", data[1].copy(), {"units": "s", "description": "MET as recorded"}),
            "rate": ("time", data[2].astype(np.int8), {"units": "1"}),
            "range": ("time", data[3].astype(np.int8), {"units": "1"}),
            "counts": (("time", "component"), data[4:7].T.astype(np.int32, order="C"),
                       {"units": "counts"}),
        },
        coords={"component": ["x", "y", "z"]},
        attrs={"inputs": ";".join(str(p) for p in plist), **jumps},
    )


def read_heater(
    paths: Sequence[str | Path] | str | Path, *, on_gap: str = "report",
    on_clock_jump: str = "drop",
) -> xr.Dataset:
    """Read heater-bit CSV files (1-s LAC stream) into a dataset on ``heater_time``.

    Parameters
    ----------
    paths : path or sequence of paths
    on_gap : {"report", "raise"}
        Two consecutive records more than one heater period (100 s) apart: recorded in
        ``attrs["stream_gaps"]`` (``[[partition, met_before, met_after], ...]``; absent
        when there is none) and flagged by `fluxcal.missions.messenger.defects`
        (default: the day is processed), or an error.
    on_clock_jump : {"drop", "raise"}
        As for `read_science` (``attrs["clock_jumps"]``).

    Raises
    ------
    InputFormatError
        Also, with ``on_gap="raise"``, when two consecutive heater records are more than
        one heater period (100 s) apart.
    """
    plist, tables = _read_stream(paths, HEATER_COLUMNS, "heater", on_clock_jump)
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[2], "heater", 0, 1, "the heater bit values 0 and 1")
    data = np.concatenate(tables, axis=1)
    data, jumps = _drop_clock_jumps(plist, tables, data, "heater", on_clock_jump)
    gaps = _check_gaps(*_gap_tables(plist, tables, data, jumps, on_gap), HEATER_PERIOD_S,
                       "heater stream", f"one heater period ({HEATER_PERIOD_S:.0f} s)",
                       on_gap=on_gap)
    return xr.Dataset(
        {
            "partition": ("heater_time", data[0].astype(np.int8), {"units": "1"}),
            "met": ("heater_time", data[1].copy(), {"units": "s"}),
            "heater": ("heater_time", data[2].astype(np.int8), {"units": "1"}),
        },
        attrs={"inputs": ";".join(str(p) for p in plist), **_gap_attrs(gaps), **jumps},
    )


def _gap_tables(plist: list[Path], tables: list[np.ndarray], data: np.ndarray,
                jumps: dict, on_gap: str) -> tuple[list[Path], list[np.ndarray]]:
    """Return the tables the gap check reads: per file, or the ordered records.

    Per file for an error (its line numbers); the ordered records when some were dropped
    and gaps are reported (the gaps the drop leaves count too).
    """
    return (plist[:1], [data]) if jumps and on_gap == "report" else (plist, tables)


def _gap_attrs(gaps: list[list[float]]) -> dict:
    """``{"stream_gaps": gaps}`` when there are gaps, else nothing (the EDR route's form)."""
    return {"stream_gaps": gaps} if gaps else {}


def _check_gaps(
    plist: Sequence[Path], tables: Sequence[np.ndarray], max_gap: float, what: str,
    limit: str | None = None, *, on_gap: str = "raise",
) -> list[list[float]]:
    """Find consecutive records of one partition more than ``max_gap`` apart.

    Checked within each file and across consecutive files.  ``on_gap="raise"``: an
    error naming the file and the line of the record after the gap (``limit`` words the
    limit, default seconds); ``"report"``: return ``[[partition, met_before, met_after],
    ...]``.
    """
    if on_gap not in ("raise", "report"):
        raise ValueError(f"on_gap: 'raise' or 'report', not {on_gap!r}")
    limit = limit or f"{max_gap:.0f} s"
    found: list[list[float]] = []
    for path, data in zip(plist, tables, strict=True):
        gaps = (np.diff(data[1]) > max_gap) & (np.diff(data[0]) == 0)
        if gaps.any() and on_gap == "raise":
            row = int(np.flatnonzero(gaps)[0]) + 1
            raise InputFormatError(
                f"{what} gap of {data[1, row] - data[1, row - 1]:.0f} s exceeds {limit}",
                path=str(path), line=row + 2, field="met",
            )
        for row in np.flatnonzero(gaps) + 1:
            found.append([float(data[0, row]), float(data[1, row - 1]), float(data[1, row])])
    for (p0, d0), (p1, d1) in zip(
        zip(plist[:-1], tables[:-1], strict=True), zip(plist[1:], tables[1:], strict=True),
        strict=True,
    ):
        if d0.shape[1] and d1.shape[1] and d0[0, -1] == d1[0, 0]:
            gap = d1[1, 0] - d0[1, -1]
            if gap > max_gap and on_gap == "raise":
                raise InputFormatError(
                    f"{what} gap of {gap:.0f} s between {p0} and this file exceeds {limit}",
                    path=str(p1), line=2, field="met",
                )
            if gap > max_gap:
                found.append([float(d1[0, 0]), float(d0[1, -1]), float(d1[1, 0])])
    return sorted(found)


def read_temperature(
    paths: Sequence[str | Path] | str | Path, max_gap_s: float = TEMPERATURE_MAX_GAP_S,
    *, on_gap: str = "report", on_clock_jump: str = "drop",
) -> xr.Dataset:
    """Read sensor-temperature CSV files into a dataset on ``temperature_time``.

    Parameters
    ----------
    paths : path or sequence of paths
        One file per day; several for a longer interval.
    max_gap_s : float
        Longest gap between consecutive records (same SCLK partition) that the linear
        interpolation to the sample times (seed 000 sec. 7) may bridge.  With Table 2's
        steepest slope (6.62 counts/degC, ~0.3 nT/degC) a temperature the interpolation
        misses by 0.2 degC already costs 0.06 nT.
    on_gap : {"report", "raise"}
        A longer gap: bridged by the interpolation, recorded in ``attrs["stream_gaps"]``
        and flagged by `fluxcal.missions.messenger.defects` (default), or an error.
    on_clock_jump : {"drop", "raise"}
        As for `read_science` (``attrs["clock_jumps"]``).

    Raises
    ------
    InputFormatError
        Naming file, line and field: a temperature outside -150..150 degC, or (with
        ``on_gap="raise"``) a gap longer than ``max_gap_s``.
    """
    plist, tables = _read_stream(paths, TEMPERATURE_COLUMNS, "temperature", on_clock_jump)
    for path, data in zip(plist, tables, strict=True):
        bad = (data[2] < -150) | (data[2] > 150)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise InputFormatError(
                f"temperature {data[2, row]} degC outside -150..150 degC", path=str(path),
                line=row + 2, field="temperature_c",
            )
    data = np.concatenate(tables, axis=1)
    data, jumps = _drop_clock_jumps(plist, tables, data, "temperature", on_clock_jump)
    gaps = _check_gaps(*_gap_tables(plist, tables, data, jumps, on_gap), max_gap_s,
                       "temperature stream", on_gap=on_gap)
    return xr.Dataset(
        {
            "partition": ("temperature_time", data[0].astype(np.int8), {"units": "1"}),
            "met": ("temperature_time", data[1].copy(), {"units": "s"}),
            "temperature_c": ("temperature_time", data[2].copy(), {"units": "degC"}),
        },
        attrs={"inputs": ";".join(str(p) for p in plist), **_gap_attrs(gaps), **jumps},
    )
