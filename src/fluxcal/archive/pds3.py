"""Label-driven PDS3 table reader: ASCII and binary ``TABLE`` objects into xarray.

Everything comes from the label (pvl parses it): the ``^TABLE`` pointer (data file name,
record or byte offset; attached or detached label), ``RECORD_BYTES``, the table's
``INTERCHANGE_FORMAT``, ``ROWS``, ``ROW_BYTES`` (with ``ROW_PREFIX_BYTES`` /
``ROW_SUFFIX_BYTES``), and each ``COLUMN`` object's ``NAME``, ``DATA_TYPE``,
``START_BYTE``, ``BYTES``, ``ITEMS`` / ``ITEM_BYTES`` / ``ITEM_OFFSET``, ``UNIT``,
``DESCRIPTION``, ``FORMAT``, the special constants (``MISSING_CONSTANT``,
``INVALID_CONSTANT``, ...) and ``SCALING_FACTOR`` / ``OFFSET``.  No byte offset is guessed.

The table bytes are read once into a ``(rows, row_stride)`` uint8 array and every
column is a slice of it: ASCII fields are converted by numpy's bytes -> number casts,
binary fields are viewed with the dtype the ``DATA_TYPE`` names (PDS3 Standards
Reference, Appendix C).  No Python code runs per row (except to locate the first bad
field once a conversion has failed).

Errors are `fluxcal.errors.InputFormatError` and name the file, the row (1-based; given
as ``line`` = the record of the data file when rows are record-aligned) and the column.

Conventions of the returned Dataset (docs/formats/archive.md):

* dimension ``row``; one variable per column named as the label's ``NAME``; a column
  with ``ITEMS = n`` has dims ``("row", "<NAME>_item")``;
* ASCII_REAL and IEEE/PC_REAL -> float64; ASCII_INTEGER -> int64, binary integers in
  their own width (native byte order); CHARACTER / TIME / DATE -> str (blanks stripped);
* a column with a special constant (``MISSING_CONSTANT``, ``INVALID_CONSTANT``,
  ``NULL_CONSTANT``, ``UNKNOWN_CONSTANT``, ``NOT_APPLICABLE_CONSTANT``,
  ``SATURATED_CONSTANT``, ``HIGH/LOW_INSTR/REPR_SATURATION``) or a ``SCALING_FACTOR`` /
  ``OFFSET`` becomes float64: stored values equal to a constant are NaN, then
  ``value * SCALING_FACTOR + OFFSET``;
* variable attrs ``units`` (``UNIT``; ``""`` for ``N/A`` or none), ``description``,
  ``format``, ``pds3_data_type``, ``pds3_column_number`` and the constants;
* dataset attrs: every top-level keyword of the label (text, numbers, lists; dates as
  ISO text) and ``pds3_label``, ``pds3_data_file``, ``pds3_table``.

References
----------
PDS3 Standards Reference (JPL D-7669 part 2), chapters 5 (pointers), 15 (object
definitions: TABLE, COLUMN), Appendix C (data types).
"""

from __future__ import annotations

import datetime as dt
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pvl
import xarray as xr
from pvl.collections import Quantity
from pvl.decoder import OmniDecoder
from pvl.grammar import OmniGrammar

from fluxcal.archive.fixedparse import parse_ints, parse_reals, pow10
from fluxcal.errors import InputFormatError
from fluxcal.products.paths import pointer_target

__all__ = [
    "ROW_DIM",
    "column_names",
    "find_label",
    "parse_label_text",
    "read_label",
    "read_table",
    "read_table_columns",
    "table_names",
]

ROW_DIM = "row"
_LABEL_SCAN = 1 << 22  # an attached label must end (END) in the first 4 MiB
_END = re.compile(rb"(?m)^[ \t]*END[ \t]*\r?$")
_CONSTANTS = ("MISSING_CONSTANT", "INVALID_CONSTANT", "NULL_CONSTANT", "UNKNOWN_CONSTANT",
              "NOT_APPLICABLE_CONSTANT", "SATURATED_CONSTANT", "HIGH_INSTR_SATURATION",
              "HIGH_REPR_SATURATION", "LOW_INSTR_SATURATION", "LOW_REPR_SATURATION")
_TEXT = {"CHARACTER", "TIME", "DATE", "ASCII_TIME", "ASCII_DATE", "ASCII_DATE_TIME",
         "DATE_TIME", "ASCII_CHARACTER"}
