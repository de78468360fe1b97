"""MESSENGER MAG CDR/RDR products: the archive's table layouts, in time order, and averages.

Tables (``.TAB``, blank separated, one sample per line), as archived
(docs/formats/messenger.md says which parts are confirmed):

* full resolution (CDR) ``MAG<FFF>SCI<yyddd>_V<nn>``, 12 columns
  ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG X Y Z BX BY BZ``;
* averages (RDR) ``MAG<FFF>SCIAVG<yyddd>_<NN>_V<nn>`` (NN = 01, 05, 10, 60 s), 16 columns
  ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG NAVG X Y Z BX BY BZ DBX DBY DBZ``.

UTC and ``TIME_TAG`` are the lag-corrected time (sec. 5, 9): UTC fields from the integer
TT2000 epoch (milliseconds truncated, as SPICE ``timout`` prints them), ``TIME_TAG`` the
lag-corrected MET; for an average both are the centre of the interval and ``DB*`` are the
population standard deviations of the field components in it.  The SC product has no
position columns; RTN positions are ``R LATITUDE AZIMUTH`` (km, deg, deg, sec. 10.2); the
SHC quality flag (sec. 12) is in the label and the CDF, not in the table.  A table that
takes the archive's name keeps the archive's columns exactly (issue 32): the telemetry
defect flags (the bits of `fluxcal.missions.messenger.defects.DEFECT_FLAGS`; in an
average the OR of its samples' bits) are the CDF/netCDF/Zarr variable ``defect_flag``,
and their spans are in every product's ``defect_spans`` attribute (the TAB's label too)
and the day's ``MAGOFFSETS`` report (docs/decisions/products.md, decision 68).

Samples are written in time order: the lag correction moves samples recorded after a
fast -> slow rate switch before the last fast ones (the net lag grows), so each day is
sorted by its corrected epoch (stable) and of several samples at one epoch only the first
is kept; both counts go to the label, the CDF and the log (`order_day`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (Table 1), 9, 10, 11, 12.
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache, partial
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
import yaml
from numba import njit

from fluxcal.calibration import averaging
from fluxcal.errors import InputFormatError
from fluxcal.geometry.compiled import row_norms, unwrap_degrees
from fluxcal.geometry.days import day_start, from_day_of_year
from fluxcal.geometry.time import (
    SclkKernel,
    et_to_tt2000,
    tt2000_to_et,
    tt2000_to_utc_fields,
    utc_to_et,
)
from fluxcal.missions.messenger.calibration_data import data_dir
from fluxcal.missions.messenger.defects import DEFECT_FLAGS, FLAG_MEANINGS
from fluxcal.missions.messenger.levels import FRAMES, POSITION_VARIABLE, SC_ID, frame_variables
from fluxcal.missions.messenger.options import DEFAULT_VERSION
from fluxcal.products import Column
from fluxcal.products.declared import Product, Quicklook

log = logging.getLogger(__name__)

NS = 1_000_000_000

#: Progress callback: (description, steps done, steps in total).
Progress = Callable[[str, int, int], None]

#: Frame codes the archive uses (confirmed) and the ones that are fluxcal's choice.
CONFIRMED_FRAME_CODES = ("MSO", "MBF", "RTN")


@dataclass(frozen=True)
class OrderReport:
    """What `order_day` did: samples moved back in time, and duplicate epochs dropped."""

    samples: int
    reordered: int
    duplicates: int

    def label_keywords(self) -> dict[str, int]:
        """Label keywords / CDF global attributes (one per meaning)."""
        return {"FLUXCAL_REORDERED_SAMPLES": self.reordered,
                "FLUXCAL_DUPLICATES_DROPPED": self.duplicates}


def time_order(epoch: np.ndarray) -> tuple[np.ndarray | None, OrderReport]:
    """Return the sample index that puts ``epoch`` in strictly increasing order, and the report.

    A stable sort by the corrected epoch (samples at one epoch keep their recorded
    order), then of several samples at one epoch the first is kept and the others
    dropped.  ``reordered`` counts the samples whose epoch is earlier than the latest
    epoch before them in the input (those the sort moves back).  The index is ``None``
    when the epochs already increase strictly (nothing to copy).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (Table 1 net lags), sec. 9.
    """
    epoch = np.asarray(epoch)
    n = epoch.size
    if n < 2 or (np.diff(epoch) > 0).all():
        return None, OrderReport(n, 0, 0)
    latest = np.maximum.accumulate(epoch)
    reordered = int(np.count_nonzero(epoch[1:] < latest[:-1]))
    order = np.argsort(epoch, kind="stable") if reordered else np.arange(n)
    ordered = epoch[order]
    keep = np.ones(n, dtype=bool)
    keep[1:] = ordered[1:] != ordered[:-1]
    duplicates = int(n - np.count_nonzero(keep))
    return (order[keep] if duplicates else order), OrderReport(n, reordered, duplicates)


def _flags(ds: xr.Dataset) -> list[str]:
    """``["defect_flag"]`` when the calibrated day has it (`defects.flag_defects`)."""
    return ["defect_flag"] if "defect_flag" in ds else []


def _defect_flag_variable(values: np.ndarray, averaged: bool = False) -> tuple:
    """Return the products' ``defect_flag`` (uint8 bits; ISTP attrs: istp_variables.yaml)."""
    what = "OR of the samples' defect bits in the interval" if averaged else \
        "local telemetry defect bits"
    return ("time", np.asarray(values, dtype=np.uint8), {
        "units": "1", "description": f"{what} (0: none; "
        + ", ".join(f"{v} {k}" for k, v in DEFECT_FLAGS.items()) + ")",
        "flag_masks": [int(v) for v in DEFECT_FLAGS.values()],
        "flag_meanings": FLAG_MEANINGS})


