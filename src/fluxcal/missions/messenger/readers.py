"""Readers of the three MESSENGER MAG input streams (CSV with a header line).

* science: ``partition,met,rate,range,cx,cy,cz``
* heater (the LAC stream): ``partition,met,heater``
* sensor temperature: ``partition,met,temperature_c``

Several files per stream are concatenated in time order.  Every defect (unknown or
missing column, non-numeric field, rate or range out of range, counts beyond the
range's limits, MET going backwards, a heater gap longer than a heater period) raises
`fluxcal.errors.InputFormatError` naming the file, line and field.  The format is
documented in ``docs/formats/messenger.md``.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 2 (EDR content), sec. 5 Table 1,
   sec. 6 (LAC heater bit).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError

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
    """Return a (n, len(expected)) float array of the CSV's columns in ``expected`` order."""
    path = Path(path)
    try:
        with path.open() as fh:
            header = fh.readline()
    except OSError as exc:
        raise InputFormatError(f"cannot read file: {exc}", path=str(path)) from exc
    names = [h.strip() for h in header.strip().split(",")]
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
    data = _parse_numbers(path, names, [names.index(n) for n in expected])
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputFormatError(
            "non-finite value; expected a finite number", path=str(path), line=int(row) + 2,
            field=expected[col],
        )
    return data


def _parse_numbers(path: Path, names: list[str], order: list[int]) -> np.ndarray:
    """Parse the CSV body as float64, shape (n, len(names)), columns ``names[order]``.

    Uses pyarrow's CSV reader.

    pyarrow parses in C++ (~20x ``np.loadtxt``).  Empty fields are not taken as missing
    values and empty lines are not skipped, so every defect fails the parse; the slow
    line-by-line `_diagnose` then names the file, line and field.
    """
    import pyarrow as pa
    from pyarrow import csv as pacsv

    try:
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(skip_rows=1, column_names=names,
                                           block_size=1 << 24),
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
        return full.reshape(-1, len(names))[:, order]
    data = np.empty((table.num_rows, len(names)))
    for j, k in enumerate(order):
        column = table.column(k)
        if column.null_count:  # pragma: no cover - null_values=[] leaves none
            raise InputFormatError("missing value", path=str(path), field=names[k])
        data[:, j] = column.to_numpy()
    return data


def _diagnose(path: Path, names: list[str]) -> None:
    """Find the first malformed line (slow path, only after a parse failure) and raise.

    Returns without raising when every line has the right number of fields, each of
    which Python's ``float`` accepts.
    """
    with path.open() as fh:
        fh.readline()
        for lineno, line in enumerate(fh, start=2):
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


def _check_integer(
    path: Path, values: np.ndarray, name: str, lo: float, hi: float, what: str
) -> None:
    bad = (values != np.round(values)) | (values < lo) | (values > hi)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputFormatError(
            f"value {values[row]!r} outside {what}", path=str(path), line=row + 2, field=name
        )


def _check_order(paths: list[Path], tables: list[np.ndarray], stream: str) -> None:
    """MET (within the clock partition order) must never go backwards, across files too."""
    prev: tuple[float, float, Path, int] | None = None
    for path, data in zip(paths, tables, strict=True):
        if data.shape[0] == 0:
            continue
        key_p, key_m = data[:, 0], data[:, 1]
        back = (np.diff(key_p) < 0) | ((np.diff(key_p) == 0) & (np.diff(key_m) < 0))
        if back.any():
            row = int(np.flatnonzero(back)[0]) + 1
            raise InputFormatError(
                f"{stream}: MET goes backwards ({key_m[row - 1]!r} -> {key_m[row]!r})",
                path=str(path), line=row + 2, field="met",
            )
        if prev is not None and (key_p[0], key_m[0]) < prev[:2]:
            raise InputFormatError(
                f"{stream}: MET goes backwards across files ({prev[1]!r} at the end of "
                f"{prev[2]} -> {key_m[0]!r})", path=str(path), line=2, field="met",
            )
        prev = (key_p[-1], key_m[-1], path, data.shape[0] + 1)


def _read_stream(
    paths: Sequence[str | Path], columns: Sequence[str], stream: str
) -> tuple[list[Path], list[np.ndarray]]:
    if isinstance(paths, (str, Path)):
        paths = [paths]
    plist = [Path(p) for p in paths]
    if not plist:
        raise InputFormatError(f"no {stream} file given")
    tables = [_read_table(p, columns) for p in plist]
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[:, 0], "partition", 1, 2, "the clock partitions 1..2")
    # files in time order of their first record
    order = sorted(
        range(len(plist)),
        key=lambda i: (tuple(tables[i][0, :2]) if tables[i].shape[0] else (np.inf, np.inf)),
    )
    plist = [plist[i] for i in order]
    tables = [tables[i] for i in order]
    _check_order(plist, tables, stream)
    return plist, tables


