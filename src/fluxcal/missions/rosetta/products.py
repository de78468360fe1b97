"""The products of the RPC-MAG pipeline: names, columns, declarations and the quicklook.

The level functions (`level_a`, `level_b`, `level_c`, `averaged.average`) are pure; the
run around them is `fluxcal.missions.rosetta.routes.RosettaRun` on the generic driver.
This module names and declares the products (`fluxcal.products.declared`: the driver
writes them); the checks and the previous day's tail of a batch day are
`fluxcal.missions.rosetta.day_edges`.

Tables carry the archive's names (`level_products`): calibrated levels
``RPCMAG<yymmdd>T<hhmm>_CL<A|B|C>_<OB|IB>_M<mode>.TAB`` (a new file at each mode change),
resampled levels ``RPCMAG<yymmdd>_CL<E|F|G>_<OB|IB>_A<NN>.TAB``, with the columns of the
seed's tables: TIME.UTC (ISO, 6 decimals), TIME.OBT, [POSITION.X/Y/Z for C/G], BX, BY,
BZ, [T in K for A/B], QUALITY.  CDF/netCDF files are daily with ISTP names.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.5 (LEVEL_A table), 4.3.1 (B), 4.4.1 (C),
   4.6-4.8 (E, F, G).
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.errors import FluxcalError
from fluxcal.geometry.days import utc_days
from fluxcal.geometry.time import tt2000_to_utc
from fluxcal.missions.rosetta import hk, level_a
from fluxcal.products import Column
from fluxcal.products.declared import Declared, Product, Quicklook

log = logging.getLogger(__name__)

LEVELS = ("A", "B", "C", "E", "F", "G")
CALIBRATED_LEVELS = ("A", "B", "C")
PRODUCT_CODE = {lev: f"CL{lev}" for lev in LEVELS}
QUICKLOOK_STEM = "RPCMAG_QL_{sensor}"
#: ISTP ``Data_version`` of the CDF products (file names ``..._v01.cdf``).
DATA_VERSION = 1


def istp_yaml() -> dict[str, Path]:
    """Rosetta ISTP attribute files: ``{"global_yaml": ..., "variable_yaml": ...}``.

    ``missions/rosetta/data/istp_global.yaml`` (Project, Source_name, Descriptor,
    Discipline, ...) and ``istp_variables.yaml`` (the variables of the RPC-MAG levels),
    of the declared products (`fluxcal.products.declared.Product`).
    """
    data = Path(__file__).resolve().parent / "data"
    return {"global_yaml": data / "istp_global.yaml",
            "variable_yaml": data / "istp_variables.yaml"}


def average_code(seconds: float) -> str:
    """``A<NN>`` of a resampled product: ``A01``, ``A60``; fractions as ``A0p5``."""
    seconds = float(seconds)
    if seconds <= 0:
        raise FluxcalError(f"averaging interval must be positive, not {seconds} s")
    if seconds == round(seconds):
        return f"A{int(round(seconds)):02d}"
    return "A" + f"{seconds:g}".replace(".", "p")


def calibrated_tab_stem(time_utc: str, level: str, sensor: str, mode: int) -> str:
    """Archive name of a calibrated table: ``RPCMAG<yymmdd>T<hhmm>_CL<A|B|C>_<sensor>_M<mode>``.

    ``time_utc`` is the TIME.UTC of the file's first vector (``YYYY-MM-DDTHH:MM:SS...``);
    ``mode`` the filter mode (SID) of the file's vectors (docs/formats/rosetta.md).
    """
    t = str(time_utc)
    return f"RPCMAG{t[2:4]}{t[5:7]}{t[8:10]}T{t[11:13]}{t[14:16]}_CL{level}_{sensor}_M{int(mode)}"


#: Level each resampled level averages in the calibration chain (seed 003 sec. 4.6-4.8);
#: made from another level (F from K, G from L: the heater paths of sec. 4.7-4.13), its
#: names say so (`made_from`).
AVERAGED_FROM = {"E": "A", "F": "B", "G": "C"}


def made_from(attrs: dict, level: str) -> str | None:
    """Return the source level of a resampled level made from an unusual one, else None.

    ``attrs["averaged_from"]`` (``"LEVEL_K"``) names it; F from B, G from C and E from A
    (`AVERAGED_FROM`), and calibrated levels, return None.
    """
    src = str(attrs.get("averaged_from", "")).upper().removeprefix("LEVEL_")
    if not src or level in CALIBRATED_LEVELS or AVERAGED_FROM.get(level) == src:
        return None
    return src


def resampled_tab_stem(day: np.datetime64, level: str, sensor: str, seconds: float,
                       source: str | None = None) -> str:
    """Archive name of a resampled table: ``RPCMAG<yymmdd>_CL<E|F|G>_<sensor>_A<NN>``.

    ``source`` (`made_from`) appends ``_FROM<source>``: LEVEL_F from LEVEL_K is
    ``RPCMAG<yymmdd>_CLF_<sensor>_A<NN>_FROMK``, beside the F from B of the same day.
    """
    d = str(np.datetime64(day, "D"))
    stem = f"RPCMAG{d[2:4]}{d[5:7]}{d[8:10]}_CL{level}_{sensor}_{average_code(seconds)}"
    return f"{stem}_FROM{source.upper()}" if source else stem


def logical_source(level: str, sensor: str, seconds: float | None = None,
                   source: str | None = None) -> str:
    """ISTP ``Logical_source`` of a level product, without date (e.g. ``rosetta_rpcmag_cla-ob``).

    Resampled levels carry the interval: ``rosetta_rpcmag_clf-ob-a01``; one made from an
    unusual level (``source``, `made_from`) also that: ``rosetta_rpcmag_clf-ob-a01-fromk``.
    """
    base = f"rosetta_rpcmag_cl{level}-{sensor}".lower()
    if level in CALIBRATED_LEVELS or seconds is None:
        return base
    base = f"{base}-{average_code(seconds).lower()}"
    return f"{base}-from{source.lower()}" if source else base


def product_columns(level: str) -> list:
    """Table columns of a level (seed 003 tables of sec. 4.2.3.5, 4.3.1, 4.4.1, 4.6-4.8)."""
    cols = [
        Column("time_utc", "A26", "UTC", "TIME.UTC, UTC time of observation, microseconds",
               label="TIME.UTC", data_type="TIME"),
        Column("obt", "F17.6", "s", "TIME.OBT, s/c clock, s since 2003-01-01", label="TIME.OBT"),
    ]
    if level in ("C", "G"):
        cols += [
            Column(
                "position",
                "F15.3",
                "km",
                f"spacecraft position, {c.upper()}",
                component=c,
                label=f"POSITION.{c.upper()}",
            )
            for c in "xyz"
        ]
    cols += [
        Column(
            "b",
            "F11.3",
            "nT",
            f"magnetic field {c.upper()} component, calibrated",
            component=c,
            label=f"B{c.upper()}",
        )
        for c in "xyz"
    ]
    if level in ("A", "B"):
        cols.append(Column("temperature", "F8.2", "K", "sensor temperature", label="T"))
    cols.append(
        Column("quality", "I2", "1", "quality flag (RO-IGEP-TR0028 sec. 4.1.2)", label="QUALITY")
    )
    return cols


def level_products(
    ds: xr.Dataset,
    formats: Sequence[str] = ("tab", "cdf"),
    *,
    lsk=None,
    **common: Any,
) -> Iterator[Product]:
    """Declare one level of one sensor (`fluxcal.products.declared`), part by part.

    Tables (``tab``) carry the archive's names: calibrated levels A, B, C one file per
    UTC day and measurement-mode segment (``RPCMAG<yymmdd>T<hhmm>_CL<A|B|C>_<sensor>_M<sid>``,
    `calibrated_tab_stem`), resampled levels E, F, G one per UTC day
    (`resampled_tab_stem`).  CDF, netCDF and Zarr are one product per UTC day named by
    the ISTP convention ``rosetta_rpcmag_cl<level>-<sensor>[-a<NN>]_<yyyymmdd>_v01``.
    ``common``: further `~fluxcal.products.declared.Product` fields of every part (the
    sensor's ``inputs`` and ``calibration``).

    Raises
    ------
    FluxcalError
        No vectors, or two mode segments of one day that would get the same table name
        (same mode starting twice within one minute).
    """
    level, sensor = ds.attrs["level"], ds.attrs["sensor"]
    seconds = ds.attrs.get("average_seconds")
    epoch = ds["epoch"].values
    if epoch.size == 0:
        raise FluxcalError(f"LEVEL_{level} {sensor}: no vectors left to write")
    src_level = made_from(ds.attrs, level)
    source = logical_source(level, sensor, seconds, src_level)
    ds = ds.assign(
        time_utc=(
            "time",
            tt2000_to_utc(_round_us(epoch), digits=6, lsk=lsk),
            {"units": "UTC", "description": "TIME.UTC rounded to the microsecond"},
        )
    )
    attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("stitch_")}
    common = {**common, "attrs": {"Logical_source": source, "Data_version": str(DATA_VERSION)}}
    extra = {"LEVEL": f"LEVEL_{level}", "SENSOR": sensor}
    if seconds is not None:
        extra["AVERAGE_SECONDS"] = float(seconds)
    other = tuple(f for f in formats if f != "tab")
    day_index, days, _ = utc_days(epoch, lsk)
    for d, day64 in enumerate(days):
        sel = np.flatnonzero(day_index == d)
        if sel.size == 0:
            continue
        day = _dt.date.fromisoformat(str(np.datetime64(day64, "D")))
        # a one-day level is written as it is (a copy of a 20 Hz day is ~400 MB)
        part = ds.copy(deep=False) if sel.size == epoch.size else ds.isel(time=sel)
        part.attrs = dict(attrs)
        segment = part["mode_segment"].values if "mode_segment" in part.coords else None
        part = part.drop_vars("mode_segment", errors="ignore")
        if other:
            yield Product(f"{source}_{day:%Y%m%d}", part, day, other, logical_source=source,
                          version=DATA_VERSION, label_extra=extra, **istp_yaml(), **common)
        if "tab" not in formats:
            continue
        if level not in CALIBRATED_LEVELS:
            stem = resampled_tab_stem(day64, level, sensor, seconds or 1.0, src_level)
            yield Product(stem, part, day, ("tab",), columns=product_columns(level),
                          label_extra=extra, **common)
            continue
        if segment is None:
            segment = np.zeros(sel.size, dtype=np.int32)
        ids, first = np.unique(segment, return_index=True)
        seen: dict[str, int] = {}
        for seg in ids[np.argsort(first)]:
            piece = part.isel(time=np.flatnonzero(segment == seg))
            mode = int(piece["sid"].values[0])
            stem = calibrated_tab_stem(str(piece["time_utc"].values[0]), level, sensor, mode)
            if stem in seen:
                raise FluxcalError(
                    f"LEVEL_{level} {sensor}: two segments of mode {mode} start in the same "
                    f"minute ({stem}); the archive names cannot tell them apart"
                )
            seen[stem] = int(seg)
            yield Product(stem, piece, day, ("tab",), columns=product_columns(level),
                          label_extra={**extra, "FILTER_MODE_SID": mode}, **common)


def quicklook_dataset(levels: dict[str, xr.Dataset]) -> xr.Dataset:
    """Return the dataset drawn by the quicklook option (field, temperature, ...).

    The highest full-resolution level made: LEVEL_C (field in the output frame, sensor
    temperature in K, spacecraft position for the distance panel), else LEVEL_B (s/c
    coordinates), else LEVEL_A (URF).
    """
    for lev in ("C", "B", "A"):
        if lev in levels:
            return levels[lev]
    raise FluxcalError("quicklook needs LEVEL_A, B or C")


#: Astronomical unit (km), IAU 2012 Resolution B2 (exact).
AU_KM = 149_597_870.7


def with_distance(ds: xr.Dataset) -> xr.Dataset:
    """Add the quicklook's ``distance``: from the Sun in AU, from another centre in km.

    LEVEL_C carries ``position`` (km) from its ``position_centre`` attr (the Sun before
    the comet phase, the comet in CSEQ); without a position the dataset is unchanged.
    """
    if "position" not in ds or ds["position"].ndim != 2:
        return ds
    centre = str(ds.attrs.get("position_centre", "")).strip()
    r = np.linalg.norm(ds["position"].values.astype(float), axis=1)
    if centre.upper() in ("SUN", "10"):
        attrs = {"units": "AU", "label": "Sun distance"}
        r = r / AU_KM
    else:
        attrs = {"units": "km", "label": f"distance from {centre.title() or 'centre'}"}
    return ds.assign(distance=("time", r, attrs))


def thermistor_temperatures(
    raw: xr.Dataset, calibrations: dict, nominal: dict
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Both sensors' temperatures (K) from the thermistor words of one science file.

    Every science record carries the OB and IB thermistor words (sec. 4.1.2); the
    temperature of each is converted with its sensor's thermistor calibration
    (sec. 4.2.2.5), once per distinct word.  Bad-quality records are left out.

    Returns
    -------
    dict
        ``{"OB": (epoch, kelvin), "IB": (epoch, kelvin)}``, epoch int64 TT2000 ns.
    """
    good = level_a.good_vectors(raw["quality"].values)
    epoch = raw["epoch"].values[good].astype(np.int64)
    out = {}
    for sensor, cal in calibrations.items():
        words, inverse = np.unique(raw[f"t_{sensor.lower()}_counts"].values[good],
                                   return_inverse=True)
        kelvin = level_a.sensor_temperature(words, cal, nominal) + hk.KELVIN
        out[sensor] = (epoch, kelvin[inverse])
    return out


def quicklook_product(
    levels: dict[str, xr.Dataset],
    temperatures: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> Quicklook:
    """Declare ``RPCMAG_QL_<sensor>_<yyyymmdd>.png`` per UTC day.

    Panels: the field of `quicklook_dataset`, the sensor temperatures (both sensors'
    when ``temperatures`` is given, see `thermistor_temperatures`, interpolated to the
    field's time stamps for drawing; else the sensor's own), quality and distance.
    """
    ds = quicklook_dataset(levels)
    if temperatures:
        t = ds["epoch"].values.astype(np.int64)
        extra = {}
        for sensor, (epoch, kelvin) in temperatures.items():
            if epoch.size:
                values = np.interp((t - t[0]) / 1e9, (epoch - t[0]) / 1e9, kelvin)
                extra[f"temperature_{sensor}"] = ("time", values, {"units": "K"})
        if extra:
            ds = ds.drop_vars("temperature", errors="ignore").assign(extra)
    ds = with_distance(ds)
    frame = str(ds["b"].attrs.get("frame", ds.attrs.get("frame", "")) or "") or None
    return Quicklook(QUICKLOOK_STEM.format(sensor=ds.attrs["sensor"]), ds, field="b",
                     frame=frame)


def sensor_products(
    levels: dict[str, xr.Dataset],
    wanted: Sequence[str],
    *,
    formats: Sequence[str] = ("tab", "cdf"),
    quicklook: bool = False,
    temperatures: dict | None = None,
    lsk=None,
    **common: Any,
) -> Iterator[Declared]:
    """Declare one sensor's levels asked for, its HK product and its quicklook.

    ``levels`` maps level names (and ``"HK"``) to datasets; ``wanted`` the levels
    declared (in `LEVELS` order); ``common`` as `level_products`.  Kernels loaded.
    """
    for lev in LEVELS:
        if lev in wanted:
            yield from level_products(levels[lev], formats, lsk=lsk, **common)
    if "HK" in levels:
        yield hk_product(levels["HK"], formats, lsk=lsk, **common)
    if quicklook:
        yield quicklook_product(levels, temperatures)


def parse_levels(text: str) -> list[str]:
    """``"A,B,C"`` -> ``["A", "B", "C"]``, checked against `LEVELS`."""
    levels = [t.strip().upper() for t in str(text).split(",") if t.strip()]
    bad = [lev for lev in levels if lev not in LEVELS]
    if bad or not levels:
        raise FluxcalError(f"unknown level(s) {bad or text!r}; choose from {','.join(LEVELS)}")
    return levels


def _round_us(epoch: np.ndarray) -> np.ndarray:
    """Round TT2000 ns to the nearest microsecond (the TIME.UTC string has 6 digits)."""
    return (np.asarray(epoch, dtype=np.int64) + 500) // 1000 * 1000


def _utc(epoch: np.ndarray, lsk) -> np.ndarray:
    return tt2000_to_utc(epoch, digits=0, lsk=lsk)


def hk_product(ds: xr.Dataset, formats: Sequence[str], *, lsk=None, **common: Any) -> Product:
    """Declare HK LEVEL_A: table ``RPCMAG_<yyyymmdd>_HKA`` (fluxcal's name), ISTP-named CDF."""
    ds = ds.assign(
        time_utc=(
            "time",
            tt2000_to_utc(_round_us(ds["epoch"].values), digits=6, lsk=lsk),
            {"units": "UTC"},
        )
    )
    source = "rosetta_rpcmag_cla-hk"
    day = _dt.date.fromisoformat(str(_utc(ds["epoch"].values[:1], lsk)[0])[:10])
    # column names of seed 003 sec. 4.1.1
    cols = [
        Column("time_utc", "A26", label="TIME.UTC", data_type="TIME"),
        Column("obt", "F17.6", label="TIME.OBT"),
        Column("t_ob", "F8.2", label="T.OB"),
        Column("t_ib", "F8.2", label="T.IB"),
        Column("stage_a_id", "I6", label="STAGE.A.ID"),
        Column("stage_b_id", "I6", label="STAGE.B.ID"),
        Column("filter_cfg", "I6", label="FILTER.CFG"),
        Column("ref_voltage", "F9.5", label="MAG.REF.VOLTAGE"),
        Column("neg_voltage", "F9.5", label="MAG.NEG.VOLTAGE"),
        Column("pos_voltage", "F9.5", label="MAG.POS.VOLTAGE"),
        Column("b_ob", "F11.3", label="B{c}.OB"),
    ]
    return Product(f"RPCMAG_{day:%Y%m%d}_HKA", ds, day, tuple(formats), logical_source=source,
                   version=DATA_VERSION, columns=cols, **istp_yaml(), **common,
                   attrs={"level": "A (HK)", "Logical_source": source,
                          "Data_version": str(DATA_VERSION)})
