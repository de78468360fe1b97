"""Archive-style ASCII table (``.TAB``) with its PDS3-like label (``.LBL``).

The table has one sample per line, values separated by one space, no header, CRLF
line ends; each value is printed with its column's printf format.  The label lists
the columns (name, data type, unit, description, format, and the byte positions when
every row has the same length), the software version and the provenance attributes.

Formatting is vectorized: one ``%`` operation formats a whole chunk of rows (no
Python loop per sample), so the bytes depend only on the values and formats.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

import fluxcal
from fluxcal.errors import InputFormatError
from fluxcal.products.atomic import atomic_group, atomic_path
from fluxcal.products.attrs import decode_value
from fluxcal.products.columns import TIME_DIM, Column, ResolvedColumn, resolve_columns
from fluxcal.products.label import Statement, Symbol, as_dict, find_objects, parse_label
from fluxcal.products.label import render_label as _render

CHUNK_ROWS = 20_000
EOL = "\r\n"
_DATA_TYPE = {"int": "ASCII_INTEGER", "real": "ASCII_REAL", "str": "CHARACTER"}
_WS = re.compile(r"\s")


def _column_values(ds: xr.Dataset, col: ResolvedColumn) -> np.ndarray:
    var = ds[col.variable]
    arr = var.values if col.index is None else var.values[:, col.index]
    if col.kind == "str":
        arr = arr.astype(str)
        joined = "\x00".join(arr.tolist())
        if "" in arr or _WS.search(joined):
            raise InputFormatError(
                "string values printed in a whitespace-separated table must be non-empty "
                "and contain no whitespace",
                field=col.label,
            )
    elif col.kind == "real" and col.fill is not None:
        arr = np.where(np.isnan(arr), col.fill, arr)
    return arr


def format_rows(ds: xr.Dataset, cols: Sequence[ResolvedColumn]) -> tuple[list[str], list[int]]:
    """Format the table as text chunks; also return the widths of the first row's values.

    Pure (no I/O).  ``"".join(chunks)`` is the whole table.
    """
    n = ds.sizes.get(TIME_DIM, 0)
    values = [_column_values(ds, c) for c in cols]
    line_fmt = " ".join(c.fmt for c in cols) + EOL
    chunks: list[str] = []
    for start in range(0, n, CHUNK_ROWS):
        stop = min(n, start + CHUNK_ROWS)
        block = np.empty((stop - start, len(cols)), dtype=object)
        for j, v in enumerate(values):
            block[:, j] = v[start:stop].tolist()
        try:
            chunks.append((line_fmt * (stop - start)) % tuple(block.ravel().tolist()))
        except (TypeError, ValueError) as exc:
            raise InputFormatError(f"cannot format rows {start}..{stop}: {exc}") from exc
    widths = (
        [len(c.fmt % v[0].item() if hasattr(v[0], "item") else c.fmt % v[0])
         for c, v in zip(cols, values, strict=True)]
        if n
        else []
    )
    return chunks, widths


def _fixed_row_bytes(chunks: Sequence[str], widths: Sequence[int], n: int) -> int | None:
    if not n:
        return None
    row = sum(widths) + len(widths) - 1 + len(EOL)
    return row if sum(len(c) for c in chunks) == n * row else None


def label_statements(
    ds: xr.Dataset,
    cols: Sequence[ResolvedColumn],
    table_name: str,
    widths: Sequence[int],
    row_bytes: int | None,
    label_extra: Mapping[str, Any] | None = None,
) -> list[Statement]:
    """Build the label as ODL statements (pure)."""
    n = ds.sizes.get(TIME_DIM, 0)
    attrs = dict(ds.attrs)
    st: list[Statement] = [
        ("PDS_VERSION_ID", Symbol("PDS3")),
        ("RECORD_TYPE", Symbol("FIXED_LENGTH" if row_bytes else "STREAM")),
    ]
    if row_bytes:
        st.append(("RECORD_BYTES", row_bytes))
    st += [
        ("FILE_RECORDS", n),
        ("^TABLE", table_name),
        ("PRODUCT_ID", Path(table_name).stem),
        ("PRODUCT_CREATION_TIME", str(attrs.get("creation_time", ""))),
        ("SOFTWARE_NAME", "fluxcal"),
        ("SOFTWARE_VERSION_ID", str(attrs.get("software_version", fluxcal.__version__))),
    ]
    for k, v in (label_extra or {}).items():
        st.append((k, v))
    prov: list[Statement] = []
    inputs = attrs.get("inputs") or []
    if inputs:
        prov.append(("INPUT_FILE_NAME", [r.get("path", r.get("name", "")) for r in inputs]))
        prov.append(("INPUT_FILE_SHA256", [r.get("sha256", "") for r in inputs]))
    cal = attrs.get("calibration") or {}
    if cal:
        prov.append(("CALIBRATION_NAME", list(cal)))
        prov.append(("CALIBRATION_SOURCE", [r.get("path", r.get("version", ""))
                                            for r in cal.values()]))
        prov.append(("CALIBRATION_SHA256", [r.get("sha256", "") for r in cal.values()]))
    kernels = attrs.get("kernels") or []
    if kernels:
        prov.append(("KERNEL_NAME", [r.get("path", r.get("name", "")) for r in kernels]))
        prov.append(("KERNEL_SHA256", [r.get("sha256", "") for r in kernels]))
    if "command_line" in attrs:
        prov.append(("COMMAND_LINE", str(attrs["command_line"])))
    if prov:
        st.append(("OBJECT", ("PROVENANCE", prov)))
    if attrs:
        st.append(("OBJECT", ("DATASET_ATTRIBUTES", [(k, v) for k, v in attrs.items()])))
    table: list[Statement] = [
        ("INTERCHANGE_FORMAT", Symbol("ASCII")),
        ("ROWS", n),
        ("COLUMNS", len(cols)),
    ]
    if row_bytes:
        table.append(("ROW_BYTES", row_bytes))
    table.append(("DESCRIPTION", "One sample per line, values separated by one space, "
                                 "no header, CRLF line ends."))
    start = 1
    for i, c in enumerate(cols):
        var = ds[c.variable]
        body: list[Statement] = [
            ("COLUMN_NUMBER", i + 1),
            ("NAME", c.label),
            ("DATA_TYPE", Symbol(_DATA_TYPE[c.kind])),
        ]
        if row_bytes:
            body += [("START_BYTE", start), ("BYTES", widths[i])]
            start += widths[i] + 1
        body += [("FORMAT", c.fmt), ("UNIT", c.unit), ("DESCRIPTION", c.description)]
        if c.fill is not None:
            body.append(("MISSING_CONSTANT", c.fill))
        body += [("FLUXCAL_VARIABLE", c.variable), ("FLUXCAL_DTYPE", str(var.dtype))]
        if c.component is not None:
            body += [("FLUXCAL_COMPONENT", c.component),
                     ("FLUXCAL_COMPONENT_DIM", str(var.dims[1]))]
        table.append(("OBJECT", ("COLUMN", body)))
    st.append(("OBJECT", ("TABLE", table)))
    return st


def write_tab(
    ds: xr.Dataset,
    stem: Path,
    columns: Sequence[Column] | None = None,
    label_extra: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write ``stem.TAB`` and ``stem.LBL`` atomically; return both paths.

    Both are written under temporary names and renamed together at the end (the
    table first).  On failure neither file is left (an older pair is kept).
    """
    stem = Path(stem)
    cols = resolve_columns(ds, columns)
    chunks, widths = format_rows(ds, cols)
    n = ds.sizes.get(TIME_DIM, 0)
    row_bytes = _fixed_row_bytes(chunks, widths, n)
    tab = stem.with_name(stem.name + ".TAB")
    lbl = stem.with_name(stem.name + ".LBL")
    label = _render(label_statements(ds, cols, tab.name, widths, row_bytes, label_extra))
    with atomic_group(), atomic_path(tab) as tmp_tab, atomic_path(lbl) as tmp_lbl:
        with open(tmp_tab, "w", encoding="ascii", newline="") as f:
            for chunk in chunks:
                f.write(chunk)
        tmp_lbl.write_text(label, encoding="utf-8", newline="")
    return [tab, lbl]