_ASCII_REAL = {"ASCII_REAL", "REAL", "FLOAT", "ASCII_FLOAT"}
_ASCII_INT = {"ASCII_INTEGER", "INTEGER", "ASCII_UNSIGNED_INTEGER", "UNSIGNED_INTEGER"}
# binary DATA_TYPE -> numpy kind and byte order (PDS3 Standards Reference, Appendix C)
_BINARY = {
    **{k: ("i", ">") for k in ("MSB_INTEGER", "INTEGER", "MAC_INTEGER", "SUN_INTEGER")},
    **{k: ("i", "<") for k in ("LSB_INTEGER", "PC_INTEGER", "VAX_INTEGER")},
    **{k: ("u", ">") for k in ("MSB_UNSIGNED_INTEGER", "UNSIGNED_INTEGER",
                                "MAC_UNSIGNED_INTEGER", "SUN_UNSIGNED_INTEGER")},
    **{k: ("u", "<") for k in ("LSB_UNSIGNED_INTEGER", "PC_UNSIGNED_INTEGER",
                                "VAX_UNSIGNED_INTEGER")},
    **{k: ("f", ">") for k in ("IEEE_REAL", "FLOAT", "REAL", "MAC_REAL", "SUN_REAL")},
    "PC_REAL": ("f", "<"),
}


class _Decoder(OmniDecoder):
    """pvl's default decoder, without trying a date format on a value that cannot be one.

    Every PVL/ODL date or time begins with a digit; pvl tries its dozens of ``strptime``
    formats on every unquoted value (``ASCII_REAL``, ``PDS3``...), which was half of the
    parsing time of a label.  The decoded values are the same (tested).
    """

    def decode_datetime(self, value: str) -> Any:
        """Reject a value not starting with a digit at once; else pvl's decoding."""
        if not value[:1].isdigit():
            raise ValueError(f"{value!r} is not a date or time")
        return super().decode_datetime(value)


def parse_label_text(text: str) -> pvl.PVLModule:
    """Parse label text with pvl's default grammar and the `_Decoder` above."""
    return pvl.loads(text, decoder=_Decoder(grammar=OmniGrammar()))


# --- the label ------------------------------------------------------------------------


