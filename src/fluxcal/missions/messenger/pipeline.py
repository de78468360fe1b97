"""The whole MESSENGER MAG EDR -> CDR chain on in-memory datasets.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import logging

import numpy as np
import xarray as xr

from fluxcal import __version__
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration

log = logging.getLogger(__name__)

DEFAULT_FRAMES = ("mso", "j2000", "mbf", "rtn", "sc")


def calibrate(
    science: xr.Dataset,
    heater: xr.Dataset,
    temperature: xr.Dataset,
    cal: MessengerCalibration,
    *,
    frames: tuple[str, ...] = DEFAULT_FRAMES,
    max_offset_step: float | None = 2.0,
    method: str = "interpolate",
) -> xr.Dataset:
    """Run sec. 5-13 on raw streams; kernels must be loaded (`KernelPool`).

    Parameters
    ----------
    science, heater, temperature : xarray.Dataset
        Raw streams as returned by `fluxcal.missions.messenger.readers`.
    cal : MessengerCalibration
        Calibration valid for the day (`load_calibration`).
    frames : tuple of str
        Keys of `levels.FRAMES` to produce.
    max_offset_step : float or None
        Smoothness threshold (counts) of sec. 13; ``None`` skips the check.
    method : {"interpolate", "oracle"}
        Geometry evaluation: vectorized (default) or one SPICE call per sample.

    Returns
    -------
    xarray.Dataset
        Every intermediate and final variable; attrs carry provenance and the offset
        step report.

    Raises
    ------
    ValidationError
        When the offsets are not smooth (sec. 13).
    """
    unknown = set(frames) - set(levels.FRAMES)
    if unknown:
        raise InputFormatError(
            f"unknown frame(s) {sorted(unknown)}; expected some of {sorted(levels.FRAMES)}",
            field="frames",
        )
    if science.sizes.get("time", 0) == 0:
        raise InputFormatError("no science samples", field="met")
    sclk = SclkKernel.from_pool(levels.SC_ID)
    ds = levels.correct_time(science, cal, sclk)
    levels.check_heater_coverage(ds, heater, cal, sclk)
    periods, changes = levels.find_heater_periods(heater, cal, sclk)
    ds = levels.correct_heater_signal(ds, periods, cal)
    ds = levels.mark_sunlit(ds, cal, method=method)
    ds = levels.correct_offsets(ds, temperature, changes, cal, sclk)
    ds = levels.counts_to_field(ds, cal)
    ds = levels.add_geometry(ds, cal, frames, method=method)
    ds = levels.assign_quality(ds, cal)
    report = (
        levels.validate_offsets(ds, max_offset_step)
        if max_offset_step is not None
        else levels.offset_step_report(ds)
    )
    ds.attrs.update(
        software_version=f"fluxcal {__version__}",
        calibration_files=cal.provenance(),
        offset_largest_step_counts=", ".join(
            f"{a}: {r['step_counts']:.4f}" for a, r in report.items()
        ),
        heater_periods=int(len(periods)),
        duty_cycle_changes=int(len(changes)),
        references="MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016)",
    )
    log.info("calibrated %d samples, %d heater periods", ds.sizes["time"], len(periods))
    return ds


def day_of(science: xr.Dataset) -> np.datetime64:
    """Return the UTC instant of the first science sample (selects the calibration)."""
    sclk = SclkKernel.from_pool(levels.SC_ID)
    et = sclk.to_et(science["partition"].values[:1], science["met"].values[:1])
    from fluxcal.geometry.time import et_to_utc

    return np.datetime64(str(et_to_utc(et, digits=0)[0]), "s")
