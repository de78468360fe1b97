"""Readers of archived calibrated magnetometer products into fluxcal's Dataset shape.

`read_product` reads a PDS3 table (`fluxcal.archive.pds3.read_table`) and maps the
label's column names -- the label is the source of truth -- to the variables of
fluxcal's own products:

* **MESSENGER MAG CDR / RDR** (``MAG<FFF>SCI<yyddd>_V<nn>``, 12 columns
  ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG X Y Z BX BY BZ``;
  ``MAG<FFF>SCIAVG<yyddd>_<NN>_V<nn>``, 16 columns with ``NAVG`` and ``DBX DBY DBZ``;
  RTN: ``R LATITUDE AZIMUTH``, ``BR BT BN``; SC: no position) ->
  ``epoch``, ``met``, ``b`` (time, b_component ``B_X B_Y B_Z`` / ``B_R B_T B_N``),
  ``b_total``, ``position`` (time, position_component) or ``r``, ``latitude``,
  ``azimuth``, and for averages ``count`` and ``b_std``.  The archived tables have no
  quality column (the SHC flag is in the label): ``quality`` exists only when the table
  has a ``QUALITY`` column.
* **Rosetta RPC-MAG CALIBRATED / RESAMPLED** (``RPCMAG<yymmdd>T<hhmm>_CL<A|B|C>_<IB|OB>_M<mode>``,
  ``RPCMAG<yymmdd>_CL<E|F|G>_<IB|OB>_A<NN>``; columns ``TIME.UTC TIME.OBT
  [POSITION.X/Y/Z] BX BY BZ [T] QUALITY``) -> ``epoch``, ``obt``, ``b`` (time,
  component ``x y z``), ``b_total``, ``position``, ``temperature``, ``quality`` (an
  integer, or the text of the V9 8-digit quality string when the label says CHARACTER).

Every Dataset has dimension ``time``, the int64 TT2000 coordinate ``epoch`` and the
indexed UTC ``time`` (`fluxcal.products.timeindex.with_time_index`); ``b`` carries
``units`` and ``frame`` / ``coordinate_system`` when the frame is known (label keyword
``COORDINATE_SYSTEM_NAME``, fluxcal's ``output_frame`` attribute, or the product type);
the dataset attrs hold the label keywords, the decoded fluxcal ``DATASET_ATTRIBUTES``
when present, and ``mission``, ``product_type``, ``level``, ``sensor``,
``average_seconds`` from the name.  See docs/formats/archive.md for what is confirmed.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12 (CDR/RDR content).
.. [2] RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 4.2-4.8 (level tables).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.archive.pds3 import find_label, read_label, read_table
from fluxcal.errors import InputFormatError

__all__ = ["FRAME_CODES", "identify", "normalise_frame", "read_product"]

_MSGR_NAME = re.compile(r"MAG(?P<frame>[A-Z0-9]+?)SCI(?P<avg>AVG)?(?P<yyddd>\d{5})"
                        r"(?:_(?P<seconds>\d{2}))?_V(?P<version>\d{2})", re.IGNORECASE)
_ROS_NAME = re.compile(r"RPCMAG(?P<date>\d{6})(?:T(?P<hhmm>\d{4}))?_CL(?P<level>[A-Z])_"
                       r"(?P<sensor>IB|OB)_(?:M(?P<mode>\d+)|A(?P<avg>[0-9p]+))",
                       re.IGNORECASE)
_MSGR_TIME = ("YEAR", "DAY_OF_YEAR", "HOUR", "MINUTE", "SECOND")

#: SPICE frame names and the frame codes fluxcal's products use for them.
FRAME_CODES = {"MSGR_MSO": "MSO", "IAU_MERCURY": "MBF", "MSGR_RTN": "RTN",
               "MSGR_SPACECRAFT": "SC", "MSGR_VSO": "VSO", "J2000": "J2000",
               "67P/C-G_CSEQ": "CSEQ", "ECLIPJ2000": "ECLIPJ2000",
               "ROS_SPACECRAFT": "ROS_SPACECRAFT"}
#: Rosetta levels whose frame follows from the level (sec. 4.2-4.8).
_ROSETTA_FRAMES = {"A": "ROS_RPC_MAG_{sensor}", "E": "ROS_RPC_MAG_{sensor}",
                   "B": "ROS_SPACECRAFT", "F": "ROS_SPACECRAFT"}


def normalise_frame(name: Any) -> str | None:
    """Return the frame code of a frame name (``MSGR_MSO`` -> ``MSO``), None if empty.

    Case and a trailing description in parentheses (``ROS_RPC_MAG_OB (URF)``) are
    ignored; unknown names are returned upper-cased.
    """
    if name is None:
        return None
    text = str(name).split("(")[0].strip().upper()
    if not text or text in ("N/A", "UNK", "UNKNOWN"):
        return None
    return FRAME_CODES.get(text, text)


def identify(columns: list[str]) -> str:
    """Return ``"messenger"`` or ``"rosetta"`` from a table's column names (or raise)."""
    if all(c in columns for c in _MSGR_TIME):
        return "messenger"
    if "TIME.UTC" in columns:
        return "rosetta"
    raise InputFormatError(
        "not an archived MESSENGER MAG CDR/RDR (columns YEAR DAY_OF_YEAR HOUR MINUTE "
        "SECOND) or Rosetta RPC-MAG CALIBRATED/RESAMPLED table (column TIME.UTC); it has "
        f"{' '.join(columns)}")


