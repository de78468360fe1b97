"""Table columns: which dataset variable goes to which column, printed how.

A `Column` names a variable (or a coordinate along ``time``, e.g. ``epoch``) of the
Dataset.  A vector variable with dims ``("time", "component")`` expands into one
column per component unless ``component`` picks one.  Column names in the label are
``f"{name}_{c}"`` (``B_mso_x``, ``B_mso_y``, ``B_mso_z``) or, if ``label`` is given,
``label.format(c=c)`` for a vector (``label="B{c}"`` gives ``Bx``, ``By``, ``Bz``)
and ``label`` itself for a scalar.
"""

from __future__ import annotations

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
        printf format of one value, e.g. ``"%10.3f"``, ``"%d"``, ``"%s"``.  Give a
        width to make the table fixed-width.  ``None`` picks an exact default by
        dtype (``%.17g`` for floats, ``%d`` for integers, ``%s`` for strings).
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
        Printed instead of NaN values (recorded as ``MISSING_CONSTANT``).
    """

    name: str
    fmt: str | None = None
    unit: str = ""
    description: str = ""
    component: str | None = None
    label: str | None = None
    fill: float | None = None


@dataclass(frozen=True)
class ResolvedColumn:
    """A single printed column: the variable, the component (if any) and its metadata."""

    variable: str
    component: str | None
    index: int | None
    label: str
    fmt: str
    unit: str
    description: str
    kind: str  # "int", "real" or "str"
    fill: float | None


def _kind(dtype: np.dtype) -> str:
    if np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.bool_):
        return "int"
    if np.issubdtype(dtype, np.floating):
        return "real"
    if dtype.kind in "USO":
        return "str"
    raise InputFormatError(f"dtype {dtype} cannot be printed in a table", field=str(dtype))


_DEFAULT_FMT = {"int": "%d", "real": "%.17g", "str": "%s"}


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
        variable with more than one extra dimension, or an unknown component.
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
        fmt = col.fmt or _DEFAULT_FMT[kind]
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
                               kind, col.fill)
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
                               col.fill)
            )
    labels = [c.label for c in out]
    dupes = {x for x in labels if labels.count(x) > 1}
    if dupes:
        raise InputFormatError(f"duplicate column names {sorted(dupes)}", field=sorted(dupes)[0])
    return out
