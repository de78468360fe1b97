"""Write raw RPC-MAG telemetry as archive-style EDITED products (a forward-model fixture).

The simulator's raw datasets (as `fluxcal.missions.rosetta.io.read_science_csv`
returns) are written the way the PDS3 archive lays out EDITED raw data: one detached-label
ASCII table per sensor and measurement-mode run, split at UTC midnight of the time
stamps, named ``RPCMAG<yymmdd>T<hhmm>_RAW_<OB|IB>_M<mode>`` (``hhmm`` of the first
record, the mode only in the name), HK as ``RPCMAG<yymmdd>T<hhmm>_RAW_HK``, in
``DATA/EDITED/<yyyy>/<MON>/<OB|IB|HK>/``.  Tables and labels are declared products
written by fluxcal's writer (`fluxcal.products.declared.write_declared`, without
provenance: raw telemetry); the columns carry the names of seed 003 sec. 4.1.1 / 4.1.2.
The calibration files get their archived names (`write_archive_calibration`).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.1, 4.1.2, 4.2.3.5.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import FluxcalError
from fluxcal.missions.rosetta import calib
from fluxcal.missions.rosetta.io import _utc
from fluxcal.products import Column
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.declared import Product, write_declared

EDITED = ("DATA", "EDITED")
#: Month folders of the archive tree (``DATA/EDITED/<yyyy>/<MON>/``).
MONTHS = ("JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC")


def edited_folder(root: Path, day: str, kind: str) -> Path:
    """``root/DATA/EDITED/<yyyy>/<MON>/<kind>`` for ``day`` ``YYYY-MM-DD``."""
    return Path(root).joinpath(*EDITED, day[:4], MONTHS[int(day[5:7]) - 1], kind)


def product_stem(first_utc: str, kind: str, mode: int | None = None) -> str:
    """``RPCMAG<yymmdd>T<hhmm>_RAW_<kind>[_M<mode>]`` from the first record's TIME.UTC."""
    t = str(first_utc)
    tail = f"_M{int(mode)}" if mode is not None else ""
    return f"RPCMAG{t[2:4]}{t[5:7]}{t[8:10]}T{t[11:13]}{t[14:16]}_RAW_{kind}{tail}"


def _science_columns(sensor: str) -> list:
    return [
        Column("time_utc", "A26", "UTC", "UTC time of observation", label="TIME.UTC",
               data_type="TIME"),
        Column("obt", "F17.6", "s", "s/c clock at observation time, s since 2003-01-01",
               label="TIME.OBT"),
        *(Column("b_counts", "I7", "count",
                 f"magnetic field {c.upper()}, uncalibrated, 20-bit ADC counts, URF",
                 component=c, label=f"B{c.upper()}.{sensor}") for c in "xyz"),
        Column("t_ob_counts", "I5", "count", "OB sensor temperature, ADC counts",
               label="T.OB"),
        Column("t_ib_counts", "I5", "count", "IB sensor temperature, ADC counts",
               label="T.IB"),
        Column("quality", "I2", "1", "bits 0-2 bad x/y/z, bit 3 sensor (0 OB, 1 IB)",
               label="QUALITY"),
    ]


def _hk_columns() -> list:
    words = [("t_ob_counts", "I5", "T.OB"), ("t_ib_counts", "I5", "T.IB"),
             ("stage_a_id", "I5", "STAGE.A.ID"), ("stage_b_id", "I5", "STAGE.B.ID"),
             ("filter_cfg", "I5", "FILTER.CFG"), ("ref_voltage_counts", "I7", "MAG.REF.VOLTAGE"),
             ("neg_voltage_counts", "I3", "MAG.NEG.VOLTAGE"),
             ("pos_voltage_counts", "I3", "MAG.POS.VOLTAGE")]
    return [
        Column("time_utc", "A26", "UTC", "UTC time of observation", label="TIME.UTC",
               data_type="TIME"),
        Column("obt", "F17.6", "s", "s/c clock at observation time, s since 2003-01-01",
               label="TIME.OBT"),
        *(Column(name, fmt, "count", f"{label}, ADC counts", label=label)
          for name, fmt, label in words),
        *(Column("b_ob_counts", "I5", "count", f"OB field {c.upper()}, 16-bit ADC counts",
                 component=c, label=f"B{c.upper()}.OB") for c in "xyz"),
    ]