def _at(var: xr.Variable, index: np.ndarray | None) -> xr.Variable:
    """``var`` at the sample ``index`` along its first axis (itself when ``None``)."""
    if index is None:
        return var
    return xr.Variable(var.dims, np.take(var.values, index, axis=0), var.attrs)


def _take(ds: xr.Dataset, names: Sequence[str], index: np.ndarray | None) -> xr.Dataset:
    """Variables ``names`` of ``ds`` and ``epoch`` at ``index`` (views when ``None``)."""
    return xr.Dataset({name: _at(ds[name].variable, index) for name in names},
                      coords={"epoch": _at(ds["epoch"].variable, index)},
                      attrs=dict(ds.attrs))


@njit(cache=True, nogil=True)
def _reorder_rows_kernel(values, index, buffer):  # pragma: no cover - compiled
    """``values[:m] = values[index]`` (``m = index.size``), one column at a time via ``buffer``.

    Rows already in place (``index[i] == i``, most of a day) are neither read nor written.
    """
    m = index.size
    for c in range(values.shape[1]):
        k = 0
        for i in range(m):
            if index[i] != i:
                buffer[k] = values[index[i], c]
                k += 1
        k = 0
        for i in range(m):
            if index[i] != i:
                values[i, c] = buffer[k]
                k += 1


def _reorder_owned(var: xr.Variable, index: np.ndarray, buffer: np.ndarray) -> xr.Variable:
    """``var`` at ``index``, reordered in its own array one column at a time through ``buffer``.

    For arrays nothing else holds (a frame computed for this product): no second copy of
    the whole array; the result is the first ``index.size`` rows of the same array
    (`_reorder_rows_kernel`, one compiled pass per column).
    """
    values = var.values
    rows = values.reshape(values.shape[0], -1)  # a view: (n,) -> (n, 1)
    _reorder_rows_kernel(rows, np.ascontiguousarray(index, dtype=np.int64), buffer)
    return xr.Variable(var.dims, values[:index.size], var.attrs)