def read_label(path: Path | str) -> pvl.PVLModule:
    """Parse the PDS3 label of ``path``: a detached ``.LBL`` or a file with an attached label.

    The text up to the ``END`` statement is parsed with pvl (its default, lenient
    "Omni" grammar, which reads PDS3 labels written by other software, e.g. an
    unquoted ``N/A``); bytes after ``END`` (an attached table) are not read.

    Raises
    ------
    InputFormatError
        Missing file, no ``END`` in the first 4 MiB, non-ASCII text, or a syntax error
        (with the line pvl reports).
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            head = f.read(_LABEL_SCAN)
    except FileNotFoundError as exc:
        raise InputFormatError("label file not found", path=str(path)) from exc
    end = _END.search(head)
    if end is None:
        raise InputFormatError("no END statement in the first 4 MiB: not a PDS3 label",
                               path=str(path))
    raw = head[:end.end()]
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        raise InputFormatError(f"label is not ASCII (byte {raw[exc.start]:#04x})",
                               path=str(path), line=raw[:exc.start].count(b"\n") + 1) from exc
    try:
        return parse_label_text(text)
    except Exception as exc:  # pvl's LexerError/ParseError carry lineno
        msg = " ".join(str(getattr(exc, "msg", exc)).split())
        raise InputFormatError(f"not a PDS3 label: {msg}", path=str(path),
                               line=getattr(exc, "lineno", None)) from exc


def find_label(path: Path | str) -> Path:
    """Return the label of ``path``: itself if ``.LBL`` or attached, else ``<stem>.LBL``.

    Raises
    ------
    InputFormatError
        ``path`` does not exist, or has no attached label and no ``.LBL`` beside it.
    """
    path = Path(path)
    if not path.exists():
        raise InputFormatError("file not found", path=str(path))
    if path.suffix.lower() == ".lbl":
        return path
    with open(path, "rb") as f:
        start = f.read(64).lstrip()
    if start.startswith((b"PDS_VERSION_ID", b"CCSD")):
        return path
    for suffix in (".LBL", ".lbl"):
        if path.with_suffix(suffix).exists():
            return path.with_suffix(suffix)
    raise InputFormatError("no attached PDS3 label and no .LBL file beside it",
                           path=str(path))


def table_names(label: Mapping[str, Any]) -> list[str]:
    """Names of the table objects the label points to (``^TABLE``, ``^MAG_TABLE``...)."""
    return [k[1:] for k in label.keys() if k.startswith("^") and k.upper().endswith("TABLE")]


def column_names(label: Mapping[str, Any], label_path: Path | str,
                 table: str | None = None) -> list[str]:
    """Names of the COLUMN objects of a table of ``label`` (the only one by default).

    ``^STRUCTURE`` format files are followed (looked up from ``label_path``).
    """
    names = table_names(label)
    obj = _find_object(label, table or (names[0] if len(names) == 1 else ""))
    if obj is None:
        return []
    obj = _expand_structure(obj, Path(label_path))
    return [str(v.get("NAME")) for k, v in obj.items() if k == "COLUMN" and isinstance(v, Mapping)]


# --- the table's layout -----------------------------------------------------------------


@dataclass(frozen=True)
class _Column:
    name: str
    number: int
    data_type: str
    start: int  # 0-based byte in the row
    nbytes: int
    items: int | None
    item_bytes: int
    item_offset: int
    attrs: dict[str, Any] = field(default_factory=dict)
    constants: tuple[float, ...] = ()
    scale: float | None = None
    offset: float | None = None


@dataclass(frozen=True)
class _Layout:
    label_path: Path
    data_path: Path
    name: str
    offset: int  # byte of the first row
    rows: int
    stride: int  # bytes per row incl. prefix/suffix
    prefix: int
    ascii: bool
    columns: tuple[_Column, ...]

    def record(self, row: int) -> int | None:
        """1-based record of the data file holding 1-based ``row`` (None if unaligned)."""
        if self.offset % self.stride:
            return None
        return self.offset // self.stride + row


def _err(msg: str, path: Path, line: int | None = None,
         column: str | None = None) -> InputFormatError:
    return InputFormatError(msg, path=str(path), line=line, field=column)


def _int_key(block: Mapping[str, Any], key: str, where: str, path: Path,
             column: str | None = None, default: int | None = None) -> int:
    value = block.get(key, default)
    if value is None:
        raise _err(f"{where} has no {key}", path, column=column)
    if isinstance(value, Quantity):
        value = value.value
    if isinstance(value, bool) or not isinstance(value, int):
        raise _err(f"{where} {key} = {value!r} is not an integer", path, column=column)
    return int(value)


def _locate_file(folder: Path, name: str, label_path: Path, pointer: str = "^TABLE") -> Path:
    """Find the data file a pointer names, relative to the label's folder.

    PDS3 names are upper case, but copies on disk are often lower case: an exact name
    is tried first, then a unique case-insensitive match in the same folder.  The name
    is a plain file name in that folder: a pointer never leads out of it
    (`fluxcal.products.paths.pointer_target`; PDS3 Standards Reference ch. 5: a
    pointer names a file, found by the search rules, not a path;
    docs/decisions/products.md, decision 66).
    """
    exact = pointer_target(folder, name, label_path, pointer)
    if exact.exists():
        return exact
    matches = [p for p in folder.iterdir() if p.name.lower() == name.lower()] \
        if folder.is_dir() else []
    if len(matches) == 1:
        return pointer_target(folder, matches[0].name, label_path, pointer)
    raise _err(f"data file {name!r} named by the label's pointer not found in {folder}",
               label_path)


def _pointer(label: Mapping[str, Any], label_path: Path, name: str) -> tuple[Path, int]:
    """Resolve ``^name`` to ``(data file, 0-based byte offset)`` (PDS3 ref. ch. 5)."""
    value = label.get("^" + name)
    if value is None:
        raise _err(f"label has no ^{name} pointer", label_path)
    file_name: str | None = None
    where: Any = None
    if isinstance(value, str):
        file_name = value
    elif isinstance(value, (list, tuple)) and len(value) == 2 and isinstance(value[0], str):
        file_name, where = value
    elif isinstance(value, (int, Quantity)) and not isinstance(value, bool):
        where = value
    else:
        raise _err(f"^{name} = {value!r}: expected \"FILE\", (\"FILE\", record), "
                   "(\"FILE\", n <BYTES>), record or n <BYTES>", label_path)
    if where is None:
        offset = 0
    elif isinstance(where, Quantity):
        if str(where.units).upper() != "BYTES":
            raise _err(f"^{name} offset unit {where.units!r}: expected <BYTES>", label_path)
        offset = int(where.value) - 1
    else:
        offset = (int(where) - 1) * _int_key(label, "RECORD_BYTES", "label", label_path)
    if offset < 0:
        raise _err(f"^{name} points before the start of the file", label_path)
    data = label_path if file_name is None else _locate_file(label_path.parent, file_name,
                                                             label_path, "^" + name)
    return data, offset


def _number(value: Any) -> float:
    if isinstance(value, Quantity):
        value = value.value
    if isinstance(value, str):
        text = value.strip()
        based = re.fullmatch(r"(\d+)#([0-9A-Fa-f]+)#", text)  # e.g. "16#FFFF#"
        return float(int(based.group(2), int(based.group(1)))) if based else float(text)
    return float(value)


def _attr_value(value: Any) -> Any:
    """Convert a label value to a netCDF-friendly attribute value."""
    if isinstance(value, Quantity):
        return f"{value.value} <{value.units}>"
    if isinstance(value, dt.datetime):
        if value.tzinfo is not None:
            value = value.astimezone(dt.UTC).replace(tzinfo=None)
        return value.isoformat()
    if isinstance(value, (dt.date, dt.time)):
        return value.isoformat()
    if isinstance(value, (list, tuple, set)):
        items = [_attr_value(v) for v in value]
        return items if all(isinstance(v, (str, int, float)) for v in items) else str(items)
    if isinstance(value, (str, int, float)):
        return value
    return str(value)


def _description(value: Any) -> str:
    text = " ".join(str(value if value is not None else "").split())
    return "" if text.upper() == "N/A" else text


def _column(obj: Mapping[str, Any], number: int, label_path: Path, row_bytes: int,
            ascii_table: bool) -> _Column:
    keys = {str(k).upper(): v for k, v in obj.items() if not isinstance(v, Mapping)}
    if any(isinstance(v, Mapping) for v in obj.values()):
        raise _err(f"COLUMN {number} holds a sub-object (BIT_COLUMN?): not supported",
                   label_path, column=str(keys.get("NAME", f"COLUMN {number}")))
    name = keys.get("NAME")
    where = f"COLUMN {number}" + (f" ({name})" if name else "")
    if name is None:
        raise _err(f"{where} has no NAME", label_path, column=f"COLUMN {number}")
    name = str(name)
    if "DATA_TYPE" not in keys:
        raise _err(f"{where} has no DATA_TYPE", label_path, column=name)
    data_type = str(keys["DATA_TYPE"]).upper().replace(" ", "_")
    start = _int_key(keys, "START_BYTE", where, label_path, name) - 1
    nbytes = _int_key(keys, "BYTES", where, label_path, name)
    items = keys.get("ITEMS")
    if items is not None:
        items = _int_key(keys, "ITEMS", where, label_path, name)
        item_bytes = _int_key(keys, "ITEM_BYTES", where, label_path, name)
        item_offset = _int_key(keys, "ITEM_OFFSET", where, label_path, name, item_bytes)
        span = (items - 1) * item_offset + item_bytes
        if items < 1 or item_bytes < 1 or span > nbytes:
            raise _err(f"{where}: ITEMS {items} x ITEM_OFFSET {item_offset} (ITEM_BYTES "
                       f"{item_bytes}) span {span} bytes, more than BYTES = {nbytes}",
                       label_path, column=name)
    else:
        item_bytes = item_offset = nbytes
    if start < 0 or nbytes < 1 or start + nbytes > row_bytes:
        raise _err(f"{where}: START_BYTE {start + 1} + BYTES {nbytes} lies outside the row "
                   f"of {row_bytes} bytes", label_path, column=name)
    kind_ok = (data_type in _TEXT or data_type in _ASCII_REAL or data_type in _ASCII_INT
               if ascii_table else
               data_type in _BINARY or data_type in _TEXT or data_type.startswith("ASCII_"))
    if not kind_ok:
        raise _err(f"{where}: DATA_TYPE {data_type} is not supported in an "
                   f"{'ASCII' if ascii_table else 'BINARY'} table", label_path, column=name)
    if not ascii_table and data_type in _BINARY:
        kind = _BINARY[data_type][0]
        if item_bytes not in ((4, 8) if kind == "f" else (1, 2, 4, 8)):
            raise _err(f"{where}: {data_type} of {item_bytes} bytes is not supported",
                       label_path, column=name)
    constants = []
    attrs: dict[str, Any] = {}
    for key in _CONSTANTS:
        if key in keys:
            try:
                constants.append(_number(keys[key]))
            except (TypeError, ValueError) as exc:
                raise _err(f"{where}: {key} = {keys[key]!r} is not a number", label_path,
                           column=name) from exc
            attrs[key.lower()] = _attr_value(keys[key])
    try:
        scale = _number(keys["SCALING_FACTOR"]) if "SCALING_FACTOR" in keys else None
        offset = _number(keys["OFFSET"]) if "OFFSET" in keys else None
    except (TypeError, ValueError) as exc:
        raise _err(f"{where}: SCALING_FACTOR/OFFSET is not a number", label_path,
                   column=name) from exc
    unit = str(keys.get("UNIT", "")).strip()
    attrs = {"units": "" if unit.upper() in ("N/A", "NONE", "UNK") else unit,
             "description": _description(keys.get("DESCRIPTION")),
             "format": str(keys.get("FORMAT", "")),
             "pds3_data_type": data_type, "pds3_column_number": number, **attrs}
    if scale is not None:
        attrs["scaling_factor"] = scale
    if offset is not None:
        attrs["offset"] = offset
    return _Column(name, number, data_type, start, nbytes, items, item_bytes, item_offset,
                   attrs, tuple(constants), scale, offset)


def _find_object(label: Mapping[str, Any], name: str) -> Mapping[str, Any] | None:
    for k, v in label.items():
        if k == name and isinstance(v, Mapping):
            return v
    return None


_MAX_STRUCTURE_DEPTH = 8


def _format_file(name: Any, label_path: Path) -> Path:
    """Find a ``^STRUCTURE`` file: beside the label, else in a ``LABEL`` folder above it.

    The second place is where PDS3 volumes keep shared format files (``LABEL/*.FMT``);
    names are matched case-insensitively there too (`_locate_file`).
    """
    if not isinstance(name, str):
        raise _err(f"^STRUCTURE = {name!r}: expected a file name", label_path)
    pointer_target(label_path.parent, name, label_path, "^STRUCTURE")  # a plain name
    try:
        return _locate_file(label_path.parent, name, label_path, "^STRUCTURE")
    except InputFormatError:
        pass
    for folder in label_path.resolve().parents:
        for sub in (p for p in folder.iterdir() if p.is_dir() and p.name.upper() == "LABEL") \
                if folder.is_dir() else ():
            try:
                return _locate_file(sub, name, label_path, "^STRUCTURE")
            except InputFormatError:
                continue
    raise _err(f"format file {name!r} named by ^STRUCTURE not found beside the label or in "
               "a LABEL folder above it", label_path)


def _expand_structure(obj: Mapping[str, Any], label_path: Path,
                      depth: int = 0) -> Mapping[str, Any]:
    """Replace each ``^STRUCTURE`` pointer of ``obj`` by the objects of its format file.

    A format file holding one TABLE object is unpacked into the referencing table (as
    pdr does); pointers inside format files are followed (at most 8 levels).
    """
    if not any(str(k).upper() == "^STRUCTURE" for k in obj.keys()):
        return obj
    if depth >= _MAX_STRUCTURE_DEPTH:
        raise _err("^STRUCTURE files nest more than 8 levels deep", label_path)
    out = pvl.PVLObject()
    for key, value in obj.items():
        if str(key).upper() != "^STRUCTURE":
            out.append(key, value)
            continue
        path = _format_file(value, label_path)
        try:
            fmt = parse_label_text(path.read_text(encoding="ascii"))
        except Exception as exc:  # pvl's parse errors, UnicodeDecodeError
            raise InputFormatError(f"not a PDS3 format file: {' '.join(str(exc).split())}",
                                   path=str(path), line=getattr(exc, "lineno", None)) from exc
        items = list(fmt.items())
        if len(items) == 1 and isinstance(items[0][1], Mapping) and "TABLE" in items[0][0]:
            items = list(items[0][1].items())
        inner = pvl.PVLObject()
        for k, v in items:
            inner.append(k, v)
        for k, v in _expand_structure(inner, path, depth + 1).items():
            out.append(k, v)
    return out


def _layout(label: Mapping[str, Any], label_path: Path, table: str | None) -> _Layout:
    names = table_names(label)
    if table is None:
        if len(names) != 1:
            raise _err(f"label points to {len(names)} tables {names}: name one "
                       "(table=...)" if names else "label has no ^...TABLE pointer",
                       label_path)
        table = names[0]
    obj = _find_object(label, table)
    if obj is None:
        raise _err(f"label has no OBJECT = {table}", label_path)
    obj = _expand_structure(obj, label_path)
    data_path, offset = _pointer(label, label_path, table)
    fmt = obj.get("INTERCHANGE_FORMAT")
    if fmt is None:
        raise _err(f"{table} has no INTERCHANGE_FORMAT", label_path)
    fmt = str(fmt).upper()
    if fmt not in ("ASCII", "BINARY"):
        raise _err(f"{table} INTERCHANGE_FORMAT = {fmt}: expected ASCII or BINARY", label_path)
    rows = _int_key(obj, "ROWS", table, label_path)
    row_bytes = _int_key(obj, "ROW_BYTES", table, label_path)
    prefix = _int_key(obj, "ROW_PREFIX_BYTES", table, label_path, default=0)
    suffix = _int_key(obj, "ROW_SUFFIX_BYTES", table, label_path, default=0)
    if rows < 0 or row_bytes < 1:
        raise _err(f"{table} ROWS = {rows}, ROW_BYTES = {row_bytes}", label_path)
    stride = prefix + row_bytes + suffix
    ascii_table = fmt == "ASCII"
    if ascii_table and str(label.get("RECORD_TYPE", "")).upper() == "FIXED_LENGTH":
        record_bytes = _int_key(label, "RECORD_BYTES", "label", label_path)
        if record_bytes != stride:
            raise _err(f"record length mismatch: RECORD_BYTES = {record_bytes} but the "
                       f"{table} rows are {stride} bytes (ROW_BYTES + prefix/suffix)",
                       label_path)
    if any(k == "CONTAINER" for k, v in obj.items() if isinstance(v, Mapping)):
        raise _err(f"{table} holds CONTAINER objects: not supported", label_path)
    objs = [v for k, v in obj.items() if k == "COLUMN" and isinstance(v, Mapping)]
    if not objs:
        raise _err(f"{table} has no COLUMN object", label_path)
    cols = tuple(_column(o, i + 1, label_path, row_bytes, ascii_table)
                 for i, o in enumerate(objs))
    seen: set[str] = set()
    for c in cols:
        if c.name in seen:
            raise _err(f"two columns are named {c.name}", label_path, column=c.name)
        seen.add(c.name)
    declared = obj.get("COLUMNS")
    if declared is not None and int(declared) != len(cols):
        raise _err(f"{table} COLUMNS = {declared} but {len(cols)} COLUMN objects",
                   label_path)
    return _Layout(label_path, data_path, table, offset, rows, stride, prefix, ascii_table,
                   cols)


# --- the table's bytes ------------------------------------------------------------------


def _other_pointers_after(label: Mapping[str, Any], lay: _Layout) -> bool:
    """Whether another object of the label starts in the same file after this table."""
    for key in label.keys():
        if not key.startswith("^") or key[1:] == lay.name:
            continue
        try:
            path, off = _pointer(label, lay.label_path, key[1:])
        except InputFormatError:
            continue
        if path.resolve() == lay.data_path.resolve() and off > lay.offset:
            return True
    return False


def _read_bytes(label: Mapping[str, Any], lay: _Layout) -> np.ndarray:
    """Read the table as a ``(rows, stride)`` uint8 array; check size and row count."""
    size = os.path.getsize(lay.data_path)
    need = lay.offset + lay.rows * lay.stride
    if lay.ascii and lay.rows:
        _check_first_line(lay)
    if lay.ascii and size != need:
        _check_line_lengths(lay, size)
    if size < need:
        have = max(size - lay.offset, 0)
        if have % lay.stride == 0:
            raise _err(f"wrong row count: the file holds {have // lay.stride} rows of "
                       f"{lay.stride} bytes, the label says ROWS = {lay.rows} (wrong ROWS, "
                       "or a file truncated at a row end)", lay.data_path,
                       lay.record(have // lay.stride + 1))
        row = have // lay.stride + 1
        cut = have - (row - 1) * lay.stride - lay.prefix
        col = next((c for c in lay.columns if c.start + c.nbytes > cut), lay.columns[-1])
        raise _err(f"truncated: the file ends in row {row} of ROWS = {lay.rows} "
                   f"({size} bytes, the label needs {need}); column {col.name} is cut",
                   lay.data_path, lay.record(row), col.name)
    extra = size - need
    if extra and not _other_pointers_after(label, lay):
        if extra % lay.stride == 0:
            raise _err(f"wrong row count: the file holds {lay.rows + extra // lay.stride} "
                       f"rows of {lay.stride} bytes, the label says ROWS = {lay.rows}",
                       lay.data_path, lay.record(lay.rows + 1))
        raise _err(f"{extra} bytes after the last of ROWS = {lay.rows} rows of "
                   f"{lay.stride} bytes (wrong ROWS or ROW_BYTES)", lay.data_path,
                   lay.record(lay.rows + 1))
    raw = np.fromfile(lay.data_path, dtype=np.uint8, count=lay.rows * lay.stride,
                      offset=lay.offset)
    raw = raw.reshape(lay.rows, lay.stride)
    if lay.ascii and lay.rows:
        _check_line_ends(raw, lay)
    return raw


def _check_first_line(lay: _Layout) -> None:
    """Check that the first ASCII row ends where the label puts its line end."""
    with open(lay.data_path, "rb") as f:
        f.seek(lay.offset)
        chunk = f.read(lay.stride + 2)
    nl = chunk.find(b"\n")
    if nl == lay.stride - 1 or (nl < 0 and len(chunk) < lay.stride):
        return  # right, or a truncated first row (reported by the size check)
    actual = f"{nl + 1} bytes" if nl >= 0 else f"longer than {lay.stride} bytes"
    raise _err(f"record length mismatch: row 1 is {actual} (up to its line end), the "
               f"label's rows are {lay.stride} bytes (ROW_BYTES/RECORD_BYTES)",
               lay.data_path, lay.record(1))


def _check_line_lengths(lay: _Layout, size: int) -> None:
    """Name the first ASCII row whose line is not ``stride`` bytes (error path only)."""
    stop = min(size, lay.offset + lay.rows * lay.stride)
    buf = np.fromfile(lay.data_path, dtype=np.uint8, count=stop - lay.offset,
                      offset=lay.offset)
    ends = np.flatnonzero(buf == 10)
    lengths = np.diff(ends, prepend=-1)
    bad = np.flatnonzero(lengths != lay.stride)
    if bad.size:
        row = int(bad[0]) + 1
        raise _err(f"record length mismatch: row {row} is {int(lengths[bad[0]])} bytes "
                   f"(up to its line end), the label's rows are {lay.stride} bytes "
                   "(ROW_BYTES/RECORD_BYTES)", lay.data_path, lay.record(row))


def _check_line_ends(raw: np.ndarray, lay: _Layout) -> None:
    """Every ASCII row ends with CRLF (or LF) exactly at the label's row length."""
    lf = raw[:, -1] == 10
    crlf = lf & (raw[:, -2] == 13) if lay.stride > 1 else np.zeros_like(lf)
    ok = crlf if crlf[0] else lf
    if ok.all():
        return
    row = int(np.flatnonzero(~ok)[0]) + 1
    start = lay.offset + (row - 1) * lay.stride
    with open(lay.data_path, "rb") as f:
        f.seek(start)
        chunk = f.read(max(4 * lay.stride, 256))
    nl = chunk.find(b"\n")
    actual = f"{nl + 1} bytes" if nl >= 0 else "no line end"
    raise _err(f"record length mismatch: row {row} does not end with a line end at byte "
               f"{lay.stride} (its line is {actual}; the label's ROW_BYTES/RECORD_BYTES "
               "do not match the table)", lay.data_path, lay.record(row))


def _first_bad(text: np.ndarray, convert: Any) -> int:
    """Index of the first value ``convert`` rejects (error path only)."""
    for i, t in enumerate(text.tolist()):  # only after a vectorized cast failed
        try:
            convert(t)
        except ValueError:
            return i
    return 0


def _ascii_values(field: np.ndarray, col: _Column, lay: _Layout) -> np.ndarray:
    width = field.shape[-1]
    if col.data_type in _TEXT:
        text = np.ascontiguousarray(field).view(f"S{width}")[..., 0]
        try:
            return np.char.strip(text).astype(str)
        except UnicodeDecodeError as exc:
            raise _err(f"non-ASCII text in column {col.name}", lay.data_path,
                       column=col.name) from exc
    as_int = col.data_type in _ASCII_INT
    dtype, convert = (np.int64, int) if as_int else (np.float64, float)
    flat = field.reshape(-1, width)
    values, ok = parse_ints(flat) if as_int else parse_reals(flat, pow10())
    if not ok.all():  # rows off the compiled fast path: numpy's exact parser
        slow = np.flatnonzero(~ok)
        slow_text = np.ascontiguousarray(flat[slow]).view(f"S{width}")[:, 0]
        try:
            values[slow] = slow_text.astype(dtype)
        except ValueError:
            i = int(slow[_first_bad(slow_text, convert)])
            row = i // field.shape[1] + 1
            what = "an integer" if as_int else "a number"
            bad = bytes(flat[i]).decode("ascii", "replace").strip()
            raise _err(f"row {row}: {bad!r} is not {what} ({col.data_type})", lay.data_path,
                       lay.record(row), col.name) from None
    return values.reshape(field.shape[:-1])


def _binary_values(field: np.ndarray, col: _Column) -> np.ndarray:
    kind, order = _BINARY[col.data_type]
    dtype = np.dtype(f"{order}{kind}{col.item_bytes}")
    values = np.ascontiguousarray(field).view(dtype)[..., 0]
    return values.astype(dtype.newbyteorder("="))


def _column_values(raw: np.ndarray, col: _Column, lay: _Layout) -> np.ndarray:
    s = lay.prefix + col.start
    if col.items is None:
        field = raw[:, s:s + col.nbytes][:, None, :]
    else:
        idx = s + np.arange(col.items)[:, None] * col.item_offset + np.arange(col.item_bytes)
        field = raw[:, idx]  # (rows, items, item_bytes)
    if lay.ascii or col.data_type in _TEXT or col.data_type not in _BINARY:
        values = _ascii_values(field, col, lay)
    else:
        values = _binary_values(field, col)
    if col.items is None:
        values = values[:, 0]
    if values.dtype.kind in "iuf" and (col.constants or col.scale is not None
                                       or col.offset is not None):
        stored = values
        values = stored.astype(np.float64)
        if col.constants:
            # compare in the stored type (a float32 -1e32 is not the float64 -1e32)
            consts = np.array(col.constants, dtype=stored.dtype if stored.dtype.kind == "f"
                              else np.float64)
            values[np.isin(stored, consts)] = np.nan
        if col.scale is not None:
            values *= col.scale
        if col.offset is not None:
            values += col.offset
    return values


# --- public readers ---------------------------------------------------------------------


def read_table(
    label_path: Path | str,
    table: str | None = None,
    *,
    columns: Sequence[str] | None = None,
    required: Sequence[str] = (),
    label: Mapping[str, Any] | None = None,
) -> xr.Dataset:
    """Read one PDS3 table, as its label describes it, into an xarray Dataset.

    Parameters
    ----------
    label_path : Path
        The detached label (``.LBL``), or the data file with an attached label, or a
        data file with its ``.LBL`` beside it (`find_label`).
    table : str, optional
        Name of the table object (``TABLE``, ``MAG_TABLE``...); needed only when the
        label points to several.
    columns : sequence of str, optional
        Read only these columns (label names), in this order; default all.
    required : sequence of str
        Column names that must be in the label.
    label : mapping, optional
        The label of ``label_path`` already parsed by `read_label` (parsed again when
        not given; pvl takes a sizeable fraction of a second per label).

    Returns
    -------
    xarray.Dataset
        Dimension ``row``; one variable per column (see the module docstring).

    Raises
    ------
    InputFormatError
        Naming the file, the row (``line``: the data file's record) and the column:
        malformed label, missing pointer/object/keyword, missing data file, a required
        column not in the label, record length not matching the rows, truncated file,
        file with more rows than ``ROWS``, a field that is not a number.

    References
    ----------
    PDS3 Standards Reference, ch. 5 (pointers), ch. 15 (TABLE, COLUMN), Appendix C.
    """
    label_path = find_label(label_path)
    if label is None:
        label = read_label(label_path)
    lay = _layout(label, label_path, table)
    by_name = {c.name: c for c in lay.columns}
    wanted = list(required) + [n for n in (columns or ()) if n not in required]
    missing = [n for n in wanted if n not in by_name]
    if missing:
        raise _err(f"column(s) {', '.join(missing)} not in table {lay.name} (it has "
                   f"{', '.join(by_name)})", label_path, column=missing[0])
    selected = [by_name[n] for n in columns] if columns is not None else list(lay.columns)
    raw = _read_bytes(label, lay)
    data: dict[str, xr.Variable] = {}
    for col in selected:
        values = _column_values(raw, col, lay)
        dims = (ROW_DIM,) if values.ndim == 1 else (ROW_DIM, f"{col.name}_item")
        data[col.name] = xr.Variable(dims, values, dict(col.attrs))
    attrs = {str(k): _attr_value(v) for k, v in label.items()
             if not isinstance(v, Mapping)}
    attrs.update(pds3_label=str(label_path), pds3_data_file=str(lay.data_path),
                 pds3_table=lay.name)
    return xr.Dataset(data, attrs=attrs)


def read_table_columns(
    label_path: Path | str,
    names: Mapping[str, str],
    table: str | None = None,
) -> xr.Dataset:
    """Read the columns ``names`` (label NAME -> variable name) of a table, renamed.

    Raises
    ------
    InputFormatError
        Naming the label and the first missing column when a label NAME is absent
        (and everything `read_table` raises).
    """
    ds = read_table(label_path, table, columns=list(names), required=list(names))
    renamed = ds.rename({k: v for k, v in names.items() if k != v})
    item_dims = {f"{k}_item": f"{v}_item" for k, v in names.items()
                 if k != v and f"{k}_item" in ds.dims}
    return renamed.rename_dims(item_dims) if item_dims else renamed
