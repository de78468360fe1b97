"""Rosetta RPC-MAG EDITED raw products (the PDS3 archive's CODMAC 2 layout) as fluxcal input.

The archive holds the raw telemetry of seed 003 sec. 4.1 as detached-label PDS3 ASCII
tables, one file per sensor and measurement mode (a new file starts when the mode
changes; the mode is in the name, not in a column)::

    DATA/EDITED/<yyyy>/<MON>/<OB|IB>/RPCMAG<yymmdd>T<hhmm>_RAW_<OB|IB>_M<mode>.LBL/.TAB
    DATA/EDITED/<yyyy>/<MON>/HK/RPCMAG<yymmdd>T<hhmm>_RAW_HK.LBL/.TAB      (fluxcal's guess)

Products are found by name anywhere below a folder (the archive tree or one flat
folder), case-insensitively (some mirrors lower-case the names).  Each is read with the
label-driven PDS3 reader (`fluxcal.archive.pds3.read_table`) and turned into exactly the
Dataset `fluxcal.missions.rosetta.io.read_science_csv` / `read_hk_csv` return, the
mode of the file name becoming the per-sample ``sid``; the files of one sensor are
concatenated in time order.  Every error names the file, the row and the column.
What is confirmed and what is fluxcal's assumption: docs/formats/rosetta.md, "Archive
input"; decisions: docs/decisions/rosetta_archive.md.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.1 (HK columns), 4.1.2 (science columns),
   4.2.3.5 (filter modes SID 1-6).
"""

from __future__ import annotations

import datetime as _dt
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.archive.pds3 import read_table
from fluxcal.errors import InputFormatError
from fluxcal.missions.rosetta.calib import check_sensor
from fluxcal.missions.rosetta.io import (
    _RANGES,
    _epoch,
    hk_dataset,
    read_hk_csv,
    read_science_csv,
    science_dataset,
)
from fluxcal.missions.rosetta.level_a import wrong_quality

SENSORS = ("OB", "IB")
_NAME = re.compile(
    r"^RPCMAG(\d{6})T(\d{4})_RAW_(?:(OB|IB)_M(\d+)|(HK))\.(LBL|TAB)$", re.IGNORECASE
)
#: Archive columns (seed 003 sec. 4.1.2) -> the CSV field of `io.SCIENCE_COLUMNS` they fill.
SCIENCE_FIELDS = {
    "BX.{s}": "bx",
    "BY.{s}": "by",
    "BZ.{s}": "bz",
    "T.OB": "t_ob",
    "T.IB": "t_ib",
    "QUALITY": "quality",
}
#: Archive HK columns (sec. 4.1.1) -> the CSV field of `io.HK_COLUMNS`.
HK_FIELDS = {
    "T.OB": "t_ob",
    "T.IB": "t_ib",
    "STAGE.A.ID": "stage_a_id",
    "STAGE.B.ID": "stage_b_id",
    "FILTER.CFG": "filter_cfg",
    "MAG.REF.VOLTAGE": "ref_voltage",
    "MAG.NEG.VOLTAGE": "neg_voltage",
    "MAG.POS.VOLTAGE": "pos_voltage",
    "BX.OB": "bx_ob",
    "BY.OB": "by_ob",
    "BZ.OB": "bz_ob",
}
TIME_COLUMNS = ("TIME.UTC", "TIME.OBT")


@dataclass(frozen=True)
class RawProduct:
    """One EDITED product as named: ``kind`` OB, IB or HK, ``mode`` (None for HK)."""

    label: Path
    kind: str
    start: _dt.datetime
    mode: int | None