def _with_frame(base: xr.Dataset, ds: xr.Dataset, frame: str,
                index: np.ndarray | None, buffer: np.ndarray | None = None) -> xr.Dataset:
    """Add one frame's field and position (`frame_variables`), in ``index`` order, to ``base``.

    Variables of ``ds`` are copied in that order; those computed for this frame are
    reordered in place (`_reorder_owned`) when a float ``buffer`` of ``ds``'s length is given.
    """
    out = {}
    for name, var in frame_variables(ds, frame).items():
        owned = (index is not None and buffer is not None and name not in ds
                 and var.dtype == buffer.dtype and var.values.flags.c_contiguous)
        out[name] = _reorder_owned(var, index, buffer) if owned else _at(var, index)
    return base.assign(out)


def _log_order(ds: xr.Dataset, report: OrderReport) -> None:
    if report.reordered or report.duplicates:
        log.log(logging.WARNING if report.duplicates else logging.INFO,
                "day %s: %d of %d samples moved back into time order, %d duplicate "
                "epoch(s) dropped (first kept)", day_code(ds)[2], report.reordered,
                report.samples, report.duplicates)


def order_day(ds: xr.Dataset, frames: Sequence[str]) -> tuple[xr.Dataset, OrderReport]:
    """Return the variables the products of ``frames`` need, in time order, and the report.

    `time_order` applied to ``epoch``, ``et``, ``met_corrected``, ``quality``,
    ``b_<frame>`` and the frame's position (`frame_variables`: taken from ``ds`` or
    computed from its J2000 field); `day_products` does the same one frame at a time (less
    memory).

    Parameters
    ----------
    ds : xarray.Dataset
        One calibrated day (`fluxcal.missions.messenger.chain.calibrate`, split by
        `split_days`).
    frames : sequence of str
        Product frames (keys of `FRAMES`).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (Table 1 net lags), sec. 9.
    """
    index, report = time_order(ds["epoch"].values)
    out = _take(ds, ["et", "met_corrected", "quality", *_flags(ds)], index)
    for frame in frames:
        out = _with_frame(out, ds, frame, index)
    _log_order(ds, report)
    return out, report


#: Samples per call of `tt2000_to_utc_fields` in `utc_columns` (its eight int64 fields
#: of a whole 20 Hz day would be 110 MB of temporaries; a chunk's are 17 MB).
UTC_CHUNK = 1 << 18


