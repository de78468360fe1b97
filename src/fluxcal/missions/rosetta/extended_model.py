"""RPC-MAG extended temperature model 006 with midnight stitching (seed 003, sec. 4.2.3.3).

The daily polynomial ``P_d(T)`` (files ``RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT``) is
subtracted from the ground-calibrated field; consecutive days of one campaign are shifted
so the applied offset is continuous at midnight.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fluxcal.calibration import thermal
from fluxcal.missions.rosetta.calib import DailyOffsetModel

NS = 1_000_000_000
#: Default largest gap (s) across which the midnight stitching of sec. 4.2.3.3 continues.
STITCH_GAP_S = 3 * 3600.0


@dataclass(frozen=True)
class StitchState:
    """End-of-day state carried to the next day's midnight stitching (sec. 4.2.3.3).

    Attributes
    ----------
    epoch : int
        TT2000 ns of the last vector of the previous day.
    temperature : float
        Its calibrated temperature (deg C).
    coefficients : ndarray, shape (6, 3)
        The previous day's polynomial.
    correction : ndarray, shape (3,)
        The shift (nT) already subtracted from the previous day's polynomial.
    """

    epoch: int
    temperature: float
    coefficients: np.ndarray
    correction: np.ndarray

    def to_attrs(self) -> dict:
        """Flatten into dataset attributes (``stitch_*``)."""
        return {
            "stitch_epoch": int(self.epoch),
            "stitch_temperature_c": float(self.temperature),
            "stitch_coefficients": np.asarray(self.coefficients, dtype=float).ravel().tolist(),
            "stitch_correction_nt": np.asarray(self.correction, dtype=float).tolist(),
        }

    @classmethod
    def from_attrs(cls, attrs: Mapping) -> StitchState | None:
        """Rebuild from `to_attrs` output; ``None`` when the attributes are absent."""
        if "stitch_epoch" not in attrs:
            return None
        return cls(
            int(attrs["stitch_epoch"]),
            float(attrs["stitch_temperature_c"]),
            np.asarray(attrs["stitch_coefficients"], dtype=float).reshape(6, 3),
            np.asarray(attrs["stitch_correction_nt"], dtype=float),
        )


def extended_offset(
    epoch: np.ndarray,
    temperature: np.ndarray,
    day_index: np.ndarray,
    days: list[np.datetime64],
    models: Mapping[np.datetime64, DailyOffsetModel],
    *,
    stitch_gap_s: float = STITCH_GAP_S,
    previous: StitchState | None = None,
    lookup: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, StitchState | None, list[str]]:
    """Daily extended-temperature offsets with the midnight stitching of sec. 4.2.3.3.

    For day ``d`` with polynomial ``P_d`` the offset is ``P_d(T) - c_d``.  When the gap
    from the previous day's last vector to this day's first is at most ``stitch_gap_s``,
    ``c_d = c_{d-1} + P_d(T_e) - P_{d-1}(T_e)`` with ``T_e`` the last temperature of the
    previous day, so the applied offset is continuous across midnight; otherwise (a new
    campaign) ``c_d = 0``.  A day without a file has offset 0 and breaks the chain.

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        Time stamps (TT2000 ns, before the filter time shift), non-decreasing.
    temperature : ndarray, shape (n,)
        Calibrated sensor temperature, deg C (the polynomial's variable, issue 4).
    day_index : ndarray of int, shape (n,)
        Index into ``days`` of each vector's UTC day.
    days : list of numpy.datetime64[D]
    models : mapping day -> DailyOffsetModel
    stitch_gap_s : float
        Largest gap that still continues a campaign (default 3 h).
    previous : StitchState, optional
        End state of the previous day processed separately.
    lookup : (index, grid_temperature), optional
        When ``temperature == grid_temperature[index]`` (quantised thermistor words), the
        polynomials are evaluated on the grid and gathered (same values, faster).

    Returns
    -------
    offset : ndarray, shape (n, 3)
        To subtract from the ground-calibrated field.
    state : StitchState or None
        End state after the last day (``None`` if the last day had no model).
    sources : list of str
        Files used.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3.
    """
    n = len(epoch)
    out = np.zeros((n, 3))
    sources: list[str] = []
    state = previous
    bounds = np.searchsorted(day_index, np.arange(len(days) + 1))
    for d, day in enumerate(days):
        i0, i1 = int(bounds[d]), int(bounds[d + 1])
        if i1 <= i0:
            continue
        model = models.get(day)
        if model is None:
            state = None
            continue
        sources.append(model.source)
        t = temperature[i0:i1]
        correction = np.zeros(3)
        if state is not None and (epoch[i0] - state.epoch) <= stitch_gap_s * NS:
            te = np.array([state.temperature])
            correction = (
                state.correction
                + thermal.polynomial(model.coefficients, te)[0]
                - thermal.polynomial(state.coefficients, te)[0]
            )
        if lookup is None:
            out[i0:i1] = thermal.polynomial(model.coefficients, t) - correction
        else:
            index, grid = lookup
            out[i0:i1] = (thermal.polynomial(model.coefficients, grid) - correction)[index[i0:i1]]
        state = StitchState(int(epoch[i1 - 1]), float(t[-1]), model.coefficients, correction)
    return out, state, sources


def utc_days(epoch: np.ndarray, lsk=None) -> tuple[np.ndarray, list[np.datetime64], np.ndarray]:
    """UTC day of each time: ``(day_index, days, midnight_tt2000)``.

    ``midnight_tt2000[k]`` is the TT2000 of 00:00 UTC of ``days[k]``; vectors are assigned by
    comparison with these boundaries (correct across leap seconds).
    """
    from fluxcal.geometry.time import tt2000_to_utc, utc_to_tt2000

    epoch = np.asarray(epoch, dtype=np.int64)
    if epoch.size == 0:
        return np.zeros(0, dtype=np.int64), [], np.zeros(0, dtype=np.int64)
    ends = tt2000_to_utc(np.array([epoch.min(), epoch.max()]), digits=0, lsk=lsk)
    first, last = (np.datetime64(str(s)[:10], "D") for s in ends)
    days = list(np.arange(first, last + np.timedelta64(1, "D"), dtype="M8[D]"))
    midnight = utc_to_tt2000(np.array([f"{d}T00:00:00" for d in days]), lsk=lsk)
    day_index = np.searchsorted(midnight, epoch, side="right") - 1
    return day_index, days, midnight
