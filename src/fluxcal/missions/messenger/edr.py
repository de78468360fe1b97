"""MESSENGER MAG EDRs (PDS3 labels + tables) read through a declared column mapping.

The archived EDRs are packet based (seed 000 sec. 2, issue 14): the science (SCI) EDR
gives each packet's MET, the offset of its first sample in units of 0.05 s and the
samples; the rate setting is packet state kept in the science-header (SHD) EDR; the
heater bit is in the log-AC (LAC) EDR at 1 s (sec. 6); the sensor temperature is in the
status EDR as raw counts.  The column names and the file-name patterns are not built in:
they come from a mapping file (TOML; the documented template is
``data/edr_mapping_template.toml``), and every table is read by the label-driven reader
`fluxcal.archive.pds3.read_table`.

`read_edr` returns the three Datasets `fluxcal.missions.messenger.readers` returns for
the CSV streams (same variables, dtypes and dimensions), so the pipeline runs unchanged:

* sample time (recorded, before the Table 1 net lag that the pipeline subtracts, as for
  the CSV route): ``t = MET + 0.05 * delta_ts + (I - 1) / rate_hz``, computed in whole
  microseconds (the clock's fine tick) so the sum is exact;
* SCI/SHD join: each science packet takes the state of the latest header row of its own
  clock partition at or before its MET; a packet with none is an error naming its file
  and row;
* versions: per EDR kind and day only the files of the highest ``_V<n>`` are read (the
  others are logged as skipped);
* clock partitions: a partition column, or the label's clock start count ``p/...`` with
  a new partition at a MET reset inside a file.

Docs: ``docs/formats/messenger.md`` ("EDR route"), ``docs/decisions/messenger_edr.md``.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 2 (EDR content), sec. 5 Table 1
   (rate settings, sample rates; the net lag is subtracted later), sec. 6 (LAC heater bit).
"""

from __future__ import annotations

import datetime as _dt
import logging
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.archive.pds3 import read_table
from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.calibration_data import resolve_table
from fluxcal.missions.messenger.defects import clock_jumps, ordered_records
from fluxcal.missions.messenger.readers import (
    COUNT_LIMITS,
    HEATER_PERIOD_S,
    MAX_RATE_SETTING,
    TEMPERATURE_MAX_GAP_S,
)
from fluxcal.textfile import read_text

log = logging.getLogger(__name__)

#: EDR kinds and the fields each must declare (mapping tables ``[<kind>.<field>]``).
KINDS: dict[str, tuple[str, ...]] = {
    "science": ("met", "partition", "delta_ts", "sample_index", "range", "counts"),
    "science_header": ("met", "partition", "rate"),
    "lac": ("met", "partition", "heater"),
    "status": ("met", "partition", "temperature"),
}
#: Which days' files a batch day D reads, per kind (offsets in days): the header state
#: and the heater look-back may lie in the previous day, temperatures are interpolated.
DAY_OFFSETS = {"science": (0,), "science_header": (-1, 0), "lac": (-1, 0),
               "status": (-1, 0, 1)}
US = 1_000_000
_KEY = 10**16  # partition * _KEY + MET in microseconds: one sortable int64 key


def _mapping_error(mapping: Path, entry: str, message: str) -> InputFormatError:
    return InputFormatError(f"mapping entry [{entry}]: {message}", path=str(mapping))


@dataclass(frozen=True)
class EdrMapping:
    """A loaded, checked mapping file (see the template for the meaning of each entry)."""

    path: Path
    entries: dict[str, Any]

    def file(self, kind: str) -> tuple[re.Pattern[str], str | None]:
        """Return the label-name pattern and the table object name (None: the only one)."""
        f = self.entries[kind]["file"]
        return re.compile(f["pattern"]), (f.get("table") or None)

    def field(self, kind: str, name: str) -> dict[str, Any]:
        """Return the entry ``[<kind>.<name>]``."""
        return self.entries[kind][name]


