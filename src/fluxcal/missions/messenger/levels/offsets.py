"""MESSENGER levels, step 3: temperature and relaxed duty-cycle offsets (seed 000 sec. 7).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 7, eq. 1-7, Tables
       2-3.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration.gain_matrix import range_conversion
from fluxcal.calibration.offsets import breakpoint_temperature, two_segment_offset
from fluxcal.calibration.relaxation import (
    DutyCycleChanges,
    relaxed_offset,
    state_at_changes,
    steady_state_offset,
)
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.frames import rotation_matrices
from fluxcal.geometry.positions import position
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger._compiled import offset_chain_kernel
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.identity import NAIF_NAME
from fluxcal.missions.messenger.levels._common import (
    _apply,
    _date_et,
    _scalar,
    _unit_rows,
    _vector,
)
from fluxcal.missions.messenger.levels.time import aux_times_et


def sunlit_before_v10(
    et: np.ndarray, cal: MessengerCalibration, *, method: str = "interpolate"
) -> np.ndarray:
    """Return True for samples before V10 with the deployed sensor in sunlight (S = 1).

    The Sun direction in MSGR_SPACECRAFT has a positive Y component (the sunlit side,
    Table 5's S = 1, as `quality_flags` decides it), evaluated only for deployed
    samples before MAG FSW V10; all other samples are False.  Kernels (SPK, CK, FK)
    must be loaded when such samples exist.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (last paragraphs), sec. 12.
    """
    et = np.asarray(et, dtype=float)
    out = np.zeros(et.shape, dtype=bool)
    sel = (et >= _date_et(cal, "boom_deployment")) & ~(et >= _date_et(cal, "heater_mode_v10"))
    if sel.any():
        e = et[sel]
        sun = position(NAIF_NAME, "SUN", "J2000", e, method=method)  # MESSENGER - Sun
        att = rotation_matrices("MSGR_SPACECRAFT", "J2000", e, method=method)
        out[sel] = _apply(att, _unit_rows(-sun), transpose=True)[:, 1] > 0
    return out


def mark_sunlit(ds: xr.Dataset, cal: MessengerCalibration, *, method: str = "interpolate"
                ) -> xr.Dataset:
    """Add ``sunlit`` (`sunlit_before_v10`), which `correct_offsets` needs before V10."""
    var = _scalar(sunlit_before_v10(ds["et"].values, cal, method=method), "1",
                  "deployed sensor in sunlight before V10 (sec. 7)")
    var.attrs["v10_et"] = _date_et(cal, "heater_mode_v10")
    return ds.assign(sunlit=var)


def offset_model(
    et: np.ndarray,
    temperature_c: np.ndarray,
    changes: DutyCycleChanges,
    cal: MessengerCalibration,
    sunlit: np.ndarray | None = None,
) -> np.ndarray:
    """Return the total offset ``cT(T) + Delta(t)`` in fine-range counts (sec. 7).

    Before V10 (2007-03-09) there is no duty-cycle term, and deployed samples in
    sunlight (``sunlit``) use ``cT(22.4 C)`` (sec. 7, last paragraph); the others
    (stowed, shadow) use ``cT`` at the measured temperature.
    One compiled pass (`fluxcal.missions.messenger._compiled.offset_chain_kernel`);
    `offset_model_reference` is the numpy version the tests compare with.

    Parameters
    ----------
    sunlit : ndarray of bool, shape (n,), optional
        Deployed sensor in sunlight (`sunlit_before_v10`); needed when a sample lies
        before V10.

    Raises
    ------
    FluxcalError
        ``sunlit`` missing while a sample lies before V10.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 2-7, Tables 2-3.
    """
    et = np.ascontiguousarray(et, dtype=float)
    temp = np.ascontiguousarray(temperature_c, dtype=float)
    fixed = _fixed_mask(et, sunlit, cal)
    model = _offset_model_tables(changes, cal)
    if et.ndim != 1 or temp.shape != et.shape or model is None or fixed.shape != et.shape:
        return offset_model_reference(et, temperature_c, changes, cal, sunlit)
    offset = np.empty((et.size, 3))
    duty = np.empty((et.size, 3))
    unused = np.empty((0, 3))
    offset_chain_kernel(et, fixed, np.empty(0), np.empty(0), False, 0.0, *model, unused,
                        np.empty(0, dtype=np.int8), np.eye(3), unused, False,
                        temp, offset, duty, unused, unused)
    return offset


def _fixed_mask(et: np.ndarray, sunlit: np.ndarray | None, cal: MessengerCalibration
                ) -> np.ndarray:
    """``sunlit`` as a contiguous bool array; an error when missing before V10."""
    et = np.asarray(et, dtype=float)
    if sunlit is None:
        if np.any(~(et >= _date_et(cal, "heater_mode_v10"))):
            raise FluxcalError(
                "samples before MAG FSW V10 (2007-03-09) need the sunlit mask (sec. 7: the "
                "22.4 C offsets are for deployed sunlit data only); run sunlit_before_v10",
            )
        return np.zeros(et.shape, dtype=bool)
    return np.ascontiguousarray(sunlit, dtype=bool)


def _offset_model_tables(changes: DutyCycleChanges, cal: MessengerCalibration) -> tuple | None:
    """Arguments ``model_start .. delay`` of `offset_chain_kernel`, or None.

    None when the numpy reference must decide: NaN change times (the reference's
    result), decreasing ones (its ``ValueError``), or tables of other shapes.
    """
    rel = cal.constants["relaxation"]
    coefficients = np.ascontiguousarray(cal.offset_coefficients(), dtype=float)
    change_time = np.ascontiguousarray(changes.time, dtype=float)
    target = steady_state_offset(
        changes.duty_cycle_ppt, cal.duty_cycle_d0, rel["min_duty_cycle_ppt"]
    )
    if (coefficients.shape != (3, 4) or change_time.ndim != 1 or target.shape != (
            change_time.size, 3) or np.isnan(change_time).any()
            or np.any(change_time[1:] < change_time[:-1])):
        return None
    pad = np.zeros((1, 3))  # row 0: before the first change, zero target and state
    if change_time.size:
        state = state_at_changes(change_time, target, tau=rel["tau_s"], delay=rel["delay_s"],
                                 look_back=int(rel["look_back"]),
                                 look_back_s=float(rel["look_back_s"]))
    else:
        state = np.empty((0, 3))
    return (
        _date_et(cal, "heater_mode_v10"), float(cal.constants["pre_v10"]["fixed_temperature_c"]),
        coefficients, np.ascontiguousarray(breakpoint_temperature(coefficients)), change_time,
        np.concatenate([pad, target]), np.concatenate([pad, state]), float(rel["tau_s"]),
        float(rel["delay_s"]),
    )


def offset_model_reference(
    et: np.ndarray,
    temperature_c: np.ndarray,
    changes: DutyCycleChanges,
    cal: MessengerCalibration,
    sunlit: np.ndarray | None = None,
) -> np.ndarray:
    """Numpy reference of `offset_model` (whole-array passes; the tests compare).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 2-7, Tables 2-3.
    """
    ct, delta = _offset_parts_reference(et, temperature_c, changes, cal, sunlit)
    return ct + delta


def _offset_parts_reference(
    et: np.ndarray, temperature_c: np.ndarray, changes: DutyCycleChanges,
    cal: MessengerCalibration, sunlit: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """``cT`` (at 22.4 C for sunlit samples before V10) and ``Delta`` (0 before V10)."""
    rel = cal.constants["relaxation"]
    et = np.asarray(et, dtype=float)
    temp = np.asarray(temperature_c, dtype=float)
    v10 = et >= _date_et(cal, "heater_mode_v10")
    fixed = cal.constants["pre_v10"]["fixed_temperature_c"]
    temp = np.where(v10 | ~_fixed_mask(et, sunlit, cal), temp, fixed)
    ct = two_segment_offset(temp, cal.offset_coefficients())
    target = steady_state_offset(
        changes.duty_cycle_ppt, cal.duty_cycle_d0, rel["min_duty_cycle_ppt"]
    )
    delta = relaxed_offset(
        et, changes.time, target, tau=rel["tau_s"], delay=rel["delay_s"],
        look_back=int(rel["look_back"]), look_back_s=float(rel["look_back_s"]),
    )
    delta[~v10] = 0.0
    return ct, delta


#: Samples may lie this far (s) outside the temperature stream (`interpolate_temperature`).
TEMPERATURE_MARGIN_S = 60.0


def interpolate_temperature(et: np.ndarray, temp_et: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
    """Linear interpolation of the sensor temperature to the sample times.

    Raises
    ------
    InputFormatError
        When samples lie outside the temperature stream (no extrapolation).
    """
    if temp_et.size == 0:
        raise InputFormatError("temperature stream is empty", field="temperature_c")
    _check_temperature_cover(bool(et.size) and (
        et.min() < temp_et[0] - TEMPERATURE_MARGIN_S
        or et.max() > temp_et[-1] + TEMPERATURE_MARGIN_S))
    return np.interp(et, temp_et, temp_c)


def _check_temperature_cover(outside: bool) -> None:
    if outside:
        raise InputFormatError(
            "science samples extend beyond the temperature stream by more than 60 s",
            field="temperature_c",
        )


def correct_offsets(
    ds: xr.Dataset,
    temperature: xr.Dataset,
    changes: DutyCycleChanges,
    cal: MessengerCalibration,
    sclk: SclkKernel,
) -> xr.Dataset:
    """Subtract the thermal offsets and the heater signal from the counts.

    Offsets and heater signal are modelled in fine-range counts; coarse-range samples get
    ``M_coarse^-1 M_fine`` times them.

    Before V10 the dataset needs ``sunlit`` (`mark_sunlit`): deployed samples in
    sunlight get Table 2 at 22.4 C, the others at the measured temperature (sec. 7).

    Returns
    -------
    xarray.Dataset
        With ``temperature`` (degC), ``offset`` (fine counts), ``duty_cycle_offset``
        (``Delta``, fine counts), ``offset_applied`` (counts of the sample's range,
        offset + heater signal) and ``counts_corrected``.

    Notes
    -----
    Temperature interpolation (`interpolate_temperature`), offset model
    (`offset_model`), range conversion and subtraction run in one compiled pass
    (`fluxcal.missions.messenger._compiled.offset_chain_kernel`);
    `correct_offsets_reference` is the numpy version the tests compare with, run instead
    for inputs it must decide (see `_offset_model_tables`; a temperature stream of one
    record or with unsorted or NaN times is interpolated by ``np.interp`` first).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 1-7.
    """
    et = ds["et"].values
    t_et = aux_times_et(temperature, sclk)
    t_c = temperature["temperature_c"].values
    if t_et.size == 0:
        raise InputFormatError("temperature stream is empty", field="temperature_c")
    model = _offset_model_tables(changes, cal)
    conv = range_conversion(cal.matrices, reference=0)
    counts = ds["counts"].values
    heater = ds["heater_signal"].values
    rng = ds["range"].values
    n = et.shape[0] if et.ndim == 1 else -1
    fixed = _fixed_mask(et, ds["sunlit"].values if "sunlit" in ds else None, cal)
    if (model is None or et.dtype != np.float64 or et.ndim != 1 or conv.shape[0] < 2
            or fixed.shape != (n,)
            or counts.shape != (n, 3) or counts.dtype.kind not in "iuf"
            or heater.shape != (n, 3) or heater.dtype != np.float64 or rng.shape != (n,)
            or rng.dtype.kind not in "iu"):
        return correct_offsets_reference(ds, temperature, changes, cal, sclk)
    t_et = np.ascontiguousarray(t_et, dtype=float)
    t_c = np.ascontiguousarray(t_c, dtype=float)
    interpolate = t_et.size >= 2 and t_c.shape == t_et.shape and not (
        np.isnan(t_et).any() or np.any(t_et[1:] < t_et[:-1]))
    if interpolate:
        temp = np.empty(n)
    else:  # np.interp's own cases (one record, unsorted or NaN times) and errors
        temp = interpolate_temperature(et, t_et, t_c)
    offset, duty, applied, corrected = (np.empty((n, 3)) for _ in range(4))
    outside = offset_chain_kernel(
        np.ascontiguousarray(et), fixed, t_et, t_c, interpolate, TEMPERATURE_MARGIN_S,
        *model, np.ascontiguousarray(heater), np.ascontiguousarray(rng),
        np.ascontiguousarray(conv[1]), np.ascontiguousarray(counts), True,
        temp, offset, duty, applied, corrected,
    )
    _check_temperature_cover(interpolate and outside)
    return _offset_dataset(ds, temp, offset, duty, applied, corrected)


def correct_offsets_reference(
    ds: xr.Dataset,
    temperature: xr.Dataset,
    changes: DutyCycleChanges,
    cal: MessengerCalibration,
    sclk: SclkKernel,
) -> xr.Dataset:
    """Numpy reference of `correct_offsets` (whole-array passes; the tests compare).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 1-7.
    """
    et = ds["et"].values
    t_et = aux_times_et(temperature, sclk)
    temp = interpolate_temperature(et, t_et, temperature["temperature_c"].values)
    sunlit = ds["sunlit"].values if "sunlit" in ds else None
    ct, duty = _offset_parts_reference(et, temp, changes, cal, sunlit)
    offset = ct + duty
    fine_total = offset + ds["heater_signal"].values
    conv = range_conversion(cal.matrices, reference=0)
    rng = ds["range"].values
    applied = fine_total.copy()
    coarse = rng == 1
    if coarse.any():
        applied[coarse] = np.einsum("ij,nj->ni", conv[1], fine_total[coarse])
    corrected = ds["counts"].values - applied
    return _offset_dataset(ds, temp, offset, duty, applied, corrected)


def _offset_dataset(
    ds: xr.Dataset, temp: np.ndarray, offset: np.ndarray, duty: np.ndarray,
    applied: np.ndarray, corrected: np.ndarray,
) -> xr.Dataset:
    return ds.assign(
        temperature=_scalar(temp, "degC", "sensor temperature interpolated to the samples"),
        offset=_vector(offset, "counts", "thermal offset cT(T) + Delta(t), fine-range counts"),
        duty_cycle_offset=_vector(duty, "counts",
                                  "duty-cycle offset Delta(t) (eq. 6f), fine-range counts"),
        offset_applied=_vector(applied, "counts", "offset + heater signal, counts of the range"),
        counts_corrected=_vector(corrected, "counts", "counts minus offsets (eq. 1)"),
    )
