"""IMAP MAG L2: L1B (burst) or L1C (normal) with the L2 matrices, offsets and time deltas.

``B = M[range] @ b + offset`` per vector, ``M`` the sensor's 3x3 matrix for the range
from the L2 matrices file (``URFTOORFO`` for MAGo, ``URFTOORFI`` for MAGi: unit reference
frame to the idealised mechanical frame ``IMAP_MAG_BASE``), ``offset`` and the time delta
(s, added to the time tag) per vector from the offsets file, whose ``epoch`` must be the
input's.  The result is in the sensor frame (``IMAP_MAG_BASE``); `to_frame` rotates it
into another frame through `fluxcal.geometry.frames.rotate` with the user's IMAP kernels:
``srf`` (spacecraft, a fixed mounting: the IMAP frames kernel is enough) or the frames
that need attitude and ephemeris (``dsrf``, ``gse``, ``gsm``, ``rtn``); a frame the loaded
kernels do not define is refused by name.

References
----------
IMAP MAG L2 as described by the IMAP Science Operations Center's public
``imap_processing`` package (``mag/l2``: matrix per range, offsets added, time deltas in
seconds, the product truncated to the UTC day; frame names of its ``ValidFrames``), and
the team's L2 files in ``../shared/data/imap/team/calibration``.  docs/decisions/imap.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cdflib
import numpy as np
import spiceypy
import xarray as xr

from fluxcal.calibration.matrices import apply_lookup
from fluxcal.errors import InputFormatError
from fluxcal.geometry.frames import rotate
from fluxcal.geometry.time import tt2000_to_et, utc_day_start_tt2000
from fluxcal.products.timeindex import default_lsk

#: The sensor frame of the L2 field (after the L2 matrix).
SENSOR_FRAME = "IMAP_MAG_BASE"
#: Output frames: name -> SPICE frame of the IMAP frames kernel.
FRAMES = {"sensor": SENSOR_FRAME, "srf": "IMAP_SPACECRAFT", "dsrf": "IMAP_DPS",
          "gse": "IMAP_GSE", "gsm": "IMAP_GSM", "rtn": "IMAP_RTN"}
#: Frames that need attitude (CK) and ephemeris (SPK) besides the frames kernel.
NEED_ATTITUDE = ("dsrf", "gse", "gsm", "rtn")
#: The offsets file stores its epochs to the microsecond (the team's 2025-10-17 pair
#: differs by up to 496 ns): a row belongs to the vector less than 1 us from it.
OFFSET_TIME_TOLERANCE_NS = 1000
_MATRIX = {"mago": "URFTOORFO", "magi": "URFTOORFI"}


@dataclass(frozen=True)
class L2Calibration:
    """The L2 matrices (per sensor, (4, 3, 3) by range) and the per-vector offsets."""

    matrices: dict[str, np.ndarray]
    offset_epoch: np.ndarray
    offsets: np.ndarray
    timedeltas: np.ndarray
    quality_flag: np.ndarray
    quality_bitmask: np.ndarray
    matrices_file: str
    offsets_file: str


def _cdf(path: Path, option: str) -> cdflib.CDF:
    try:
        return cdflib.CDF(str(path))
    except Exception as exc:  # noqa: BLE001 - cdflib raises many kinds on a bad file
        raise InputFormatError(f"not a CDF file ({exc}); give the team's L2 file",
                               path=str(path), field=option) from None


def _var(cdf, path: Path, name: str, option: str) -> np.ndarray:
    if name not in cdf.cdf_info().zVariables:
        raise InputFormatError(f"no variable {name!r}: not the team's L2 file for "
                               f"{option}", path=str(path), field=option)
    return np.asarray(cdf.varget(name))


def load_l2_calibration(matrices: Path, offsets: Path) -> L2Calibration:
    """Read the team's L2 matrices and offsets files.

    The matrices variable is stored (row, column, range): ``M[r][i, j] = var[i, j, r]``.

    Raises
    ------
    InputFormatError
        Not a CDF, a variable missing, or of the wrong shape (naming file and variable).
    """
    matrices, offsets = Path(matrices), Path(offsets)
    cm = _cdf(matrices, "--l2-matrices")
    mats = {}
    for sensor, name in _MATRIX.items():
        arr = _var(cm, matrices, name, "--l2-matrices").astype(np.float64)
        if arr.shape != (3, 3, 4) or not np.isfinite(arr).all():
            raise InputFormatError(f"{name} has shape {arr.shape}, expected finite (3, 3, 4) "
                                   "(row, column, range)", path=str(matrices), field=name)
        mats[sensor] = np.ascontiguousarray(arr.transpose(2, 0, 1))
    co = _cdf(offsets, "--l2-offsets")
    epoch = _var(co, offsets, "epoch", "--l2-offsets").astype(np.int64).reshape(-1)
    off = _var(co, offsets, "offsets", "--l2-offsets").astype(np.float64).reshape(-1, 3)
    dt = _var(co, offsets, "timedeltas", "--l2-offsets").astype(np.float64).reshape(-1)
    if off.shape[0] != epoch.size or dt.size != epoch.size:
        raise InputFormatError(f"offsets {off.shape} / timedeltas {dt.shape} do not match "
                               f"epoch ({epoch.size})", path=str(offsets), field="offsets")
    names = co.cdf_info().zVariables
    flag = (np.asarray(co.varget("quality_flag")).reshape(-1) if "quality_flag" in names
            else np.zeros(epoch.size))
    mask = (np.asarray(co.varget("quality_bitmask")).reshape(-1) if "quality_bitmask" in names
            else np.zeros(epoch.size))
    return L2Calibration(mats, epoch, off, dt, flag.astype(np.uint8), mask.astype(np.uint16),
                         matrices.name, offsets.name)


def calibrate(ds: xr.Dataset, cal: L2Calibration, day: np.datetime64 | str | None = None
              ) -> xr.Dataset:
    """Return the L2 of one sensor's L1B/L1C dataset in the sensor frame (``IMAP_MAG_BASE``).

    ``b = M[range] @ b + offset``; ``epoch`` + time delta; with ``day`` only that UTC day
    is kept (after the time deltas, as the team does).

    Raises
    ------
    InputFormatError
        The offsets file's epochs are not the input's (count or first differing time), or
        a range outside 0..3.
    """
    t = ds["epoch"].values.astype(np.int64)
    far = (np.abs(t - cal.offset_epoch) >= OFFSET_TIME_TOLERANCE_NS
           if t.size == cal.offset_epoch.size else None)
    if far is None or far.any():
        where = (f"{t.size} vectors, offsets file {cal.offset_epoch.size}" if far is None
                 else f"vector {int(np.flatnonzero(far)[0])} is "
                      f"{int(np.abs(t - cal.offset_epoch)[far][0])} ns from its row")
        raise InputFormatError(f"the offsets file is not for this input ({where}): the team's "
                               "offsets file holds one row per input vector, same epoch to 1 us",
                               path=cal.offsets_file, field="epoch")
    rng = ds["range"].values.astype(np.int64)
    bad = (rng < 0) | (rng > 3)
    if bad.any():
        raise InputFormatError(f"vector {int(np.flatnonzero(bad)[0])}: range "
                               f"{int(rng[bad][0])} is not 0..3", field="range")
    sensor = ds.attrs.get("sensor", "mago")
    b = apply_lookup(cal.matrices[sensor], rng, ds["b"].values) + cal.offsets
    epoch = t + np.round(cal.timedeltas * 1e9).astype(np.int64)
    out = xr.Dataset(
        {"b": (("time", "component"), b, {"units": "nT", "frame": "sensor",
                                          "description": f"Magnetic field, {SENSOR_FRAME}"}),
         "range": ("time", rng, {"units": "1"}),
         "quality_flag": ("time", cal.quality_flag, {"units": "1"}),
         "quality_bitmask": ("time", cal.quality_bitmask, {"units": "1"})},
        coords={"epoch": ("time", epoch), "component": ds["component"].values},
        attrs={**ds.attrs, "level": "l2", "output_frame": "sensor",
               "l2_matrices_file": cal.matrices_file, "l2_offsets_file": cal.offsets_file},
    )
    if day is not None:
        lo = utc_day_start_tt2000(np.datetime64(day, "D"), default_lsk())
        hi = utc_day_start_tt2000(np.datetime64(day, "D") + 1, default_lsk())
        out = out.isel(time=(epoch >= lo) & (epoch < hi))
    return out


def check_frames(frames: list[str]) -> None:
    """Refuse an unknown frame name, or one the loaded SPICE kernels do not define.

    Raises
    ------
    InputFormatError
        Naming the frame and the kernels it needs.
    """
    for name in frames:
        if name not in FRAMES:
            raise InputFormatError(f"frame {name!r}: expected one of {tuple(FRAMES)}",
                                   field="--frame")
        if name == "sensor":
            continue
        need = ("the IMAP frames kernel (imap_*.tf)" if name == "srf" else
                "the IMAP frames kernel and attitude (CK) and ephemeris (SPK) kernels")
        for frame in (SENSOR_FRAME, FRAMES[name]):
            if spiceypy.namfrm(frame) == 0:
                raise InputFormatError(f"frame {name.upper()} ({FRAMES[name]}) needs {need}; "
                                       f"{frame} is not defined by the kernels given: add "
                                       "them with --kernels", field="--frame")


def to_frame(l2: xr.Dataset, frame: str) -> xr.Dataset:
    """Rotate a sensor-frame L2 dataset into ``frame`` (`FRAMES`; kernels loaded).

    Raises
    ------
    InputFormatError, KernelError
        A frame the kernels do not define (`check_frames`), or times they do not cover.
    """
    if frame == "sensor":
        return l2
    check_frames([frame])
    et = tt2000_to_et(l2["epoch"].values.astype(np.int64), default_lsk())
    b = rotate(l2["b"].values, et, SENSOR_FRAME, FRAMES[frame])
    out = l2.copy()
    out["b"] = (("time", "component"), b, {**l2["b"].attrs, "frame": frame,
                                           "description": f"Magnetic field, {FRAMES[frame]}"})
    out.attrs = {**l2.attrs, "output_frame": frame}
    return out
