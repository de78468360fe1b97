"""The IMAP MAG team's product layouts: their L1B/L1C CSV in, their CDF variables out.

fluxcal's own IMAP products hold ``b`` (time, component) in nT with ``Epoch``; the team's
(and so every tool written for them) hold ``epoch``, ``vectors`` (epoch, direction) with
x, y, z and the sensor range as the 4th column, ``compression_flags`` (epoch, compression)
with the flag and the width, and global attributes ``Logical_source``, ``is_mago``,
``is_active``, ``vectors_per_second``, ``missing_sequences``.  `to_team` builds that
layout from a fluxcal L1B/L1C dataset; `team_product` declares it, one CDF per UTC
day written as it is (`fluxcal.products.cdf.write_cdf_as_is`, ISTP checked);
`from_team` reads it back into fluxcal's layout, and `read_l1b_csv` reads the team's
L1B validation CSVs (``t,coarse,fine,...``).

References
----------
Variable names, dimensions and global attributes as in the team's public L1B CDF
``imap_mag_l1b_norm-mago_20251017_v002.cdf`` and the ``imap_processing`` package's MAG
L1B/L1C products; docs/decisions/imap.md (team-layout entry).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import cdflib
import numpy as np
import pandas as pd
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import datetime64_to_tt2000, tt2000_to_datetime64
from fluxcal.missions.imap.cadence import interval_rates
from fluxcal.products.declared import Product
from fluxcal.products.timeindex import default_lsk
from fluxcal.products.writer import read_fluxcal_product

COMPONENTS = np.array(["x", "y", "z"])
#: CDF fill of the team's float vectors and of TT2000.
FILL_F8 = -1.0e31
FILL_TT2000 = np.int64(-9223372036854775808)
_CSV_INT = ("coarse", "fine", "sequence", "range", "compression", "compression_width")


def read_l1b_csv(path: Path, *, sensor: str | None = None, mode: str | None = None
                 ) -> xr.Dataset:
    """Read a team L1B/L1C CSV (``t,coarse,fine,sequence,x,y,z,range,compression,...``).

    ``t`` (UTC, ISO 8601) becomes the int64 TT2000 ``epoch``; ``x, y, z`` the field ``b``
    in nT.  Sensor and mode come from the name (``...-mago-normal-in.csv``) unless given.
    Rows of an L1C output with an empty ``coarse`` (generated rows) keep -1 there.

    Raises
    ------
    InputFormatError
        A missing column or an unreadable value (naming the line and the column).
    """
    path = Path(path)
    try:
        table = pd.read_csv(path)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise InputFormatError(f"not a CSV table: {exc}", path=str(path)) from None
    need = ("t", "x", "y", "z", "range")
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise InputFormatError(f"column(s) {missing} missing; expected the team's L1B CSV "
                               "layout t,coarse,fine,sequence,x,y,z,range,compression,"
                               "compression_width", path=str(path))
    try:
        times = pd.to_datetime(table["t"], format="ISO8601").to_numpy("datetime64[ns]")
    except (ValueError, TypeError) as exc:
        raise InputFormatError(f"column t: not an ISO 8601 time ({exc})",
                               path=str(path), field="t") from None
    name = path.name.lower()
    sensor = sensor or ("magi" if "magi" in name else "mago")
    mode = mode or ("burst" if "burst" in name else "norm")
    ints = {}
    for col in _CSV_INT:
        values = table[col] if col in table.columns else pd.Series(np.zeros(len(table)))
        bad = ~np.isfinite(values.to_numpy(float)) & (col == "range") & ("interp" not in table)
        if bad.any():
            raise InputFormatError(f"line {int(np.flatnonzero(bad)[0]) + 2}: column range is "
                                   "empty", path=str(path), field="range")
        ints[col] = np.nan_to_num(values.to_numpy(float), nan=-1).astype(np.int64)
    b = table[["x", "y", "z"]].to_numpy(float)
    data = {"b": (("time", "component"), b,
                  {"units": "nT", "description": "Magnetic field, sensor frame"})}
    data |= {c: ("time", v, {"units": "1"}) for c, v in ints.items()}
    if "interp" in table.columns:
        data["generated"] = ("time", table["interp"].astype(str).str.lower()
                             .eq("true").to_numpy().astype(np.int8), {"units": "1"})
    return xr.Dataset(data, coords={"epoch": ("time", datetime64_to_tt2000(times, default_lsk())),
                                    "component": COMPONENTS},
                      attrs={"sensor": sensor, "mode": mode, "level": "l1b",
                             "source_file": path.name})


def vectors_per_second(epoch: np.ndarray) -> str:
    """Return the team's ``vectors_per_second`` attribute: ``"<start ns>:<rate>,..."``.

    Rates from the cadence (`fluxcal.missions.imap.cadence.interval_rates`), one entry per
    change, starting at the first sample.
    """
    epoch = np.asarray(epoch, dtype=np.int64)
    if epoch.size < 2:
        return f"{int(epoch[0])}:2" if epoch.size else ""
    rates = interval_rates(epoch)
    change = np.r_[0, np.flatnonzero(np.diff(rates)) + 1]
    return ",".join(f"{int(epoch[i])}:{int(rates[i])}" for i in change)


def to_team(ds: xr.Dataset, logical_source: str, version: str = "v001") -> xr.Dataset:
    """Return the team's layout of a fluxcal L1B or L1C dataset (one mode and sensor).

    ``vectors`` = x, y, z (nT) and the range; ``compression_flags`` = flag and width;
    an L1C also gets ``generated_flag`` and ``vector_magnitude`` and loses its
    ``MISSING`` rows (the team's L1C holds no row without a field).
    """
    if "generated" in ds:
        ds = ds.isel(time=ds["generated"].values >= 0)
    epoch = ds["epoch"].values.astype(np.int64)
    field = ds["b"] if "b" in ds else ds["counts"]
    vec = np.column_stack([field.values.astype(np.float64),
                           ds["range"].values.astype(np.float64)])
    units = "nT" if "b" in ds else "counts"
    cmp = np.column_stack([ds["compression"].values if "compression" in ds else
                           np.zeros(epoch.size), ds["compression_width"].values
                           if "compression_width" in ds else np.zeros(epoch.size)]
                          ).astype(np.int8)
    level = logical_source.split("_")[2].upper()
    sensor = ds.attrs.get("sensor", logical_source[-4:])
    out = xr.Dataset(
        {
            "vectors": (("epoch", "direction"), vec, _attrs(
                f"Magnetic field x, y, z ({units}) in the sensor frame and the sensor range "
                "(4th column)", "Magnetic field", "F12.5", units, FILL_F8, -1e9, 1e9,
                depend_1="direction", labl="direction_label")),
            "compression_flags": (("epoch", "compression"), cmp, _attrs(
                "Compression flag and compression width (bits) per vector",
                "Compression", "I2", " ", np.int8(-128), np.int8(0), np.int8(21),
                var_type="support_data", depend_1="compression",
                labl="compression_label")),
        },
        coords={
            "epoch": ("epoch", epoch, {
                "CATDESC": "Time, TT2000 nanoseconds since J2000", "FIELDNAM": "epoch",
                "FILLVAL": FILL_TT2000, "FORMAT": " ", "LABLAXIS": "epoch", "UNITS": "ns",
                "VALIDMIN": np.int64(-315575942816000000),
                "VALIDMAX": np.int64(3155630469184000000), "VAR_TYPE": "support_data",
                "MONOTON": "INCREASE", "SCALETYP": "linear", "TIME_BASE": "J2000",
                "TIME_SCALE": "Terrestrial Time", "DISPLAY_TYPE": "time_series"}),
            "direction": ("direction", np.arange(4), _meta("Vector component index")),
            "direction_label": ("direction", np.array(["x", "y", "z", "range"]),
                                _label("Vector component", "direction")),
            "compression": ("compression", np.arange(2), _meta("Compression index")),
            "compression_label": ("compression", np.array(["flag", "width"]),
                                  _label("Compression flag and width", "compression")),
        },
    )
    if level == "L2":
        frame = ds.attrs.get("output_frame", "sensor")
        name = "vectors" if frame == "sensor" else f"b_{frame}"
        out = out.drop_vars(["vectors", "compression_flags", "compression",
                             "compression_label"]).isel(direction=slice(0, 3))
        out[name] = (("epoch", "direction"), vec[:, :3], _attrs(
            f"Magnetic field x, y, z (nT), frame {frame}", "Magnetic field", "F12.5", "nT",
            FILL_F8, -1e9, 1e9, depend_1="direction", labl="direction_label"))
        out["range"] = ("epoch", vec[:, 3].astype(np.int8), _attrs(
            "Sensor range 0..3", "Range", "I1", " ", np.int8(-128), np.int8(0), np.int8(3),
            var_type="support_data"))
        out["magnitude"] = ("epoch", np.linalg.norm(vec[:, :3], axis=1), _attrs(
            "Magnitude of the field", "Magnitude", "F12.5", "nT", FILL_F8, 0.0, 1e9))
        for q, dtype in (("quality_flag", np.uint8), ("quality_bitmask", np.uint16)):
            if q in ds:
                out[q + ("s" if q == "quality_flag" else "")] = ("epoch", ds[q].values.astype(
                    dtype), _attrs(q.replace("_", " "), q, "I5", " ", dtype(0), dtype(0),
                                   np.iinfo(dtype).max - 1, var_type="support_data"))
    if "generated" in ds:
        out["generated_flag"] = ("epoch", ds["generated"].values.astype(np.int8), _attrs(
            "0 normal-mode sample, 1 filtered and interpolated from burst mode",
            "Generated flag", "I2", " ", np.int8(-128), np.int8(-1), np.int8(1),
            var_type="support_data"))
        out["vector_magnitude"] = ("epoch", np.linalg.norm(vec, axis=1), _attrs(
            "Magnitude of the 4-element vector as the team's L1C defines it",
            "Magnitude", "F12.5", "nT", FILL_F8, 0.0, 1e9))
    out.attrs = {
        "Project": "STP>Solar-Terrestrial Physics", "Source_name": "IMAP>Interstellar "
        "Mapping and Acceleration Probe", "Discipline": "Space Physics>Heliospheric "
        "Physics", "Mission_group": "IMAP", "PI_name": "Dr. David J. McComas",
        "PI_affiliation": "Princeton University", "Instrument_type": "Magnetic Fields "
        "(space)", "Descriptor": "MAG>Magnetometer", "Data_level": level,
        "Data_type": f"{level}_{logical_source.split('_', 3)[3]}>Level {level} "
                     f"{sensor.upper()}", "Data_version": version,
        "Logical_source": logical_source,
        "Logical_file_id": f"{logical_source}_{_day(epoch)}_{version}",
        "Logical_source_description": f"IMAP MAG {level} {sensor.upper()} (fluxcal)",
        "TEXT": "IMAP MAG vectors written by fluxcal in the IMAP MAG team's layout.",
        "HTTP_LINK": "https://imap.princeton.edu/", "Generated_by": "fluxcal",
        "Generation_date": str(np.datetime64("now", "s")),
        "is_mago": str(sensor == "mago"), "is_active": "True",
        "all_vectors_primary": str(sensor == "mago"),
        "vectors_per_second": vectors_per_second(epoch),
        "missing_sequences": "",
        "Parents": [str(p) for p in np.atleast_1d(ds.attrs.get("input_files", []))
                    if str(p)] or ["fluxcal"],
    }
    return out


def _day(epoch: np.ndarray) -> str:
    if not epoch.size:
        return "00000000"
    return str(tt2000_to_datetime64(epoch[:1], default_lsk())[0].astype("M8[D]")).replace("-", "")


def _attrs(catdesc: str, fieldnam: str, fmt: str, units: str, fill, vmin, vmax, *,
           var_type: str = "data", depend_1: str | None = None,
           labl: str | None = None) -> dict:
    out = {"CATDESC": catdesc, "DEPEND_0": "epoch", "DISPLAY_TYPE": "time_series",
           "FIELDNAM": fieldnam, "FILLVAL": fill, "FORMAT": fmt, "UNITS": units,
           "VALIDMIN": vmin, "VALIDMAX": vmax, "VAR_TYPE": var_type}
    if depend_1:
        out |= {"DEPEND_1": depend_1, "LABL_PTR_1": labl}
    else:
        out["LABLAXIS"] = fieldnam
    return out


def _meta(catdesc: str) -> dict:
    return {"CATDESC": catdesc, "FIELDNAM": catdesc, "FILLVAL": np.int64(-9223372036854775808),
            "FORMAT": "I3", "LABLAXIS": catdesc, "UNITS": " ", "VALIDMIN": np.int64(0),
            "VALIDMAX": np.int64(3), "VAR_TYPE": "support_data"}


def _label(catdesc: str, dim: str) -> dict:
    return {"CATDESC": catdesc, "FIELDNAM": catdesc, "FORMAT": "A5", "VAR_TYPE": "metadata",
            "DEPEND_1": dim}


def from_team(path: Path) -> xr.Dataset:
    """Read a team-layout L1B/L1C CDF (the team's own or fluxcal's) into fluxcal's layout.

    Raises
    ------
    InputFormatError
        No ``epoch`` or no ``vectors`` (epoch, 4) variable.
    """
    path = Path(path)
    try:
        cdf = cdflib.CDF(str(path))
        names = cdf.cdf_info().zVariables
    except Exception as exc:  # cdflib raises plain OSError/ValueError on a bad file
        raise InputFormatError(f"not a CDF file ({exc})", path=str(path)) from None
    if "epoch" not in names or "vectors" not in names:
        raise InputFormatError("not the team's layout: no 'epoch' and 'vectors' variables",
                               path=str(path))
    epoch = np.asarray(cdf.varget("epoch"), dtype=np.int64).reshape(-1)
    vec = np.asarray(cdf.varget("vectors"), dtype=np.float64).reshape(epoch.size, -1)
    if vec.shape[1] != 4:
        raise InputFormatError(f"'vectors' has {vec.shape[1]} columns, expected x, y, z, "
                               "range", path=str(path), field="vectors")
    cmp = (np.asarray(cdf.varget("compression_flags"), dtype=np.int64).reshape(epoch.size, 2)
           if "compression_flags" in names else np.zeros((epoch.size, 2), np.int64))
    g = cdf.globalattsget()
    source = str(np.atleast_1d(g.get("Logical_source", [""]))[0])
    return xr.Dataset(
        {"b": (("time", "component"), vec[:, :3],
               {"units": "nT", "description": "Magnetic field, sensor frame"}),
         "range": ("time", vec[:, 3].astype(np.int64), {"units": "1"}),
         "compression": ("time", cmp[:, 0], {"units": "1"}),
         "compression_width": ("time", cmp[:, 1], {"units": "1"})},
        coords={"epoch": ("time", epoch), "component": COMPONENTS},
        attrs={"sensor": "magi" if source.endswith("magi") else "mago",
               "mode": "burst" if "burst" in source else "norm",
               "level": source.split("_")[2] if source.count("_") >= 3 else "l1b",
               "Logical_source": source, "source_file": path.name},
    )


def read_l1b(path: Path) -> xr.Dataset:
    """Read an L1B (or L1C) file of any layout, recognised by content, into fluxcal's.

    The team's CSV (first column ``t``), a team-layout CDF (``epoch`` + ``vectors``:
    `from_team`), or a fluxcal product (`fluxcal.products.writer.read_fluxcal_product`).

    Raises
    ------
    InputFormatError
        None of these layouts, a field not in nT, a fluxcal product without the
        compression flags L1C keeps, or one whose ``sensor``
        or ``mode`` attribute (part of the products' names) is not mago/magi, norm/burst
        (naming the file).
    """
    path = Path(path)
    with path.open("rb") as fh:
        head = fh.read(8)
    if head.startswith(b"t,"):
        return read_l1b_csv(path)
    if head[:4] == bytes.fromhex("cdf30001") and \
            "vectors" in cdflib.CDF(str(path)).cdf_info().zVariables:
        return from_team(path)
    ds = read_fluxcal_product(path)
    if "b" not in ds or "range" not in ds or "epoch" not in ds.coords:
        raise InputFormatError("not an IMAP MAG L1B/L1C product: expected fluxcal's ('b', "
                               "'range', 'epoch'), the team's CDF ('epoch', 'vectors') or "
                               "the team's CSV (t,coarse,fine,...,x,y,z,range)", path=str(path))
    for name in ("compression", "compression_width"):  # L1C keeps them per row
        if name not in ds:
            raise InputFormatError(f"the L1B product holds no {name!r} variable (written by "
                                   "another tool or edited?): L1C needs it per vector",
                                   path=str(path), field=name)
    ds = ds.drop_vars("time", errors="ignore") if "time" in ds.coords else ds
    for key, known in (("sensor", ("mago", "magi")), ("mode", ("norm", "burst"))):
        value = ds.attrs.get(key, known[0])  # they name the products (decision 66, rule 3)
        if value not in known:
            raise InputFormatError(f"{value!r} is not an IMAP MAG {key} ({', '.join(known)}); "
                                   "fix the input file", path=str(path), field=key)
    return ds


def team_product(ds: xr.Dataset, logical_source: str, version: str = "v001") -> Product:
    """Declare the team-layout CDFs of one (mode, sensor-or-frame) dataset, one per UTC day.

    Named ``<logical_source>_<yyyymmdd>_<version>.cdf`` as the team's files; each day's
    part is laid out by `team_day`.
    """
    return Product(f"{logical_source}_{{day:%Y%m%d}}_{version}", ds, formats=("cdf",),
                   layout=partial(team_day, logical_source=logical_source, version=version))


def team_day(part: xr.Dataset, provenance: Mapping[str, Any], *, logical_source: str,
             version: str = "v001") -> xr.Dataset:
    """Return one UTC day of a dataset in the team's layout (`to_team`).

    The team's ``Parents`` name the files it was made from: the inputs and calibration
    files of ``provenance`` (`fluxcal.products.provenance.provenance_attrs`), by name;
    ``Generation_date`` is the provenance's ``creation_time`` (``SOURCE_DATE_EPOCH``
    honoured: a rerun is byte-identical; docs/decisions/products.md decision 75).
    """
    team = to_team(part, logical_source, version)
    if provenance.get("creation_time"):
        team.attrs["Generation_date"] = str(provenance["creation_time"]).removesuffix("Z")
    parents = [i["name"] for i in provenance.get("inputs", [])] + [
        c["name"] for c in provenance.get("calibration", {}).values() if "name" in c]
    if parents:
        team.attrs["Parents"] = parents
    return team