def load_mapping(path: str | Path) -> EdrMapping:
    """Read and check a mapping file.

    Raises
    ------
    InputFormatError
        Naming the mapping file and the entry: not TOML, a missing kind or field, a
        pattern without the ``yyddd``/``version`` groups, a partition with neither a
        column nor ``from_label``, ``counts`` without one vector or three columns, a
        non-positive ``delta_ts.unit_s``, and a missing or malformed temperature
        conversion (required: the procedure document gives none).
    """
    path = Path(path)
    try:
        entries = tomllib.loads(read_text(path, "a TOML mapping file"))
    except OSError as exc:
        raise InputFormatError(f"cannot read the mapping file: {exc.strerror}",
                               path=str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputFormatError(f"not a TOML mapping file: {exc}", path=str(path)) from None
    for kind, fields in KINDS.items():
        block = entries.get(kind)
        if not isinstance(block, dict):
            raise _mapping_error(path, kind, "missing; see edr_mapping_template.toml")
        file = block.get("file")
        if not isinstance(file, dict) or not isinstance(file.get("pattern"), str):
            raise _mapping_error(path, f"{kind}.file", "needs pattern = '<regex>'")
        try:
            rx = re.compile(file["pattern"])
        except re.error as exc:
            raise _mapping_error(path, f"{kind}.file", f"pattern: {exc}") from None
        if not {"yyddd", "version"} <= set(rx.groupindex):
            raise _mapping_error(path, f"{kind}.file",
                                 "pattern needs the named groups (?P<yyddd>...) and "
                                 "(?P<version>...)")
        for name in fields:
            _check_field(path, kind, name, block.get(name))
    return EdrMapping(path, entries)


def _check_field(path: Path, kind: str, name: str, spec: Any) -> None:
    entry = f"{kind}.{name}"
    if not isinstance(spec, dict):
        raise _mapping_error(path, entry, "missing; see edr_mapping_template.toml")
    column = spec.get("column", "")
    if not isinstance(column, str):
        raise _mapping_error(path, entry, "column must be a text (a label COLUMN NAME)")
    if name == "partition":
        if not column and not spec.get("from_label"):
            raise _mapping_error(path, entry, "needs column = '<NAME>' or from_label = "
                                 "'<label keyword>'")
    elif name == "counts":
        cols = spec.get("columns")
        if not column and not (isinstance(cols, list) and len(cols) == 3
                               and all(isinstance(c, str) and c for c in cols)):
            raise _mapping_error(path, entry, "needs column = '<NAME>' (ITEMS = 3) or "
                                 "columns = ['<X>', '<Y>', '<Z>']")
    elif name != "sample_index" and not column:
        raise _mapping_error(path, entry, "needs column = '<label COLUMN NAME>'")
    if name == "sample_index" and spec.get("from", "rows") not in ("rows", "items"):
        raise _mapping_error(path, entry, "from must be 'rows' (one row per sample) or "
                             "'items' (one row per packet, samples as ITEMS)")
    if name == "delta_ts":
        unit = spec.get("unit_s")
        if not isinstance(unit, (int, float)) or unit <= 0:
            raise _mapping_error(path, entry, "needs unit_s > 0 (seconds per delta_ts unit)")
    if name == "heater" and "bit" in spec and (
            not isinstance(spec["bit"], int) or not 0 <= spec["bit"] < 63):
        raise _mapping_error(path, entry, "bit must be an integer 0..62")
    if name == "temperature":
        _check_conversion(path, spec.get("conversion"))


def _check_conversion(path: Path, conv: Any) -> None:
    entry = "status.temperature.conversion"
    missing = ("no conversion of the raw temperature counts to degC is declared (the "
               "MESSENGER MAG EDR-to-CDR Processing document gives none): set kind = "
               "'polynomial' with coefficients = [c0, c1, ...] or kind = 'table' with "
               "counts and degc, from the MAG EDR SIS")
    if not isinstance(conv, dict):
        raise _mapping_error(path, entry, missing)
    kind = conv.get("kind")
    if kind == "polynomial":
        c = conv.get("coefficients")
        if not c:
            raise _mapping_error(path, entry, missing)
        if not all(isinstance(v, (int, float)) and np.isfinite(v) for v in c):
            raise _mapping_error(path, entry, "coefficients must be finite numbers")
    elif kind == "table":
        n, t = conv.get("counts"), conv.get("degc")
        if not n or not t:
            raise _mapping_error(path, entry, missing)
        n_arr, t_arr = np.asarray(n, dtype=float), np.asarray(t, dtype=float)
        if n_arr.shape != t_arr.shape or n_arr.size < 2 or np.any(np.diff(n_arr) <= 0):
            raise _mapping_error(path, entry, "table needs counts (strictly increasing) and "
                                 "degc of the same length, at least 2 points")
    else:
        raise _mapping_error(path, entry, f"kind {kind!r}: choose 'polynomial' or 'table'")


def temperature_from_counts(counts: np.ndarray, conversion: dict[str, Any]) -> np.ndarray:
    """Apply the mapping's declared conversion of raw temperature counts to degC.

    ``polynomial``: ``c0 + c1 n + c2 n^2 + ...``; ``table``: linear interpolation, NaN
    for a count outside the table (the caller reports it).
    """
    n = np.asarray(counts, dtype=float)
    if conversion["kind"] == "polynomial":
        return np.polynomial.polynomial.polyval(n, np.asarray(conversion["coefficients"],
                                                              dtype=float))
    return np.interp(n, np.asarray(conversion["counts"], dtype=float),
                     np.asarray(conversion["degc"], dtype=float), left=np.nan, right=np.nan)


# --- files and versions -------------------------------------------------------------------


@dataclass(frozen=True)
class EdrFile:
    """One label selected for reading."""

    path: Path
    day: _dt.date
    version: int


def _day(yyddd: str) -> _dt.date:
    """``yyddd`` (MESSENGER 2004-2015: 20yy) -> date."""
    return _dt.date(2000 + int(yyddd[:2]), 1, 1) + _dt.timedelta(days=int(yyddd[2:]) - 1)


def select_files(folder: str | Path, mapping: EdrMapping, kind: str,
                 days: Sequence[_dt.date] | None = None) -> list[EdrFile]:
    """Return the labels of ``kind`` under ``folder``: per day, the highest version only.

    Lower versions of a day are skipped and logged (INFO).  ``days`` restricts the
    selection to those days.
    """
    rx, _ = mapping.file(kind)
    found: dict[_dt.date, list[EdrFile]] = {}
    for p in sorted(Path(folder).rglob("*")):
        m = rx.match(p.name)
        if m is None or not p.is_file():
            continue
        try:
            day = _day(m["yyddd"])
        except ValueError:
            raise InputFormatError(f"{m['yyddd']!r} is not a valid yyddd day",
                                   path=str(p)) from None
        if days is not None and day not in days:
            continue
        found.setdefault(day, []).append(EdrFile(p, day, int(m["version"])))
    selected: list[EdrFile] = []
    for day in sorted(found):
        best = max(f.version for f in found[day])
        for f in found[day]:
            if f.version == best:
                selected.append(f)
            else:
                log.info("%s EDR %s skipped: version %d of %s is superseded by version %d",
                         kind, f.path.name, f.version, day, best)
    return selected


# --- reading one table ----------------------------------------------------------------------


@dataclass
class _Stream:
    """Rows of one EDR kind over its files, in time order, with their origin."""

    files: list[Path]       # the labels
    data_files: list[Path]  # the tables they point to (rows are counted there)
    file_index: np.ndarray  # per row: index into files
    row: np.ndarray         # per row: 0-based row in its file
    partition: np.ndarray   # int64
    met_us: np.ndarray      # int64 MET in microseconds
    values: dict[str, np.ndarray]
    columns: dict[str, tuple[str, ...]]  # field -> its label column name(s)

    jumps: list[list[float]] | None = None  # clock jumps dropped (`_drop_clock_jumps`)

    def where(self, i: int) -> tuple[str, int]:
        """Return (data file, 1-based row) of stream row ``i``."""
        return str(self.data_files[int(self.file_index[i])]), int(self.row[i]) + 1

    def take(self, keep: np.ndarray) -> _Stream:
        """Return the rows of ``keep`` (a mask)."""
        return _Stream(files=self.files, data_files=self.data_files,
                       file_index=self.file_index[keep], row=self.row[keep],
                       partition=self.partition[keep], met_us=self.met_us[keep],
                       values={k: v[keep] for k, v in self.values.items()},
                       columns=self.columns, jumps=self.jumps)


def _drop_clock_jumps(stream: _Stream, met_us: np.ndarray, what: str) -> _Stream:
    """Drop the rows off the longest run in (partition, ``met_us``) order (issue 23).

    The dropped runs are added to ``stream.jumps`` (`fluxcal.missions.messenger.defects.
    clock_jumps`: ``[partition, met_before, met_after, n]``, MET in seconds); fewer than
    half the rows in order refuses the stream, naming the file of the first dropped row.
    """
    keep = ordered_records(stream.partition, met_us)
    if keep.all():
        return stream
    path, _ = stream.where(int(np.flatnonzero(~keep)[0]))
    found = clock_jumps(stream.partition, met_us / US, keep, stream=what, where=path)
    out = stream.take(keep)
    out.jumps = (stream.jumps or []) + found
    return out


def _column(ds: xr.Dataset, mapping: EdrMapping, entry: str, name: str,
            label: Path) -> np.ndarray:
    if name not in ds.data_vars:
        raise InputFormatError(
            f"mapping entry [{entry}] of {mapping.path.name} names column {name!r}, which "
            f"the label does not have (its columns: {', '.join(map(str, ds.data_vars))})",
            path=str(label), field=name)
    return ds[name].values


def _numeric(values: np.ndarray, label: Path, name: str, integer: bool) -> np.ndarray:
    """Check a column is numeric, finite (and whole); return float64 values."""
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputFormatError("not a numeric column", path=str(label), field=name) from None
    bad = ~np.isfinite(v)
    if integer:
        bad |= np.isfinite(v) & (v != np.round(v))
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise InputFormatError(
            f"value {v.reshape(v.shape[0], -1)[row].tolist()} is not "
            f"{'a whole number' if integer else 'finite'}", path=str(label),
            line=row + 1, field=name)
    return v


def _partition(ds: xr.Dataset, mapping: EdrMapping, kind: str, label: Path,
               met_us: np.ndarray) -> np.ndarray:
    spec = mapping.field(kind, "partition")
    if spec.get("column"):
        col = spec["column"]
        p = _numeric(_column(ds, mapping, f"{kind}.partition", col, label), label, col, True)
        bad = p < 1
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise InputFormatError(f"partition {p[row]:g} < 1", path=str(label),
                                   line=row + 1, field=col)
        return p.astype(np.int64)
    key = spec["from_label"]
    text = ds.attrs.get(key)
    if text is None:
        raise InputFormatError(
            f"mapping entry [{kind}.partition] of {mapping.path.name} takes the partition "
            f"from the label keyword {key}, which the label does not have",
            path=str(label), field=key)
    m = re.match(r"^\s*(?:(\d+)\s*/)?\s*[\d.:]+\s*$", str(text))
    if m is None:
        raise InputFormatError(f"{key} = {text!r}: expected 'p/count' or 'count'",
                               path=str(label), field=key)
    first = int(m[1]) if m[1] else 1  # no 'p/': the only partition before the reset
    drop = float(spec.get("reset_drop_s", 1.0e6)) * US
    resets = np.concatenate([[0], np.cumsum(np.diff(met_us) < -drop)])
    return first + resets.astype(np.int64)


def _read_stream(files: Sequence[EdrFile], mapping: EdrMapping, kind: str,
                 extra: dict[str, tuple[str, ...]]) -> _Stream:
    """Read every file of ``kind``: MET, partition and the ``extra`` fields' columns.

    ``extra`` maps a field name to its label column names (one or three).  Files are
    ordered by their first (partition, MET); rows off the longest run in (partition,
    MET) order (MET going back in a file or across files) are dropped and counted.
    """
    if not files:
        rx, _ = mapping.file(kind)
        raise InputFormatError(f"no {kind} EDR label matching {rx.pattern!r} "
                               f"(mapping {mapping.path.name})")
    _, table = mapping.file(kind)
    met_col = mapping.field(kind, "met")["column"]
    parts = []
    for f in files:
        ds = read_table(f.path, table)
        met = _numeric(_column(ds, mapping, f"{kind}.met", met_col, f.path), f.path,
                       met_col, False)
        met_us = np.rint(met * US).astype(np.int64)
        part = _partition(ds, mapping, kind, f.path, met_us)
        values = {}
        for name, cols in extra.items():
            arrs = [_column(ds, mapping, f"{kind}.{name}", c, f.path) for c in cols]
            # three scalar columns -> (rows, 3); three ITEMS columns -> (rows, items, 3)
            values[name] = arrs[0] if len(arrs) == 1 else np.stack(arrs, axis=-1)
        parts.append((f.path, part, met_us, values,
                      Path(ds.attrs.get("pds3_data_file", f.path))))
    parts.sort(key=lambda t: (t[1][0], t[2][0]) if t[2].size else (np.inf, np.inf))
    files_sorted = [p[0] for p in parts]
    n = [p[2].size for p in parts]
    stream = _Stream(
        files=files_sorted,
        data_files=[p[4] for p in parts],
        file_index=np.repeat(np.arange(len(parts)), n),
        row=np.concatenate([np.arange(k) for k in n]) if n else np.zeros(0, int),
        partition=np.concatenate([p[1] for p in parts]),
        met_us=np.concatenate([p[2] for p in parts]),
        values={name: np.concatenate([p[3][name] for p in parts]) for name in extra},
        columns=dict(extra),
    )
    # MET going back within a partition (a jump back, a spike, files that overlap): the
    # rows off the longest time-ordered run are dropped and counted (issue 23)
    return _drop_clock_jumps(stream, stream.met_us, f"{kind} EDR")


def _check_range(stream: _Stream, name: str, lo: float, hi: float, what: str) -> np.ndarray:
    """Whole numbers within ``lo..hi`` (every item); return them as int64."""
    values = stream.values[name]
    col = stream.columns[name]
    v = np.asarray(values, dtype=float)
    flat = v.reshape(v.shape[0], -1)
    bad = ~np.isfinite(flat) | (flat != np.round(flat)) | (flat < lo) | (flat > hi)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        path, row = stream.where(i)
        raise InputFormatError(f"value {flat[i, j]:g} outside {what}", path=path,
                               line=row, field=col[min(j, len(col) - 1)])
    return v.astype(np.int64)


def _check_gaps(stream: _Stream, max_gap_s: float, what: str, limit: str,
                on_gap: str = "report") -> list[list[float]]:
    """Consecutive records of one partition more than ``max_gap_s`` apart.

    ``on_gap="report"`` (default, as the CSV readers): return ``[[partition, met_before,
    met_after], ...]`` for ``attrs["stream_gaps"]`` (processed and flagged,
    `fluxcal.missions.messenger.defects`); ``"raise"``: an error naming the row.
    """
    gap = np.diff(stream.met_us) > max_gap_s * US
    gap &= np.diff(stream.partition) == 0
    if gap.any() and on_gap == "raise":
        i = int(np.flatnonzero(gap)[0]) + 1
        path, row = stream.where(i)
        raise InputFormatError(
            f"{what} gap of {(stream.met_us[i] - stream.met_us[i - 1]) / US:.0f} s "
            f"exceeds {limit}", path=path, line=row, field="met")
    return [[float(stream.partition[i]), stream.met_us[i - 1] / US, stream.met_us[i] / US]
            for i in np.flatnonzero(gap) + 1]


def _stream_attrs(stream: _Stream, gaps: list[list[float]] | None = None) -> dict:
    """``stream_gaps`` and ``clock_jumps`` when there are any (the CSV readers' attrs)."""
    out: dict[str, Any] = {}
    if gaps:
        out["stream_gaps"] = gaps
    if stream.jumps:
        out["clock_jumps"] = stream.jumps
    return out


# --- the three streams ----------------------------------------------------------------------


def _sample_rates(day: _dt.date, calibration_folder: Path | None) -> np.ndarray:
    """Sample rate (Hz) per rate setting 0..10: Table 1 as the calibration tables hold it."""
    lat = resolve_table("latency", np.datetime64(day, "s"), calibration_folder).columns
    order = np.argsort(lat["rate_setting"])
    return np.asarray(lat["sample_rate_hz"], dtype=float)[order]


def _packet_rows_to_samples(sci: _Stream, mapping: EdrMapping) -> _Stream:
    """One row per packet (samples as ITEMS) -> one row per sample, ``I`` = item + 1.

    Counts: three columns of N items (x, y, z) or one of 3N items (x1 y1 z1 x2 ...);
    range: N items or one value per packet; ``[science.sample_count]`` (optional) gives
    the valid samples of each packet (the remaining items are padding).
    """
    c = np.asarray(sci.values["counts"])
    if c.ndim == 2 and len(sci.columns["counts"]) == 1:
        if c.shape[1] % 3:
            raise InputFormatError(
                f"mapping entry [science.counts] of {mapping.path.name}: with sample_index "
                f"from = 'items' column {sci.columns['counts'][0]!r} needs 3N items "
                f"(x1 y1 z1 x2 ...), has {c.shape[1]}", path=str(sci.files[0]),
                field=sci.columns["counts"][0])
        c = c.reshape(c.shape[0], -1, 3)
    if c.ndim != 3:
        raise InputFormatError(
            f"mapping entry [science.sample_index] of {mapping.path.name}: from = 'items' "
            "needs counts with ITEMS (one row per packet)", path=str(sci.files[0]),
            field=sci.columns["counts"][0])
    rows, n_items = c.shape[:2]
    index = np.tile(np.arange(1, n_items + 1), rows)
    valid = np.ones(rows * n_items, dtype=bool)
    if "sample_count" in sci.values:
        count = _check_range(sci, "sample_count", 0, n_items,
                             f"0..{n_items} samples (the ITEMS of the counts)")
        valid = index <= np.repeat(count, n_items)
    rng = np.asarray(sci.values["range"])
    rng = rng.reshape(-1) if rng.ndim == 2 else np.repeat(rng, n_items)
    rep = {name: np.repeat(np.asarray(sci.values[name]), n_items)[valid]
           for name in sci.values if name not in ("counts", "range", "sample_count")}
    return _Stream(
        files=sci.files, data_files=sci.data_files,
        file_index=np.repeat(sci.file_index, n_items)[valid],
        row=np.repeat(sci.row, n_items)[valid],
        partition=np.repeat(sci.partition, n_items)[valid],
        met_us=np.repeat(sci.met_us, n_items)[valid],
        values={**rep, "counts": c.reshape(-1, 3)[valid], "range": rng[valid],
                "sample_index": index[valid]},
        columns={**sci.columns, "sample_index": ("(item number)",)},
        jumps=sci.jumps,
    )


def _science(folder: Path, mapping: EdrMapping, days: Sequence[_dt.date] | None,
             calibration_folder: Path | None) -> xr.Dataset:
    sci_files = select_files(folder, mapping, "science", _days(days, "science"))
    spec = {k: mapping.field("science", k) for k in KINDS["science"]}
    counts = spec["counts"]
    extra = {
        "delta_ts": (spec["delta_ts"]["column"],),
        "range": (spec["range"]["column"],),
        "counts": (counts["column"],) if counts.get("column") else tuple(counts["columns"]),
    }
    items = spec["sample_index"].get("from", "rows") == "items"
    if spec["sample_index"].get("column") and not items:
        extra["sample_index"] = (spec["sample_index"]["column"],)
    count_col = mapping.entries["science"].get("sample_count", {}).get("column", "")
    if items and count_col:
        extra["sample_count"] = (count_col,)
    sci = _read_stream(sci_files, mapping, "science", extra)
    if items:
        sci = _packet_rows_to_samples(sci, mapping)
    hdr = _read_stream(select_files(folder, mapping, "science_header",
                                    _days(days, "science_header")),
                       mapping, "science_header",
                       {"rate": (mapping.field("science_header", "rate")["column"],)})
    rate_all = _check_range(hdr, "rate", 0, MAX_RATE_SETTING,
                            f"the rate settings 0..{MAX_RATE_SETTING} (Table 1)")
    n = sci.met_us.size
    dts = _check_range(sci, "delta_ts", 0, np.inf, "whole delta_ts units >= 0")
    rng = _check_range(sci, "range", 0, 1, "the range flags 0 (fine) and 1 (coarse)")
    cts = _check_range(sci, "counts", *COUNT_LIMITS,
                       f"the signed 16-bit count limits {COUNT_LIMITS}")
    if cts.ndim != 2 or cts.shape[1] != 3:
        raise InputFormatError(
            f"mapping entry [science.counts] of {mapping.path.name}: column "
            f"{extra['counts'][0]!r} has {cts.shape[1] if cts.ndim == 2 else 1} item(s); "
            "expected 3 (x, y, z)", path=str(sci.files[0]), field=extra["counts"][0])
    # packets: consecutive rows sharing partition, MET and delta_ts
    new = np.ones(n, dtype=bool)
    new[1:] = ((sci.partition[1:] != sci.partition[:-1]) | (sci.met_us[1:] != sci.met_us[:-1])
               | (dts[1:] != dts[:-1]))
    if "sample_index" in sci.values:
        index = _check_range(sci, "sample_index", 1, np.inf, "whole sample indices >= 1")
    else:
        starts = np.flatnonzero(new)
        index = np.arange(n) - starts[np.cumsum(new) - 1] + 1
    # SCI/SHD join: latest header row of the same partition at or before the packet MET
    hkey = hdr.partition * _KEY + hdr.met_us
    skey = sci.partition * _KEY + sci.met_us
    h = np.searchsorted(hkey, skey, side="right") - 1
    ok = h >= 0
    ok[ok] = hdr.partition[h[ok]] == sci.partition[ok]
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        path, row = sci.where(i)
        raise InputFormatError(
            f"science packet at MET {sci.met_us[i] / US:.6f} (partition {sci.partition[i]}) "
            "has no science-header state at or before it in its clock partition (first "
            f"header row: MET {hdr.met_us[0] / US:.6f}, partition {hdr.partition[0]}, "
            f"{hdr.files[0].name})", path=path, line=row, field=extra["delta_ts"][0])
    rate = rate_all[h]
    hz = _sample_rates(sci_files[0].day if sci_files else _dt.date(2012, 1, 1),
                       calibration_folder)
    period_us = np.rint(US / hz).astype(np.int64)
    unit_us = float(spec["delta_ts"]["unit_s"]) * US
    if unit_us != round(unit_us):
        raise _mapping_error(mapping.path, "science.delta_ts",
                             "unit_s must be a whole number of microseconds")
    t_us = sci.met_us + int(round(unit_us)) * dts + (index - 1) * period_us[rate]
    # overlapping packets (sample times going back): the samples off the longest
    # time-ordered run are dropped and counted (issue 23)
    jumps = list(sci.jumps or [])
    keep = ordered_records(sci.partition, t_us, strict=True)
    part = sci.partition
    if not keep.all():
        path, _ = sci.where(int(np.flatnonzero(~keep)[0]))
        jumps += clock_jumps(part, t_us / US, keep, stream="science EDR samples", where=path)
        part, t_us, rate, rng, cts = (a[keep] for a in (part, t_us, rate, rng, cts))
    return xr.Dataset(
        {
            "partition": ("time", part.astype(np.int8), {"units": "1"}),
            "met": ("time", t_us / US, {"units": "s", "description": "MET as recorded"}),
            "rate": ("time", rate.astype(np.int8), {"units": "1"}),
            "range": ("time", rng.astype(np.int8), {"units": "1"}),
            "counts": (("time", "component"), cts.astype(np.int32), {"units": "counts"}),
        },
        coords={"component": ["x", "y", "z"]},
        attrs={"inputs": ";".join(str(p) for p in sci.files + hdr.files),
               **({"clock_jumps": jumps} if jumps else {})},
    )


def _heater(folder: Path, mapping: EdrMapping, days: Sequence[_dt.date] | None) -> xr.Dataset:
    spec = mapping.field("lac", "heater")
    lac = _read_stream(select_files(folder, mapping, "lac", _days(days, "lac")), mapping,
                       "lac", {"heater": (spec["column"],)})
    if "bit" in spec:
        word = _check_range(lac, "heater", 0, 2.0**62, "non-negative whole status words")
        bits = (word >> int(spec["bit"])) & 1
    else:
        bits = _check_range(lac, "heater", 0, 1, "the heater bit values 0 and 1")
    gaps = _check_gaps(lac, HEATER_PERIOD_S, "heater stream",
                       f"one heater period ({HEATER_PERIOD_S:.0f} s)")
    return xr.Dataset(
        {
            "partition": ("heater_time", lac.partition.astype(np.int8), {"units": "1"}),
            "met": ("heater_time", lac.met_us / US, {"units": "s"}),
            "heater": ("heater_time", bits.astype(np.int8), {"units": "1"}),
        },
        attrs={"inputs": ";".join(str(p) for p in lac.files), **_stream_attrs(lac, gaps)},
    )


def _temperature(folder: Path, mapping: EdrMapping,
                 days: Sequence[_dt.date] | None) -> xr.Dataset:
    spec = mapping.field("status", "temperature")
    st = _read_stream(select_files(folder, mapping, "status", _days(days, "status")),
                      mapping, "status", {"temperature": (spec["column"],)})
    raw = np.asarray(st.values["temperature"], dtype=float)
    bad = ~np.isfinite(raw) if raw.ndim == 1 else np.ones(raw.shape[0], dtype=bool)
    if bad.any():
        path, row = st.where(int(np.flatnonzero(bad)[0]))
        raise InputFormatError("temperature counts: expected one finite number per row",
                               path=path, line=row, field=spec["column"])
    temp = temperature_from_counts(raw, spec["conversion"])
    bad = ~np.isfinite(temp) | (temp < -150) | (temp > 150)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        path, row = st.where(i)
        raise InputFormatError(
            f"temperature {temp[i]} degC (from {raw[i]:g} counts by the mapping's "
            "conversion; NaN: outside its table) outside -150..150 degC",
            path=path, line=row, field=spec["column"])
    gaps = _check_gaps(st, TEMPERATURE_MAX_GAP_S, "temperature stream",
                       f"{TEMPERATURE_MAX_GAP_S:.0f} s")
    return xr.Dataset(
        {
            "partition": ("temperature_time", st.partition.astype(np.int8), {"units": "1"}),
            "met": ("temperature_time", st.met_us / US, {"units": "s"}),
            "temperature_c": ("temperature_time", temp, {"units": "degC"}),
        },
        attrs={"inputs": ";".join(str(p) for p in st.files), **_stream_attrs(st, gaps)},
    )


def _days(days: Sequence[_dt.date] | None, kind: str) -> list[_dt.date] | None:
    if days is None:
        return None
    return sorted({d + _dt.timedelta(days=k) for d in days for k in DAY_OFFSETS[kind]})


def read_edr(
    folder: str | Path,
    mapping: str | Path | EdrMapping,
    *,
    days: Sequence[_dt.date] | None = None,
    calibration_folder: Path | None = None,
) -> tuple[xr.Dataset, xr.Dataset, xr.Dataset]:
    """Read the MAG EDRs under ``folder`` into the science, heater and temperature Datasets.

    The Datasets have the variables, dtypes and dimensions of
    `fluxcal.missions.messenger.readers.read_science`, `read_heater` and
    `read_temperature`; ``met`` of the science samples is the recorded sample time
    ``MET + unit_s * delta_ts + (I - 1) / rate_hz`` (the pipeline subtracts the net lag).

    Parameters
    ----------
    folder : path
        Searched recursively for the labels the mapping's patterns match.
    mapping : path or EdrMapping
        The mapping file (`load_mapping`).
    days : sequence of datetime.date, optional
        Read only the science of these days (yyddd of the file names), with the header
        and heater files of the day before and the status files of the days around
        (`DAY_OFFSETS`); default every file.
    calibration_folder : Path, optional
        Calibration tables (Table 1 sample rates; default packaged).

    Returns
    -------
    (science, heater, temperature) : tuple of xarray.Dataset

    Raises
    ------
    InputFormatError
        Naming the file, row and column: everything `fluxcal.archive.pds3.read_table`
        raises, a mapped column not in the label (naming the mapping entry), values out
        of range, a packet without header state, a stream with fewer than half its
        rows in time order.  As for the CSV streams, heater and temperature gaps are
        recorded (``attrs["stream_gaps"]``) and rows or samples off the time-ordered
        run (MET going back, overlapping packets) dropped and counted
        (``attrs["clock_jumps"]``), for `fluxcal.missions.messenger.defects` to flag.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 2, sec. 5 Table 1, sec. 6.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFormatError("not a folder", path=str(folder))
    m = mapping if isinstance(mapping, EdrMapping) else load_mapping(mapping)
    sci = _science(folder, m, days, calibration_folder)
    return sci, _heater(folder, m, days), _temperature(folder, m, days)


def edr_days(folder: str | Path, mapping: str | Path | EdrMapping) -> list[_dt.date]:
    """Days (from the file names) that have a science EDR under ``folder``."""
    m = mapping if isinstance(mapping, EdrMapping) else load_mapping(mapping)
    return sorted({f.day for f in select_files(folder, m, "science")})
