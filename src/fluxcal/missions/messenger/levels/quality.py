"""MESSENGER levels, step 6: the SHC quality flag of Table 5 (seed 000 sec. 12).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 7 (last
       paragraphs), sec. 12, Table 5.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.missions.messenger._compiled import quality_kernel
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.levels._common import (
    _date_et,
    _scalar,
)


def quality_flags(
    et: np.ndarray,
    sun_y_sc: np.ndarray,
    heater_applied: np.ndarray,
    cal: MessengerCalibration,
) -> np.ndarray:
    """Return the three-digit SHC quality flag of Table 5 for each sample (int 0..222).

    S: 0 before boom deployment, else 1 when the Sun is on the spacecraft +Y side
    (``sun_y_sc > 0``, sensor in sunlight), 2 otherwise.  H: 0/1/2 for MAG FSW V8/V9/V10
    by date.  C: 1 before boom deployment and, before V10, in shadow (S = 2); 2 where
    the heater signal was removed; 0 otherwise.

    One compiled pass (`fluxcal.missions.messenger._compiled.quality_kernel`);
    `quality_flags_reference` is the numpy version the tests compare with.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (last paragraphs), sec. 12,
       Table 5.
    """
    return _quality(et, sun_y_sc, heater_applied, cal, np.int64)


def _quality(
    et: np.ndarray, sun_y_sc: np.ndarray, heater_applied: np.ndarray,
    cal: MessengerCalibration, dtype: type,
) -> np.ndarray:
    """`quality_flags` as ``dtype`` (the numpy reference for inputs of other shapes)."""
    et = np.asarray(et, dtype=float)
    sun_y = np.asarray(sun_y_sc)
    heater = np.asarray(heater_applied, dtype=bool)
    if (et.ndim != 1 or sun_y.shape != et.shape or heater.shape != et.shape
            or sun_y.dtype.kind not in "biuf"):
        return quality_flags_reference(et, sun_y_sc, heater_applied, cal).astype(dtype)
    out = np.empty(et.size, dtype=dtype)
    quality_kernel(et, sun_y, heater, _date_et(cal, "boom_deployment"),
                   _date_et(cal, "heater_mode_v9"), _date_et(cal, "heater_mode_v10"), out)
    return out


def quality_flags_reference(
    et: np.ndarray,
    sun_y_sc: np.ndarray,
    heater_applied: np.ndarray,
    cal: MessengerCalibration,
) -> np.ndarray:
    """Numpy reference of `quality_flags` (whole-array passes; the tests compare).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (last paragraphs), sec. 12,
       Table 5.
    """
    et = np.asarray(et, dtype=float)
    boom = et >= _date_et(cal, "boom_deployment")
    v9 = et >= _date_et(cal, "heater_mode_v9")
    v10 = et >= _date_et(cal, "heater_mode_v10")
    s = np.where(~boom, 0, np.where(np.asarray(sun_y_sc) > 0, 1, 2))
    h = np.where(v10, 2, np.where(v9, 1, 0))
    c = np.zeros_like(s)
    c[np.asarray(heater_applied, dtype=bool)] = 2
    c[(~v10) & (s == 2)] = 1
    c[~boom] = 1
    return 100 * s + 10 * h + c


def assign_quality(ds: xr.Dataset, cal: MessengerCalibration) -> xr.Dataset:
    """Add the SHC ``quality`` flag (Table 5); needs ``sun_sc`` and ``heater_applied``.

    C = 2 ("contamination present but corrected") where the heater waveform was removed
    and also where a heater-induced duty-cycle offset (``duty_cycle_offset``, eq. 6f) of
    at least ``[quality] min_duty_offset_counts`` (1 count) was removed on some axis, e.g.
    in the hour of relaxation after the heater stops (docs/decisions/messenger.md).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, sec. 12, Table 5.
    """
    corrected = np.asarray(ds["heater_applied"].values, dtype=bool)
    if "duty_cycle_offset" in ds:
        limit = float(cal.constants["quality"]["min_duty_offset_counts"])
        corrected = corrected | (np.abs(ds["duty_cycle_offset"].values) >= limit).any(axis=1)
    q = _quality(ds["et"].values, ds["sun_sc"].values[:, 1], corrected, cal, np.int16)
    return ds.assign(quality=_scalar(q, "1", "SHC quality flag (Table 5)"))