def _runs(day: np.ndarray, sid: np.ndarray | None) -> list[np.ndarray]:
    """Index ranges of the runs of one UTC day (and one SID)."""
    change = day[1:] != day[:-1]
    if sid is not None:
        change |= sid[1:] != sid[:-1]
    cuts = np.flatnonzero(change) + 1
    return [np.arange(a, b) for a, b in zip(np.r_[0, cuts], np.r_[cuts, day.size], strict=True)]


def _write(ds: xr.Dataset, rows: np.ndarray, stem: Path, columns, extra: dict,
           seen: set) -> list[Path]:
    if stem.name in seen:
        raise FluxcalError(f"two EDITED products would be named {stem.name} (the same mode "
                           "starting twice within one minute)")
    seen.add(stem.name)
    piece = ds.isel(time=rows)
    piece.attrs = {"description": "archive-style EDITED raw product written by fluxcal"}
    day = _dt.date.fromisoformat(str(piece["time_utc"].values[0])[:10])
    product = Product(stem.name, piece, day, ("tab",), columns=columns, label_extra=extra)
    return write_declared([product], stem.parent, lambda _: {})  # raw telemetry: no provenance


def write_science_products(raw: xr.Dataset, root: Path, *, flat: bool = False,
                           lsk=None) -> list[Path]:
    """Write one sensor's raw science as EDITED products; return labels and tables.

    A product per run of one SID within one UTC day of the time stamps; the SID is the
    ``M<mode>`` of the name (not a column).  ``flat`` writes into ``root`` itself
    instead of ``root/DATA/EDITED/<yyyy>/<MON>/<sensor>/``.

    Raises
    ------
    FluxcalError
        Two runs of one mode starting within one minute (their names would clash).
    """
    sensor = str(raw.attrs["sensor"]).upper()
    utc = _utc(raw["epoch"].values, lsk)
    ds = raw.assign(time_utc=("time", utc))
    day = np.char.ljust(utc, 10).astype("U10")
    sid = raw["sid"].values
    written: list[Path] = []
    seen: set = set()
    for rows in _runs(day, sid):
        first, mode = str(utc[rows[0]]), int(sid[rows[0]])
        folder = Path(root) if flat else edited_folder(root, first[:10], sensor)
        extra = {"INSTRUMENT_ID": "RPCMAG", "PROCESSING_LEVEL_ID": 2, "SENSOR": sensor}
        written += _write(ds, rows, folder / product_stem(first, sensor, mode),
                          _science_columns(sensor), extra, seen)
    return written


def write_hk_products(hk: xr.Dataset, root: Path, *, flat: bool = False,
                      lsk=None) -> list[Path]:
    """Write raw HK as EDITED HK products, one per UTC day; return labels and tables."""
    utc = _utc(hk["epoch"].values, lsk)
    ds = hk.assign(time_utc=("time", utc))
    day = np.char.ljust(utc, 10).astype("U10")
    written: list[Path] = []
    seen: set = set()
    for rows in _runs(day, None):
        first = str(utc[rows[0]])
        folder = Path(root) if flat else edited_folder(root, first[:10], "HK")
        extra = {"INSTRUMENT_ID": "RPCMAG", "PROCESSING_LEVEL_ID": 2}
        written += _write(ds, rows, folder / product_stem(first, "HK"), _hk_columns(), extra,
                          seen)
    return written


def write_archive_calibration(calib_dir: Path) -> list[Path]:
    """Give ``calib_dir`` the ground calibration files under their archived names.

    fluxcal's shipped ``RPCMAG_001_CALIB_FSDPU_FM<S>.TXT`` (the seed's name) are copied
    as ``RPCMAG_GND_CALIB_FSDPU_FM<S>.TXT`` (the archive's); the alignment
    ``RPCMAG_SC_ALIGN.TXT`` and the daily ``RPCMAG_<yymmdd>_006_CALIB_<S>.TXT`` already
    carry the archived names.
    """
    out = []
    for name in calib.GROUND_FILE.values():  # the archive's names: calib.ARCHIVE_NAMES
        dest = Path(calib_dir) / calib.ARCHIVE_NAMES[name]
        atomic_write_bytes(dest, (calib.default_dir() / name).read_bytes(), now=True)
        out.append(dest)
    return out
