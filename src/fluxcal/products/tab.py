"""Archive-style fixed-width ASCII table (``.TAB``) with its PDS3 detached label (``.LBL``).

The table has one sample per line, values in fixed-width fields separated by one
space, no header, CRLF line ends: every row has the same length, so the label's
``RECORD_BYTES``/``ROW_BYTES`` and each column's ``START_BYTE``/``BYTES`` slice it
exactly.  Each value is printed with its column's FORTRAN format (`FieldFormat`).

Formatting is compiled: `fluxcal.products.fixedwidth.format_rows` writes whole rows
(every ``I`` and ``F`` field) into a ``(rows, row_bytes)`` byte buffer, 100,000 rows at
a time, reading the variables' arrays in place; ``E`` and ``A`` fields follow column
by column.  Each chunk is written once, as it is, to the temporary file of the atomic
pair (`fluxcal.products.atomic`).  The bytes depend only on the values and formats,
and equal Python's printf output of the same format (``"%10.3f" % x``).  Runs of
columns printed from the same arrays as an earlier table (one day's frames share their
time columns) are copied from that table's bytes (`fluxcal.products.tabshare`).

The label is written and read with `pvl` (PDS3 encoder and grammar):
``PDS_VERSION_ID = PDS3``, ``RECORD_TYPE = FIXED_LENGTH``, ``RECORD_BYTES``,
``FILE_RECORDS``, ``^TABLE``, product keywords, a ``PROVENANCE`` group, the dataset
attributes as ``ATTRIBUTE`` objects (`fluxcal.products.label`), and ``OBJECT = TABLE``
with one ``OBJECT = COLUMN`` per column (``NAME``, ``DATA_TYPE``, ``START_BYTE``,
``BYTES``, ``FORMAT``, ``UNIT``, ``DESCRIPTION``, ``MISSING_CONSTANT`` when a fill is
used, and ``FLUXCAL:*`` keywords that let `read_tab` rebuild the Dataset).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pvl
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import fixedwidth as fw
from fluxcal.products.atomic import atomic_group, atomic_path
from fluxcal.products.columns import (
    DEFAULT_REAL,
    TIME_DIM,
    Column,
    ResolvedColumn,
    resolve_columns,
)
from fluxcal.products.label import (
    Symbol,
    as_dict,
    attributes_object,
    decode_attributes,
    find_objects,
    read_label,
    render_label,
    text_value,
)
from fluxcal.products.paths import check_pointers
from fluxcal.products.provenance import portable_attrs
from fluxcal.products.tabshare import SHARED, Run
from fluxcal.version import software_version

__all__ = ["CHUNK_ROWS", "format_chunk", "label_module", "read_label", "read_tab",
           "write_tab"]

CHUNK_ROWS = 100_000
EOL = b"\r\n"
_DATA_TYPE = {"int": "ASCII_INTEGER", "real": "ASCII_REAL", "str": "CHARACTER"}
# Keywords the writer owns: label_extra may not change the file's structure.
_STRUCTURAL = {"PDS_VERSION_ID", "RECORD_TYPE", "RECORD_BYTES", "FILE_RECORDS", "^TABLE"}
_WHY = {fw.TOO_WIDE: "does not fit the width", fw.NOT_FINITE: "is infinite",
        fw.TOO_LARGE: "is too large to print with these decimals"}


def layout(cols: Sequence[ResolvedColumn]) -> tuple[list[int], int]:
    """0-based start byte of each column and the row length (one blank between, CRLF)."""
    starts, pos = [], 0
    for c in cols:
        starts.append(pos)
        pos += c.fmt.width + 1
    return starts, pos - 1 + len(EOL)


def _format_text(buf: np.ndarray, start: int, values: np.ndarray, col: ResolvedColumn,
                 first_row: int) -> None:
    """Copy a string column into its field (left-justified, blank-padded); validated."""
    try:
        b = values if values.dtype.kind == "S" else values.astype("S")
    except UnicodeEncodeError as exc:
        raise InputFormatError(f"string values must be ASCII: {exc}", field=col.label) from exc
    b = np.ascontiguousarray(b)
    src = b.view(np.uint8).reshape(b.shape[0], b.dtype.itemsize)
    code, row = fw.copy_text(src, buf, start, col.fmt.width)
    if code in (fw.EMPTY, fw.BLANK_INSIDE):
        raise InputFormatError(
            "string values printed in a whitespace-separated table must be non-empty "
            f"and contain no whitespace (row {first_row + row}: {b[row]!r})",
            field=col.label, line=first_row + row + 1)
    if code != fw.OK:
        raise InputFormatError(
            f"value {b[row].decode()!r} at row {first_row + row} is longer than "
            f"{col.fmt.fortran}", field=col.label, line=first_row + row + 1)


def _check(code: int, row: int, values: np.ndarray, col: ResolvedColumn,
           first_row: int) -> None:
    if code != fw.OK:
        raise InputFormatError(
            f"value {np.asarray(values[row]).item()!r} at row {first_row + row} {_WHY[code]} of "
            f"{col.fmt.fortran}" + (f" (fill {col.fill!r})" if col.fill is not None else ""),
            field=col.label, line=first_row + row + 1)


def _real_values(arr: np.ndarray, col: ResolvedColumn) -> np.ndarray:
    v = np.ascontiguousarray(arr, dtype=np.float64)
    if col.fill is not None and col.kind == "real":
        v = np.where(np.isnan(v), float(col.fill), v)
    return v


def _ensure_roundtrip(buf: np.ndarray, start: int, v: np.ndarray) -> None:
    """Guarantee the default ``E24.16`` text reads back as the same float64.

    The kernel rounds exactly except at decimal near-ties of magnitudes outside
    1e+-22 (double-double scale, see `fluxcal.products.fixedwidth`); should one ever
    miss, that row is printed by Python's correctly rounded ``%24.16E`` instead.
    """
    width = DEFAULT_REAL.width
    text = np.ascontiguousarray(buf[:, start:start + width]).view(f"S{width}").ravel()
    back = text.astype(np.float64)
    bad = np.flatnonzero(~((back == v) | (np.isnan(back) & np.isnan(v))))
    for i in bad.tolist():  # expected empty; one Python format per exceptional row
        buf[i, start:start + width] = np.frombuffer(
            (f"%{width}.{DEFAULT_REAL.decimals}E" % v[i]).encode(), np.uint8)


class _Group(NamedTuple):
    """Columns formatted by one `fixedwidth.format_rows` call, and their sources."""

    columns: list[int]  # indices into the table's columns
    spec: np.ndarray
    fills: np.ndarray
    limits: np.ndarray
    reals: list[int]  # source index per float64 slot
    ints: list[int]  # source index per int64 slot


class _Rows:
    """How one table's rows are formatted.

    ``I`` and ``F`` columns are written by `fixedwidth.format_rows` (whole rows, one
    compiled pass per chunk, read straight from the variables' arrays); ``E`` and ``A``
    columns by their own kernels afterwards, into the fields left blank.  A source is a
    variable as a 2-D ``(rows, components)`` array; `fixedwidth.SLOTS` sources of each
    kind per call, so a table with more variables takes several calls (groups).
    """

    def __init__(self, cols: Sequence[ResolvedColumn], sources: Sequence[np.ndarray],
                 source_of: Sequence[tuple[int, int]], skip: Sequence[int] = ()) -> None:
        self.cols = list(cols)
        self.starts, self.row_bytes = layout(cols)
        self.sources = list(sources)
        self.source_of = list(source_of)  # per column: (source index, component)
        self.others = [j for j, c in enumerate(self.cols) if c.fmt.code in "EA"]
        self.groups: list[_Group] = []
        members: list[int] = []
        slots: dict[str, dict[int, int]] = {"I": {}, "F": {}}
        for j, c in enumerate(self.cols):
            if c.fmt.code in "EA" or j in skip:  # skip: left blank (copied in by the caller)
                continue
            keys = slots[c.fmt.code]
            src = self.source_of[j][0]
            if src not in keys and len(keys) == fw.SLOTS:
                self.groups.append(self._group(members, slots))
                members, slots = [], {"I": {}, "F": {}}
                keys = slots[c.fmt.code]
            keys.setdefault(src, len(keys))
            members.append(j)
        if members or not self.groups:
            self.groups.append(self._group(members, slots))

    def _group(self, members: list[int], slots: dict[str, dict[int, int]]) -> _Group:
        spec = np.zeros((len(members), 8), np.int64)
        fills = np.zeros(len(members))
        limits = np.zeros((len(members), 2), np.uint64)
        for g, j in enumerate(members):
            c, f = self.cols[j], self.cols[j].fmt
            src, comp = self.source_of[j]
            if f.code == "I":  # at least `decimals` digits, a sign takes one place
                places = f.width if f.decimals <= f.width else 0
                places_neg = f.width - 1 if f.decimals <= f.width - 1 else 0
            else:
                places = f.width - (f.decimals + 1 if f.decimals > 0 else 0)
                places_neg = places - 1
            has_fill = c.fill is not None and c.kind == "real"
            spec[g] = (fw.INT if f.code == "I" else fw.FIXED, slots[f.code][src], comp,
                       self.starts[j], f.width, f.decimals, int(f.zero_pad), int(has_fill))
            fills[g] = float(c.fill) if has_fill else 0.0
            limits[g] = (fw.integer_limit(places), fw.integer_limit(places_neg))
        return _Group(list(members), spec, fills, limits, list(slots["F"]), list(slots["I"]))

    def _slot_arrays(self, sources: list[int], dtype: type, start: int,
                     stop: int) -> tuple[np.ndarray, ...]:
        out = []
        for src in sources:
            a = self.sources[src][start:stop]
            if dtype is np.int64 and a.dtype == np.uint64 and a.size \
                    and a.max() > np.iinfo(np.int64).max:
                j = next(j for j, s in enumerate(self.source_of) if s[0] == src)
                raise InputFormatError("uint64 values beyond int64 cannot be printed",
                                       field=self.cols[j].label)
            out.append(np.ascontiguousarray(a, dtype=dtype))
        pad = np.zeros((0, 1), dtype)
        return tuple(out + [pad] * (fw.SLOTS - len(out)))

    def format(self, start: int, stop: int, out: np.ndarray | None = None) -> np.ndarray:
        """Rows ``start:stop`` as a ``(rows, row_bytes)`` uint8 array (``out`` reused)."""
        if out is None:
            out = np.empty((stop - start, self.row_bytes), np.uint8)
        buf = out[: stop - start]
        for k, g in enumerate(self.groups):
            reals = self._slot_arrays(g.reals, np.float64, start, stop)
            ints = self._slot_arrays(g.ints, np.int64, start, stop)
            code, _, _ = fw.format_rows(buf, reals, ints, g.spec, g.fills, g.limits, k == 0)
            if code != fw.OK:
                self._raise_first(g, reals, ints, start)
        for j in self.others:
            self._format_other(buf, j, start, stop)
        return buf

    def _values(self, j: int, start: int, stop: int) -> np.ndarray:
        src, comp = self.source_of[j]
        return self.sources[src][start:stop, comp]

    def _format_other(self, buf: np.ndarray, j: int, start: int, stop: int) -> None:
        c, s = self.cols[j], self.starts[j]
        values = self._values(j, start, stop)
        if c.fmt.code == "A":
            _format_text(buf, s, values, c, start)
            return
        v = _real_values(values, c)
        code, row = fw.format_exp(v, buf, s, c.fmt.width, c.fmt.decimals)
        _check(code, row, v, c, start)
        if c.fmt == DEFAULT_REAL:
            _ensure_roundtrip(buf, s, v)

    def _raise_first(self, g: _Group, reals: tuple[np.ndarray, ...],
                     ints: tuple[np.ndarray, ...], start: int) -> None:
        """Raise for the first failing row of the first failing column (column order)."""
        n = reals[0].shape[0] if g.reals else ints[0].shape[0]
        scratch = np.empty((n, self.row_bytes), np.uint8)
        for k, j in enumerate(g.columns):
            code, row, _ = fw.format_rows(scratch, reals, ints, g.spec[k:k + 1],
                                          g.fills[k:k + 1], g.limits[k:k + 1], True)
            if code != fw.OK:
                c = self.cols[j]
                v = self._values(j, start, start + n)
                _check(code, row, _real_values(v, c) if c.fmt.code == "F" else v, c, start)
        raise AssertionError("format_rows failed, but no column alone")  # unreachable


def _sources(ds: xr.Dataset, cols: Sequence[ResolvedColumn]
             ) -> tuple[list[np.ndarray], list[tuple[int, int]]]:
    """Each variable once, as ``(rows, components)``; per column (source, component)."""
    index: dict[str, int] = {}
    sources: list[np.ndarray] = []
    source_of = []
    for c in cols:
        if c.variable not in index:
            a = ds[c.variable].values
            index[c.variable] = len(sources)
            sources.append(a.reshape(a.shape[0], 1) if a.ndim == 1 else a)
        source_of.append((index[c.variable], 0 if c.index is None else c.index))
    return sources, source_of


def _shared_runs(ds: xr.Dataset, cols: Sequence[ResolvedColumn], starts: Sequence[int],
                 n: int) -> list[Run]:
    """Return the runs of ``I``/``F`` columns whose arrays earlier tables printed."""
    arrays = [ds[c.variable].values for c in cols]
    formats = [(c.fmt, c.kind, c.fill) for c in cols]
    return SHARED.runs(arrays, [-1 if c.index is None else c.index for c in cols], formats,
                       [c.fmt.code in "IF" for c in cols], starts,
                       [c.fmt.width for c in cols], n)


def format_chunk(ds: xr.Dataset, cols: Sequence[ResolvedColumn], start: int,
                 stop: int, arrays: Sequence[np.ndarray] | None = None,
                 out: np.ndarray | None = None) -> np.ndarray:
    """Rows ``start:stop`` of the table as a ``(rows, row_bytes)`` uint8 array.

    ``arrays`` (one per column, optional) replace the dataset's values.  ``out`` (at
    least ``stop - start`` rows) is reused when given: a fresh buffer per chunk would
    cost a page fault per 4 KiB, about as much as the formatting.
    """
    if arrays is None:
        sources, source_of = _sources(ds, cols)
    else:
        sources = [a.reshape(a.shape[0], 1) for a in arrays]
        source_of = [(j, 0) for j in range(len(cols))]
    return _Rows(cols, sources, source_of).format(start, stop, out)


def _text(s: str) -> str:
    """Return a label text value: whitespace folded, ``"`` turned into ``'``."""
    return " ".join(str(s).replace('"', "'").split()) or "N/A"


