"""RPC-MAG extended temperature model 006 with midnight stitching (seed 003, sec. 4.2.3.3).

The daily polynomial ``P_d(T)`` (files ``RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT``) is
subtracted from the ground-calibrated field; consecutive days of one campaign are shifted
so that the offset of the day's first vector equals the offset stored for the previous
day's last vector (the midnight jump vanishes; docs/decisions/rosetta.md, decision 27).

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
#: Vectors within this of a daily model's fitted range (deg C) count as inside it.
RANGE_TOLERANCE_C = 0.02


@dataclass(frozen=True)
class StitchState:
    """End-of-day state carried to the next day's midnight stitching (sec. 4.2.3.3).

    "The specific calculated offset values at the end of a day are stored in a separate
    file": the extended offset applied to the day's last vector, and when that vector was.

    Attributes
    ----------
    epoch : int
        TT2000 ns of the last vector of the day (telemetry time, before the filter shift).
    offset : ndarray, shape (3,)
        The extended-model offset (nT) subtracted from that vector, ``P_d(T~_e) - c_d``.
    correction : ndarray, shape (3,)
        The day's shift ``c_d`` (nT), for the record.
    """

    epoch: int
    offset: np.ndarray
    correction: np.ndarray

    def to_attrs(self) -> dict:
        """Flatten into dataset attributes (``stitch_*``)."""
        return {
            "stitch_epoch": int(self.epoch),
            "stitch_offset_nt": np.asarray(self.offset, dtype=float).tolist(),
            "stitch_correction_nt": np.asarray(self.correction, dtype=float).tolist(),
        }

    @classmethod
    def from_attrs(cls, attrs: Mapping) -> StitchState | None:
        """Rebuild from `to_attrs` output; ``None`` when the attributes are absent.

        A state written by fluxcal before decision 27 (last temperature, coefficients and
        correction) is converted: its end offset is ``P(T_e) - correction``.
        """
        if "stitch_epoch" not in attrs:
            return None
        correction = np.asarray(attrs["stitch_correction_nt"], dtype=float)
        if "stitch_offset_nt" in attrs:
            offset = np.asarray(attrs["stitch_offset_nt"], dtype=float)
        else:
            coefficients = np.asarray(attrs["stitch_coefficients"], dtype=float).reshape(6, 3)
            te = np.array([float(attrs["stitch_temperature_c"])])
            offset = thermal.polynomial(coefficients, te)[0] - correction
        if offset.shape != (3,) or correction.shape != (3,):
            raise ValueError("stitch_offset_nt and stitch_correction_nt need 3 values each")
        return cls(int(attrs["stitch_epoch"]), offset, correction)


def day_correction(
    first_epoch: int,
    first_model_offset: np.ndarray,
    previous: StitchState | None,
    stitch_gap_s: float = STITCH_GAP_S,
) -> np.ndarray:
    """Return the shift ``c_d`` (nT) of a day (``first_model_offset``: ``P_d`` at its start).

    Sec. 4.2.3.3: "the data of the following day will be shifted in that way that a
    possible midnight jump disappears": ``c_d = P_d(T~_first) - O_end`` with ``O_end`` the
    offset applied to the previous day's last vector, so the first vector of the day gets
    exactly the offset of the last one before.  No shift (``c_d = 0``) without a previous
    state or when the gap exceeds ``stitch_gap_s`` ("if subsequent measurements are
    interrupted by more than a few hours an offset-jump adaption is neither needed nor
    used").

    Raises
    ------
    ValueError
        The previous state is not before ``first_epoch`` (e.g. the state file of the same or
        a later day).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3.
    """
    if previous is None:
        return np.zeros(3)
    gap = int(first_epoch) - int(previous.epoch)
    if gap <= 0:
        raise ValueError(
            f"stitching state of TT2000 {previous.epoch} is not before the first vector "
            f"(TT2000 {int(first_epoch)}): pass the state of the previous day"
        )
    if gap > stitch_gap_s * NS:
        return np.zeros(3)
    return np.asarray(first_model_offset, dtype=float) - previous.offset


def stitch_day(
    model: DailyOffsetModel,
    first: tuple[int, float],
    last: tuple[int, float],
    previous: StitchState | None,
    stitch_gap_s: float = STITCH_GAP_S,
) -> tuple[np.ndarray, StitchState]:
    """Shift and end state of one day from its first and last vector alone.

    ``first`` and ``last`` are ``(epoch TT2000 ns, reduced temperature deg C)`` of the day's
    first and last good vector.  The batch resolves the chain of days with this (without
    calibrating the whole day); `extended_offset` gives the same numbers.

    Returns
    -------
    correction : ndarray, shape (3,)
    state : StitchState
        End of the day.
    """
    t = np.array([first[1], last[1]], dtype=float)
    p = thermal.polynomial(model.coefficients, t)
    correction = day_correction(first[0], p[0], previous, stitch_gap_s)
    return correction, StitchState(int(last[0]), p[1] - correction, correction)


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

    For day ``d`` with polynomial ``P_d`` the offset is ``P_d(T~) - c_d``, ``c_d`` from
    `day_correction`: when the previous day's last vector is at most ``stitch_gap_s``
    before this day's first, the day is shifted so that its first vector gets the offset
    of the previous day's last vector (the jump vanishes); otherwise (a new campaign)
    ``c_d = 0``.  A day without a file has offset 0 and breaks the chain.

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        Time stamps (TT2000 ns, before the filter time shift), non-decreasing.
    temperature : ndarray, shape (n,)
        Reduced temperature ``T~`` (deg C), the polynomial's variable
        (`GroundCalibration.extended_model_temperature`).
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

    Raises
    ------
    ValueError
        ``previous`` is not before the first vector.

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
        correction, state = stitch_day(
            model, (int(epoch[i0]), float(t[0])), (int(epoch[i1 - 1]), float(t[-1])), state,
            stitch_gap_s,
        )
        if lookup is None:
            out[i0:i1] = thermal.polynomial(model.coefficients, t) - correction
        else:
            index, grid = lookup
            out[i0:i1] = (thermal.polynomial(model.coefficients, grid) - correction)[index[i0:i1]]
    return out, state, sources


def outside_fitted_range(
    temperature: np.ndarray,
    day_index: np.ndarray,
    days: list[np.datetime64],
    models: Mapping[np.datetime64, DailyOffsetModel],
    tolerance_c: float = RANGE_TOLERANCE_C,
) -> list[str]:
    """Say, per day, which vectors a daily polynomial reaches outside its fitted range.

    A file written by ``fluxcal rosetta fit`` records the reduced temperatures it was
    fitted over (``DailyOffsetModel.temperature_range``); a cubic applied beyond them is an
    extrapolation whose error the fit does not state (issue 34: 1.2 nT at 4 C outside).
    Files without a range (the seed's) are not judged.

    Parameters
    ----------
    temperature : ndarray, shape (n,)
        Reduced temperature ``T~`` (deg C) of each vector.
    day_index : ndarray of int, shape (n,)
        Index into ``days`` of each vector's UTC day.
    days : list of numpy.datetime64[D]
    models : mapping day -> DailyOffsetModel
    tolerance_c : float
        Vectors less than this outside (deg C) are not reported: two half steps of the
        thermistor word (0.0098 C each, docs/decisions/rosetta_fit.md decision 6), the
        resolution the range itself was measured with.

    Returns
    -------
    list of str
        One line per day with vectors outside: how many, the range, and how far (C).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (daily polynomials fitted per day).
    """
    out = []
    t = np.asarray(temperature, dtype=float)
    for d, day in enumerate(days):  # a loop over days, not samples
        model = models.get(day)
        if model is None or model.temperature_range is None:
            continue
        lo, hi = model.temperature_range
        sel = t[np.asarray(day_index) == d]
        below, above = sel < lo - tolerance_c, sel > hi + tolerance_c
        n = int(np.count_nonzero(below | above))
        if not n:
            continue
        far = max(float(lo - sel[below].min()) if below.any() else 0.0,
                  float(sel[above].max() - hi) if above.any() else 0.0)
        out.append(
            f"{day}: {n} of {sel.size} vectors at reduced temperatures outside the range "
            f"{lo:.2f} .. {hi:.2f} C the daily model {model.source or 'file'} was fitted on "
            f"(up to {far:.2f} C outside: the polynomial is extrapolated there, its error "
            f"unknown; lowest T~ {sel.min():.2f} C, highest {sel.max():.2f} C)")
    return out
