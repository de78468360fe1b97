"""MESSENGER MAG CDR products: archive-like tables per frame and day, and averages.

Column layout follows the archived MESSENGER CDR tables: ``year doy hour minute second
met x y z bx by bz`` (corrected UTC, corrected MET, position in km, field in nT) plus
the SHC quality flag.  RTN products carry ``r lat az`` (km, deg, deg) as position.
Averaged products (``...SCIAVG``) carry the bin centre time, the number of samples, the
mean position and field and the standard deviation of each field component.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9, 10, 11, 12.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from fluxcal.missions.messenger.levels import FRAMES
from fluxcal.products import write_product
from fluxcal.products.atomic import atomic_group

#: Position variable of each frame's product.
POSITION_OF = {"mso": "pos_mso", "j2000": "pos_j2000", "mbf": "pos_mbf", "rtn": "pos_rtn",
               "sc": "pos_j2000", "vso": "pos_j2000"}
AVERAGES_S = (1, 5, 10, 60)


def _utc_fields(et: np.ndarray) -> dict[str, np.ndarray]:
    from fluxcal.geometry.time import et_to_utc

    text = et_to_utc(np.atleast_1d(et), style="doy", digits=3)  # "YYYY DOY HH MM SS.sss"
    width = 21
    if text.size and int(np.char.str_len(text).max()) != width:
        raise ValueError("unexpected UTC string width")
    d = (np.frombuffer(text.astype(f"S{width}").tobytes(), dtype=np.uint8)
         .reshape(-1, width).astype(np.int64) - 48)

    def num(a: int, b: int) -> np.ndarray:
        out = np.zeros(d.shape[0], dtype=np.int64)
        for k in range(a, b):
            out = out * 10 + d[:, k]
        return out

    return {
        "year": num(0, 4).astype(np.int16),
        "doy": num(5, 8).astype(np.int16),
        "hour": num(9, 11).astype(np.int8),
        "minute": num(12, 14).astype(np.int8),
        "second": num(15, 17) + num(18, 21) / 1000.0,
    }


def product_dataset(ds: xr.Dataset, frame: str) -> xr.Dataset:
    """Return the product content (time, position, field, flag) for one frame.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 9-12.
    """
    utc = _utc_fields(ds["et"].values)
    pos = ds[POSITION_OF[frame]]
    data = {k: ("time", v, {"units": u}) for (k, v), u in zip(
        utc.items(), ("year", "day", "h", "min", "s"), strict=True)}
    data["met"] = ("time", ds["met_corrected"].values, {"units": "s",
                   "description": "MET corrected for the net lag"})
    data["position"] = (("time", "component"), pos.values, dict(pos.attrs))
    data["b"] = (("time", "component"), ds[f"b_{frame}"].values,
                 {"units": "nT", "description": f"magnetic field in {FRAMES[frame][0]}"})
    data["quality"] = ("time", ds["quality"].values, {"units": "1",
                       "description": "SHC data quality flag (Table 5)"})
    return xr.Dataset(data, coords={"epoch": ds["epoch"], "component": ["x", "y", "z"]},
                      attrs=dict(ds.attrs))


def average(prod: xr.Dataset, seconds: int, day_start_tt2000: int) -> xr.Dataset:
    """Average a product over ``seconds``-long bins counted from the day start.

    Returns the bin centre ``epoch``, ``count``, mean ``position`` and ``b``, and
    ``b_std`` (population standard deviation of each field component).
    """
    epoch = prod["epoch"].values
    width = np.int64(seconds) * 1_000_000_000
    idx = (epoch - day_start_tt2000) // width
    bins, inv, count = np.unique(idx, return_inverse=True, return_counts=True)

    def mean(v: np.ndarray) -> np.ndarray:
        sums = [np.bincount(inv, v[:, j], bins.size) for j in range(3)]
        return np.stack(sums, axis=1) / count[:, None]

    b = prod["b"].values
    bm = mean(b)
    var = mean(b * b) - bm * bm
    centre = day_start_tt2000 + bins * width + width // 2
    q = np.zeros(bins.size, dtype=prod["quality"].dtype)
    np.maximum.at(q, inv, prod["quality"].values)
    vec = ("time", "component")
    return xr.Dataset(
        {
            "count": ("time", count.astype(np.int32), {"units": "1",
                      "description": "number of samples in the bin"}),
            "position": (vec, mean(prod["position"].values), dict(prod["position"].attrs)),
            "b": (vec, bm, {"units": "nT", "description": "mean field"}),
            "b_std": (vec, np.sqrt(np.maximum(var, 0.0)), {"units": "nT",
                      "description": "standard deviation of each field component"}),
            "quality": ("time", q, {"units": "1", "description": "largest SHC flag in the bin"}),
        },
        coords={"epoch": ("time", centre, {"units": "ns"}), "component": ["x", "y", "z"]},
        attrs=dict(prod.attrs, averaging_interval_s=seconds),
    )


def istp_files() -> tuple[Path, Path]:
    """Return the mission's ISTP (global, variable) attribute files for `write_product`."""
    from fluxcal.missions.messenger.calibration_data import data_dir

    return data_dir() / "istp_global.yaml", data_dir() / "istp_variables.yaml"


@lru_cache(maxsize=1)
def _istp_products() -> tuple[dict, dict]:
    from fluxcal.missions.messenger.calibration_data import data_dir

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