def _put_extra(module: pvl.PVLModule, label_extra: Mapping[str, Any]) -> None:
    """Merge caller keywords: an existing keyword is replaced in place (once)."""
    for key, value in label_extra.items():
        k = str(key).upper()
        if k in _STRUCTURAL:
            raise InputFormatError(f"label_extra may not set {k} (the writer owns it)",
                                   field=k)
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, Mapping) or (isinstance(value, (list, tuple)) and not value):
            raise InputFormatError(f"label_extra {k}: a PDS3 keyword holds a number, text or "
                                   "a non-empty sequence", field=k)
        texts = value if isinstance(value, (list, tuple)) else [value]
        if any(isinstance(t, str) and ('"' in t or not t.isascii()) for t in texts):
            raise InputFormatError(f"label_extra {k}: PDS3 text must be ASCII without a "
                                   f"double quote, got {value!r}", field=k)
        if k in module:
            module[k] = value
        else:
            module.append(k, value)


def _provenance(attrs: Mapping[str, Any]) -> pvl.PVLGroup:
    """Human-readable provenance (the exact values are in DATASET_ATTRIBUTES)."""
    g = pvl.PVLGroup()

    def put(key: str, values: list[str]) -> None:
        if values:
            g[key] = [text_value(str(v))[0] for v in values]

    inputs = attrs.get("inputs") or []
    put("INPUT_FILE_NAME", [r.get("name", "") or "N/A" for r in inputs])
    put("INPUT_FILE_SHA256", [r.get("sha256", "") or "N/A" for r in inputs])
    cal = attrs.get("calibration") or {}
    put("CALIBRATION_NAME", list(cal))
    put("CALIBRATION_SOURCE", [r.get("name", r.get("version", "")) or "N/A"
                               for r in cal.values()])
    put("CALIBRATION_SHA256", [r.get("sha256", "") or "N/A" for r in cal.values()])
    kernels = attrs.get("kernels") or []
    put("KERNEL_NAME", [r.get("name", "") or "N/A" for r in kernels])
    put("KERNEL_SHA256", [r.get("sha256", "") or "N/A" for r in kernels])
    if "command_line" in attrs:
        g["COMMAND_LINE"] = text_value(str(attrs["command_line"]))[0]
    return g


