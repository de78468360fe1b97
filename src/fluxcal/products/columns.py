"""Table columns: which dataset variable goes to which column, printed how.

A `Column` names a variable (or a coordinate along ``time``, e.g. ``epoch``) of the
Dataset.  A vector variable with dims ``("time", "component")`` expands into one
column per component unless ``component`` picks one.  Column names in the label are
``f"{name}_{c}"`` (``B_mso_x``, ``B_mso_y``, ``B_mso_z``) or, if ``label`` is given,
``label.format(c=c)`` for a vector (``label="B{c}"`` gives ``Bx``, ``By``, ``Bz``)
and ``label`` itself for a scalar.

Formats are FORTRAN edit descriptors, as a PDS3 label states them: ``Iw`` (``Iw.m``:
at least ``m`` digits, zero-padded, e.g. ``I3.3`` prints day 5 as ``005``), ``Fw.d``,
``Ew.d`` and ``Aw``.  The printf forms callers used before (``%4d``, ``%03d``,
``%10.3f``, ``%06.3f``, ``%15.7e``, ``%s``, ``%-22s``, ``%d``) are accepted and mapped
(`parse_format`); the label always says FORTRAN.  Every column has a fixed width.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError

TIME_DIM = "time"


@dataclass(frozen=True)
class Column:
    """One variable of the Dataset printed as one (scalar) or three (vector) columns.

    Parameters
    ----------
    name : str
        Data variable or coordinate of the Dataset (first dimension ``time``).
    fmt : str
        FORTRAN format of one value (``"F10.3"``, ``"I4"``, ``"I3.3"``, ``"E15.7"``,
        ``"A23"``) or the equivalent printf form (``"%10.3f"``, ``"%4d"``, ``"%03d"``,
        ``"%15.7e"``, ``"%-23s"``).  ``"%d"``/``"%s"`` without a width and ``None``
        pick an exact fixed width: ``I`` wide enough for the integer dtype (``I20``
        for int64), ``E24.16`` for floats (17 significant digits: round-trips every
        float64), ``A`` as wide as the longest string.
    unit : str
        Unit written in the label; ``""`` takes the variable's ``units`` attr.
    description : str
        Description written in the label; ``""`` takes the variable's
        ``description`` (or ``long_name``) attr.
    component : str, optional
        For a vector variable: print only this component (e.g. ``"x"``).
    label : str, optional
        Column name in the label (``{c}`` is replaced by the component).
    fill : float, optional
        Printed instead of NaN values (recorded as ``MISSING_CONSTANT``); it must fit
        the format.  Without a fill, NaN is printed as ``NaN``.
    data_type : str, optional
        PDS3 ``DATA_TYPE`` for the label (default by kind: ``ASCII_INTEGER``,
        ``ASCII_REAL``, ``CHARACTER``), e.g. ``"TIME"`` for a UTC string column.
    """

    name: str
    fmt: str | None = None
    unit: str = ""
    description: str = ""
    component: str | None = None
    label: str | None = None
    fill: float | None = None
    data_type: str | None = None


@dataclass(frozen=True)
class FieldFormat:
    """A fixed-width FORTRAN edit descriptor.

    ``code`` is ``"I"``, ``"F"``, ``"E"`` or ``"A"``; ``width`` the field width in
    bytes; ``decimals`` the digits after the point (``F``, ``E``) or the minimum
    number of digits (``I``, 1 when not given); ``zero_pad`` keeps printf's ``0``
    flag for ``F`` (``%06.3f`` prints ``05.123``; the label says ``F6.3``).
    """

    code: str
    width: int
    decimals: int = 0
    zero_pad: bool = False

    @property
    def fortran(self) -> str:
        """The descriptor as the label states it (``I4``, ``I3.3``, ``F10.3``, ``A23``)."""
        if self.code == "A" or (self.code == "I" and self.decimals <= 1):
            return f"{self.code}{self.width}"
        return f"{self.code}{self.width}.{self.decimals}"


_FORTRAN = re.compile(r"^([IFEA])(\d+)(?:\.(\d+))?$", re.I)
_PRINTF = re.compile(r"^%(-?)(0?)(\d*)(?:\.(\d+))?([dfeEs])$")
_INT_WIDTH = {
    np.dtype(t): len(str(np.iinfo(t).min if np.dtype(t).kind == "i" else np.iinfo(t).max))
    for t in (np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64)
}
MAX_E_DECIMALS = 16  # E24.16: 17 significant digits, enough for any float64
DEFAULT_REAL = FieldFormat("E", 24, 16)
_DEFAULT_NAMES = (None, "%d", "%s", "%.17g")


def parse_format(fmt: str | None, kind: str, dtype: np.dtype, str_width: int = 1,
                 field: str | None = None) -> FieldFormat:
    """Map a FORTRAN or printf format (or ``None``) to a `FieldFormat` for one column.

    Parameters
    ----------
    fmt : str or None
        ``"F10.3"``/``"%10.3f"`` etc.; ``None`` (or ``"%d"``, ``"%s"``, ``"%.17g"``)
        picks the exact default of the kind.
    kind : {"int", "real", "str"}
        What the column holds (`ResolvedColumn.kind`).
    dtype : numpy.dtype
        The variable's dtype (sets the default integer width).
    str_width : int
        Length of the longest string value (the default ``A`` width).
    field : str, optional
        Column name for error messages.

    Returns
    -------
    FieldFormat

    Raises
    ------
    InputFormatError
        Unknown format, no width, or a format that does not suit the values (``I`` or
        ``A`` for reals, ``F``/``E``/``I`` for strings, ``E`` with more than 16
        decimals).
    """
    if fmt in _DEFAULT_NAMES:
        if kind == "int":
            width = 1 if np.dtype(dtype).kind == "b" else _INT_WIDTH[np.dtype(dtype)]
            ff = FieldFormat("I", width, 1)
        elif kind == "real":
            ff = DEFAULT_REAL
        else:
            ff = FieldFormat("A", max(1, str_width))
    elif m := _FORTRAN.match(fmt):
        code, width, dec = m.group(1).upper(), int(m.group(2)), m.group(3)
        if code == "A" and dec is not None:
            raise InputFormatError(f"format {fmt!r}: A takes no decimals", field=field)
        ff = FieldFormat(code, width, int(dec) if dec is not None else int(code == "I"))
    elif m := _PRINTF.match(fmt):
        _left, zero, width, dec, conv = m.groups()  # strings are always left-justified
        if not width:
            raise InputFormatError(f"format {fmt!r} has no width; a PDS3 table needs a "
                                   "fixed width (e.g. 'F10.3' or '%10.3f')", field=field)
        w = int(width)
        if conv == "d":
            ff = FieldFormat("I", w, int(dec) if dec is not None else (w if zero else 1))
        elif conv == "s":
            ff = FieldFormat("A", w)
        elif conv == "f":
            ff = FieldFormat("F", w, 6 if dec is None else int(dec), zero_pad=bool(zero))
        else:
            if zero:
                raise InputFormatError(f"format {fmt!r}: zero-padded E is not supported",
                                       field=field)
            ff = FieldFormat("E", w, 6 if dec is None else int(dec))
    else:
        raise InputFormatError(f"unknown column format {fmt!r}; expected FORTRAN Iw, Iw.m, "
                               "Fw.d, Ew.d, Aw or the printf forms %wd, %w.df, %w.de, %ws",
                               field=field)
    allowed = {"int": "IFE", "real": "FE", "str": "A"}[kind]
    if ff.code not in allowed:
        raise InputFormatError(f"format {fmt!r} ({ff.fortran}) cannot print {kind} values "
                               f"(allowed: {', '.join(allowed)})", field=field)
    if ff.width < 1 or ff.decimals > 22:
        raise InputFormatError(f"format {fmt!r}: width must be >= 1 and decimals <= 22",
                               field=field)
    if ff.code == "E" and ff.decimals > MAX_E_DECIMALS:
        raise InputFormatError(f"format {fmt!r}: E takes at most {MAX_E_DECIMALS} decimals "
                               "(17 significant digits hold any float64)", field=field)
    return ff


@dataclass(frozen=True)
class ResolvedColumn:
    """A single printed column: the variable, the component (if any) and its metadata."""

    variable: str
    component: str | None
    index: int | None
    label: str
    fmt: FieldFormat
    unit: str
    description: str
    kind: str  # "int", "real" or "str"
    fill: float | None
    data_type: str | None = None


def _kind(dtype: np.dtype) -> str:
    if np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.bool_):
        return "int"
    if np.issubdtype(dtype, np.floating):
        return "real"
    if dtype.kind in "USO":
        return "str"
    raise InputFormatError(f"dtype {dtype} cannot be printed in a table", field=str(dtype))


def _max_str_len(values: np.ndarray) -> int:
    if values.size == 0:
        return 1
    if values.dtype.kind in "US":
        return max(1, int(np.char.str_len(values).max()))
    return max(1, max(len(str(v)) for v in values.ravel().tolist()))


def default_columns(ds: xr.Dataset) -> list[Column]:
    """Columns for every time-dependent coordinate and data variable, exact formats."""
    names = [n for n in ds.coords if ds[n].dims[:1] == (TIME_DIM,) and n != TIME_DIM]
    names += [n for n in ds.data_vars if ds[n].dims[:1] == (TIME_DIM,)]
    return [Column(str(n)) for n in names]


def resolve_columns(ds: xr.Dataset, columns: Sequence[Column] | None) -> list[ResolvedColumn]:
    """Expand ``columns`` over ``ds`` into single printed columns.

    Raises
    ------
    InputFormatError
        If a column names a missing variable, a variable not along ``time``, a
        variable with more than one extra dimension, an unknown component, or a
        format that does not suit the variable (`parse_format`).
    """
    if columns is None:
        columns = default_columns(ds)
    out: list[ResolvedColumn] = []
    for col in columns:
        if col.name not in ds.variables:
            raise InputFormatError(
                f"column names variable {col.name!r}, not in the dataset "
                f"(have {sorted(map(str, ds.variables))})",
                field=col.name,
            )
        var = ds[col.name]
        if var.dims[:1] != (TIME_DIM,) or var.ndim > 2:
            raise InputFormatError(
                f"variable {col.name!r} has dims {var.dims}; expected ('time',) or "
                "('time', <component dim>)",
                field=col.name,
            )
        kind = _kind(var.dtype)
        str_width = _max_str_len(var.values) if kind == "str" and col.fmt in _DEFAULT_NAMES \
            else 1
        fmt = parse_format(col.fmt, kind, var.dtype, str_width, col.name)
        unit = col.unit or str(var.attrs.get("units", ""))
        desc = col.description or str(
            var.attrs.get("description", var.attrs.get("long_name", ""))
        )
        if var.ndim == 1:
            if col.component is not None:
                raise InputFormatError(
                    f"component {col.component!r} given for scalar variable {col.name!r}",
                    field=col.name,
                )
            out.append(
                ResolvedColumn(col.name, None, None, col.label or col.name, fmt, unit, desc,
                               kind, col.fill, col.data_type)
            )
            continue
        cdim = var.dims[1]
        comps = [str(c) for c in ds[cdim].values] if cdim in ds.coords else [
            str(i) for i in range(var.shape[1])
        ]
        wanted = comps if col.component is None else [col.component]
        for c in wanted:
            if c not in comps:
                raise InputFormatError(
                    f"component {c!r} not in {comps} of variable {col.name!r}", field=col.name
                )
            label = col.label.format(c=c) if col.label else f"{col.name}_{c}"
            out.append(
                ResolvedColumn(col.name, c, comps.index(c), label, fmt, unit, desc, kind,
                               col.fill, col.data_type)
            )
    labels = [c.label for c in out]
    dupes = {x for x in labels if labels.count(x) > 1}
    if dupes:
        raise InputFormatError(f"duplicate column names {sorted(dupes)}", field=sorted(dupes)[0])
    return out
