"""MESSENGER MAG processing levels, each a function ``Dataset -> Dataset``.

The science dataset (dimension ``time``) produced by `fluxcal.missions.messenger.readers`
goes through, in order:

1. `correct_time` (sec. 5, 9): per-sample net lag, MET -> ET, TT2000 epoch;
2. `correct_heater_signal` (sec. 6): periodic heater signal;
3. `correct_offsets` (sec. 7): temperature and relaxed duty-cycle offsets;
4. `counts_to_field` (sec. 8): eq. 8 with each sample's range matrix;
5. `add_geometry` (sec. 10, 11): frames and positions;
6. `assign_quality` (sec. 12);
7. `validate_offsets` (sec. 13).

Calibration constants (`MessengerCalibration`) and the SCLK conversion are arguments;
geometry steps need the kernels loaded by the caller (`fluxcal.geometry.kernels.KernelPool`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 5-13.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
import xarray as xr

from fluxcal.calibration._compiled import offset_chain_kernel
from fluxcal.calibration.gain_matrix import counts_to_nt, range_conversion
from fluxcal.calibration.heater_signal import HeaterPeriods, heater_periods, heater_signal
from fluxcal.calibration.offset_steps import largest_steps
from fluxcal.calibration.offsets import breakpoint_temperature, two_segment_offset
from fluxcal.calibration.rate_latency import per_sample_lag
from fluxcal.calibration.relaxation import (
    DutyCycleChanges,
    duty_cycle_changes,
    relaxed_offset,
    state_at_changes,
    steady_state_offset,
)
from fluxcal.errors import FluxcalError, InputFormatError, ValidationError
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger._compiled import quality_kernel
from fluxcal.missions.messenger.calibration_data import MessengerCalibration

log = logging.getLogger(__name__)

COMPONENT = ["x", "y", "z"]
SC_ID = -236

#: Output frames: product key -> (SPICE frame, archive product name stem).
FRAMES: dict[str, tuple[str, str]] = {
    "mso": ("MSGR_MSO", "MAGMSOSCI"),
    "j2000": ("J2000", "MAGJ2000SCI"),
    "mbf": ("IAU_MERCURY", "MAGMBFSCI"),
    "rtn": ("MSGR_RTN", "MAGRTNSCI"),
    "sc": ("MSGR_SPACECRAFT", "MAGSCSCI"),
    "vso": ("MSGR_VSO", "MAGVSOSCI"),
}


def _vector(values: np.ndarray, units: str, description: str) -> xr.Variable:
    return xr.Variable(("time", "component"), values, {"units": units, "description": description})


def _scalar(values: np.ndarray, units: str, description: str) -> xr.Variable:
    return xr.Variable(("time",), values, {"units": units, "description": description})


def _date_et(cal: MessengerCalibration, key: str) -> float:
    return float(utc_to_et(np.array([str(cal.date(key))]))[0])


# ----------------------------------------------------------------------------------------
# 1. time
# ----------------------------------------------------------------------------------------
def correct_time(ds: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel) -> xr.Dataset:
    """Convert each sample's MET to ET and TT2000 and subtract its net lag there.

    The lag (Table 1, seconds) is subtracted from the ET of the recorded MET, not from
    the MET before conversion: both are seconds (the SCLK rate differs from 1 by far
    less than 1e-5, i.e. < 3e-5 s on a 2.4-s lag), and a sample recorded within the lag
    after the start of an SCLK partition (e.g. partition 2, 2013-01-08) would otherwise
    need a clock reading outside its partition (docs/decisions/messenger.md).

    Parameters
    ----------
    ds : xarray.Dataset
        Raw science samples with ``partition``, ``met`` (s) and ``rate`` on ``time``.
    cal : MessengerCalibration
        Table 1 net lags.
    sclk : SclkKernel
        MESSENGER clock (id -236).

    Returns
    -------
    xarray.Dataset
        With ``met_corrected``, ``lag``, ``et``, ``et_recorded`` (uncorrected, decides
        the product day) and the coordinate ``epoch`` (TT2000 ns).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 9.
    """
    lag = per_sample_lag(ds["rate"].values, cal.net_lag_s)
    met = ds["met"].values - lag
    # the recorded MET is a valid clock reading of its partition; the lag is subtracted
    # on the ET (and TT2000) scale, so a sample recorded just after a partition start
    # does not need a clock reading before it.  TT2000 straight from the clock's TT
    # parallel time (no TDB round trip).
    et_recorded, tt2000_recorded = sclk.to_et_and_tt2000(ds["partition"].values,
                                                         ds["met"].values)
    et = et_recorded - lag
    tt2000 = tt2000_recorded - np.round(lag * 1e9).astype(np.int64)
    out = _time_dataset(ds, lag, met, et, tt2000, et_recorded)
    # Table 1's sample rates travel with the rate settings (sec. 13 gap rule)
    rate = ds["rate"]
    return out.assign(rate=xr.Variable(rate.dims, rate.values, {
        **rate.attrs, "sample_rate_hz": [float(r) for r in cal.sample_rate_hz]}))


def _time_dataset(
    ds: xr.Dataset, lag: np.ndarray, met: np.ndarray, et: np.ndarray, tt2000: np.ndarray,
    et_recorded: np.ndarray,
) -> xr.Dataset:
    out = ds.assign(
        et_recorded=_scalar(et_recorded, "s", "ephemeris time of the recorded (EDR) MET"),
        lag=_scalar(lag, "s", "net time lag subtracted from the MET (Table 1)"),
        met_corrected=_scalar(met, "s", "MET corrected for the net lag"),
        et=_scalar(et, "s", "ephemeris time (TDB seconds past J2000)"),
    )
    epoch = ("time", tt2000, {"units": "ns", "standard": "TT2000"})
    return out.assign_coords(epoch=epoch)


def aux_times_et(aux: xr.Dataset, sclk: SclkKernel) -> np.ndarray:
    """Return the ET of an auxiliary stream (heater bits, temperatures) from its MET."""
    return sclk.to_et(aux["partition"].values, aux["met"].values)


# ----------------------------------------------------------------------------------------
# 2. heater
# ----------------------------------------------------------------------------------------
def find_heater_periods(
    heater: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel
) -> tuple[HeaterPeriods, DutyCycleChanges]:
    """Heater periods and duty-cycle changes (on the ET scale) from the heater stream.

    A heater stream that starts inside heater operation (less than one heater period of
    data before the first rising edge) gives a first change at ``-inf``: that duty cycle
    is taken as steady before the data (`fluxcal.missions.messenger.pipeline.calibrate`
    warns when that enters a science sample).  A last period cut inside
    its on-phase by the end of the stream keeps the previous period's duty cycle.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7.
    """
    t = aux_times_et(heater, sclk)
    h = cal.constants["heater"]
    periods = heater_periods(t, heater["heater"].values, period=h["period_s"], min_on=h["min_on_s"])
    changes = duty_cycle_changes(periods, period=h["period_s"], data_end=float(t[-1]) + 1.0,
                                 data_start=float(t[0]),
                                 evaluation_periods=int(h["evaluation_periods"]))
    return periods, changes


def check_heater_coverage(
    ds: xr.Dataset, heater: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel
) -> None:
    """Require the heater stream to cover the V10 science samples (within one period).

    Raises
    ------
    InputFormatError
        When V10 samples (heater modelled) lie before the first or after the last heater
        record by more than one heater period.
    """
    et = ds["et"].values
    v10 = et >= _date_et(cal, "heater_mode_v10")
    if not v10.any():
        return
    t = aux_times_et(heater, sclk)
    period = cal.constants["heater"]["period_s"]
    first, last = et[v10].min(), et[v10].max()
    if t.size == 0 or first < t[0] - period or last > t[-1] + period:
        span = f"[{t[0]:.1f}, {t[-1]:.1f}]" if t.size else "empty"
        raise InputFormatError(
            f"the heater stream (ET {span}) does not cover the science samples "
            f"(ET [{first:.1f}, {last:.1f}]) within one heater period; give the heater "
            "files of the whole interval (and of the previous day for the look-back)",
            path=heater.attrs.get("inputs"), field="met",
        )


def correct_heater_signal(
    ds: xr.Dataset, periods: HeaterPeriods, cal: MessengerCalibration
) -> xr.Dataset:
    """Compute the periodic heater signal (fine-range counts) at every sample (sec. 6).

    The signal is applied only from MAG FSW V10 (2007-03-09) on, in heater periods whose
    bit stayed on >= 10 s; it is subtracted in `correct_offsets`.

    Returns
    -------
    xarray.Dataset
        With ``heater_signal`` (counts, fine range) and ``heater_applied`` (bool).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    signal, applied = heater_signal(ds["et"].values, periods, cal.heater_signal,
                                    cal.heater_duty_bins_percent,
                                    applies_from=_date_et(cal, "heater_mode_v10"))
    return ds.assign(
        heater_signal=_vector(signal, "counts", "heater signal, fine-range counts (sec. 6)"),
        heater_applied=_scalar(applied, "1", "heater signal subtracted"),
    )


