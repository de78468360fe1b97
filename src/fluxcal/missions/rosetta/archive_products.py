"""Reader of Rosetta RPC-MAG archived calibrated products (CALIBRATED, RESAMPLED).

``RPCMAG<yymmdd>T<hhmm>_CL<A|B|C>_<IB|OB>_M<mode>``, ``RPCMAG<yymmdd>_CL<E|F|G>_<IB|OB>_A<NN>``;
columns ``TIME.UTC TIME.OBT [POSITION.X/Y/Z] BX BY BZ [T] QUALITY`` -> ``epoch``,
``obt``, ``b`` (time, component ``x y z``), ``b_total``, ``position``,
``temperature``, ``quality`` (an integer, or the text of the V9 8-digit quality string
when the label says CHARACTER).  `READER` plugs this into
`fluxcal.archive.products.read_archive_product`.

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028), sec. 4.2-4.8 (level tables).
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
    frame_code,
    need_columns,
    vector_variable,
)
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.products.timeindex import default_lsk

_NAME = re.compile(r"RPCMAG(?P<date>\d{6})(?:T(?P<hhmm>\d{4}))?_CL(?P<level>[A-Z])_"
                   r"(?P<sensor>IB|OB)_(?:M(?P<mode>\d+)|A(?P<avg>[0-9p]+))",
                   re.IGNORECASE)

#: Rosetta's SPICE frame names and the frame codes fluxcal's products use for them.
ROSETTA_FRAME_CODES = {"67P/C-G_CSEQ": "CSEQ", "ROS_SPACECRAFT": "ROS_SPACECRAFT"}
_CODES = {**FRAME_CODES, **ROSETTA_FRAME_CODES}
#: Levels whose frame follows from the level (sec. 4.2-4.8).
_LEVEL_FRAMES = {"A": "ROS_RPC_MAG_{sensor}", "E": "ROS_RPC_MAG_{sensor}",
                 "B": "ROS_SPACECRAFT", "F": "ROS_SPACECRAFT"}


def matches(columns: list[str]) -> bool:
    """Return True for a table with the ``TIME.UTC`` column of the calibrated levels."""
    return "TIME.UTC" in columns


def read(table: xr.Dataset, label: Path, product_id: str, stem: str,
         keywords: Mapping[str, Any], fluxcal: Mapping[str, Any]) -> Parts:
    """Return the variables, coordinates and attrs of a level table (module docstring)."""
    name = _NAME.search(product_id) or _NAME.search(stem)
    (utc,) = need_columns(table, ("TIME.UTC",), label)
    try:
        epoch = utc_to_tt2000(utc, default_lsk())
    except InputFormatError as exc:
        raise InputFormatError(str(exc), path=str(label), field="TIME.UTC") from exc
    level = (name.group("level").upper() if name else
             str(keywords.get("LEVEL", "")).replace("LEVEL_", "").upper() or None)
    sensor = (name.group("sensor").upper() if name else
              str(keywords.get("SENSOR", "")).upper() or None)
    frame = frame_code(keywords.get("COORDINATE_SYSTEM_NAME"), _CODES) \
        or frame_code(fluxcal.get("output_frame"), _CODES)
    if frame is None and level in _LEVEL_FRAMES and sensor:
        frame = _LEVEL_FRAMES[level].format(sensor=sensor)
    battrs = {"description": "magnetic field"}
    if frame:
        battrs.update(frame=frame, coordinate_system=frame)
    data: dict[str, Any] = {"b": vector_variable(table, ("BX", "BY", "BZ"), "component",
                                                 ["x", "y", "z"], battrs, label)}
    if "TIME.OBT" in table:
        data["obt"] = ("time", table["TIME.OBT"].values.astype(np.float64),
                       {"units": "s", "description": "TIME.OBT, s since 2003-01-01"})
    if "POSITION.X" in table:
        data["position"] = vector_variable(table, ("POSITION.X", "POSITION.Y", "POSITION.Z"),
                                           "component", ["x", "y", "z"],
                                           {"description": "position"}, label)
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


#: The Rosetta reader for `fluxcal.archive.products.read_archive_product`.
READER = ArchivedReader(
    description="Rosetta RPC-MAG CALIBRATED/RESAMPLED table (column TIME.UTC)",
    matches=matches, read=read, frame_codes=ROSETTA_FRAME_CODES)