def parse_name(path: Path) -> RawProduct | None:
    """Return the product a ``.LBL``/``.TAB`` name describes, ``None`` if it is not one.

    Raises
    ------
    InputFormatError
        A name of the pattern whose date or time does not exist (e.g. month 13).
    """
    path = Path(path)
    m = _NAME.match(path.name)
    if m is None:
        return None
    try:
        start = _dt.datetime.strptime(m.group(1) + m.group(2), "%y%m%d%H%M")
    except ValueError:
        raise InputFormatError(
            f"{m.group(1)}T{m.group(2)} in the name is not a date yymmdd and time hhmm",
            path=str(path),
        ) from None
    kind = (m.group(3) or m.group(5)).upper()
    mode = int(m.group(4)) if m.group(4) else None
    return RawProduct(label_of(path), kind, start, mode)


def _sibling(path: Path, suffix: str) -> Path:
    """``path`` with ``suffix`` in the case that exists (upper first), else upper case."""
    for s in (suffix.upper(), suffix.lower()):
        p = path.with_suffix(s)
        if p.is_file():
            return p
    return path.with_suffix(suffix.upper())


def label_of(path: Path) -> Path:
    """Return the detached label of a product given by its label or its table."""
    return _sibling(Path(path), ".LBL")


def table_of(label: Path) -> Path:
    """Return the table beside a label (same stem, ``.TAB``), which manifests hash."""
    return _sibling(Path(label), ".TAB")


#: Per-folder index of EDITED product names, keyed by the folder's mtime (a batch looks
#: up every day many times; a folder's mtime changes when a file is added or removed).
_FOLDER_INDEX: dict[str, tuple[int, list[str], list[RawProduct]]] = {}


def _folder(path: str) -> tuple[list[str], list[RawProduct]]:
    """Sub-folders and products (by label) of one folder, from the index when unchanged."""
    mtime = os.stat(path).st_mtime_ns
    cached = _FOLDER_INDEX.get(path)
    if cached is not None and cached[0] == mtime:
        return cached[1], cached[2]
    folders, products, stems = [], [], {}
    with os.scandir(path) as entries:
        for entry in entries:
            if entry.is_dir():
                folders.append(entry.path)
            elif _NAME.match(entry.name):
                stems.setdefault(entry.name[:-4].upper(), []).append(entry.name)
    for names in stems.values():
        labels = [n for n in names if n.upper().endswith(".LBL")]
        if not labels:  # a table of the pattern without its label: refused, not skipped
            raise InputFormatError("EDITED table without its detached label (.LBL): fluxcal "
                                   "reads the table through the label",
                                   path=os.path.join(path, names[0]))
        products.append(parse_name(Path(path) / labels[0]))
    _FOLDER_INDEX[path] = (mtime, folders, products)
    return folders, products


def find_products(
    folder: Path, *, kind: str | None = None, day: _dt.date | None = None
) -> list[RawProduct]:
    """EDITED products below ``folder`` (recursively), sorted by start time and name.

    Parameters
    ----------
    folder : Path
        The archive tree (``DATA/EDITED/...`` anywhere below) or a flat folder.
    kind : {"OB", "IB", "HK"}, optional
        Only this sensor, or HK.
    day : datetime.date, optional
        Only the products whose name carries this date (``RPCMAG<yymmdd>T...``).
    """
    found, stack = [], [str(folder)]
    while stack:
        folders, products = _folder(stack.pop())
        stack += folders
        found += [p for p in products if (kind is None or p.kind == kind)
                  and (day is None or p.start.date() == day)]
    return sorted(found, key=lambda p: (p.start, p.label.name.upper()))


def is_archive_source(source) -> bool:
    """Whether ``source`` is EDITED products: a folder, a ``.LBL``/``.TAB`` or a sequence."""
    if isinstance(source, (list, tuple)):
        return True
    path = Path(source)
    return path.is_dir() or path.suffix.upper() in (".LBL", ".TAB")