def _columns(frame: str, averaged: bool):
    from fluxcal.products import Column

    pos_label = "{c}" if frame != "rtn" else None
    cols = []
    if averaged:
        cols += [Column("year", "%4d"), Column("doy", "%03d"), Column("hour", "%02d"),
                 Column("minute", "%02d"), Column("second", "%06.3f"),
                 Column("count", "%6d")]
    else:
        cols += [Column("year", "%4d"), Column("doy", "%03d"), Column("hour", "%02d"),
                 Column("minute", "%02d"), Column("second", "%06.3f"), Column("met", "%17.6f")]
    if frame == "rtn":
        cols += [Column("position", "%16.4f", component="x", label="r"),
                 Column("position", "%12.7f", component="y", label="lat"),
                 Column("position", "%12.7f", component="z", label="az")]
    else:
        cols += [Column("position", "%14.3f", label=pos_label)]
    cols += [Column("b", "%11.3f", label="b{c}")]
    if averaged:
        cols += [Column("b_std", "%9.3f", label="sd_b{c}")]
    cols += [Column("quality", "%03d")]
    return cols


def write_day(
    ds: xr.Dataset,
    out_dir: Path,
    frames: Sequence[str],
    formats: Sequence[str],
    averages: Sequence[int],
    provenance: dict,
) -> list[Path]:
    """Write every product of one UTC day (all or nothing) and return the final paths.

    Every file is written under a temporary name; the renames into place happen only
    when every product of the day is complete (`fluxcal.products.atomic.atomic_group`;
    inside a caller's group, at the end of that group).
    """
    from fluxcal.geometry.time import utc_to_tt2000

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    year, doy, yyddd = day_code(ds)
    day0 = np.datetime64(f"{year}-01-01") + np.timedelta64(doy - 1, "D")
    day_start = int(utc_to_tt2000(np.array([f"{day0}T00:00:00"]))[0])
    global_yaml, variable_yaml = istp_files()
    istp = {"global_yaml": global_yaml, "variable_yaml": variable_yaml}
    written: list[Path] = []
    with atomic_group():
        for frame in frames:
            prod = product_dataset(ds, frame)
            prod.attrs.update(provenance)
            stem = FRAMES[frame][1]
            extra = {"PRODUCT_ID": f"{stem}{yyddd}", "COORDINATE_SYSTEM": FRAMES[frame][0]}
            written += write_product(prod, out_dir / f"{stem}{yyddd}", formats,
                                     _columns(frame, False),
                                     dict(extra, **istp_product_attrs(frame)), **istp)
            for sec in averages:
                avg = average(prod, int(sec), day_start)
                avg = avg.assign(_utc_fields_ds(avg))
                name = f"{stem}AVG{yyddd}_{int(sec):02d}"
                written += write_product(avg, out_dir / name, formats, _columns(frame, True),
                                         dict(extra, PRODUCT_ID=name, AVERAGING_INTERVAL_S=sec,
                                              **istp_product_attrs(frame, int(sec))), **istp)
    return written


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
    return xr.Dataset(
        {
            b: (vec, ds[b].values, {"units": "nT", "frame": FRAMES[frame][0],
                                    "description": f"magnetic field in {FRAMES[frame][0]}"}),
            "offset": (vec, ds["offset"].values, {
                "units": "counts",
                "description": "applied offset cT(T) + Delta(t) (thermal + duty cycle), "
                               "fine-range counts (sec. 7)"}),
            "quality": ("time", ds["quality"].values, {"units": "1",
                        "description": "SHC data quality flag (Table 5)"}),
            "distance": ("time", np.linalg.norm(ds["pos_mso"].values, axis=1), {
                "units": "km", "description": "distance of MESSENGER from Mercury's centre"}),
        },
        coords={"epoch": ("time", ds["epoch"].values), "component": ["x", "y", "z"]},
    )


def write_quicklook(ds: xr.Dataset, out_dir: Path, frame: str) -> list[Path]:
    """Write the day's quicklook PNG ``<stem><yyddd>_<yyyymmdd>.png`` (atomically).

    Panels: the field in ``frame``, its magnitude, the applied offsets, the quality
    flag and the distance from Mercury (`fluxcal.products.quicklook.write_quicklooks`).
    """
    from fluxcal.products.quicklook import write_quicklooks

    yyddd = day_code(ds)[2]
    return write_quicklooks(quicklook_dataset(ds, frame), Path(out_dir),
                            f"{FRAMES[frame][1]}{yyddd}", field=f"b_{frame}",
                            frame=FRAMES[frame][0])


def _day_et(ds: xr.Dataset) -> np.ndarray:
    """Return the times that decide a sample's product day (recorded EDR time if known)."""
    return ds["et_recorded"].values if "et_recorded" in ds else ds["et"].values


def day_code(ds: xr.Dataset) -> tuple[int, int, str]:
    """Return (year, day of year, ``yyddd``) of the first sample's (EDR) UTC day."""
    utc = _utc_fields(_day_et(ds)[:1])
    year, doy = int(utc["year"][0]), int(utc["doy"][0])
    return year, doy, f"{year % 100:02d}{doy:03d}"


def _utc_fields_ds(avg: xr.Dataset) -> dict:
    from fluxcal.geometry.time import tt2000_to_et

    utc = _utc_fields(tt2000_to_et(avg["epoch"].values))
    return {k: ("time", v, {"units": u}) for (k, v), u in zip(
        utc.items(), ("year", "day", "h", "min", "s"), strict=True)}


def split_days(ds: xr.Dataset) -> list[xr.Dataset]:
    """Split a calibrated dataset by the UTC day of the recorded (EDR) time.

    A sample stays in its EDR day even when the lag correction moves its time a few
    hundredths of a second across midnight, so each EDR day gives exactly one CDR day.
    """
    utc = _utc_fields(_day_et(ds))
    key = utc["year"].astype(np.int64) * 1000 + utc["doy"]
    edges = np.flatnonzero(np.diff(key)) + 1
    bounds = np.concatenate([[0], edges, [key.size]])
    return [ds.isel(time=slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