# ----------------------------------------------------------------------------------------
# 3. offsets
# ----------------------------------------------------------------------------------------
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
    from fluxcal.geometry.frames import rotation_matrices
    from fluxcal.geometry.positions import position

    et = np.asarray(et, dtype=float)
    out = np.zeros(et.shape, dtype=bool)
    sel = (et >= _date_et(cal, "boom_deployment")) & ~(et >= _date_et(cal, "heater_mode_v10"))
    if sel.any():
        e = et[sel]
        sun = position("MESSENGER", "SUN", "J2000", e, method=method)  # MESSENGER - Sun
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
    One compiled pass (`fluxcal.calibration._compiled.offset_chain_kernel`);
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
    (`fluxcal.calibration._compiled.offset_chain_kernel`); `correct_offsets_reference`
    is the numpy version the tests compare with, run instead for inputs it must decide
    (see `_offset_model_tables`; a temperature stream of one record or with unsorted or
    NaN times is interpolated by ``np.interp`` first).

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


# ----------------------------------------------------------------------------------------
# 4. counts -> nT
# ----------------------------------------------------------------------------------------
def counts_to_field(ds: xr.Dataset, cal: MessengerCalibration) -> xr.Dataset:
    """Convert corrected counts to nT in sensor coordinates (eq. 8, Table 4).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8, Table 4.
    """
    b = counts_to_nt(ds["counts_corrected"].values, ds["range"].values, cal.matrices)
    return ds.assign(b_sensor=_vector(b, "nT", "magnetic field, sensor coordinates"))


