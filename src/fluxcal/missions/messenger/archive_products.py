"""Reader of MESSENGER MAG archived calibrated products (CDR, RDR).

``MAG<FFF>SCI<yyddd>_V<nn>``, 12 columns ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG
X Y Z BX BY BZ``; ``MAG<FFF>SCIAVG<yyddd>_<NN>_V<nn>``, 16 columns with ``NAVG`` and
``DBX DBY DBZ``; RTN: ``R LATITUDE AZIMUTH``, ``BR BT BN``; SC: no position) ->
``epoch``, ``met``, ``b`` (time, b_component ``B_X B_Y B_Z`` / ``B_R B_T B_N``),
``b_total``, ``position`` (time, position_component) or ``r``, ``latitude``,
``azimuth``, and for averages ``count`` and ``b_std``.  The archived tables have no
quality column (the SHC flag is in the label): ``quality`` exists only when the table
has a ``QUALITY`` column.  `READER` plugs this into
`fluxcal.archive.products.read_archive_product`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12 (CDR/RDR content).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.archive.products import (
    FRAME_CODES,
    ArchivedReader,
    Parts,
    check_range,
    first_set,
    frame_code,
    need_columns,
    vector_variable,
)
from fluxcal.geometry.time import utc_fields_to_tt2000
from fluxcal.products.timeindex import default_lsk

_NAME = re.compile(r"MAG(?P<frame>[A-Z0-9]+?)SCI(?P<avg>AVG)?(?P<yyddd>\d{5})"
                   r"(?:_(?P<seconds>\d{2}))?_V(?P<version>\d{2})", re.IGNORECASE)
_TIME = ("YEAR", "DAY_OF_YEAR", "HOUR", "MINUTE", "SECOND")

#: MESSENGER's SPICE frame names and the frame codes fluxcal's products use for them.
MESSENGER_FRAME_CODES = {"MSGR_MSO": "MSO", "IAU_MERCURY": "MBF", "MSGR_RTN": "RTN",
                         "MSGR_SPACECRAFT": "SC", "MSGR_VSO": "VSO"}
_CODES = {**FRAME_CODES, **MESSENGER_FRAME_CODES}


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
    where = label or Path("table")
    for values, lo, hi, name in ((doy, 1, 366, "DAY_OF_YEAR"), (hour, 0, 23, "HOUR"),
                                 (minute, 0, 59, "MINUTE"), (second, 0, 60.999, "SECOND")):
        check_range(np.asarray(values), lo, hi, name, where)
    ms = np.rint(np.asarray(second, dtype=np.float64) * 1000.0)
    return utc_fields_to_tt2000(year, doy, hour, minute, ms / 1000.0, default_lsk())


def matches(columns: list[str]) -> bool:
    """Return True for a table with the UTC field columns of a CDR/RDR."""
    return all(c in columns for c in _TIME)


def read(table: xr.Dataset, label: Path, product_id: str, stem: str,
         keywords: Mapping[str, Any], fluxcal: Mapping[str, Any]) -> Parts:
    """Return the variables, coordinates and attrs of a CDR/RDR table (module docstring)."""
    name = _NAME.search(product_id) or _NAME.search(stem)
    y, d, h, m, s = need_columns(table, _TIME, label)
    epoch = messenger_epoch(y, d, h, m, s, label)
    axes = first_set(table, (("BX", "BY", "BZ"), ("BR", "BT", "BN"))) or ("BX", "BY", "BZ")
    rtn = axes[0] == "BR"
    frame = frame_code(keywords.get("COORDINATE_SYSTEM_NAME"), _CODES) \
        or (frame_code(name.group("frame"), _CODES) if name else None) \
        or ("RTN" if rtn else None)
    b_labels = [f"B_{a[-1]}" for a in axes]
    battrs = {"description": "magnetic field"}
    if frame:
        battrs.update(frame=frame, coordinate_system=frame)
    data: dict[str, Any] = {"b": vector_variable(table, axes, "b_component", b_labels, battrs,
                                                 label)}
    if "TIME_TAG" in table:
        data["met"] = ("time", table["TIME_TAG"].values.astype(np.float64),
                       {"units": "s", "description": "lag-corrected MET (TIME_TAG)"})
    if "NAVG" in table:
        data["count"] = ("time", table["NAVG"].values, {"units": "1",
                                                        "description": "samples averaged"})
    std = tuple("D" + a for a in axes)
    if std[0] in table:
        data["b_std"] = vector_variable(table, std, "b_component", b_labels,
                                        {"description": "standard deviation of the field"},
                                        label)
    if "R" in table and "LATITUDE" in table:
        r, lat, az = need_columns(table, ("R", "LATITUDE", "AZIMUTH"), label)
        data.update(r=("time", r, table["R"].attrs), latitude=("time", lat,
                    table["LATITUDE"].attrs), azimuth=("time", az, table["AZIMUTH"].attrs))
    elif "X" in table:
        data["position"] = vector_variable(table, ("X", "Y", "Z"), "position_component",
                                           ["X", "Y", "Z"], {"description": "position"}, label)
    if "QUALITY" in table:
        data["quality"] = ("time", table["QUALITY"].values, {"units": "1"})
    attrs = {"mission": "MESSENGER", "product_type": "RDR" if "NAVG" in table else "CDR"}
    seconds = keywords.get("AVERAGING_INTERVAL_S") or (name.group("seconds") if name else None)
    if seconds is not None and "NAVG" in table:
        attrs["average_seconds"] = float(seconds)
    return data, {"epoch": ("time", epoch)}, attrs


#: The MESSENGER reader for `fluxcal.archive.products.read_archive_product`.
READER = ArchivedReader(
    description="MESSENGER MAG CDR/RDR (columns YEAR DAY_OF_YEAR HOUR MINUTE SECOND)",
    matches=matches, read=read, frame_codes=MESSENGER_FRAME_CODES)