def _need(table: xr.Dataset, names: tuple[str, ...], label: Path) -> list[np.ndarray]:
    missing = [n for n in names if n not in table]
    if missing:
        raise InputFormatError(f"column {missing[0]} is missing (needed: {' '.join(names)})",
                               path=str(label), field=missing[0])
    return [table[n].values for n in names]


def _first_set(table: xr.Dataset, options: tuple[tuple[str, ...], ...]) -> tuple[str, ...] | None:
    for names in options:
        if names[0] in table:
            return names
    return None


def _check_range(values: np.ndarray, lo: float, hi: float, name: str, label: Path) -> None:
    bad = np.flatnonzero(~((values >= lo) & (values <= hi)))
    if bad.size:
        row = int(bad[0]) + 1
        raise InputFormatError(f"row {row}: {name} = {values[bad[0]]} is outside {lo}..{hi}",
                               path=str(label), line=row, field=name)


def messenger_epoch(year: np.ndarray, doy: np.ndarray, hour: np.ndarray, minute: np.ndarray,
                    second: np.ndarray, label: Path | None = None) -> np.ndarray:
    """TT2000 (int64 ns) from the UTC fields of a MESSENGER table, exact to the ms.

    ``SECOND`` is printed with three decimals (milliseconds); it is rounded to the
    nearest millisecond (removing the float's representation error).  A second
    ``60.xxx`` is read as a leap second (the last second of a day that ends with one).

    Raises
    ------
    InputFormatError
        A field out of range (DAY_OF_YEAR 1..366, HOUR 0..23, MINUTE 0..59, SECOND
        0..<61), naming the row and column.
    """
    from fluxcal.geometry.time import utc_fields_to_tt2000
    from fluxcal.products.timeindex import default_lsk

    where = label or Path("table")
    for values, lo, hi, name in ((doy, 1, 366, "DAY_OF_YEAR"), (hour, 0, 23, "HOUR"),
                                 (minute, 0, 59, "MINUTE"), (second, 0, 60.999, "SECOND")):
        _check_range(np.asarray(values), lo, hi, name, where)
    ms = np.rint(np.asarray(second, dtype=np.float64) * 1000.0)
    return utc_fields_to_tt2000(year, doy, hour, minute, ms / 1000.0, default_lsk())


def _fluxcal_attrs(label: Mapping[str, Any]) -> dict[str, Any]:
    from fluxcal.products.label import decode_attributes, find_objects

    objs = find_objects(label, "DATASET_ATTRIBUTES")
    return decode_attributes(objs[0]) if objs else {}


