"""Readers of archived calibrated magnetometer products into fluxcal's Dataset shape.

`read_product` reads a PDS3 table (`fluxcal.archive.pds3.read_table`) and hands it to
the first `ArchivedReader` whose `ArchivedReader.matches` accepts the label's column
names -- the label is the source of truth.  Each mission ships its reader (its file
names, columns and frames) in its own folder; the readers are an argument
(``readers``, name -> `ArchivedReader`) that the caller passes down: the command line and
``fluxcal.read_product`` pass every registered mission's (issue 32).  Nothing here looks
missions up.

Every Dataset has dimension ``time``, the int64 TT2000 coordinate ``epoch`` and the
indexed UTC ``time`` (`fluxcal.products.timeindex.with_time_index`); ``b`` carries
``units`` and ``frame`` / ``coordinate_system`` when the frame is known (label keyword
``COORDINATE_SYSTEM_NAME``, fluxcal's ``output_frame`` attribute, or the product type);
``b_total`` is ``|b|``; the dataset attrs hold the label keywords, the decoded fluxcal
``DATASET_ATTRIBUTES`` when present, and what the reader adds (``mission``,
``product_type``, ...).  See docs/formats/archive.md for what is confirmed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.archive.pds3 import find_label, read_label, read_table
from fluxcal.errors import InputFormatError
from fluxcal.products.label import decode_attributes, find_objects
from fluxcal.products.timeindex import with_time_index

__all__ = ["ArchivedReader", "FRAME_CODES", "frame_code", "frame_codes", "identify",
           "normalise_frame", "read_product"]

#: Frame codes of the frames that belong to no mission.
FRAME_CODES = {"J2000": "J2000", "ECLIPJ2000": "ECLIPJ2000"}

#: What a reader's ``read`` returns: data variables, coordinates and dataset attrs.
Parts = tuple[dict[str, Any], dict[str, Any], dict[str, Any]]


@dataclass(frozen=True)
class ArchivedReader:
    """How one kind of archived calibrated table is recognised and read.

    Attributes
    ----------
    description : str
        What the reader reads, for the error on a table no reader accepts (e.g. the
        product names and the columns it recognises them by).
    matches : callable
        ``matches(columns) -> bool`` from the table's column names.
    read : callable
        ``read(table, label_path, product_id, stem, keywords, fluxcal_attrs) ->
        (data, coords, attrs)``: the variables (``b`` with dimension ``time`` first),
        coordinates (``epoch``) and dataset attrs of the product.
    frame_codes : mapping
        SPICE frame name -> the frame code fluxcal's products use (``MSO``, ...).
    """

    description: str
    matches: Callable[[list[str]], bool]
    read: Callable[..., Parts]
    frame_codes: Mapping[str, str] = field(default_factory=dict)


def frame_codes(readers: Mapping[str, ArchivedReader] | None = None) -> dict[str, str]:
    """Return SPICE frame name -> frame code of the generic frames and of ``readers``."""
    out = dict(FRAME_CODES)
    for reader in (readers or {}).values():
        out.update(reader.frame_codes)
    return out


def normalise_frame(name: Any, readers: Mapping[str, ArchivedReader] | None = None
                    ) -> str | None:
    """Return the frame code of a frame name (a mission's MSO frame -> ``MSO``), None if empty.

    Case and a trailing description in parentheses (``<NAME> (URF)``) are ignored;
    unknown names are returned upper-cased.  The codes are `frame_codes` of
    ``readers`` (default: the generic frames only).
    """
    return frame_code(name, frame_codes(readers))


def frame_code(name: Any, codes: Mapping[str, str]) -> str | None:
    """Return ``codes[name]`` for a frame name (case and ``(...)`` ignored), None if empty.

    Unknown names are returned upper-cased.
    """
    if name is None:
        return None
    text = str(name).split("(")[0].strip().upper()
    if not text or text in ("N/A", "UNK", "UNKNOWN"):
        return None
    return codes.get(text, text)


def identify(columns: list[str], readers: Mapping[str, ArchivedReader]) -> str:
    """Return the name of the first reader that accepts a table's column names (or raise)."""
    for name, reader in readers.items():
        if reader.matches(columns):
            return name
    if not readers:
        raise InputFormatError("no archived-product reader is registered; it has "
                               f"{' '.join(columns)}")
    kinds = " or ".join(reader.description for reader in readers.values())
    raise InputFormatError(f"not an archived {kinds}; it has {' '.join(columns)}")


def need_columns(table: xr.Dataset, names: tuple[str, ...], label: Path) -> list[np.ndarray]:
    """Return the values of columns ``names``; raise naming the first one missing."""
    missing = [n for n in names if n not in table]
    if missing:
        raise InputFormatError(f"column {missing[0]} is missing (needed: {' '.join(names)})",
                               path=str(label), field=missing[0])
    return [table[n].values for n in names]


def first_set(table: xr.Dataset, options: tuple[tuple[str, ...], ...]) -> tuple[str, ...] | None:
    """Return the first column set of ``options`` whose first column the table has."""
    for names in options:
        if names[0] in table:
            return names
    return None


def check_range(values: np.ndarray, lo: float, hi: float, name: str, label: Path) -> None:
    """Raise naming row and column when a value of ``values`` lies outside ``lo..hi``."""
    bad = np.flatnonzero(~((values >= lo) & (values <= hi)))
    if bad.size:
        row = int(bad[0]) + 1
        raise InputFormatError(f"row {row}: {name} = {values[bad[0]]} is outside {lo}..{hi}",
                               path=str(label), line=row, field=name)


def fluxcal_attrs(label: Mapping[str, Any]) -> dict[str, Any]:
    """Return the decoded fluxcal ``DATASET_ATTRIBUTES`` object of a label, or ``{}``."""
    objs = find_objects(label, "DATASET_ATTRIBUTES")
    return decode_attributes(objs[0]) if objs else {}


def vector_variable(table: xr.Dataset, names: tuple[str, ...], dim: str, labels: list[str],
                    attrs: dict[str, Any], label: Path) -> xr.DataArray:
    """Return columns ``names`` as one (time, ``dim``) variable with the first's units."""
    cols = need_columns(table, names, label)
    values = np.stack([np.asarray(c, dtype=np.float64) for c in cols], axis=1)
    return xr.DataArray(values, dims=("time", dim), coords={dim: labels},
                        attrs={**attrs, "units": table[names[0]].attrs.get("units", "")})


def read_product(path: Path | str, readers: Mapping[str, ArchivedReader]) -> xr.Dataset:
    """Read an archived calibrated product (``.TAB`` + ``.LBL``) into fluxcal's shape.

    Parameters
    ----------
    path : Path
        The ``.LBL`` or the ``.TAB`` (with its label beside it, or attached).
    readers : mapping of name -> ArchivedReader
        The readers to try, in order (the command line passes every registered
        mission's).

    Returns
    -------
    xarray.Dataset
        See the module docstring (``time`` index, ``epoch``, ``b``, ...).

    Raises
    ------
    InputFormatError
        Everything `fluxcal.archive.pds3.read_table` raises; a table no reader accepts;
        what the reader raises (a needed column missing, a time field out of range,
        naming row and column).
    """
    label_path = find_label(path)
    label = read_label(label_path)
    table = read_table(label_path, label=label)
    try:
        kind = identify([str(n) for n in table.data_vars], readers)
    except InputFormatError as exc:
        raise InputFormatError(str(exc), path=str(label_path)) from exc
    stem = Path(str(table.attrs.get("pds3_data_file", label_path))).stem
    product_id = str(table.attrs.get("PRODUCT_ID", stem))
    keywords = {k: v for k, v in table.attrs.items()}
    fluxcal = fluxcal_attrs(label)
    data, coords, attrs = readers[kind].read(table, label_path, product_id, stem, keywords,
                                             fluxcal)
    ds = xr.Dataset(data, coords=coords)
    ds["b_total"] = ("time", np.sqrt((ds["b"].values ** 2).sum(axis=1)),
                     {"units": ds["b"].attrs.get("units", ""), "description": "|B|"})
    ds.attrs = {**fluxcal, **keywords, **attrs}
    return with_time_index(ds)