def _labels(source, kind: str, what: str) -> list[Path]:
    if isinstance(source, (list, tuple)):
        labels = [label_of(Path(p)) for p in source]
    elif Path(source).is_dir():
        labels = [p.label for p in find_products(Path(source), kind=kind)]
        if not labels:
            pattern = "RPCMAG<yymmdd>T<hhmm>_" + (
                "RAW_HK.LBL" if kind == "HK" else f"RAW_{kind}_M<mode>.LBL")
            raise InputFormatError(f"no EDITED {what} products ({pattern}) in this folder",
                                   path=str(source))
    else:
        labels = [label_of(Path(source))]
    for label in labels:
        product = parse_name(label)
        if product is None or product.kind != kind:
            raise InputFormatError(
                f"not an EDITED {what} product name (expected RPCMAG<yymmdd>T<hhmm>_"
                + ("RAW_HK" if kind == "HK" else f"RAW_{kind}_M<mode>") + ".LBL)",
                path=str(label),
            )
        if not label.is_file():
            raise InputFormatError("label file not found", path=str(label))
    return labels


def science_labels(source, sensor: str) -> list[Path]:
    """Labels of the ``sensor`` science products of a folder, one product or a sequence.

    Raises
    ------
    InputFormatError
        No product of the sensor in the folder; a name of another sensor, of HK or not
        of the pattern; a missing label.
    """
    sensor = check_sensor(sensor)
    return _labels(source, sensor, f"{sensor} science")


def hk_labels(source) -> list[Path]:
    """Labels of the HK products of a folder, one product or a sequence (`science_labels`)."""
    return _labels(source, "HK", "HK")


# ----------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------
def _read(label: Path) -> xr.Dataset:
    return read_table(label)


def _column(ds: xr.Dataset, name: str, label: Path) -> xr.DataArray:
    if name not in ds.variables:
        have = ", ".join(str(v) for v in ds.data_vars)
        raise InputFormatError(f"column missing (the label has: {have})",
                               path=str(label), field=name)
    return ds[name]


def _integers(values: np.ndarray, name: str, csv_name: str, label: Path) -> np.ndarray:
    """Whole numbers of a column, range-checked as the CSV reader checks them."""
    v = np.asarray(values)
    if v.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(v) | (v != np.round(v)))
        if bad.size:
            raise InputFormatError(f"{v[bad[0]]!r} is not an integer", path=str(label),
                                   line=int(bad[0]) + 1, field=name)
        v = v.astype(np.int64)
    elif v.dtype.kind not in "iu":
        raise InputFormatError(f"values of type {v.dtype} are not integers", path=str(label),
                               field=name)
    v = v.astype(np.int64)
    lo, hi = _RANGES[csv_name]
    out = np.flatnonzero((v < lo) | (v > hi))
    if out.size:
        i = int(out[0])
        raise InputFormatError(f"{v[i]} outside {lo}..{hi}", path=str(label), line=i + 1,
                               field=name)
    return v


def _data_file(ds: xr.Dataset, label: Path) -> Path:
    """Return the table file holding the rows of ``ds`` (errors about a row name it)."""
    return Path(ds.attrs.get("pds3_data_file", table_of(label)))


def _times(ds: xr.Dataset, label: Path, sclk, lsk) -> tuple[np.ndarray, np.ndarray]:
    """``(epoch TT2000, obt)`` of one table, as the CSV reader makes them (rows 1-based)."""
    table = _data_file(ds, label)

    utc = _column(ds, "TIME.UTC", label).values
    if utc.dtype.kind == "M":  # a reader that decoded the TIME column: back to its text
        utc = np.datetime_as_string(utc.astype("M8[us]"), unit="us")
    utc = np.char.strip(np.asarray(utc, dtype=str))
    obt = np.asarray(_column(ds, "TIME.OBT", label).values)
    if obt.dtype.kind not in "iuf":
        raise InputFormatError(f"values of type {obt.dtype} are not numbers", path=str(table),
                               field="TIME.OBT")
    obt = obt.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(obt))
    if bad.size:
        raise InputFormatError(f"{obt[bad[0]]!r} is not a finite number", path=str(table),
                               line=int(bad[0]) + 1, field="TIME.OBT")
    rows = np.arange(1, obt.size + 1)
    epoch, _ = _epoch(utc, obt, table, sclk, lsk, rows=rows, names=TIME_COLUMNS)
    return epoch, obt