def read_label(path: Path) -> list[Statement]:
    """Parse a ``.LBL`` file."""
    return parse_label(Path(path).read_text(encoding="utf-8"))


def read_tab(path: Path) -> xr.Dataset:
    """Read a ``.TAB`` (and the ``.LBL`` beside it) back into a Dataset.

    Columns of one variable are regrouped into ``(time, component)`` variables;
    ``units`` and ``description`` attrs come from the label, dataset attrs from its
    ``DATASET_ATTRIBUTES`` object.  ``epoch``, if printed, becomes the coordinate.
    """
    path = Path(path)
    if path.suffix.upper() != ".TAB":
        path = path.with_name(path.name + ".TAB")
    lbl = path.with_suffix(".LBL")
    st = read_label(lbl)
    tables = find_objects(st, "TABLE")
    if not tables:
        raise InputFormatError("label has no TABLE object", path=str(lbl))
    cols = [as_dict(c) for c in find_objects(tables[0], "COLUMN")]
    ncol = len(cols)
    if ncol == 0:
        raise InputFormatError("label describes no COLUMN", path=str(lbl))
    fields = []
    for j, c in enumerate(cols):
        dtype = np.dtype(str(c.get("FLUXCAL_DTYPE", "str")))
        if dtype.kind in "iub":
            fields.append((f"f{j}", np.int64))
        elif dtype.kind == "f":
            fields.append((f"f{j}", np.float64))
        else:
            width = max(int(c.get("BYTES", 0)), dtype.itemsize // 4, 64)
            fields.append((f"f{j}", f"U{width}"))
    try:  # numpy's C parser, whitespace-delimited, one typed field per column
        if path.stat().st_size == 0:  # an empty day (loadtxt would warn)
            table = np.zeros(0, dtype=np.dtype(fields))
        else:
            table = np.loadtxt(path, dtype=np.dtype(fields), ndmin=1, encoding="ascii")
    except ValueError as exc:
        raise InputFormatError(f"table does not match its label's {ncol} columns: {exc}",
                               path=str(path)) from exc
    variables: dict[str, dict[str, Any]] = {}
    for j, c in enumerate(cols):
        dtype = np.dtype(str(c.get("FLUXCAL_DTYPE", "str")))
        raw = table[f"f{j}"]
        if dtype.kind == "f":
            vals = raw
            miss = c.get("MISSING_CONSTANT")
            if miss is not None:
                vals = np.where(vals == float(miss), np.nan, vals)
            vals = vals.astype(dtype)
        elif dtype.kind in "iub":
            vals = raw.astype(dtype)
        else:
            vals = raw.astype(dtype if dtype.kind == "U" else str)
        name = str(c.get("FLUXCAL_VARIABLE", c["NAME"]))
        entry = variables.setdefault(name, {"values": [], "components": [], "attrs": {},
                                            "dim": c.get("FLUXCAL_COMPONENT_DIM")})
        entry["values"].append(vals)
        if "FLUXCAL_COMPONENT" in c:
            entry["components"].append(str(c["FLUXCAL_COMPONENT"]))
        entry["attrs"]["units"] = str(c.get("UNIT", ""))
        if c.get("DESCRIPTION"):
            entry["attrs"]["description"] = str(c["DESCRIPTION"])
    data_vars: dict[str, Any] = {}
    coords: dict[str, Any] = {}
    for name, e in variables.items():
        if e["components"]:
            dim = str(e["dim"] or "component")
            coords.setdefault(dim, np.array(e["components"], dtype=str))
            var = xr.DataArray(np.stack(e["values"], axis=1), dims=(TIME_DIM, dim),
                               coords={dim: np.array(e["components"], dtype=str)},
                               attrs=e["attrs"])
        else:
            var = xr.DataArray(e["values"][0], dims=(TIME_DIM,), attrs=e["attrs"])
        (coords if name == "epoch" else data_vars)[name] = var
    ds = xr.Dataset(data_vars, coords=coords)
    attrs_obj = find_objects(st, "DATASET_ATTRIBUTES")
    if attrs_obj:
        ds.attrs = {k: _plain(decode_value(v)) for k, v in attrs_obj[0]}
    return ds


def _plain(v: Any) -> Any:
    if isinstance(v, Symbol):
        return str(v)
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v