def read_science(paths: Sequence[str | Path] | str | Path) -> xr.Dataset:
    """Read science-sample CSV files into a raw dataset on dimension ``time``.

    Returns
    -------
    xarray.Dataset
        ``partition`` (int8), ``met`` (s), ``rate`` (int8), ``range`` (int8), ``counts``
        (time, component) int32; attrs ``inputs``.

    Raises
    ------
    InputFormatError
        For every defect listed in the module docstring.
    """
    plist, tables = _read_stream(paths, SCIENCE_COLUMNS, "science")
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[:, 2], "rate", 0, MAX_RATE_SETTING,
                       f"the rate settings 0..{MAX_RATE_SETTING} (Table 1)")
        _check_integer(path, data[:, 3], "range", 0, 1, "the range flags 0 (fine) and 1 (coarse)")
        for j, name in enumerate(("cx", "cy", "cz")):
            _check_integer(path, data[:, 4 + j], name, *COUNT_LIMITS,
                           f"the signed 16-bit count limits {COUNT_LIMITS}")
    data = tables[0] if len(tables) == 1 else np.concatenate(tables)
    return xr.Dataset(
        {
            "partition": ("time", data[:, 0].astype(np.int8), {"units": "1"}),
            # a copy: a view would keep the whole (n, 7) parsed table (95 MB a 20 Hz day)
            "met": ("time", np.ascontiguousarray(data[:, 1]),
                    {"units": "s", "description": "MET as recorded"}),
            "rate": ("time", data[:, 2].astype(np.int8), {"units": "1"}),
            "range": ("time", data[:, 3].astype(np.int8), {"units": "1"}),
            "counts": (("time", "component"), data[:, 4:7].astype(np.int32), {"units": "counts"}),
        },
        coords={"component": ["x", "y", "z"]},
        attrs={"inputs": ";".join(str(p) for p in plist)},
    )


def read_heater(paths: Sequence[str | Path] | str | Path) -> xr.Dataset:
    """Read heater-bit CSV files (1-s LAC stream) into a dataset on ``heater_time``.

    Raises
    ------
    InputFormatError
        Also when two consecutive heater records are more than one heater period
        (100 s) apart.
    """
    plist, tables = _read_stream(paths, HEATER_COLUMNS, "heater")
    for path, data in zip(plist, tables, strict=True):
        _check_integer(path, data[:, 2], "heater", 0, 1, "the heater bit values 0 and 1")
    _check_gaps(plist, tables, HEATER_PERIOD_S, "heater stream",
                f"one heater period ({HEATER_PERIOD_S:.0f} s)")
    data = np.concatenate(tables)
    return xr.Dataset(
        {
            "partition": ("heater_time", data[:, 0].astype(np.int8), {"units": "1"}),
            "met": ("heater_time", data[:, 1], {"units": "s"}),
            "heater": ("heater_time", data[:, 2].astype(np.int8), {"units": "1"}),
        },
        attrs={"inputs": ";".join(str(p) for p in plist)},
    )


def _check_gaps(
    plist: Sequence[Path], tables: Sequence[np.ndarray], max_gap: float, what: str,
    limit: str | None = None,
) -> None:
    """Raise when consecutive records of one partition are more than ``max_gap`` apart.

    Checked within each file and across consecutive files; the error names the file and
    the line of the record after the gap; ``limit`` words the limit (default seconds).
    """
    limit = limit or f"{max_gap:.0f} s"
    for path, data in zip(plist, tables, strict=True):
        gaps = (np.diff(data[:, 1]) > max_gap) & (np.diff(data[:, 0]) == 0)
        if gaps.any():
            row = int(np.flatnonzero(gaps)[0]) + 1
            raise InputFormatError(
                f"{what} gap of {data[row, 1] - data[row - 1, 1]:.0f} s exceeds {limit}",
                path=str(path), line=row + 2, field="met",
            )
    for (p0, d0), (p1, d1) in zip(
        zip(plist[:-1], tables[:-1], strict=True), zip(plist[1:], tables[1:], strict=True),
        strict=True,
    ):
        if d0.shape[0] and d1.shape[0] and d0[-1, 0] == d1[0, 0]:
            gap = d1[0, 1] - d0[-1, 1]
            if gap > max_gap:
                raise InputFormatError(
                    f"{what} gap of {gap:.0f} s between {p0} and this file exceeds {limit}",
                    path=str(p1), line=2, field="met",
                )


def read_temperature(
    paths: Sequence[str | Path] | str | Path, max_gap_s: float = TEMPERATURE_MAX_GAP_S
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

    Raises
    ------
    InputFormatError
        Naming file, line and field: a temperature outside -150..150 degC, or a gap
        longer than ``max_gap_s``.
    """
    plist, tables = _read_stream(paths, TEMPERATURE_COLUMNS, "temperature")
    for path, data in zip(plist, tables, strict=True):
        bad = (data[:, 2] < -150) | (data[:, 2] > 150)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise InputFormatError(
                f"temperature {data[row, 2]} degC outside -150..150 degC", path=str(path),
                line=row + 2, field="temperature_c",
            )
    _check_gaps(plist, tables, max_gap_s, "temperature stream")
    data = np.concatenate(tables)
    return xr.Dataset(
        {
            "partition": ("temperature_time", data[:, 0].astype(np.int8), {"units": "1"}),
            "met": ("temperature_time", data[:, 1], {"units": "s"}),
            "temperature_c": ("temperature_time", data[:, 2], {"units": "degC"}),
        },
        attrs={"inputs": ";".join(str(p) for p in plist)},
    )
