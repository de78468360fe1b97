"""Local telemetry defects of a MESSENGER day: processed, flagged and reported, not fatal.

A gap in the LAC (heater) stream longer than a heater period or in the temperature
stream longer than the interpolation limit used to refuse the whole day.  The readers
now record such gaps (``attrs["stream_gaps"]`` of the heater and temperature datasets,
`fluxcal.missions.messenger.readers`); `flag_stream_gaps` processes the day with the
best model the data allow (the heater periods found around the gap, the temperature
interpolated across it) and marks the science samples whose correction the gap leaves
uncertain in ``defect_flag``, one bit per cause:

========================  =====  ===========================================================
cause                     value  span flagged (science samples, ET)
========================  =====  ===========================================================
``heater_gap``            1      last heater record before the gap .. first after it plus
                                 `heater_settle_s` (an unseen duty-cycle change relaxes
                                 with tau: eq. 6f)
``temperature_gap``       2      last temperature record before the gap .. first after it
``temperature_glitch``    4      the records either side of a dropped glitch record
========================  =====  ===========================================================

A temperature glitch (one record off the line through its neighbours;
`drop_temperature_glitches`) could trip the sec. 13 smoothness check and refuse the day;
the record is dropped before the offsets are computed, the interpolation bridges it, and
its span is flagged.

``defect_flag`` is 0 elsewhere; Table 5's ``quality`` is unchanged.  The dataset's
``defect_spans`` attribute lists each span (cause, UTC start and end, seconds, samples)
for the day's report.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (LAC heater bit), sec. 7
   (temperature interpolation, eq. 6f relaxation), sec. 12 (quality flags).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import xarray as xr

log = logging.getLogger(__name__)

#: Bit of ``defect_flag`` per cause (docs/formats/messenger.md, "Defect flag").
DEFECT_FLAGS = {"heater_gap": 1, "temperature_gap": 2, "temperature_glitch": 4}
#: A temperature record further than this (degC) from the line through its two
#: neighbours (and further than they are from theirs) is a glitch.  Table 2's steepest slope (6.62
#: counts/degC) makes 0.3 degC the smallest jump that trips sec. 13's 2-count check; 0.5
#: degC leaves room for a record's quantisation and for real curvature (the sensor's
#: fastest changes, e.g. the 55-C excursions, bend by far less between 10-s records).
GLITCH_DEGC = 0.5


def drop_temperature_glitches(
    temperature: xr.Dataset, threshold_degc: float = GLITCH_DEGC
) -> xr.Dataset:
    """Drop isolated glitch records of the temperature stream; record them for the flags.

    A record ``i`` (with records ``i - 1`` and ``i + 1`` of the same partition) is a
    glitch when it lies more than ``threshold_degc`` from the line through its two
    neighbours and further than either neighbour from theirs (a glitch of ``d`` leaves
    ``d / 2`` at each neighbour).  The linear interpolation of sec. 7 then bridges it.
    The dropped records are listed in ``attrs["temperature_glitches"]`` as
    ``[partition, met_before, met_after, met, T]``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (temperature interpolated to
       the samples), sec. 13 (offset smoothness).
    """
    t = np.asarray(temperature["temperature_c"].values, dtype=float)
    met = np.asarray(temperature["met"].values, dtype=float)
    part = np.asarray(temperature["partition"].values)
    if t.size < 3:
        return temperature.assign_attrs(temperature_glitches=[])
    same = (part[1:-1] == part[:-2]) & (part[1:-1] == part[2:])
    # distance from the line through the two neighbours (time-weighted: records need not
    # be evenly spaced); a glitch of d puts d there and d/2 at each neighbour
    w = (met[1:-1] - met[:-2]) / np.maximum(met[2:] - met[:-2], 1e-9)
    off = np.where(same, np.abs(t[1:-1] - ((1 - w) * t[:-2] + w * t[2:])), 0.0)
    padded = np.r_[0.0, off, 0.0]
    peak = (off >= padded[:-2]) & (off >= padded[2:])
    bad = np.flatnonzero(peak & (off > threshold_degc)) + 1
    glitches = [[float(part[i]), float(met[i - 1]), float(met[i + 1]), float(met[i]),
                 float(t[i])] for i in bad]
    keep = np.ones(t.size, dtype=bool)
    keep[bad] = False
    return temperature.isel(temperature_time=keep).assign_attrs(temperature_glitches=glitches)


def heater_settle_s(cal) -> float:
    """Seconds after a heater-stream gap until an unseen duty-cycle change is below 1 count.

    The largest duty-cycle offset is ``max(D0) * 400 ppt`` (40 %, the top duty-cycle bin,
    Table 3); it relaxes as ``exp(-t / tau)`` (eq. 6f), so after ``tau ln(max offset /
    1 count)`` it is under the telemetry's fine-count resolution (the same limit as
    ``[quality] min_duty_offset_counts``): 872 s * ln(131) = 4252 s with Table 3.
    """
    tau = float(cal.constants["relaxation"]["tau_s"])
    limit = float(cal.constants["quality"]["min_duty_offset_counts"])
    largest = float(np.max(np.abs(cal.duty_cycle_d0))) * 400.0
    return tau * math.log(max(largest / limit, 1.0))


def flag_stream_gaps(
    ds: xr.Dataset, heater: xr.Dataset, temperature: xr.Dataset, cal, sclk
) -> xr.Dataset:
    """Add ``defect_flag`` and ``defect_spans`` for the gaps the readers recorded.

    Parameters
    ----------
    ds : xarray.Dataset
        Calibrated science (``et`` on ``time``).
    heater, temperature : xarray.Dataset
        The streams as read (`read_heater`, `read_temperature`), with ``stream_gaps``.
    cal : MessengerCalibration
    sclk : SclkKernel
        MET -> ET of the gap ends.

    Returns
    -------
    xarray.Dataset
        ``ds`` with ``defect_flag`` (uint8, bits of `DEFECT_FLAGS`) and the attribute
        ``defect_spans`` (one string per span; absent when there is none).
    """
    from fluxcal.geometry.time import et_to_utc

    et = np.asarray(ds["et"].values, dtype=float)
    flag = np.zeros(et.size, dtype=np.uint8)
    spans: list[str] = []
    glitches = np.asarray(temperature.attrs.get("temperature_glitches", []), dtype=float)
    for cause, stream, extra, key in (
        ("heater_gap", heater, heater_settle_s(cal), "stream_gaps"),
        ("temperature_gap", temperature, 0.0, "stream_gaps"),
        ("temperature_glitch", temperature, 0.0, "temperature_glitches"),
    ):
        if key == "temperature_glitches":
            gaps = glitches.reshape(-1, 5)[:, :3]
        else:
            gaps = np.asarray(stream.attrs.get(key, []), dtype=float).reshape(-1, 3)
        if not gaps.size:
            continue
        part = gaps[:, 0].astype(np.int64)
        t0 = sclk.to_et(part, gaps[:, 1])
        t1 = sclk.to_et(part, gaps[:, 2]) + extra
        for a, b in zip(t0, t1, strict=True):  # a loop over the few gaps of a day
            inside = (et >= a) & (et <= b)
            flag[inside] |= DEFECT_FLAGS[cause]
            utc = et_to_utc(np.array([a, b]), digits=0)
            spans.append(f"{cause} (flag {DEFECT_FLAGS[cause]}): {utc[0]} .. {utc[1]}, "
                         f"{b - a:.0f} s, {int(inside.sum())} samples")
            log.warning("%s", spans[-1])
    out = ds.assign(defect_flag=(
        "time", flag,
        {"units": "1", "description": "local telemetry defects, bits: "
         + ", ".join(f"{v} {k}" for k, v in DEFECT_FLAGS.items())},
    ))
    if spans:  # a day without defects keeps its products as they were (byte for byte)
        out.attrs["defect_spans"] = "; ".join(spans)
    return out
