"""RPC-MAG LEVEL_A science data: calibrated field in instrument (URF) coordinates.

Steps (seed 003, sec. 4.2.3): drop vectors flagged bad; counts -> engineering nT;
calibrated sensor temperature; ground calibration ``B_c = omega0(T) sigma(T) (B_r - B_off(T))``;
the daily extended-temperature offset with midnight stitching; the filter-mode time shift.
Each step is a pure array function; `level_a` chains them on a ``Dataset``.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2, 3.3, 4.2.3.1-4.2.3.5.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
import xarray as xr

from fluxcal.calibration import counts as cnt
from fluxcal.calibration import matrices as mat
from fluxcal.calibration import thermal, timeshift
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.days import utc_days
from fluxcal.missions.rosetta import hk
from fluxcal.missions.rosetta.calib import (
    DailyOffsetModel,
    GroundCalibration,
    TimeShiftTable,
    check_sensor,
)
from fluxcal.missions.rosetta.extended_model import (
    STITCH_GAP_S,
    StitchState,
    extended_offset,
    outside_fitted_range,
)

log = logging.getLogger(__name__)

#: Quality bits meaning "bad component" (bit 0: x, 1: y, 2: z); bit 3 is the sensor id.
BAD_BITS = 0b0111
SENSOR_BIT = 0b1000


# ----------------------------------------------------------------------------------------
# Pure array steps
# ----------------------------------------------------------------------------------------
def wrong_quality(quality: np.ndarray, sensor: str) -> np.ndarray:
    """Mask of quality words that cannot belong to ``sensor``'s vectors.

    Bit 3 is the sensor id (0 = OB, 1 = IB); bits above 3 are undefined (seed 003,
    sec. 4.1.2).
    """
    q = np.asarray(quality, dtype=np.int64)
    expected = SENSOR_BIT if check_sensor(sensor) == "IB" else 0
    return ((q & SENSOR_BIT) != expected) | (q > 0b1111) | (q < 0)


def good_vectors(quality: np.ndarray) -> np.ndarray:
    """Mask of vectors with no bad-component bit (bits 0-2) set.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.2 (QUALITY) and 4.2.3 step 1.
    """
    return (np.asarray(quality, dtype=np.int64) & BAD_BITS) == 0


def field_counts_to_nt(counts: np.ndarray, nominal: dict) -> np.ndarray:
    """Signed 20-bit science counts -> engineering nT (seed 003, sec. 4.2.3.1)."""
    p = nominal["science_field"]
    return cnt.signed_to_value(counts, p["b_min_nt"], p["b_max_nt"], p["bits"])


def field_nt_to_counts(b: np.ndarray, nominal: dict) -> np.ndarray:
    """Inverse of `field_counts_to_nt` (nearest count; forward models)."""
    p = nominal["science_field"]
    return cnt.value_to_signed(b, p["b_min_nt"], p["b_max_nt"], p["bits"])


def sensor_temperature(counts: np.ndarray, cal: GroundCalibration, nominal: dict) -> np.ndarray:
    """Thermistor words -> calibrated sensor temperature T^c in deg C.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.2.5 (words -> volts), 3.3.3 and 4.2.3.2
       item 1 (``T^c = c0 + c1 U + c2 U^2 + c3 U^3 - T^O``).
    """
    u = hk.thermistor_voltage(counts, nominal)
    return thermal.thermistor_temperature(u, cal.thermistor, cal.thermistor_offset)


def offset(temperature: np.ndarray, cal: GroundCalibration) -> np.ndarray:
    """Sensor offset ``B_off = A_0 + A_1 T - B_res`` (nT), shape (n, 3).

    ``B_res`` is left out when the calibration file says ``B_RES_IN_OFFSET = 0`` (the
    reading of sec. 4.2.3.2 item 2; docs/decisions/rosetta.md, decision 25).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.3.1.1 / 3.3.2.1 (with B^res) and 4.2.3.2 item 2.
    """
    linear = thermal.linear_in_temperature(cal.offset, temperature)
    return linear - cal.residual_field if cal.residual_in_offset else linear


def sensitivity(temperature: np.ndarray, cal: GroundCalibration) -> np.ndarray:
    """Diagonal of sigma^0(T) = SIGMA_00 + SIGMA_01 T, shape (n, 3).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.3.1.2 / 3.3.2.2 and 4.2.3.2 item 4.
    """
    return thermal.linear_in_temperature(cal.sensitivity, temperature)


def misalignment(
    temperature: np.ndarray, cal: GroundCalibration, *, form: str = "unit"
) -> np.ndarray:
    """omega^0(T) = omega^1(xi^1(T)) K^-1, shape (n, 3, 3).

    Parameters
    ----------
    temperature : array_like, shape (n,)
        Calibrated sensor temperature, deg C.
    cal : GroundCalibration
    form : {"unit", "sec321"}
        Which of the seed's two omega forms (see `fluxcal.calibration.matrices`).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2.2.3, 3.3.1.3 / 3.3.2.3, 4.2.3.2 item 5.
    """
    xi = thermal.linear_in_temperature(cal.angles, temperature)
    omega1 = mat.orthogonalisation_matrix(xi[:, 0], xi[:, 1], xi[:, 2], form=form)
    return omega1 @ cal.k_inverse


def ground_calibrate(
    b_raw: np.ndarray, temperature: np.ndarray, cal: GroundCalibration, *, form: str = "unit"
) -> np.ndarray:
    """``B_c = omega0(T) sigma(T) (B_r - B_off(T))`` in nT, shape (n, 3).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.2 items 2-6.
    """
    b_m = np.asarray(b_raw, dtype=float) - offset(temperature, cal)
    return mat.apply(misalignment(temperature, cal, form=form), sensitivity(temperature, cal) * b_m)


def ground_calibrate_words(
    b_raw: np.ndarray,
    words: np.ndarray,
    cal: GroundCalibration,
    nominal: dict,
    *,
    form: str = "unit",
) -> tuple[np.ndarray, np.ndarray]:
    """`ground_calibrate` for thermistor words: one matrix per distinct word, then a gather.

    The calibrated temperature depends only on the 16-bit thermistor word, so offset,
    sensitivity and misalignment are evaluated once per word in ``min..max`` and looked
    up per vector; identical to the per-vector formula, several times faster.

    Returns
    -------
    b_cal : ndarray, shape (n, 3)
        ``omega0(T) sigma(T) (B_r - B_off(T))`` (nT).
    temperature : ndarray, shape (n,)
        Calibrated temperature (deg C) of each vector.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.2.5, 4.2.3.2 items 1-6.
    """
    words = np.asarray(words, dtype=np.int64)
    if words.size == 0:
        return np.zeros((0, 3)), np.zeros(0)
    lo, hi = int(words.min()), int(words.max())
    grid = np.arange(lo, hi + 1)
    t_grid = sensor_temperature(grid, cal, nominal)
    table = misalignment(t_grid, cal, form=form) * sensitivity(t_grid, cal)[:, None, :]
    corr = mat.apply(table, offset(t_grid, cal))  # M(T) B_off(T) per word
    index = words - lo
    b_cal = mat.apply_lookup(table, index, b_raw) - corr[index]
    return b_cal, t_grid[index]


def ground_uncalibrate(
    b_cal: np.ndarray, temperature: np.ndarray, cal: GroundCalibration, *, form: str = "unit"
) -> np.ndarray:
    """Exact inverse of `ground_calibrate`: ``B_r = sigma^-1 omega0^-1 B_c + B_off``.

    Used by the forward model (`fluxcal.missions.rosetta.simulate`).
    """
    b_m = mat.solve(misalignment(temperature, cal, form=form), b_cal) / sensitivity(
        temperature, cal
    )
    return b_m + offset(temperature, cal)


def filter_time_shift(
    sid: np.ndarray, table: TimeShiftTable, *, sensor: str, primary: str = "OB"
) -> np.ndarray:
    """Seconds to add to each time stamp for its filter mode (seed 003, sec. 4.2.3.5).

    The primary sensor (OB unless told) uses the filtered-data table, the other sensor
    the SECONDARY table.

    Raises
    ------
    KeyError
        ``(index, sid)`` of the first vector whose SID has no entry in the table.
    """
    is_primary = check_sensor(sensor) == check_sensor(primary)
    return timeshift.mode_shifts(sid, table.sid, table.primary if is_primary else table.secondary)


def stitch_edges(raw: xr.Dataset, sensor: str) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """``((epoch, word), (epoch, word))`` of the first and last good vector of ``raw``.

    Epoch is the telemetry TT2000 (before the filter shift) and word the sensor's own
    thermistor word: all the midnight stitching of sec. 4.2.3.3 needs of a day
    (`fluxcal.missions.rosetta.extended_model.stitch_day`).  ``None`` without good vectors.
    """
    good = np.flatnonzero(good_vectors(raw["quality"].values))
    if good.size == 0:
        return None
    epoch = raw["epoch"].values
    words = raw[f"t_{check_sensor(sensor).lower()}_counts"].values
    i, j = int(good[0]), int(good[-1])
    return (int(epoch[i]), int(words[i])), (int(epoch[j]), int(words[j]))


# ----------------------------------------------------------------------------------------
# Level function
# ----------------------------------------------------------------------------------------
def level_a(
    raw: xr.Dataset,
    calibration: GroundCalibration,
    time_shifts: TimeShiftTable,
    nominal: dict,
    *,
    daily_models: Mapping[np.datetime64, DailyOffsetModel] | None = None,
    primary: str = "OB",
    stitch_gap_s: float = STITCH_GAP_S,
    previous: StitchState | None = None,
    omega_form: str = "unit",
    lsk=None,
) -> xr.Dataset:
    """Raw science counts -> LEVEL_A field (nT, instrument coordinates).

    Parameters
    ----------
    raw : xarray.Dataset
        Raw science data of one sensor (`fluxcal.missions.rosetta.io.read_science_csv` or
        `fluxcal.missions.rosetta.simulate.simulate`): ``epoch`` (TT2000 ns), ``obt`` (s),
        ``sid``, ``b_counts`` (time, component), ``t_ob_counts``, ``t_ib_counts``,
        ``quality``; attribute ``sensor``.
    calibration : GroundCalibration
        Of the same sensor.
    time_shifts : TimeShiftTable
    nominal : dict
        Nominal conversion constants (`calib.load_nominal_conversion`).
    daily_models : mapping, optional
        Daily extended-temperature models by UTC day; days without one get the ground
        calibration alone (the ``extended_temperature_model`` attribute says so).
    primary : {"OB", "IB"}
        The primary sensor (time-shift table choice).
    stitch_gap_s : float
        Midnight stitching gap limit (default 3 h).
    previous : StitchState, optional
        Stitching state of the previous day when days are processed one by one.
    omega_form : {"unit", "sec321"}
        Orthogonalisation form (docs/decisions/rosetta.md).
    lsk : LeapSecondTable, optional
        Needed only with daily models (UTC day boundaries); default the loaded LSK.

    Returns
    -------
    xarray.Dataset
        ``b`` (nT), ``temperature`` (K), ``obt`` (s, shifted), ``sid``, ``quality``,
        coordinate ``epoch`` shifted to the physical event time and sorted; attributes
        ``n_dropped_quality``, ``n_reordered``, calibration provenance and the stitching
        end state (`StitchState.to_attrs`); coordinate ``mode_segment`` numbers the runs
        of one filter mode (SID) in telemetry order (one calibrated TAB file each).

    Raises
    ------
    InputFormatError
        Quality word of the wrong sensor, a SID without a time shift, counts out of range.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3 steps 1-5.
    """
    sensor = check_sensor(raw.attrs.get("sensor", calibration.sensor))
    if sensor != calibration.sensor:
        raise InputFormatError(
            f"science data are from sensor {sensor} "
            f"but the calibration is for {calibration.sensor}",
            path=raw.attrs.get("source"),
        )
    source = raw.attrs.get("source")
    row = raw["row"].values if "row" in raw else np.arange(raw.sizes["time"]) + 1
    wrong = wrong_quality(raw["quality"].values, sensor)
    if np.any(wrong):
        i = int(np.flatnonzero(wrong)[0])
        raise InputFormatError(
            f"quality {int(raw['quality'].values[i])} does not belong to a {sensor} vector "
            f"(bit 3 must be {int(sensor == 'IB')}, bits above 3 must be 0; "
            f"RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 4.1.2)",
            path=source,
            line=int(row[i]),
            field="quality",
        )
    good = good_vectors(raw["quality"].values)
    n_dropped = int((~good).sum())
    data = raw.isel(time=np.flatnonzero(good)) if n_dropped else raw
    row = row[good]
    epoch = data["epoch"].values.astype(np.int64)

    try:
        b_raw = field_counts_to_nt(data["b_counts"].values, nominal)
        b_c, t_c = ground_calibrate_words(
            b_raw, data[f"t_{sensor.lower()}_counts"].values, calibration, nominal, form=omega_form
        )
    except ValueError as exc:
        raise InputFormatError(f"counts out of range: {exc}", path=source) from None

    attrs = dict(raw.attrs)
    models = daily_models or {}
    if models:
        day_index, days, _ = utc_days(epoch, lsk)
        words = data[f"t_{sensor.lower()}_counts"].values.astype(np.int64)
        lo = int(words.min())
        grid = calibration.extended_model_temperature(
            sensor_temperature(np.arange(lo, int(words.max()) + 1), calibration, nominal)
        )
        reduced = calibration.extended_model_temperature(t_c)
        try:
            ext, state, sources = extended_offset(
                epoch,
                reduced,
                day_index,
                days,
                models,
                stitch_gap_s=stitch_gap_s,
                previous=previous,
                lookup=(words - lo, grid),
            )
        except ValueError as exc:
            raise FluxcalError(f"{source}: midnight stitching (sec. 4.2.3.3): {exc}") from None
        b_c -= ext  # in place: a 20 Hz day's (n, 3) copy is 41 MB
        outside = outside_fitted_range(reduced, day_index, days, models)
        if outside:
            attrs["extended_model_outside_fitted_range"] = "; ".join(outside)
            for text in outside:
                log.warning("%s: %s", source, text)
    else:
        state, sources = None, []
    attrs["extended_temperature_model"] = (
        "model 006 daily files: " + ", ".join(sources)
        if sources
        else "none: ground calibration alone (no daily RPCMAG_<yymmdd>_006_CALIB file)"
    )
    if state is not None:
        attrs.update(state.to_attrs())

    try:
        shift = filter_time_shift(data["sid"].values, time_shifts, sensor=sensor, primary=primary)
    except KeyError as exc:
        i, sid = exc.args
        table = "primary" if sensor == check_sensor(primary) else "secondary"
        raise InputFormatError(
            f"filter mode SID {sid} has no time shift in the {table}-sensor table "
            f"{time_shifts.source} (RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 4.2.3.5)",
            path=source,
            line=int(row[i]),
            field="sid",
        ) from None
    new_epoch = timeshift.shift_epoch(epoch, shift)
    obt = data["obt"].values + shift
    sid = data["sid"].values
    # a new measurement-mode segment starts wherever the SID changes in telemetry order
    # (the calibrated products start a new file there, docs/formats/rosetta.md)
    segment = np.concatenate([[0], np.cumsum(sid[1:] != sid[:-1])]).astype(np.int32)
    if new_epoch.size < 2 or np.all(new_epoch[1:] >= new_epoch[:-1]):
        order = slice(None)
        n_reordered = 0
    else:
        order = np.argsort(new_epoch, kind="stable")
        n_reordered = int(np.count_nonzero(order != np.arange(order.size)))

    out = xr.Dataset(
        {
            "b": (
                ("time", "component"),
                b_c[order],
                {"units": "nT", "frame": f"ROS_RPC_MAG_{sensor} (URF)"},
            ),
            "temperature": ("time", t_c[order] + hk.KELVIN, {"units": "K"}),
            "obt": (
                "time",
                obt[order],
                {"units": "s", "description": "TIME.OBT, filter shift added"},
            ),
            "sid": ("time", data["sid"].values[order], {"units": "1"}),
            "quality": ("time", data["quality"].values[order], {"units": "1"}),
        },
        coords={
            "epoch": ("time", new_epoch[order], {"units": "ns", "time_base": "TT2000"}),
            "component": ["x", "y", "z"],
            "mode_segment": ("time", segment[order], {"units": "1"}),
        },
        attrs=attrs,
    )
    out.attrs.update(
        level="A",
        sensor=sensor,
        primary_sensor=check_sensor(primary),
        n_dropped_quality=n_dropped,
        n_reordered=n_reordered,
        ground_calibration=f"{calibration.source} (version {calibration.version})",
        residual_field_in_offset=int(calibration.residual_in_offset),
        extended_model_temperature=calibration.reduced_temperature,
        time_shift_table=time_shifts.source,
        omega_form=omega_form,
    )
    return out