def _vector(table: xr.Dataset, names: tuple[str, ...], dim: str, labels: list[str],
            attrs: dict[str, Any], label: Path) -> xr.DataArray:
    cols = _need(table, names, label)
    values = np.stack([np.asarray(c, dtype=np.float64) for c in cols], axis=1)
    return xr.DataArray(values, dims=("time", dim), coords={dim: labels},
                        attrs={**attrs, "units": table[names[0]].attrs.get("units", "")})


def _messenger(table: xr.Dataset, label: Path, name: re.Match | None,
               keywords: Mapping[str, Any]) -> tuple[dict, dict, dict]:
    y, d, h, m, s = _need(table, _MSGR_TIME, label)
    epoch = messenger_epoch(y, d, h, m, s, label)
    axes = _first_set(table, (("BX", "BY", "BZ"), ("BR", "BT", "BN"))) or ("BX", "BY", "BZ")
    rtn = axes[0] == "BR"
    frame = normalise_frame(keywords.get("COORDINATE_SYSTEM_NAME")) \
        or (normalise_frame(name.group("frame")) if name else None) or ("RTN" if rtn else None)
    b_labels = [f"B_{a[-1]}" for a in axes]
    battrs = {"description": "magnetic field"}
    if frame:
        battrs.update(frame=frame, coordinate_system=frame)
    data: dict[str, Any] = {"b": _vector(table, axes, "b_component", b_labels, battrs, label)}
    if "TIME_TAG" in table:
        data["met"] = ("time", table["TIME_TAG"].values.astype(np.float64),
                       {"units": "s", "description": "lag-corrected MET (TIME_TAG)"})
    if "NAVG" in table:
        data["count"] = ("time", table["NAVG"].values, {"units": "1",
                                                        "description": "samples averaged"})
    std = tuple("D" + a for a in axes)
    if std[0] in table:
        data["b_std"] = _vector(table, std, "b_component", b_labels,
                                {"description": "standard deviation of the field"}, label)
    if "R" in table and "LATITUDE" in table:
        r, lat, az = _need(table, ("R", "LATITUDE", "AZIMUTH"), label)
        data.update(r=("time", r, table["R"].attrs), latitude=("time", lat,
                    table["LATITUDE"].attrs), azimuth=("time", az, table["AZIMUTH"].attrs))
    elif "X" in table:
        data["position"] = _vector(table, ("X", "Y", "Z"), "position_component",
                                   ["X", "Y", "Z"], {"description": "position"}, label)
    if "QUALITY" in table:
        data["quality"] = ("time", table["QUALITY"].values, {"units": "1"})
    attrs = {"mission": "MESSENGER", "product_type": "RDR" if "NAVG" in table else "CDR"}
    seconds = keywords.get("AVERAGING_INTERVAL_S") or (name.group("seconds") if name else None)
    if seconds is not None and "NAVG" in table:
        attrs["average_seconds"] = float(seconds)
    return data, {"epoch": ("time", epoch)}, attrs