def label_module(
    ds: xr.Dataset,
    cols: Sequence[ResolvedColumn],
    table_name: str,
    label_extra: Mapping[str, Any] | None = None,
) -> pvl.PVLModule:
    """Build the PDS3 label of a table (pure).  Every keyword appears once per block."""
    n = ds.sizes.get(TIME_DIM, 0)
    attrs = portable_attrs(ds.attrs)  # no folder of this machine in the label
    label_extra = portable_attrs(label_extra or {})
    starts, row_bytes = layout(cols)
    m = pvl.PVLModule()
    m["PDS_VERSION_ID"] = Symbol("PDS3")
    m["RECORD_TYPE"] = Symbol("FIXED_LENGTH")
    m["RECORD_BYTES"] = row_bytes
    m["FILE_RECORDS"] = n
    m["^TABLE"] = table_name
    m["PRODUCT_ID"] = Path(table_name).stem
    m["PRODUCT_CREATION_TIME"] = str(attrs.get("creation_time", "")) or "N/A"
    m["SOFTWARE_NAME"] = "fluxcal"
    m["SOFTWARE_VERSION_ID"] = str(attrs.get("software_version", software_version()))
    _put_extra(m, label_extra or {})
    prov = _provenance(attrs)
    if prov:
        m["PROVENANCE"] = prov
    rest = {k: v for k, v in attrs.items() if k != "creation_time"}  # PRODUCT_CREATION_TIME
    if rest:
        m["DATASET_ATTRIBUTES"] = attributes_object(rest)
    table = pvl.PVLObject()
    table["INTERCHANGE_FORMAT"] = Symbol("ASCII")
    table["ROWS"] = n
    table["COLUMNS"] = len(cols)
    table["ROW_BYTES"] = row_bytes
    table["DESCRIPTION"] = ("One sample per line, fixed-width fields separated by one "
                            "blank, no header, CRLF line ends.")
    for i, (c, s) in enumerate(zip(cols, starts, strict=True)):
        var = ds[c.variable]
        col = pvl.PVLObject()
        col["COLUMN_NUMBER"] = i + 1
        col["NAME"] = c.label
        col["DATA_TYPE"] = Symbol(c.data_type or _DATA_TYPE[c.kind])
        col["START_BYTE"] = s + 1
        col["BYTES"] = c.fmt.width
        col["FORMAT"] = c.fmt.fortran
        col["UNIT"] = _text(c.unit)
        col["DESCRIPTION"] = _text(c.description)
        if c.fill is not None and c.kind == "real":
            col["MISSING_CONSTANT"] = float(c.fill)
        col["FLUXCAL:VARIABLE"] = c.variable
        col["FLUXCAL:DTYPE"] = str(var.dtype)
        if c.component is not None:
            col["FLUXCAL:COMPONENT"] = c.component
            col["FLUXCAL:COMPONENT_DIM"] = str(var.dims[1])
        table.append("COLUMN", col)
    m["TABLE"] = table
    return m