def utc_columns(epoch: np.ndarray) -> dict[str, xr.Variable]:
    """Return the UTC columns YEAR, DAY_OF_YEAR, HOUR, MINUTE, SECOND of int64 TT2000.

    ``second`` is the second of the minute with the milliseconds truncated
    (``SS.sss``, what SPICE ``timout`` prints with ``SC.###``), computed from the integer
    epoch (`fluxcal.geometry.time.tt2000_to_utc_fields`, `UTC_CHUNK` samples at a time),
    never from a float time.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9.
    """
    epoch = np.asarray(epoch)
    n = epoch.size
    cols = {"year": np.empty(n, np.int16), "doy": np.empty(n, np.int16),
            "hour": np.empty(n, np.int8), "minute": np.empty(n, np.int8),
            "second": np.empty(n)}
    for a in range(0, n, UTC_CHUNK):
        part = slice(a, min(n, a + UTC_CHUNK))
        f = tt2000_to_utc_fields(epoch[part])
        for name in ("year", "doy", "hour", "minute"):
            cols[name][part] = f[name]
        cols["second"][part] = f["second"] + (f["nanosecond"] // 1_000_000) / 1000.0
    t = ("time",)
    return {
        "year": xr.Variable(t, cols["year"], {"units": "year"}),
        "doy": xr.Variable(t, cols["doy"], {"units": "day"}),
        "hour": xr.Variable(t, cols["hour"], {"units": "h"}),
        "minute": xr.Variable(t, cols["minute"], {"units": "min"}),
        "second": xr.Variable(t, cols["second"], {"units": "s", "description":
                                                  "second of the minute, ms truncated"}),
    }


def coordinate_system(frame: str) -> str:
    """Frame code of the products (``MSO``, ``MBF``, ``RTN`` as archived; fluxcal's others)."""
    return frame.upper()


def _component_labels(frame: str) -> list[str]:
    return ["B_R", "B_T", "B_N"] if frame == "rtn" else ["B_X", "B_Y", "B_Z"]


def product_dataset(ds: xr.Dataset, frame: str) -> xr.Dataset:
    """Return one frame's full-resolution product content (no copy of the big arrays).

    ``ds`` is the ordered day of `order_day`.  Variables: ``met`` (TIME_TAG, lag-corrected
    MET s), ``b`` (time, b_component) nT with frame-specific component labels, ``b_total``
    (``|B|``, nT), ``quality`` (SHC flag), and the position: ``position`` (time,
    position_component) km for MSO, MBF (Mercury-centred), J2000 (Sun-centred) and VSO
    (Venus-centred); ``r`` (km), ``latitude`` and ``azimuth`` (deg) for RTN; none for SC.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12.
    """
    spice_frame = FRAMES[frame][0]
    b = ds[f"b_{frame}"].values
    total = np.empty(b.shape[0])
    if b.shape[0]:
        row_norms(np.ascontiguousarray(b, dtype=float), total)
    vec = ("time", "b_component")
    data: dict[str, tuple] = {
        "met": ("time", ds["met_corrected"].values,
                {"units": "s", "description": "MET corrected for the net lag (TIME_TAG)"}),
        "b": (vec, b, {"units": "nT", "description": f"magnetic field in {spice_frame}",
                       "coordinate_system": coordinate_system(frame)}),
        "b_total": ("time", total, {"units": "nT", "description": "field magnitude |B|"}),
        "quality": ("time", ds["quality"].values,
                    {"units": "1", "description": "SHC data quality flag (Table 5)"}),
    }
    if "defect_flag" in ds:
        data["defect_flag"] = _defect_flag_variable(ds["defect_flag"].values)
    pos_name = POSITION_VARIABLE[frame]
    coords: dict[str, tuple] = {"epoch": ("time", ds["epoch"].values, ds["epoch"].attrs),
                                "b_component": ("b_component", _component_labels(frame))}
    if frame == "rtn":
        pos = ds[pos_name].values
        data["r"] = ("time", pos[:, 0], {"units": "km",
                                         "description": "distance of MESSENGER from the Sun"})
        data["latitude"] = ("time", pos[:, 1], {
            "units": "deg", "description": "latitude above the instantaneous ecliptic"})
        data["azimuth"] = ("time", pos[:, 2], {
            "units": "deg", "description": "ecliptic azimuth from the Earth-Sun line"})
    elif pos_name is not None:
        pos = ds[pos_name]
        data["position"] = (("time", "position_component"), pos.values,
                            dict(pos.attrs, coordinate_system=coordinate_system(frame)))
        coords["position_component"] = ("position_component", ["X", "Y", "Z"])
    return xr.Dataset(data, coords=coords, attrs=dict(ds.attrs))


def average(
    prod: xr.Dataset,
    seconds: int,
    day_start_tt2000: int,
    *,
    bins: averaging.Bins | None = None,
    sclk=None,
    met: np.ndarray | None = None,
) -> xr.Dataset:
    """Average a product over ``seconds``-long bins counted from the day start.

    Returns the bin centre ``epoch`` (exact integer ns), ``count`` (NAVG), the mean of the
    position variables (the azimuth unwrapped across +-180 deg first), the mean ``b``,
    ``b_std`` (population standard deviation per component, two-pass:
    `fluxcal.calibration.averaging.bin_mean_std`), ``b_total`` (``|mean B|``), ``quality``
    (the largest flag in the bin) and, when the product has ``met``, the lag-corrected
    MET of the bin centre (``met`` when given, e.g. shared by several frames; else through
    the SCLK kernel ``sclk``, default the loaded one).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9 (time), sec. 12 (flag).
    """
    epoch = prod["epoch"].values
    width = int(seconds) * NS
    if bins is None:
        bins = averaging.bin_index(epoch, width, day_start_tt2000)
    b_mean, b_std = averaging.bin_mean_std(bins, prod["b"].values)
    total = np.empty(b_mean.shape[0])
    if total.size:
        row_norms(np.ascontiguousarray(b_mean), total)
    vec = ("time",) + prod["b"].dims[1:]
    data: dict[str, tuple] = {
        "count": ("time", bins.counts.astype(np.int32),
                  {"units": "1", "description": "number of samples in the interval (NAVG)"}),
        "b": (vec, b_mean, {**prod["b"].attrs, "description": "mean field"}),
        "b_std": (vec, b_std, {"units": "nT", "description":
                               "population standard deviation of each field component"}),
        "b_total": ("time", total, {"units": "nT", "description": "magnitude of the mean field"}),
        "quality": ("time", averaging.bin_max(bins, prod["quality"].values),
                    {"units": "1", "description": "largest SHC flag in the interval"}),
    }
    if "defect_flag" in prod:
        data["defect_flag"] = _defect_flag_variable(
            averaging.bin_bitwise_or(bins, prod["defect_flag"].values), averaged=True)
    for name in ("position", "r", "latitude"):
        if name in prod:
            var = prod[name]
            data[name] = (var.dims, averaging.bin_mean(bins, var.values), dict(var.attrs))
    if "azimuth" in prod:  # unwrapped as np.unwrap(period=360) does, without temporaries
        az = np.empty(prod.sizes["time"])
        unwrap_degrees(prod["azimuth"].values, az)
        az = averaging.bin_mean(bins, az)
        data["azimuth"] = ("time", (az + 180.0) % 360.0 - 180.0, dict(prod["azimuth"].attrs))
    if "met" in prod:
        met = _met_at(bins.centre, sclk) if met is None else met
        data["met"] = ("time", met, dict(
            prod["met"].attrs, description="lag-corrected MET of the interval centre"))
    coords = {k: v for k, v in prod.coords.items() if k != "epoch"}
    coords["epoch"] = ("time", bins.centre, prod["epoch"].attrs)
    return xr.Dataset(data, coords=coords, attrs=dict(prod.attrs, averaging_interval_s=seconds))


def _met_at(tt2000: np.ndarray, sclk) -> np.ndarray:
    """Clock reading (MET s) at TT2000 epochs through the SCLK kernel."""
    if tt2000.size == 0:
        return np.zeros(0)
    sclk = sclk or SclkKernel.from_pool(SC_ID)
    return sclk.from_et(tt2000_to_et(tt2000))[1]


def istp_files() -> tuple[Path, Path]:
    """Return the mission's ISTP (global, variable) attribute files of its products."""
    return data_dir() / "istp_global.yaml", data_dir() / "istp_variables.yaml"


@lru_cache(maxsize=1)
def _istp_products() -> tuple[dict, dict]:
    glob = yaml.safe_load((data_dir() / "istp_global.yaml").read_text())
    table = yaml.safe_load((data_dir() / "istp_products.yaml").read_text())
    return glob, table


def istp_product_attrs(frame: str, seconds: int | None = None) -> dict[str, str]:
    """ISTP ``Data_type``, ``Logical_source`` and its description for one product.

    ``Logical_source`` follows the ISTP rule ``source_descriptor_datatype`` (the short
    forms before ``>``, lower case), e.g. ``messenger_mag_mso-sci`` or
    ``messenger_mag_mso-avg60``.

    Parameters
    ----------
    frame : str
        Frame key of `FRAMES`.
    seconds : int, optional
        Averaging interval of a ``SCIAVG`` product; ``None`` for full resolution.
    """
    glob, table = _istp_products()
    template = table["full" if seconds is None else "average"]
    fields = {"FRAME": frame.upper(), "frame_name": table["frames"][frame],
              "seconds": seconds}
    out = {k: " ".join(str(v).format(**fields).split()) for k, v in template.items()}
    short = [str(x).split(">")[0].strip() for x in
             (glob["Source_name"], glob["Descriptor"], out["Data_type"])]
    out["Logical_source"] = "_".join(short).lower()
    return out


def product_name(frame: str, yyddd: str, version: int, seconds: int | None = None) -> str:
    """Archive file name stem: ``MAG<FFF>SCI<yyddd>_V<nn>`` or ``...SCIAVG<yyddd>_<NN>_V<nn>``.

    Examples
    --------
    >>> product_name("mso", "12153", 1), product_name("rtn", "12153", 8, 60)
    ('MAGMSOSCI12153_V01', 'MAGRTNSCIAVG12153_60_V08')
    """
    if not 0 < int(version) < 100:
        raise ValueError(f"product version must be 1..99, not {version}")
    stem = FRAMES[frame][1]
    if seconds is None:
        return f"{stem}{yyddd}_V{int(version):02d}"
    return f"{stem}AVG{yyddd}_{int(seconds):02d}_V{int(version):02d}"


def table_columns(frame: str, averaged: bool) -> list:
    """Return the archive's table columns, exactly (names as archived; formats fluxcal's).

    CDR: ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG X Y Z BX BY BZ`` (12); RDR adds
    ``NAVG`` after ``TIME_TAG`` and ``DBX DBY DBZ`` at the end (16).  RTN: ``R LATITUDE
    AZIMUTH`` and ``BR BT BN`` (``DBR DBT DBN``) in the same positions; SC: no position
    columns (9 and 13).  No column of fluxcal's own: the defect flags are in the CDF
    (docs/formats/messenger.md, the table of columns).
    """
    cols = [Column("year", "%4d", label="YEAR"), Column("doy", "%03d", label="DAY_OF_YEAR"),
            Column("hour", "%02d", label="HOUR"), Column("minute", "%02d", label="MINUTE"),
            Column("second", "%06.3f", label="SECOND"),
            Column("met", "%17.6f", label="TIME_TAG")]
    if averaged:
        cols.append(Column("count", "%5d", label="NAVG"))
    if frame == "rtn":
        cols += [Column("r", "%14.1f", label="R"), Column("latitude", "%10.5f", label="LATITUDE"),
                 Column("azimuth", "%10.5f", label="AZIMUTH")]
    elif POSITION_VARIABLE[frame] is not None:
        cols += [Column("position", "%14.3f", component=c, label=c) for c in "XYZ"]
    axes = "RTN" if frame == "rtn" else "XYZ"
    labels = _component_labels(frame)
    cols += [Column("b", "%11.3f", component=lab, label=f"B{a}")
             for lab, a in zip(labels, axes, strict=True)]
    if averaged:
        cols += [Column("b_std", "%9.3f", component=lab, label=f"DB{a}")
                 for lab, a in zip(labels, axes, strict=True)]
    return cols


def _quality_keywords(quality: np.ndarray) -> dict:
    """Return the SHC flags present, for the label and the CDF (not a table column)."""
    quality = np.asarray(quality)
    if quality.dtype.kind in "iu" and quality.size and quality.min() >= 0:  # Table 5: 0..222
        counts = np.bincount(quality.ravel())
        flags = np.flatnonzero(counts)
        counts = counts[flags]
    else:
        flags, counts = np.unique(quality, return_counts=True)
    return {"DATA_QUALITY_ID": [f"{int(q):03d}" for q in flags],
            "FLUXCAL_QUALITY_SAMPLES": [int(c) for c in counts]}


def day_products(
    ds: xr.Dataset,
    frames: Sequence[str],
    formats: Sequence[str],
    averages: Sequence[int],
    version: int = DEFAULT_VERSION,
    attrs: Mapping[str, Any] | None = None,
) -> Iterator[Product]:
    """Declare every product of one UTC day (`fluxcal.products.declared`), one frame at a time.

    The day is put in time order first (`time_order`); each frame's field and position
    are taken from ``ds`` or computed from its J2000 field when that frame's products are
    made (`frame_variables`), after the previous frame's were written, so only one
    frame's arrays (and their sorted copies) exist at a time.  The bins of each averaging
    interval, the table's UTC columns, the averages' MET and the quality keywords are
    computed once per day and time grid and shared by all frames.

    Each product is two declarations sharing its content: the table under the archive's
    name (`product_name`) with its UTC columns (`utc_columns`), columns (`table_columns`)
    and label keywords, and the other formats under the ISTP name of its
    ``Logical_source`` (`istp_product_attrs`) with ``Data_version``.

    Parameters
    ----------
    ds : xarray.Dataset
        One calibrated day (`split_days`).
    formats : sequence of str
        Product formats (`fluxcal.products.format_names.FORMATS`).
    version : int
        Product version, the ``_V<nn>`` of the file names (1..99).
    attrs : mapping, optional
        Global attributes set after the provenance (then ``averaging_interval_s``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12.
    """
    year, doy, yyddd = day_code(ds)
    day = from_day_of_year(year, doy)
    day0 = day_start(day)
    index, report = time_order(ds["epoch"].values)
    _log_order(ds, report)
    base = _take(ds, ["met_corrected", "quality", *_flags(ds)], index)
    epoch = base["epoch"].values
    bins = {int(s): averaging.bin_index(epoch, int(s) * NS, day0) for s in averages}
    sclk = SclkKernel.from_pool(SC_ID) if averages and epoch.size else None
    global_yaml, variable_yaml = istp_files()
    common = {"day": day, "variable_yaml": variable_yaml, "global_yaml": global_yaml}
    order_kw = report.label_keywords()
    tab = "tab" in formats
    others = tuple(f for f in formats if f != "tab")
    # per time grid, shared by every frame: the table's UTC columns, the averages' MET
    # (interval centres) and the quality keywords
    utc = {None: utc_columns(epoch), **{s: utc_columns(b.centre) for s, b in bins.items()}} \
        if tab else {}
    met = {s: _met_at(b.centre, sclk) for s, b in bins.items()}
    quality: dict = {None: _quality_keywords(base["quality"].values)}
    # a fast -> slow day's computed frames are put in time order in place through this
    buffer = np.empty(epoch.size) if index is not None else None
    for frame in frames:
        # one frame's field and position at a time (computed here, `frame_variables`)
        prod = product_dataset(_with_frame(base, ds, frame, index, buffer), frame)
        for sec in (None, *averages):
            name = product_name(frame, yyddd, version, sec)
            tab_extra = {"PRODUCT_ID": name, "PRODUCT_VERSION_ID": f"V{int(version):02d}",
                         "COORDINATE_SYSTEM_NAME": FRAMES[frame][0], **order_kw}
            istp = {**istp_product_attrs(frame, sec), **order_kw}
            key = None if sec is None else int(sec)
            out, extra = prod, dict(attrs or {})
            if key is not None:
                out = average(prod, key, day0, bins=bins[key], sclk=sclk, met=met[key])
                # after the provenance, as when it was set before averaging
                extra["averaging_interval_s"] = out.attrs.pop("averaging_interval_s")
                tab_extra["AVERAGING_INTERVAL_S"] = istp["AVERAGING_INTERVAL_S"] = sec
                if key not in quality:  # the largest flag per interval: frame-independent
                    quality[key] = _quality_keywords(out["quality"].values)
            if tab:
                yield Product(name, out.assign(utc[key]), formats=("tab",), attrs=extra,
                              columns=table_columns(frame, key is not None),
                              label_extra={**tab_extra, **quality[key]}, **common)
            if others:
                yield Product(istp["Logical_source"], out, formats=others, attrs=extra,
                              logical_source=istp["Logical_source"], version=version,
                              label_extra={**istp, "Data_version": str(int(version)),
                                           **quality[key]}, **common)
        # free this frame's arrays before the next frame's are made (peak memory)
        del prod, out


def quicklook_dataset(ds: xr.Dataset, frame: str) -> xr.Dataset:
    """Return what the day's quicklook shows, taken from the calibrated day dataset.

    Variables: ``b_<frame>`` (nT), ``offset`` (the applied thermal + duty-cycle offset
    ``cT(T) + Delta(t)`` per axis, fine-range counts), ``quality`` (SHC flag) and
    ``distance`` (MESSENGER from Mercury's centre, km).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, 10.1, 12.
    """
    vec = ("time", "component")
    b = f"b_{frame}"
    field = frame_variables(ds, frame)[b].values
    nt = "offset_nt" in ds  # edr2cdr --quicklook adds it (run.calibrate_run)
    return xr.Dataset(
        {
            b: (vec, field, {"units": "nT", "frame": FRAMES[frame][0],
                                    "description": f"magnetic field in {FRAMES[frame][0]}"}),
            "offset": (vec, ds["offset_nt" if nt else "offset"].values, {
                "units": "nT" if nt else "counts",
                "description": "applied offset cT(T) + Delta(t) (thermal + duty cycle), "
                               "fine-range counts or, given offset_nt, nT (sec. 7, eq. 8)"}),
            "quality": ("time", ds["quality"].values, {"units": "1",
                        "description": "SHC data quality flag (Table 5)"}),
            "distance": ("time", np.linalg.norm(ds["pos_mso"].values, axis=1), {
                "units": "km", "description": "distance of MESSENGER from Mercury's centre"}),
        },
        coords={"epoch": ("time", ds["epoch"].values), "component": ["x", "y", "z"]},
    )


def quicklook(ds: xr.Dataset, frame: str, day: _dt.date | None = None) -> Quicklook:
    """Declare the day's quicklook ``<stem><yyddd>_<yyyymmdd>.png`` (made when drawn).

    Panels: the field in ``frame``, its magnitude, the applied offsets, the quality
    flag and the distance from Mercury (`quicklook_dataset`,
    `fluxcal.products.quicklook.write_quicklooks`).
    """
    return Quicklook(f"{FRAMES[frame][1]}{day_code(ds)[2]}", partial(quicklook_dataset, ds, frame),
                     field=f"b_{frame}", frame=FRAMES[frame][0], day=day)


def recorded_et(ds: xr.Dataset) -> np.ndarray:
    """Return the times that decide a sample's product day (recorded EDR time if known)."""
    return ds["et_recorded"].values if "et_recorded" in ds else ds["et"].values


def _year_doy(et: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f = tt2000_to_utc_fields(et_to_tt2000(np.atleast_1d(et)))
    return f["year"], f["doy"]


def day_code(ds: xr.Dataset) -> tuple[int, int, str]:
    """Return (year, day of year, ``yyddd``) of the first sample's (EDR) UTC day."""
    year, doy = (int(v[0]) for v in _year_doy(recorded_et(ds)[:1]))
    return year, doy, f"{year % 100:02d}{doy:03d}"


def split_days(ds: xr.Dataset) -> list[xr.Dataset]:
    """Split a calibrated dataset by the UTC day of the recorded (EDR) time (no copies).

    A sample stays in its EDR day even when the lag correction moves its time a few
    hundredths of a second across midnight, so each EDR day gives exactly one CDR day.
    The recorded times increase (the readers reject a MET going backwards), so the day
    boundaries are found by binary search of each UTC midnight; the days are slices
    (views) of ``ds``.
    """
    et = recorded_et(ds)
    if et.size == 0:
        return []
    if et.size > 1 and not (np.diff(et) >= 0).all():
        raise InputFormatError("recorded (EDR) times go backwards; the science files must "
                               "be in time order", field="met")  # the readers check it
    (y0, y1), (d0, d1) = _year_doy(et[[0, -1]])
    first, last = from_day_of_year(y0, d0), from_day_of_year(y1, d1)
    midnights = np.arange(first + 1, last + 1, dtype="datetime64[D]")
    edges = np.searchsorted(et, utc_to_et(np.array([f"{d}T00:00:00" for d in midnights])))
    bounds = [0, *edges.tolist(), et.size]
    return [ds.isel(time=slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)
            if b > a]