def _check_order(pieces: list[dict], key: str = "epoch") -> list[dict]:
    """Sort files by their first time; refuse files that overlap in time (file and row)."""
    pieces = [p for p in pieces if p[key].size]
    pieces.sort(key=lambda p: (int(p[key][0]), p["label"].name.upper()))
    for prev, cur in zip(pieces, pieces[1:], strict=False):
        if int(cur[key][0]) < int(prev[key][-1]):
            raise InputFormatError(
                f"starts before the last record of {prev['label'].name} "
                "(EDITED products of one sensor must not overlap in time)",
                path=str(cur["label"]), line=1, field="TIME.UTC",
            )
    return pieces


def _join(pieces: list[dict], what: str, sclk) -> tuple[dict, dict, dict]:
    """Join the per-file pieces in time order: columns, integer columns, Dataset attrs."""
    if not pieces:
        raise InputFormatError(f"no EDITED {what} products given")
    files = [str(p["label"]) for p in pieces]
    pieces = _check_order(pieces)
    if not pieces:
        raise InputFormatError("no data records", path=files[0], line=1)
    cat = {k: np.concatenate([p[k] for p in pieces])
           for k in pieces[0] if k not in ("label", "ints")}
    ints = {k: np.concatenate([p["ints"][k] for p in pieces]) for k in pieces[0]["ints"]}
    source = files[0] if len(files) == 1 else f"{files[0]} + {len(files) - 1} more"
    return cat, ints, {"source": source, "files": files,
                       "time_source": "obt" if sclk is not None else "time_utc"}


def read_science_products(
    labels: Sequence[Path], sensor: str, *, sclk=None, lsk=None
) -> xr.Dataset:
    """Read EDITED science products of one sensor into the Dataset of `io.read_science_csv`.

    Parameters
    ----------
    labels : sequence of Path
        Detached labels ``RPCMAG<yymmdd>T<hhmm>_RAW_<sensor>_M<mode>.LBL``, any order.
    sensor : {"OB", "IB"}
    sclk : fluxcal.geometry.time.SclkKernel, optional
        Rosetta SCLK (id -226): times from TIME.OBT; default: from TIME.UTC.
    lsk : LeapSecondTable, optional

    Returns
    -------
    xarray.Dataset
        As `io.read_science_csv`: ``epoch``, ``obt``, ``sid`` (the ``M<mode>`` of each
        file's name, per sample), ``b_counts`` (columns ``BX.<S>``, ``BY.<S>``,
        ``BZ.<S>``), ``t_ob_counts``, ``t_ib_counts``, ``quality``, ``row`` (the row of
        the record in its table, 1-based); files in time order.  ``attrs["source"]``
        is the label (one file) or ``"<first label> + N more"``, ``attrs["files"]``
        every label.

    Raises
    ------
    InputFormatError
        A missing column, a non-integer count, a value out of the word's range, a time
        that cannot be parsed or goes backwards, a record of the other sensor
        (QUALITY bit 3), files overlapping in time; each naming file, row and column.
        Malformed labels and tables: `fluxcal.archive.pds3.read_table`.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.2 (columns), 4.2.3.5 (SID).
    """
    sensor = check_sensor(sensor)
    pieces = []
    for label in labels:
        label = label_of(Path(label))
        product = parse_name(label)
        if product is None or product.kind != sensor:
            raise InputFormatError(
                f"not an EDITED {sensor} science product name "
                f"(RPCMAG<yymmdd>T<hhmm>_RAW_{sensor}_M<mode>.LBL)", path=str(label))
        ds = _read(label)
        epoch, obt = _times(ds, label, sclk, lsk)
        ints = {
            csv_name: _integers(_column(ds, name.format(s=sensor), label).values,
                                name.format(s=sensor), csv_name, _data_file(ds, label))
            for name, csv_name in SCIENCE_FIELDS.items()
        }
        wrong = wrong_quality(ints["quality"], sensor)
        if np.any(wrong):
            i = int(np.flatnonzero(wrong)[0])
            raise InputFormatError(
                f"quality {int(ints['quality'][i])} does not belong to a {sensor} vector "
                "(bit 3 must be " + str(int(sensor == "IB")) + ", bits above 3 must be 0; "
                "RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 4.1.2)",
                path=str(_data_file(ds, label)), line=i + 1, field="QUALITY")
        pieces.append({"label": label, "epoch": epoch, "obt": obt, "ints": ints,
                       "sid": np.full(obt.size, product.mode, dtype=np.int16),
                       "row": np.arange(1, obt.size + 1)})
    cat, ints, attrs = _join(pieces, f"{sensor} science", sclk)
    return science_dataset(cat["epoch"], cat["obt"], cat["sid"], ints, cat["row"],
                           "row in its table", {"sensor": sensor, **attrs})