def _rosetta(table: xr.Dataset, label: Path, name: re.Match | None,
             keywords: Mapping[str, Any], fluxcal: Mapping[str, Any]) -> tuple[dict, dict, dict]:
    from fluxcal.geometry.time import utc_to_tt2000
    from fluxcal.products.timeindex import default_lsk

    (utc,) = _need(table, ("TIME.UTC",), label)
    try:
        epoch = utc_to_tt2000(utc, default_lsk())
    except InputFormatError as exc:
        raise InputFormatError(str(exc), path=str(label), field="TIME.UTC") from exc
    level = (name.group("level").upper() if name else
             str(keywords.get("LEVEL", "")).replace("LEVEL_", "").upper() or None)
    sensor = (name.group("sensor").upper() if name else
              str(keywords.get("SENSOR", "")).upper() or None)
    frame = normalise_frame(keywords.get("COORDINATE_SYSTEM_NAME")) \
        or normalise_frame(fluxcal.get("output_frame"))
    if frame is None and level in _ROSETTA_FRAMES and sensor:
        frame = _ROSETTA_FRAMES[level].format(sensor=sensor)
    battrs = {"description": "magnetic field"}
    if frame:
        battrs.update(frame=frame, coordinate_system=frame)
    data: dict[str, Any] = {"b": _vector(table, ("BX", "BY", "BZ"), "component",
                                         ["x", "y", "z"], battrs, label)}
    if "TIME.OBT" in table:
        data["obt"] = ("time", table["TIME.OBT"].values.astype(np.float64),
                       {"units": "s", "description": "TIME.OBT, s since 2003-01-01"})
    if "POSITION.X" in table:
        data["position"] = _vector(table, ("POSITION.X", "POSITION.Y", "POSITION.Z"),
                                   "component", ["x", "y", "z"], {"description": "position"},
                                   label)
    if "T" in table:
        data["temperature"] = ("time", table["T"].values.astype(np.float64), table["T"].attrs)
    if "QUALITY" in table:
        data["quality"] = ("time", table["QUALITY"].values,
                           {"units": "1", "description": "quality flag"})
    attrs: dict[str, Any] = {"mission": "ROSETTA",
                             "product_type": "RESAMPLED" if level in ("E", "F", "G")
                             else "CALIBRATED"}
    if level:
        attrs["level"] = level
    if sensor:
        attrs["sensor"] = sensor
    if name is not None and name.group("mode"):
        attrs["filter_mode_sid"] = int(name.group("mode"))
    avg = keywords.get("AVERAGE_SECONDS") or (name.group("avg") if name else None)
    if avg is not None and attrs["product_type"] == "RESAMPLED":
        attrs["average_seconds"] = float(str(avg).replace("p", "."))
    return data, {"epoch": ("time", epoch)}, attrs


def read_product(path: Path | str) -> xr.Dataset:
    """Read an archived calibrated product (``.TAB`` + ``.LBL``) into fluxcal's shape.

    Parameters
    ----------
    path : Path
        The ``.LBL`` or the ``.TAB`` (with its label beside it, or attached).

    Returns
    -------
    xarray.Dataset
        See the module docstring (``time`` index, ``epoch``, ``b``, ...).

    Raises
    ------
    InputFormatError
        Everything `fluxcal.archive.pds3.read_table` raises; a table of neither
        mission; a needed column missing (named); a time field out of range or an
        unparsable ``TIME.UTC`` (row and column named).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12.
    .. [2] RO-IGEP-TR0028, sec. 4.2-4.8.
    """
    from fluxcal.products.timeindex import with_time_index

    label_path = find_label(path)
    label = read_label(label_path)
    table = read_table(label_path, label=label)
    try:
        mission = identify([str(n) for n in table.data_vars])
    except InputFormatError as exc:
        raise InputFormatError(str(exc), path=str(label_path)) from exc
    stem = Path(str(table.attrs.get("pds3_data_file", label_path))).stem
    product_id = str(table.attrs.get("PRODUCT_ID", stem))
    keywords = {k: v for k, v in table.attrs.items()}
    fluxcal = _fluxcal_attrs(label)
    if mission == "messenger":
        name = _MSGR_NAME.search(product_id) or _MSGR_NAME.search(stem)
        data, coords, attrs = _messenger(table, label_path, name, keywords)
    else:
        name = _ROS_NAME.search(product_id) or _ROS_NAME.search(stem)
        data, coords, attrs = _rosetta(table, label_path, name, keywords, fluxcal)
    ds = xr.Dataset(data, coords=coords)
    ds["b_total"] = ("time", np.sqrt((ds["b"].values ** 2).sum(axis=1)),
                     {"units": ds["b"].attrs.get("units", ""), "description": "|B|"})
    ds.attrs = {**fluxcal, **keywords, **attrs}
    return with_time_index(ds)