# ----------------------------------------------------------------------------------------
# 5. rotation and positions
# ----------------------------------------------------------------------------------------
def sensor_frame(et: np.ndarray, cal: MessengerCalibration) -> np.ndarray:
    """Return True where the sensor frame is ``MSGR_MAG`` (after boom deployment).

    Before boom deployment (2005-03-08) the sensor frame is ``MSGR_MAG_STOWED``.
    """
    return np.asarray(et) >= _date_et(cal, "boom_deployment")


def _sensor_to_spacecraft(frame: str, et: np.ndarray, method: str) -> np.ndarray:
    """(n, 3, 3) sensor -> MSGR_SPACECRAFT; one matrix when the mounting is fixed."""
    from fluxcal.geometry.frames import rotation_matrices

    ends = rotation_matrices(frame, "MSGR_SPACECRAFT", et[[0, -1]], method="oracle")
    if method != "oracle" and np.allclose(ends[0], ends[1], rtol=0, atol=1e-14):
        return ends[:1]
    return rotation_matrices(frame, "MSGR_SPACECRAFT", et, method=method)


def _apply(m: np.ndarray, v: np.ndarray, transpose: bool = False) -> np.ndarray:
    """``out[i] = M[i] @ v[i]`` (or ``M[i].T @ v[i]``); a single matrix applies to all."""
    if m.shape[0] == 1:  # one fixed matrix: a compiled pass over the vectors
        from fluxcal.geometry import compiled

        out = np.empty(v.shape)
        compiled.apply_matrix(np.ascontiguousarray(m[0].T if transpose else m[0]),
                              np.ascontiguousarray(v, dtype=float), out)
        return out
    return np.einsum("nji,nj->ni" if transpose else "nij,nj->ni", m, v)