def read_hk_products(labels: Sequence[Path], *, sclk=None, lsk=None) -> xr.Dataset:
    """Read EDITED HK products into the Dataset of `io.read_hk_csv` (sec. 4.1.1 columns).

    Files in time order; errors as `read_science_products`.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.1.
    """
    pieces = []
    for label in labels:
        label = label_of(Path(label))
        product = parse_name(label)
        if product is None or product.kind != "HK":
            raise InputFormatError(
                "not an EDITED HK product name (RPCMAG<yymmdd>T<hhmm>_RAW_HK.LBL)",
                path=str(label))
        ds = _read(label)
        epoch, obt = _times(ds, label, sclk, lsk)
        ints = {csv_name: _integers(_column(ds, name, label).values, name, csv_name,
                                    _data_file(ds, label))
                for name, csv_name in HK_FIELDS.items()}
        pieces.append({"label": label, "epoch": epoch, "obt": obt, "ints": ints})
    cat, ints, attrs = _join(pieces, "HK", sclk)
    return hk_dataset(cat["epoch"], cat["obt"], ints, attrs)


# ----------------------------------------------------------------------------------------
# One entry for both input layouts: today's CSV files and the archive's EDITED products
# (here, not in `io`: the simulator uses `io`'s writers and must not reach `level_a`)
# ----------------------------------------------------------------------------------------
def read_science(source, sensor: str, *, sclk=None, lsk=None) -> xr.Dataset:
    """Read raw science of ``sensor`` from a CSV file or from EDITED archive products.

    ``source`` is a CSV file (`io.read_science_csv`), or a folder of EDITED products, one
    ``.LBL``/``.TAB`` product, or a sequence of labels (`read_science_products`); both
    give the same Dataset.
    """
    if is_archive_source(source):
        return read_science_products(science_labels(source, sensor), sensor, sclk=sclk,
                                     lsk=lsk)
    return read_science_csv(source, sensor, sclk=sclk, lsk=lsk)


def read_hk(source, *, sclk=None, lsk=None) -> xr.Dataset:
    """Read raw HK from a CSV file or from EDITED archive HK products (see `read_science`)."""
    if is_archive_source(source):
        return read_hk_products(hk_labels(source), sclk=sclk, lsk=lsk)
    return read_hk_csv(source, sclk=sclk, lsk=lsk)


def source_files(source, sensor: str | None = None) -> list[Path]:
    """Return the files of a raw source (provenance, manifests): the CSV, or labels, tables.

    ``sensor`` picks the science products of one sensor in a folder (``None``: HK).
    """
    if not is_archive_source(source):
        return [Path(source)]
    labels = hk_labels(source) if sensor is None else science_labels(source, sensor)
    return [p for label in labels for p in (label, table_of(label))]
