"""RPC-MAG instrument model in the forward direction: telemetry words from field.

Written from seed 003 and its tables alone, sharing no code with the pipeline
(`fluxcal.calibration`, `fluxcal.missions.rosetta.level_*`, ``hk``): the calibration
files are parsed by the loaders of `fluxcal.missions.rosetta.calib` (which only parse)
and every step runs the way the instrument does:

- the field seen by the sensor, ``B_c`` (orthogonal URF, nT), becomes the raw engineering
  field ``B_r = B_off(T) + S(T) O(T) B_c`` with ``S = sigma^-1`` and ``O = omega0^-1``
  applied by *solving* ``omega0(T) sigma(T) x = B_c`` (sec. 3.2.1, 3.2.2, 4.2.3.2);
- ``B_r`` goes through the 20-bit ADC (sec. 4.2.3.1) and the PIU's ``- 2^19``;
- the thermistor voltage of the true temperature is found by inverting the sec. 3.3.3
  cubic on a dense voltage grid, digitised by the 20-bit ADC and reduced by the PIU
  operation ``(ADC - 2^19) shr 4`` (sec. 4.2.1, 4.2.2.5), not by the pipeline's
  rounding inverse;
- the HK field and reference voltage go through the same ADC and PIU operations
  (sec. 4.2.2.1, 4.2.2.2);
- the filter-mode delay, the offset jumps (Appendix B) and the extended temperature
  model with the midnight shift of sec. 4.2.3.3 are looked up here from the parsed tables.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2-3.3, 4.2.1-4.2.3.5, Appendix B.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fluxcal.geometry.time import tt2000_to_utc, utc_to_tt2000
from fluxcal.missions.rosetta.calib import (
    DailyOffsetModel,
    GroundCalibration,
    OffsetJumpTable,
    TimeShiftTable,
)

KELVIN = 273.15
NS = 1_000_000_000
ADC_BITS = 20
#: Extended-model offsets are carried across midnight for gaps up to this (s): "more than
#: a few hours" breaks the campaign (sec. 4.2.3.3; fluxcal's default, decision 10).
STITCH_GAP_S = 3 * 3600.0


def _adc(value: np.ndarray, vmin: float, vmax: float, bits: int = ADC_BITS) -> np.ndarray:
    """ADC word (0 .. 2^bits - 1) of ``value`` in ``[vmin, vmax]`` (nearest step)."""
    full = 2**bits - 1
    word = np.rint((np.asarray(value, dtype=float) - vmin) / (vmax - vmin) * full)
    return np.clip(word, 0, full).astype(np.int64)


def omega0(temperature_c: np.ndarray, cal: GroundCalibration) -> np.ndarray:
    """Orthogonalisation matrix omega^0(T) = omega^1(xi^1(T)) K^-1, shape (n, 3, 3).

    Written from sec. 3.2.2.3 / 4.2.3.2 item 5 (the form with unit columns, docs
    decision 1); angles ``XI_10 + XI_11 T`` in degrees.
    """
    t = np.asarray(temperature_c, dtype=float)
    xy, xz, yz = (np.radians(cal.angles[0, j] + cal.angles[1, j] * t) for j in range(3))
    w = np.zeros((t.size, 3, 3))
    w[:, 0, 0] = 1.0
    w[:, 0, 1] = np.cos(xy)
    w[:, 0, 2] = np.cos(xz)
    w[:, 1, 1] = np.sin(xy)
    w[:, 1, 2] = (np.cos(yz) - np.cos(xy) * np.cos(xz)) / np.sin(xy)
    w[:, 2, 2] = np.sqrt(np.sin(xz) ** 2 - w[:, 1, 2] ** 2)
    return w @ np.asarray(cal.k_inverse, dtype=float)


def sensor_offset(
    temperature_c: np.ndarray, cal: GroundCalibration, *, include_residual: bool | None = None
) -> np.ndarray:
    """Raw-data offset ``a_0 + a_1 T``, minus ``B_res`` where it is part of it; (n, 3).

    ``B_res`` is the coil facility's residual field inside the fitted ``a_0`` (sec. 3.2.1,
    3.3.1.1); sec. 4.2.3.2 item 2 omits it.  ``include_residual`` None follows the file's
    ``B_RES_IN_OFFSET`` key (default: subtracted; docs/decisions/rosetta.md).
    """
    if include_residual is None:
        include_residual = bool(getattr(cal, "residual_in_offset", True))
    t = np.asarray(temperature_c, dtype=float)[:, None]
    off = cal.offset[0][None, :] + cal.offset[1][None, :] * t
    return off - cal.residual_field[None, :] if include_residual else off


def reduced_temperature(temperature_c: np.ndarray, cal: GroundCalibration) -> np.ndarray:
    """Return the variable of the daily extended polynomial (sec. 4.2.3.3).

    ``T^c``, or ``T^c - T^O`` when the file's ``REDUCED_TEMPERATURE`` key says
    ``CALIBRATED_MINUS_T_OFF``.
    """
    t = np.asarray(temperature_c, dtype=float)
    if getattr(cal, "reduced_temperature", "CALIBRATED") == "CALIBRATED_MINUS_T_OFF":
        return t - cal.thermistor_offset
    return t


def raw_field(
    b_c: np.ndarray, temperature_c: np.ndarray, cal: GroundCalibration, *,
    include_residual: bool | None = None,
) -> np.ndarray:
    """Raw engineering field ``B_r`` (nT) the sensor reports for ``B_c`` at temperature T.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2.1 (``B^m = F B^c``, ``phi = omega sigma``),
       3.2.2.2-3.2.2.3, 4.2.3.2 items 2-6.
    """
    t = np.asarray(temperature_c, dtype=float)
    sigma = cal.sensitivity[0][None, :] + cal.sensitivity[1][None, :] * t[:, None]
    phi = omega0(t, cal) * sigma[:, None, :]  # omega0 @ diag(sigma)
    b_m = np.linalg.solve(phi, np.asarray(b_c, dtype=float)[:, :, None])[:, :, 0]
    return b_m + sensor_offset(t, cal, include_residual=include_residual)


def science_counts(b_raw: np.ndarray, nominal: dict) -> np.ndarray:
    """Signed 20-bit EDITED RAW counts of engineering field ``b_raw`` (sec. 4.2.3.1).

    ADC word over ``B_MIN .. B_MAX``, minus ``2^19`` (the PIU operation).
    """
    p = nominal["science_field"]
    return _adc(b_raw, p["b_min_nt"], p["b_max_nt"], int(p["bits"])) - 2 ** (int(p["bits"]) - 1)


def thermistor_voltage(temperature_c: np.ndarray, cal: GroundCalibration) -> np.ndarray:
    """Voltage U with ``c0 + c1 U + c2 U^2 + c3 U^3 - T^O = T`` (sec. 3.3.3, 4.2.3.2 item 1).

    The cubic is monotonic over the PT1000 range (0.5-1.6 V, -200..+200 C; sec. 4.2.2.5):
    inverted by interpolation on a 1-uV grid.
    """
    u = np.arange(0.5, 1.6, 1e-6)
    c = cal.thermistor
    t_of_u = c[0] + u * (c[1] + u * (c[2] + u * c[3])) - cal.thermistor_offset
    if np.any(np.diff(t_of_u) <= 0):
        raise ValueError(f"{cal.source}: thermistor cubic not monotonic over 0.5-1.6 V")
    return np.interp(np.asarray(temperature_c, dtype=float), t_of_u, u)


def thermistor_words(temperature_c: np.ndarray, cal: GroundCalibration,
                     nominal: dict) -> np.ndarray:
    """16-bit thermistor words: ``(ADC - 2^19) shr 4`` of the voltage (sec. 4.2.2.5)."""
    p = nominal["thermistor"]
    adc = _adc(thermistor_voltage(temperature_c, cal), p["u_min_v"], p["u_max_v"])
    return (adc - 2 ** (ADC_BITS - 1)) >> (ADC_BITS - int(p["bits"]))


def hk_field_words(b_raw: np.ndarray, nominal: dict) -> np.ndarray:
    """16-bit HK field words: ``(ADC - 2^19) shr 4`` mod 2^16 (sec. 4.2.2.1)."""
    p = nominal["hk_field"]
    adc = _adc(b_raw, p["b_min_nt"], p["b_max_nt"])
    return np.mod((adc - 2 ** (ADC_BITS - 1)) >> (ADC_BITS - int(p["bits"])), 2 ** int(p["bits"]))


def reference_voltage_word(u_ref_v: float, nominal: dict) -> int:
    """20-bit HK word of the ADC reference ``u_ref_v`` behind its divider (sec. 4.2.2.2).

    Divider ``R_low / (R_low + R_high)`` = 0.49996 as printed (docs decision 6).
    """
    p = nominal["hk_reference_voltage"]
    monitored = u_ref_v * p["divider_r_low_ohm"] / (p["divider_r_low_ohm"]
                                                    + p["divider_r_high_ohm"])
    adc = _adc(np.array([monitored]), p["u_min_v"], p["u_max_v"])[0]
    return int(np.mod(adc - 2 ** (ADC_BITS - 1), 2**ADC_BITS))


def filter_delay(sid: np.ndarray, table: TimeShiftTable, *, secondary: bool) -> np.ndarray:
    """Seconds between the physical event and its time stamp for each SID (sec. 4.2.3.5)."""
    column = np.asarray(table.secondary if secondary else table.primary, dtype=float)
    lookup = dict(zip(np.asarray(table.sid).tolist(), column.tolist(), strict=True))
    values = np.array([lookup.get(int(s), np.nan) for s in np.unique(sid)])
    if np.isnan(values).any():
        raise ValueError(f"{table.source}: no time shift for some SID in {np.unique(sid)}")
    return values[np.searchsorted(np.unique(sid), sid)]


def jump_field(event_tt2000: np.ndarray, table: OffsetJumpTable, sensor: str, lsk=None
               ) -> np.ndarray:
    """Appendix B offset in s/c coordinates (nT) present at each event, shape (n, 3).

    The pipeline removes it from LEVEL_B data; the forward model adds it.  Intervals
    ``[start, end)`` (docs/decisions/rosetta.md); outside every interval 0.
    """
    starts = utc_to_tt2000(np.asarray(table.start_utc), lsk)
    ends = utc_to_tt2000(np.asarray(table.end_utc), lsk)
    t = np.asarray(event_tt2000, dtype=np.int64)
    k = np.searchsorted(starts, t, side="right") - 1  # intervals sorted and disjoint
    inside = (k >= 0) & (t < ends[np.maximum(k, 0)])
    out = np.zeros((t.size, 3))
    out[inside] = np.asarray(table.jumps[sensor], dtype=float)[k[inside]]
    return out


def _polynomial(coefficients: np.ndarray, t: np.ndarray) -> np.ndarray:
    powers = np.asarray(t, dtype=float)[:, None] ** np.arange(coefficients.shape[0])[None, :]
    return powers @ coefficients


def extended_offset(
    stamps_tt2000: np.ndarray, temperature_c: np.ndarray,
    models: Mapping[np.datetime64, DailyOffsetModel], lsk=None,
    *, stitch_gap_s: float = STITCH_GAP_S,
) -> np.ndarray:
    """Extended-temperature-model offset (nT, URF) of each vector, shape (n, 3).

    Day ``d`` (UTC day of the time stamp) has ``P_d(T) + s_d``: in a campaign that runs
    across midnight (gap <= ``stitch_gap_s``), ``s_d`` is chosen so the first vector of
    day ``d`` carries the offset stored at the end of day ``d-1`` (sec. 4.2.3.3: "the data
    of the following day will be shifted in that way that a possible midnight jump
    disappears"); otherwise ``s_d = 0``.  Days without a model have no extended offset.
    """
    t = np.asarray(stamps_tt2000, dtype=np.int64)
    temp = np.asarray(temperature_c, dtype=float)
    out = np.zeros((t.size, 3))
    if t.size == 0 or not models:
        return out
    first = np.datetime64(_utc_day(t[0], lsk), "D")
    last = np.datetime64(_utc_day(t[-1], lsk), "D")
    days = np.arange(first, last + np.timedelta64(2, "D"), dtype="M8[D]")
    edges = utc_to_tt2000(np.array([f"{d}T00:00:00" for d in days]), lsk)
    end_offset, end_time = None, None
    for k, day in enumerate(days[:-1]):  # a loop over days
        sel = np.flatnonzero((t >= edges[k]) & (t < edges[k + 1]))
        model = models.get(day)
        if sel.size == 0:
            continue
        if model is None:
            end_offset = None
            continue
        p = _polynomial(np.asarray(model.coefficients, dtype=float), temp[sel])
        shift = np.zeros(3)
        if end_offset is not None and (t[sel[0]] - end_time) / NS <= stitch_gap_s:
            shift = end_offset - p[0]
        out[sel] = p + shift
        end_offset, end_time = out[sel[-1]].copy(), t[sel[-1]]
    return out


def _utc_day(tt2000: int, lsk) -> str:
    return str(tt2000_to_utc(np.array([tt2000]), lsk=lsk)[0])[:10]