def write_tab(
    ds: xr.Dataset,
    stem: Path,
    columns: Sequence[Column] | None = None,
    label_extra: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write ``stem.TAB`` and ``stem.LBL`` atomically; return both paths.

    Parameters
    ----------
    ds : xarray.Dataset
        Dimension ``time``; variables named by ``columns``.
    stem : Path
        Output path without suffix.
    columns : sequence of Column, optional
        Default: every time variable with an exact format (`Column`).
    label_extra : mapping, optional
        Extra label keywords (numbers, text, non-empty sequences); a keyword the
        writer also sets (e.g. ``PRODUCT_ID``) takes the caller's value, once.

    Returns
    -------
    list of Path
        ``[stem.TAB, stem.LBL]``.

    Raises
    ------
    InputFormatError
        A value that does not fit its column format (naming the column and row), an
        infinite value, a string with whitespace, or a label value PDS3 cannot hold.

    Notes
    -----
    Both files are written under temporary names, the table chunk by chunk, and
    renamed together at the end (`atomic_group`).  On failure neither file is left
    (an older pair is kept).
    """
    stem = Path(stem)
    cols = resolve_columns(ds, columns)
    n = ds.sizes.get(TIME_DIM, 0)
    tab = stem.with_name(stem.name + ".TAB")
    lbl = stem.with_name(stem.name + ".LBL")
    label = render_label(label_module(ds, cols, tab.name, label_extra))
    runs = _shared_runs(ds, cols, layout(cols)[0], n)
    rows = _Rows(cols, *_sources(ds, cols),
                 skip=[j for r in runs if r.found for j in range(r.first, r.stop)])
    with atomic_group(), atomic_path(tab) as tmp_tab, atomic_path(lbl) as tmp_lbl:
        out = np.empty((min(n, CHUNK_ROWS), rows.row_bytes), np.uint8)
        with open(tmp_tab, "wb") as f:
            for start in range(0, n, CHUNK_ROWS):
                stop = min(n, start + CHUNK_ROWS)
                buf = rows.format(start, stop, out)
                for r in runs:
                    if r.found:
                        buf[:, r.lo:r.hi] = r.text[start:stop]
                    else:
                        r.text[start:stop] = buf[:, r.lo:r.hi]
                f.write(buf)
        tmp_lbl.write_text(label, encoding="ascii", newline="")
    for r in runs:
        if not r.found:
            SHARED.keep(r)
    return [tab, lbl]


def _parse_field(raw: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Fixed-width ASCII field bytes ``(rows, width)`` -> values of ``dtype``."""
    text = np.ascontiguousarray(raw).view(f"S{raw.shape[1]}").ravel()
    if dtype.kind in "iub":
        return text.astype(np.int64).astype(dtype)
    if dtype.kind == "f":
        return text.astype(np.float64)
    return np.char.strip(text).astype(dtype if dtype.kind in "US" else str)


def read_tab(path: Path) -> xr.Dataset:
    """Read a ``.TAB`` (and the ``.LBL`` beside it) back into a Dataset.

    The label's ``START_BYTE``/``BYTES`` slice each row.  Columns of one variable are
    regrouped into ``(time, component)`` variables; ``units`` and ``description``
    attrs come from the label, dataset attrs from its ``DATASET_ATTRIBUTES`` object.
    ``epoch``, if printed, becomes the coordinate.
    """
    path = Path(path)
    if path.suffix.upper() != ".TAB":
        path = path.with_name(path.name + ".TAB")
    lbl = path.with_suffix(".LBL")
    label = read_label(lbl)
    check_pointers(label, lbl)  # no pointer out of the label's folder (decision 66)
    tables = find_objects(label, "TABLE")
    if not tables:
        raise InputFormatError("label has no TABLE object", path=str(lbl))
    cols = [as_dict(c) for c in find_objects(tables[0], "COLUMN")]
    if not cols:
        raise InputFormatError("label describes no COLUMN", path=str(lbl))
    row_bytes = int(tables[0]["ROW_BYTES"])
    rows = int(tables[0]["ROWS"])
    raw = np.fromfile(path, dtype=np.uint8)
    if raw.size != rows * row_bytes:
        raise InputFormatError(f"table has {raw.size} bytes; the label says {rows} rows of "
                               f"{row_bytes}", path=str(path))
    raw = raw.reshape(rows, row_bytes)
    variables: dict[str, dict[str, Any]] = {}
    for c in cols:
        dtype = np.dtype(str(c.get("FLUXCAL:DTYPE", "str")))
        s0 = int(c["START_BYTE"]) - 1
        field = raw[:, s0:s0 + int(c["BYTES"])]
        try:
            vals = _parse_field(field, dtype)
        except ValueError as exc:
            raise InputFormatError(f"cannot read column: {exc}", path=str(path),
                                   field=str(c["NAME"])) from exc
        miss = c.get("MISSING_CONSTANT")
        if dtype.kind == "f":
            if miss is not None:
                vals = np.where(vals == float(miss), np.nan, vals)
            vals = vals.astype(dtype)
        name = str(c.get("FLUXCAL:VARIABLE", c["NAME"]))
        entry = variables.setdefault(name, {"values": [], "components": [], "attrs": {},
                                            "dim": c.get("FLUXCAL:COMPONENT_DIM")})
        entry["values"].append(vals)
        if "FLUXCAL:COMPONENT" in c:
            entry["components"].append(str(c["FLUXCAL:COMPONENT"]))
        unit = str(c.get("UNIT", "N/A"))
        entry["attrs"]["units"] = "" if unit == "N/A" else unit
        desc = str(c.get("DESCRIPTION", "N/A"))
        if desc != "N/A":
            entry["attrs"]["description"] = desc
    data_vars: dict[str, Any] = {}
    coords: dict[str, Any] = {}
    for name, e in variables.items():
        if e["components"]:
            dim = str(e["dim"] or "component")
            comps = np.array(e["components"], dtype=str)
            coords.setdefault(dim, comps)
            var = xr.DataArray(np.stack(e["values"], axis=1), dims=(TIME_DIM, dim),
                               coords={dim: comps}, attrs=e["attrs"])
        else:
            var = xr.DataArray(e["values"][0], dims=(TIME_DIM,), attrs=e["attrs"])
        (coords if name == "epoch" else data_vars)[name] = var
    ds = xr.Dataset(data_vars, coords=coords)
    attrs_obj = find_objects(label, "DATASET_ATTRIBUTES")
    attrs = decode_attributes(attrs_obj[0]) if attrs_obj else {}
    created = label.get("PRODUCT_CREATION_TIME")
    if created is not None and created != "N/A":
        attrs["creation_time"] = str(created)
    ds.attrs = attrs
    return ds