def _unit_rows(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` divided by their norms."""
    return v / np.sqrt(np.einsum("ij,ij->i", v, v))[:, None]


def _rotate_oracle(
    b_sc: np.ndarray, sun: np.ndarray, et: np.ndarray, frames: tuple[str, ...]
) -> dict[str, np.ndarray]:
    """Field in every frame and ``sun_sc`` with one ``pxform`` per sample and frame."""
    from fluxcal.geometry.frames import rotation_matrices

    att = rotation_matrices("MSGR_SPACECRAFT", "J2000", et, method="oracle")
    b_j2000 = _apply(att, b_sc)
    out = {"sc": b_sc, "j2000": b_j2000, "sun_sc": _apply(att, _unit_rows(-sun), True)}
    for f in frames:
        if f not in out:
            out[f] = _apply(rotation_matrices("J2000", FRAMES[f][0], et, method="oracle"),
                            b_j2000)
    return out


def _rotate_interpolated(
    b_sc: np.ndarray, sun: np.ndarray, et: np.ndarray, j2000: bool, mercury_j2000: np.ndarray,
) -> dict[str, np.ndarray]:
    """J2000 field (``j2000``: when wanted), ``sun_sc`` and ``pos_mso``: one compiled pass.

    `fluxcal.geometry.compiled.attitude_frames` interpolates the attitude leg
    (MSGR_SPACECRAFT -> J2000, from the CK records) once per sample and gives the J2000
    field, the Sun direction in the spacecraft frame and, through the J2000 -> MSGR_MSO
    leg, ``mercury_j2000`` (MESSENGER relative to Mercury, J2000) in MSGR_MSO: what
    ``spkpos`` returns in that frame without aberration correction (the frame is
    evaluated at the same epoch).  Every product frame is then one leg from the J2000
    field (`frame_variables`).
    """
    from fluxcal.geometry import compiled
    from fluxcal.geometry.frames import Rotator

    n = et.size
    empty = np.empty((0, 3))
    rotator = Rotator("MSGR_SPACECRAFT", et)
    out = {"sun_sc": np.empty((n, 3)), "pos_mso": np.empty((n, 3))}
    if j2000:
        out["j2000"] = np.empty((n, 3))
    compiled.attitude_frames(
        rotator.leg_table("MSGR_SPACECRAFT"), rotator.leg_table(FRAMES["mso"][0]),
        np.ascontiguousarray(et, dtype=float), np.ascontiguousarray(b_sc, dtype=float),
        np.ascontiguousarray(sun, dtype=float), np.ascontiguousarray(mercury_j2000, dtype=float),
        out.get("j2000", empty), out["sun_sc"], (out["pos_mso"], empty))
    return out


#: Position variable of each frame (None: the SC frame has none).
POSITION_VARIABLE: dict[str, str | None] = {
    "mso": "pos_mso", "j2000": "pos_j2000", "mbf": "pos_mbf", "rtn": "pos_rtn",
    "vso": "pos_vso", "sc": None,
}


def _field_variable(frame: str, values: np.ndarray) -> xr.Variable:
    """Return ``b_<frame>`` with its attributes."""
    return _vector(values, "nT", f"magnetic field in {FRAMES[frame][0]}")


def _position_variable(frame: str, values: np.ndarray) -> xr.Variable:
    """Return the frame's position variable (`POSITION_VARIABLE`) with its attributes."""
    spice = FRAMES[frame][0]
    if frame == "j2000":
        return _vector(values, "km", "MESSENGER relative to the Sun, J2000")
    if frame == "rtn":
        return _vector(values, "km, deg, deg",
                       "distance from the Sun, ecliptic latitude, azimuth (sec. 10.2)")
    if frame == "vso":
        return _vector(values, "km", f"MESSENGER relative to Venus, {spice}")
    return _vector(values, "km", f"MESSENGER relative to Mercury, {spice}")


def position_frames(frames: tuple[str, ...]) -> tuple[str, ...]:
    """Frames whose position `add_geometry` adds for the field ``frames``, in order.

    ``mso`` always (the quicklook's distance from Mercury and the MSO product), every
    other frame's position only with its field: an unrequested position is a 40-MB array
    per 20 Hz day and, for MBF, a whole J2000 -> IAU_MERCURY leg.
    """
    return tuple(f for f in ("j2000", "mso", "mbf", "rtn", "vso") if f == "mso" or f in frames)


def calibration_frames(frames: Sequence[str]) -> tuple[str, ...]:
    """Frames `add_geometry` computes for the products of ``frames`` (`frame_variables`).

    J2000 when any frame but SC is requested (every other frame is one leg from it, and
    ``pos_j2000`` is the Sun position of RTN and sec. 10.2); SC when requested (its field
    is the attitude leg's input, not recomputed).  A run calibrated with these holds one
    product frame's field and position at a time, each evaluated when that frame is
    written, instead of every frame's (about 40 MB per array of a 20 Hz day).
    """
    frames = tuple(frames)
    return (("j2000",) if any(f != "sc" for f in frames) else ()) + (
        ("sc",) if "sc" in frames else ())


def _sun_interpolator(et: np.ndarray):
    """MESSENGER relative to the Sun (J2000) over ``et`` (None: < 4 samples)."""
    from fluxcal.geometry.positions import StateInterpolator

    if et.size < 4:
        return None
    return StateInterpolator("MESSENGER", "SUN", "J2000", float(et.min()), float(et.max()))


def frame_variables(ds: xr.Dataset, frame: str) -> dict[str, xr.Variable]:
    """Return ``b_<frame>`` and the frame's position variable (`POSITION_VARIABLE`) of ``ds``.

    Taken from ``ds`` when it holds them, else evaluated from ``et``, ``b_j2000``,
    ``pos_j2000`` and ``pos_mso`` (what `add_geometry` gives with `calibration_frames`)
    through the interpolated legs: MSO, MBF and VSO through
    `fluxcal.geometry.frames.Rotator` from J2000 (the MBF position from MESSENGER
    relative to Mercury in J2000, through the same leg as the field), RTN by
    `rtn_from_position` (or the frame's own leg when a kernel defines MSGR_RTN
    otherwise) with the sec. 10.2 position of `spherical_rtn`, VSO's position from
    SPICE.  `add_geometry` obtains every frame but J2000 and SC here, and the product
    writer each frame when it is written: one implementation, the same bits.

    Raises
    ------
    InputFormatError
        When ``ds`` lacks the frame's variables and cannot give them (SC and J2000 are
        taken, never recomputed; the other frames need ``b_j2000``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
    """
    from fluxcal.geometry.frames import Rotator
    from fluxcal.geometry.positions import position

    pos_name = POSITION_VARIABLE[frame]
    names = [f"b_{frame}"] + ([pos_name] if pos_name is not None else [])
    if all(name in ds for name in names):
        return {name: ds[name].variable for name in names}
    if frame in ("sc", "j2000") or "b_j2000" not in ds:
        raise InputFormatError(f"the calibrated day has no {' or '.join(names)} and no "
                               "b_j2000 to compute them from", field=f"b_{frame}")
    et = ds["et"].values
    b_j2000 = ds["b_j2000"].values
    spice_frame = FRAMES[frame][0]
    if frame == "rtn":
        sun = ds["pos_j2000"].values
        if rtn_is_sun_pole_two_vector(spice_frame):
            field = rtn_from_position(b_j2000, sun, et)
        else:
            field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        pos = spherical_rtn(sun, et, sun_at=_sun_interpolator(et))
    elif frame == "mbf":  # position and field through one leg, one after the other
        rotator = Rotator("J2000", et)  # (Mercury's J2000 position freed before the field)
        pos = rotator.rotate(spice_frame, position("MESSENGER", "MERCURY", "J2000", et))
        field = rotator.rotate(spice_frame, b_j2000)
    else:  # MSO (its position is in every calibrated run) and VSO
        field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        if frame == "mso":
            return {"b_mso": _field_variable(frame, field), "pos_mso": ds["pos_mso"].variable}
        pos = position("MESSENGER", "VENUS", spice_frame, et)
    return {f"b_{frame}": _field_variable(frame, field), pos_name: _position_variable(frame, pos)}


#: The MSGR_RTN definition `rtn_from_position` reproduces (fluxcal's msgr_rtn.tf):
#: kernel-pool keyword -> accepted values.
_RTN_DEFINITION = {
    "CLASS": ("5",), "RELATIVE": ("J2000",), "DEF_STYLE": ("PARAMETERIZED",),
    "FAMILY": ("TWO-VECTOR",), "PRI_AXIS": ("X",),
    "PRI_VECTOR_DEF": ("OBSERVER_TARGET_POSITION",), "PRI_OBSERVER": ("SUN", "10"),
    "PRI_TARGET": ("-236", "MESSENGER"), "PRI_ABCORR": ("NONE",), "SEC_AXIS": ("Z",),
    "SEC_VECTOR_DEF": ("CONSTANT",), "SEC_FRAME": ("IAU_SUN",),
    "SEC_SPEC": ("RECTANGULAR",), "SEC_VECTOR": ("0 0 1",),
}


def _pool_text(name: str) -> str | None:
    """Return a kernel-pool variable as text (whole numbers as integers), or None."""
    import spiceypy

    try:
        n, kind = spiceypy.dtpool(name)
    except spiceypy.utils.exceptions.SpiceyError:
        return None
    if kind == "C":
        return " ".join(str(v).strip().upper() for v in spiceypy.gcpool(name, 0, n))
    values = spiceypy.gdpool(name, 0, n)
    return " ".join(str(int(v)) if float(v).is_integer() else repr(float(v)) for v in values)


def rtn_is_sun_pole_two_vector(frame: str) -> bool:
    """Return True when the loaded ``frame`` is the two-vector RTN frame of fluxcal's FK.

    That is: X along the Sun -> MESSENGER position (no aberration correction), Z toward
    the component of the IAU_SUN +Z axis (solar rotation axis) orthogonal to X, relative
    to J2000.  A mission kernel defining the frame otherwise makes this False (and the
    pipeline then rotates with SPICE's definition through the interpolated legs).
    """
    import spiceypy

    code = spiceypy.namfrm(frame)
    if code == 0:
        return False
    for key, accepted in _RTN_DEFINITION.items():
        if _pool_text(f"FRAME_{code}_{key}") not in accepted:
            return False
    return True


def rtn_from_position(b_j2000: np.ndarray, sun: np.ndarray, et: np.ndarray) -> np.ndarray:
    """Rotate J2000 vectors into RTN built from the Sun -> spacecraft position.

    ``R = sun / |sun|``, ``T = unit(Omega x R)`` with ``Omega`` the solar rotation axis
    (IAU_SUN +Z in J2000), ``N = R x T``: the two-vector frame MSGR_RTN of seed 000
    sec. 3.5, evaluated from the positions already computed (no frame leg to build), in
    one compiled pass (`fluxcal.geometry.compiled.rtn_rotate`).

    Parameters
    ----------
    b_j2000 : ndarray, shape (n, 3)
        Vectors in J2000.
    sun : ndarray, shape (n, 3)
        MESSENGER relative to the Sun, J2000 (km).
    et : ndarray, shape (n,)
        Ephemeris times (for the solar rotation axis).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 3.5, sec. 11.
    """
    from fluxcal.geometry import compiled

    out = np.empty_like(b_j2000)
    compiled.rtn_rotate(np.ascontiguousarray(sun, dtype=float), _solar_axis(et),
                        np.ascontiguousarray(b_j2000, dtype=float), out)
    return out


def _solar_axis(et: np.ndarray) -> np.ndarray:
    """IAU_SUN +Z in J2000: (1, 3) when fixed over ``et``, else (n, 3) per sample."""
    from fluxcal.geometry.frames import Rotator, rotation_matrices

    ends = rotation_matrices("IAU_SUN", "J2000", et[[0, -1]], method="oracle")[:, :, 2]
    if np.allclose(ends[0], ends[1], rtol=0.0, atol=1e-15):
        return ends[:1].copy()
    # a precessing pole model: the axis per sample
    return Rotator("IAU_SUN", et).rotate("J2000", np.tile([0.0, 0.0, 1.0], (et.size, 1)))


#: Grid step (s) of the sec. 10.2 angles when the samples are denser (see `spherical_rtn`).
RTN_ANGLE_STEP_S = 1.0


def spherical_rtn(
    sun: np.ndarray, et: np.ndarray, *, method: str = "interpolate",
    step: float = RTN_ANGLE_STEP_S, sun_at: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Distance from the Sun, ecliptic latitude and azimuth (sec. 10.2) per sample.

    The distance is ``|sun|`` at every sample.  The two angles vary slowly (the
    spacecraft's heliocentric direction); when the samples are denser than ``step``
    they are evaluated by `fluxcal.geometry.positions.rtn_spherical` on a ``step`` grid
    and interpolated linearly (azimuth unwrapped).  Error bound: ``step**2 / 8`` times
    the angular acceleration, below 3.7e-9 deg/s**2 even at a 200-km periapsis
    (3.2e-3 km/s**2 at 0.3 AU), so under 5e-10 deg for 1 s -- far below the 1e-7 deg
    printed in the products (checked against the per-sample evaluation in the tests).

    Parameters
    ----------
    sun : ndarray, shape (n, 3)
        MESSENGER relative to the Sun in J2000 (km) at ``et``.
    et : ndarray, shape (n,)
        Ephemeris times, increasing.
    method : {"interpolate", "oracle"}
        ``"oracle"`` evaluates every sample with one SPICE call per sample.
    step : float
        Grid step (s) of the angles.
    sun_at : callable, optional
        MESSENGER relative to the Sun (J2000) at given epochs, e.g. the
        `fluxcal.geometry.positions.StateInterpolator` that gave ``sun``; used on the
        grid instead of building another interpolator.

    Returns
    -------
    ndarray, shape (n, 3)
        ``r`` (km), latitude (deg), azimuth (deg).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.2.
    """
    from fluxcal.geometry import compiled
    from fluxcal.geometry.positions import rtn_spherical

    out = np.empty((et.size, 3))
    span = float(et[-1] - et[0]) if et.size else 0.0
    if method == "oracle" or et.size < 4 * (span / step + 2):
        out[:, 0], out[:, 1], out[:, 2] = rtn_spherical(
            "MESSENGER", et, method=method, target_position=sun)
        return out
    grid = np.linspace(et[0], et[-1], int(np.ceil(span / step)) + 1)
    _r, lat, az = rtn_spherical(
        "MESSENGER", grid, target_position=None if sun_at is None else sun_at(grid))
    # |sun|, np.interp of lat and of np.unwrap(az, period=360), az wrapped back
    compiled.rtn_spherical_interp(np.ascontiguousarray(sun, dtype=float),
                                  np.ascontiguousarray(et, dtype=float), grid,
                                  np.ascontiguousarray(lat, dtype=float),
                                  np.ascontiguousarray(az, dtype=float), out)
    return out


#: Logged and written as the ``mbf_rotation`` attribute when MBF is produced with fluxcal's
#: built-in Mercury orientation.
MBF_BUILTIN_NOTE = (
    "MBF (IAU_MERCURY) uses the IAU 2009 Mercury rotation built into fluxcal: no mission "
    "PCK redefines it. The MESSENGER PCK pck00010_msgr_v23.tpc differs by about 0.094 "
    "deg (0.5 nT on 300 nT); load the mission PCK for archive-grade MBF"
)


def mercury_orientation_is_builtin() -> bool:
    """Return True when the pool's Mercury orientation is fluxcal's IAU 2009 subset.

    Compares ``BODY199_POLE_RA``, ``BODY199_POLE_DEC`` and ``BODY199_PM`` in the kernel
    pool with the values in `fluxcal.geometry.kernels.orientation_pck`: equal means no
    mission PCK (loaded after the generic kernels) redefined them.
    """
    import re

    import spiceypy

    from fluxcal.geometry.kernels import orientation_pck

    text = orientation_pck().read_text()
    for name in ("BODY199_POLE_RA", "BODY199_POLE_DEC", "BODY199_PM"):
        match = re.search(rf"{name}\s*=\s*\(([^)]*)\)", text)
        if match is None:  # pragma: no cover - the shipped file defines all three
            raise FluxcalError(f"{orientation_pck()}: {name} not found")
        builtin = [float(v) for v in match.group(1).split()]
        try:
            pool = spiceypy.gdpool(name, 0, len(builtin))
        except spiceypy.utils.exceptions.SpiceyError:
            return False
        if len(pool) != len(builtin) or any(a != b for a, b in zip(pool, builtin, strict=True)):
            return False
    return True


def note_mbf_rotation(ds: xr.Dataset, frames: Sequence[str]) -> xr.Dataset:
    """Log and record the built-in Mercury rotation when MBF is in ``frames``.

    When MBF is produced with fluxcal's built-in Mercury rotation (no mission PCK,
    `mercury_orientation_is_builtin`): logs `MBF_BUILTIN_NOTE` as a warning, sets it as
    the ``mbf_rotation`` attribute (which every product of the run carries; placed before
    ``software_version`` when present, the attributes `pipeline.calibrate` adds last, so
    the labels list it in the same place whether MBF is computed by `add_geometry` or
    when written) and notes ``rotation_model`` on ``b_mbf`` when ``ds`` holds it.
    Otherwise returns ``ds`` itself.
    """
    if "mbf" not in frames or not mercury_orientation_is_builtin():
        return ds
    log.warning(MBF_BUILTIN_NOTE)
    attrs = dict(ds.attrs)
    keys = list(attrs)
    at = keys.index("software_version") if "software_version" in keys else len(keys)
    ordered = {k: attrs[k] for k in keys[:at]}
    ordered["mbf_rotation"] = MBF_BUILTIN_NOTE
    ordered.update((k, attrs[k]) for k in keys[at:])
    out = ds.copy(deep=False)
    out.attrs = ordered
    if "b_mbf" in out:
        out["b_mbf"].attrs["rotation_model"] = "IAU 2009 (fluxcal built-in), no mission PCK"
    return out


def add_geometry(
    ds: xr.Dataset,
    cal: MessengerCalibration,
    frames: tuple[str, ...] = ("mso", "j2000", "mbf", "rtn", "sc"),
    *,
    method: str = "interpolate",
) -> xr.Dataset:
    """Rotate the sensor field into the requested frames and add positions (sec. 10, 11).

    The field goes sensor -> MSGR_SPACECRAFT (fixed mounting of MSGR_MAG, or
    MSGR_MAG_STOWED before boom deployment) -> J2000 (attitude, CK) -> each frame, the
    composition SPICE's ``pxform`` performs.  Adds ``b_<frame>`` for each requested key
    of `FRAMES`, ``sun_sc`` (unit Sun direction in MSGR_SPACECRAFT, for the S flag) and
    ``pos_mso`` (relative to Mercury in MSGR_MSO, for the MSO product and the quicklook's
    distance); the other positions (`POSITION_VARIABLE`) only with their frame
    (`position_frames`): ``pos_j2000`` (MESSENGER relative to the Sun, J2000),
    ``pos_mbf`` (relative to Mercury in IAU_MERCURY), ``pos_rtn`` (r km, latitude deg,
    azimuth deg of sec. 10.2) and ``pos_vso`` (relative to Venus in MSGR_VSO).  With
    ``method="interpolate"`` the J2000 field, ``sun_sc`` and ``pos_mso`` come from one
    compiled pass and every other frame from them through `frame_variables` (what the
    product writer uses).  What is computed for a requested frame does not depend on the
    other frames requested.  Kernels must be loaded.  MBF produced with fluxcal's
    built-in Mercury rotation is noted (`note_mbf_rotation`).

    Parameters
    ----------
    ds : xarray.Dataset
        With ``et`` and ``b_sensor``.
    cal : MessengerCalibration
        For the boom deployment date.
    frames : tuple of str
        Keys of `FRAMES`.
    method : {"interpolate", "oracle"}
        Vectorized geometry, or one SPICE call per sample (the reference).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
    """
    from fluxcal.geometry.positions import position

    et = ds["et"].values
    b = ds["b_sensor"].values
    deployed = sensor_frame(et, cal)
    b_sc = np.empty_like(b)
    for name, sel in (("MSGR_MAG", deployed), ("MSGR_MAG_STOWED", ~deployed)):
        if sel.all():
            b_sc = _apply(_sensor_to_spacecraft(name, et, method), b)
        elif sel.any():
            b_sc[sel] = _apply(_sensor_to_spacecraft(name, et[sel], method), b[sel])
    # MESSENGER relative to the Sun (J2000): pos_j2000, the Sun direction and sec. 10.2
    sun_at = None if method == "oracle" else _sun_interpolator(et)
    if sun_at is None:
        sun = position("MESSENGER", "SUN", "J2000", et, method=method)
    else:
        sun = sun_at(et)
    fields: dict[str, xr.Variable] = {}
    positions: dict[str, xr.Variable] = {}
    if method == "oracle":
        out = _rotate_oracle(b_sc, sun, et, frames)
        for f in position_frames(frames):
            if f == "j2000":
                pos = sun
            elif f == "rtn":
                pos = spherical_rtn(sun, et, method=method, sun_at=sun_at)
            else:
                target = "VENUS" if f == "vso" else "MERCURY"
                pos = position("MESSENGER", target, FRAMES[f][0], et, method=method)
            positions[f] = _position_variable(f, pos)
        fields = {f: _field_variable(f, out.pop(f)) for f in frames}
        sun_sc = out.pop("sun_sc")
    else:
        mercury = position("MESSENGER", "MERCURY", "J2000", et, method=method)
        out = _rotate_interpolated(b_sc, sun, et, "j2000" in calibration_frames(frames),
                                   mercury_j2000=mercury)
        del mercury
        sun_sc = out.pop("sun_sc")
        positions["mso"] = _position_variable("mso", out.pop("pos_mso"))
        if "sc" in frames:
            fields["sc"] = _field_variable("sc", b_sc)
        if "j2000" in out:  # every other frame is one leg from J2000 (sec. 10.1, 11)
            fields["j2000"] = _field_variable("j2000", out.pop("j2000"))
            positions["j2000"] = _position_variable("j2000", sun)
            legs = xr.Dataset({"et": ds["et"].variable, "b_j2000": fields["j2000"],
                               "pos_j2000": positions["j2000"], "pos_mso": positions["mso"]})
            for f in frames:
                if f not in ("sc", "j2000"):
                    got = frame_variables(legs, f)
                    fields[f] = got[f"b_{f}"]
                    if f != "mso":
                        positions[f] = got[POSITION_VARIABLE[f]]
            del legs
    del b_sc, out, sun  # the Sun position stays only as pos_j2000 (J2000 requested)
    variables = {f"b_{f}": fields[f] for f in frames}
    variables.update((POSITION_VARIABLE[f], positions[f]) for f in position_frames(frames))
    variables["sun_sc"] = _vector(sun_sc, "1", "unit Sun direction in MSGR_SPACECRAFT")
    del fields, positions
    return note_mbf_rotation(ds.assign(variables), frames)


# ----------------------------------------------------------------------------------------
# 6. quality
# ----------------------------------------------------------------------------------------
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


# ----------------------------------------------------------------------------------------
# 7. validation
# ----------------------------------------------------------------------------------------
#: Sec. 13 gap rule: a step longer than this many nominal sample spacings is a gap.
GAP_SPACINGS = 2.5


def offset_step_report(ds: xr.Dataset, max_gap_s: float = 10.0) -> dict:
    """Largest step of the applied thermal offset per axis and where (sec. 13).

    Steps across data gaps are ignored: a gap is longer than ``max_gap_s`` and than
    `GAP_SPACINGS` nominal sample spacings of the sample after it (Table 1's rate, from
    the ``sample_rate_hz`` attribute `correct_time` puts on ``rate``; without it the gap
    is ``max_gap_s``).  A step over more than ``max_gap_s`` (sample spacings of 20-100 s
    at rate settings 0-2) counts as ``step * max_gap_s / dt``: the threshold is a rate
    of change per ``max_gap_s``, the same as for denser data, so that the smooth
    relaxation of sec. 7 over a long spacing is not taken for a discontinuity.  Steps
    touching a sample before V10 that is not ``sunlit`` (stowed or in shadow: offset at
    the measured temperature, flagged uncorrectable, C = 1) and steps where the 22.4 C
    rule of sunlit pre-V10 samples starts or ends are ignored as well (sec. 7): the check
    is on the calibration of sec. 6-7, not on the sensor's temperature.

    Returns
    -------
    dict
        ``{"x": {"step_counts": ..., "utc_index": i, "et": ...}, ...}``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 7, sec. 13.
    """
    et = ds["et"].values
    max_gap: float | np.ndarray = max_gap_s
    rates = ds["rate"].attrs.get("sample_rate_hz") if "rate" in ds else None
    if rates is not None:
        spacing = 1.0 / np.asarray(rates, dtype=float)[ds["rate"].values.astype(np.int64)]
        max_gap = np.maximum(max_gap_s, GAP_SPACINGS * spacing)
    segment = None
    if "sunlit" in ds:  # V10 | pre-V10 sunlit (fixed 22.4 C) | each other pre-V10 sample
        pre = ~(et >= float(ds["sunlit"].attrs.get("v10_et", np.inf)))
        segment = np.where(~pre, -1, np.where(ds["sunlit"].values, -2,
                                              np.arange(et.size, dtype=np.int64)))
    rep = largest_steps(ds["offset"].values, segment, times=et, max_gap=max_gap,
                        time_scale=max_gap_s)
    return {
        axis: {"step_counts": float(rep.largest_step[j]), "index": int(rep.index[j]),
               "et": float(et[min(rep.index[j], et.size - 1)])}
        for j, axis in enumerate(COMPONENT)
    }


def validate_offsets(ds: xr.Dataset, threshold_counts: float = 2.0) -> dict:
    """Fail the day when the applied offset has a step above ``threshold_counts``.

    Returns
    -------
    dict
        The step report (see `offset_step_report`).

    Raises
    ------
    ValidationError
        Naming the axis, the step and the time.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13.
    """
    report = offset_step_report(ds)
    for axis, item in report.items():
        if item["step_counts"] > threshold_counts:
            from fluxcal.geometry.time import et_to_utc

            utc = et_to_utc(np.array([item["et"]]))[0]
            raise ValidationError(
                f"offset {axis}: step of {item['step_counts']:.3f} counts at {utc} exceeds the "
                f"smoothness threshold {threshold_counts} counts (MESSENGER MAG EDR-to-CDR "
                "Processing, sec. 13)"
            )
    return report
