"""Local telemetry defects of a MESSENGER day: processed, flagged and reported, not fatal.

A defect in one stream used to refuse the whole day (exit 2, no products).  The readers
(`fluxcal.missions.messenger.readers` for the CSV streams, `fluxcal.missions.messenger.edr`
for the archived EDRs) now record what they find (``attrs["stream_gaps"]`` of the heater
and temperature datasets, ``attrs["clock_jumps"]`` of every stream) and `flag_defects`
processes the day with the best model the data allow and marks the science samples whose
correction the defect leaves uncertain in ``defect_flag``, one bit per cause:

========================  =====  =======  ================================================
cause                     value  action   span (science samples, ET)
========================  =====  =======  ================================================
``heater_gap``            1      flagged  last heater record before the gap .. first after
                                          it plus `heater_settle_s` (an unseen duty-cycle
                                          change relaxes with tau: eq. 6f)
``temperature_gap``       2      flagged  last temperature record before .. first after
``temperature_glitch``    4      flagged  the records either side of a dropped glitch
``science_gap``           8      missing  the two samples bounding a science gap (more than
                                          `GAP_SPACINGS` sample spacings); the missing
                                          samples are counted
``rate_change_at_gap``    16     flagged  first sample after a science gap whose two sides
                                          have different rate settings .. plus the larger
                                          net lag of the two (Table 1: the filter's lag)
``range_change_at_gap``   32     flagged  the same for a range-flag change at a gap
``clock_jump``            64     dropped  records whose MET breaks the clock's order (off
                                          the longest time-ordered run of the stream) are
                                          dropped and counted; the kept records around them
                                          bound the flagged span
========================  =====  =======  ================================================

A temperature glitch (one record off the line through its neighbours;
`drop_temperature_glitches`) could trip the sec. 13 smoothness check and refuse the day;
the record is dropped before the offsets are computed, the interpolation bridges it, and
its span is flagged.  Each sample keeps its own rate setting and range flag, so across a
rate or range change the lag (Table 1) and eq. 8 are each sample's own: the flag marks
the filter's settling, which the seed does not describe.

A stream is refused (`fluxcal.errors.InputFormatError`) only when nothing in it can be
trusted: when fewer than half its records lie on one time-ordered run
(`MIN_ORDERED_FRACTION`; the clock itself is then in doubt), with a message saying so.

``defect_flag`` is 0 elsewhere; Table 5's ``quality`` is unchanged.  The dataset's
``defect_spans`` attribute lists each span (cause, UTC start and end, seconds, samples)
for the day's report; ``defect_records`` holds the same as JSON (`span_records`), which
`fluxcal.missions.messenger.run.run_products` splits by day.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1 (rates, lags), sec. 6 (LAC
   heater bit), sec. 7 (temperature interpolation, eq. 6f relaxation), sec. 9 (MET),
   sec. 12 (quality flags), sec. 13 (gap rule of the smoothness check).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Sequence

import numpy as np
import scipy.ndimage
import xarray as xr
from numba import njit

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import et_to_utc

log = logging.getLogger(__name__)

#: Bit of ``defect_flag`` per cause (docs/formats/messenger.md, "Defect flag").
DEFECT_FLAGS = {"heater_gap": 1, "temperature_gap": 2, "temperature_glitch": 4,
                "science_gap": 8, "rate_change_at_gap": 16, "range_change_at_gap": 32,
                "clock_jump": 64}
#: What happens to the samples of each cause's span.
DEFECT_ACTIONS = {"heater_gap": "flagged", "temperature_gap": "flagged",
                  "temperature_glitch": "flagged", "science_gap": "missing",
                  "rate_change_at_gap": "flagged", "range_change_at_gap": "flagged",
                  "clock_jump": "dropped"}
#: ``flag_meanings`` of the products' ``defect_flag`` (bit order).
FLAG_MEANINGS = " ".join(DEFECT_FLAGS)
#: A temperature record further than this (degC) from the lines through its two neighbours
#: on each side, on the same side of both, is a glitch (`drop_temperature_glitches`).
#: Table 2's steepest slope (6.62 counts/degC) makes 0.3 degC the smallest jump that trips
#: sec. 13's 2-count check; 0.5 degC leaves room for a record's quantisation and for real
#: curvature (the sensor's fastest changes, e.g. the 55-C excursions, bend by far less
#: between 10-s records).
GLITCH_DEGC = 0.5
#: A science step longer than this many nominal sample spacings (of the slower side) is
#: a gap: the gap rule of the sec. 13 check (`levels.validation.GAP_SPACINGS`).
GAP_SPACINGS = 2.5
#: A stream with fewer of its records on one time-ordered run is refused.
MIN_ORDERED_FRACTION = 0.5


@njit(cache=True, nogil=True)
def _ordered_run_kernel(partition, met, strict, keep):  # pragma: no cover - compiled
    """Mark the longest run of records in (partition, MET) order in ``keep``.

    Non-decreasing MET, or increasing with ``strict`` (a record at the MET of one before
    it is then a repeat).
    Patience sorting with back links, O(n log n); of equally long runs the one whose
    records come first is not preferred in any documented way (ties are rare: a block
    sent twice).
    """
    n = met.size
    tail = np.empty(n, dtype=np.int64)
    back = np.full(n, -1, dtype=np.int64)
    length = 0
    for i in range(n):
        lo = 0
        hi = length
        while lo < hi:
            mid = (lo + hi) // 2
            j = tail[mid]
            if partition[j] < partition[i] or (partition[j] == partition[i] and (
                    met[j] < met[i] or (not strict and met[j] == met[i]))):
                lo = mid + 1
            else:
                hi = mid
        if lo > 0:
            back[i] = tail[lo - 1]
        tail[lo] = i
        if lo == length:
            length += 1
    k = tail[length - 1] if length else -1
    while k >= 0:
        keep[k] = True
        k = back[k]
    return length


def ordered_records(partition: np.ndarray, met: np.ndarray, *, strict: bool = False
                    ) -> np.ndarray:
    """Return the mask of the longest run of records in clock order (partition, then MET).

    All True when the stream never goes back (one vectorised check; the compiled search
    runs only otherwise).  ``strict``: in that search a record at an MET already kept is
    a repeat (dropped); consecutive equal MET without a step back are kept as they are.
    """
    p = np.ascontiguousarray(partition, dtype=np.float64)
    m = np.ascontiguousarray(met, dtype=np.float64)
    if p.size < 2:
        return np.ones(p.size, dtype=bool)
    dp = np.diff(p)
    if not np.any((dp < 0) | ((dp == 0) & (np.diff(m) < 0))):
        return np.ones(p.size, dtype=bool)
    keep = np.zeros(p.size, dtype=bool)
    _ordered_run_kernel(p, m, strict, keep)
    return keep


def clock_jumps(partition: np.ndarray, met: np.ndarray, keep: np.ndarray, *, stream: str,
                where: str | None = None) -> list[list[float]]:
    """Return the runs `ordered_records` dropped: ``[[partition, met_before, met_after, n]]``.

    ``met_before``/``met_after`` are the kept records around the run (the first or last
    kept record at a stream end).  Raises when fewer than `MIN_ORDERED_FRACTION` of the
    records are kept (the clock cannot be trusted; ``where`` names the file).
    """
    n = keep.size
    dropped = int(n - keep.sum())
    if not dropped:
        return []
    if keep.sum() < MIN_ORDERED_FRACTION * n:
        raise InputFormatError(
            f"{stream}: only {int(keep.sum())} of {n} records lie on one time-ordered run "
            f"of MET (fewer than {MIN_ORDERED_FRACTION:.0%}): the clock cannot be trusted, "
            "nothing of the stream is used", path=where, field="met")
    bad = ~keep
    edges = np.diff(np.r_[0, bad.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # [start, end)
    kept = np.flatnonzero(keep)
    out = []
    for a, b in zip(starts, ends, strict=True):  # a loop over the few runs of a stream
        before = kept[np.searchsorted(kept, a) - 1] if a > kept[0] else kept[0]
        after = kept[np.searchsorted(kept, b)] if b <= kept[-1] else kept[-1]
        out.append([float(partition[before]), float(met[before]), float(met[after]),
                    float(b - a)])
    log.warning("%s: %d record(s) off the time-ordered run of MET dropped (%d run(s))",
                stream, dropped, len(out))
    return out


def _line_departure(t: np.ndarray, met: np.ndarray, part: np.ndarray,
                    side: int) -> np.ndarray:
    """Signed departure of each record from the line through its two neighbours on one side.

    ``side = -1``: the line through records ``i - 2`` and ``i - 1``, extrapolated to
    ``i``; ``side = +1``: through ``i + 1`` and ``i + 2``.  NaN where that side has fewer
    than two records of the same partition.
    """
    n = t.size
    out = np.full(n, np.nan)
    if n < 3:
        return out
    i = np.arange(2, n) if side < 0 else np.arange(0, n - 2)
    a, b = (i - 2, i - 1) if side < 0 else (i + 2, i + 1)  # far, near
    ok = (part[a] == part[i]) & (part[b] == part[i]) & (met[b] != met[a])
    slope = (t[b] - t[a]) / np.where(ok, met[b] - met[a], 1.0)
    out[i] = np.where(ok, t[i] - (t[b] + slope * (met[i] - met[b])), np.nan)
    return out


def drop_temperature_glitches(
    temperature: xr.Dataset, threshold_degc: float = GLITCH_DEGC
) -> xr.Dataset:
    """Drop isolated glitch records of the temperature stream; record them for the flags.

    A glitch is a spike: one record off a curve its neighbours follow.  Record ``i`` is a
    glitch when it lies more than ``threshold_degc`` from the line through its two
    neighbours on the left (records ``i - 2``, ``i - 1`` of its partition) extrapolated
    to it *and* from the line through its two neighbours on the right, on the same side
    of both (at the first and last records but one, where a side lacks two records, the
    chord through ``i - 1`` and ``i + 1`` stands in for it).  A spike of ``d`` is ``d``
    off both lines; its neighbours are not (each lies on the line of its far side).

    A spike also bends the one-sided lines of the records two away from it, so of the
    records found within two records of each other only the one with the largest score
    (the smaller of its distances from the two lines plus its distance from the chord) is
    a glitch.

    A kink -- a real turning point of the temperature, e.g. the apex of a heater-off warm
    excursion, where the slope changes at a record -- lies *on* both one-sided lines (the
    neighbours lie on their straight lines, which meet at the record), however far it is
    from the chord, so it is kept: dropping it and interpolating the temperature left up
    to 0.39 nT in the fine-range field (issue 31; docs/decisions/messenger.md).  A spike
    on a kink is still found (both lines meet at the kink).  Smooth curvature ``a`` puts
    a record ``2 a h^2`` off the lines (``h`` the record spacing): 0.02 C for the
    sensor's 55-C excursions at 10-s records.  The linear interpolation of sec. 7 then
    bridges a glitch.  The dropped records are listed in
    ``attrs["temperature_glitches"]`` as ``[partition, met_before, met_after, met, T]``.

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
    score = _spike_score(t, met, part, threshold_degc)
    # a spike bends the lines of the records two away from it: of the spikes within two
    # records of each other only the largest score is one (ties: the earlier record)
    ranked = score - 1e-9 * np.arange(score.size) / max(score.size, 1)
    best = scipy.ndimage.maximum_filter1d(ranked, 5, mode="constant", cval=-np.inf)
    keep = ~((score > 0) & (ranked >= best))
    bad = np.flatnonzero(~keep)
    kept = np.flatnonzero(keep)
    pos = np.searchsorted(kept, bad)
    glitches = [[float(part[i]), float(met[kept[k - 1]]), float(met[kept[k]]), float(met[i]),
                 float(t[i])] for i, k in zip(bad, pos, strict=True)]
    return temperature.isel(temperature_time=keep).assign_attrs(temperature_glitches=glitches)


def _spike_score(t: np.ndarray, met: np.ndarray, part: np.ndarray,
                 threshold_degc: float) -> np.ndarray:
    """Score of each record as a spike (`drop_temperature_glitches`); 0 where it is none.

    A spike lies more than ``threshold_degc`` off both one-sided lines, on the same side;
    its score is the smaller of those two distances plus its distance from the chord (a
    record two away from a spike, or beside a kink, has one line bent and the chord
    nearly through it).
    """
    n = t.size
    same = (part[1:-1] == part[:-2]) & (part[1:-1] == part[2:])
    # signed distance from the chord through the two neighbours (time-weighted: records
    # need not be evenly spaced): stands in for a side without two records
    w = (met[1:-1] - met[:-2]) / np.maximum(met[2:] - met[:-2], 1e-9)
    chord = np.full(n, np.nan)
    chord[1:-1] = np.where(same, t[1:-1] - ((1 - w) * t[:-2] + w * t[2:]), np.nan)
    left, right = (_line_departure(t, met, part, side) for side in (-1, 1))
    left, right = np.where(np.isnan(left), chord, left), np.where(np.isnan(right), chord, right)
    with np.errstate(invalid="ignore"):  # NaN: a side without records, never a glitch
        spike = ((np.abs(left) > threshold_degc) & (np.abs(right) > threshold_degc)
                 & (np.sign(left) == np.sign(right)))
    return np.where(spike, np.minimum(np.abs(left), np.abs(right))
                    + np.abs(np.nan_to_num(chord)), 0.0)


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


def science_gaps(ds: xr.Dataset, cal) -> list[dict]:
    """Science gaps and rate or range changes at them, from the recorded sample times.

    A step of the recorded time (``et_recorded``) longer than `GAP_SPACINGS` nominal
    spacings (Table 1) of the slower of its two samples is a gap.  Returns one entry per
    cause: ``{"cause", "i", "a", "b", "missing"}`` with ``i`` the first sample after the
    gap, ``a``/``b`` the ET span to flag (recorded time) and ``missing`` the samples the
    gap lacks at the slower rate (a lower bound when the rate changed in it).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 13.
    """
    t = np.asarray(ds["et_recorded"].values if "et_recorded" in ds else ds["et"].values,
                   dtype=float)
    if t.size < 2:
        return []
    rate = np.asarray(ds["rate"].values, dtype=np.int64)
    spacing = 1.0 / np.asarray(cal.sample_rate_hz, dtype=float)[rate]
    slower = np.maximum(spacing[1:], spacing[:-1])
    dt = np.diff(t)
    idx = np.flatnonzero(dt > GAP_SPACINGS * slower) + 1
    out: list[dict] = []
    lag = np.asarray(cal.net_lag_s, dtype=float)
    rng = np.asarray(ds["range"].values) if "range" in ds else None
    for i in idx:  # a loop over the gaps of a day
        missing = max(int(round(dt[i - 1] / slower[i - 1])) - 1, 1)
        out.append({"cause": "science_gap", "i": int(i), "a": float(t[i - 1]),
                    "b": float(t[i]), "missing": missing})
        settle = float(max(lag[rate[i - 1]], lag[rate[i]]))
        if rate[i] != rate[i - 1]:
            out.append({"cause": "rate_change_at_gap", "i": int(i), "a": float(t[i]),
                        "b": float(t[i]) + settle, "missing": 0})
        if rng is not None and rng[i] != rng[i - 1]:
            out.append({"cause": "range_change_at_gap", "i": int(i), "a": float(t[i]),
                        "b": float(t[i]) + settle, "missing": 0})
    return out


def _span(cause: str, a: float, b: float, samples: int, stream: str) -> dict:
    """One span record (JSON-ready)."""
    utc = et_to_utc(np.array([a, b]), digits=0)
    return {"cause": cause, "flag": DEFECT_FLAGS[cause], "action": DEFECT_ACTIONS[cause],
            "stream": stream, "start": str(utc[0]), "end": str(utc[1]),
            "start_et": float(a), "end_et": float(b), "seconds": round(float(b - a), 3),
            "samples": int(samples)}


def span_text(span: dict) -> str:
    """One line: ``cause (flag N): start .. end, S s, N samples <action>``."""
    where = "" if span["stream"] in ("science", _STREAM_OF.get(span["cause"])) \
        else f", {span['stream']} stream"
    return (f"{span['cause']} (flag {span['flag']}{where}): {span['start']} .. "
            f"{span['end']}, {span['seconds']:.0f} s, {span['samples']} samples "
            f"{span['action']}")


_STREAM_OF = {"heater_gap": "heater", "temperature_gap": "temperature",
              "temperature_glitch": "temperature"}


def span_records(ds: xr.Dataset) -> list[dict]:
    """Return the span records of a calibrated dataset (its ``defect_records``), or []."""
    return json.loads(ds.attrs.get("defect_records", "[]"))


def day_spans(spans: Sequence[dict], et: np.ndarray) -> list[dict]:
    """Return the spans that touch the ET interval of ``et`` (a product day)."""
    if not len(spans) or np.size(et) == 0:
        return []
    lo, hi = float(np.min(et)), float(np.max(et))
    return [s for s in spans if s["end_et"] >= lo and s["start_et"] <= hi]


def set_span_attrs(ds: xr.Dataset, spans: Sequence[dict]) -> xr.Dataset:
    """Put ``defect_spans`` (text) and ``defect_records`` (JSON) on ``ds``; none: remove them."""
    drop = ("defect_spans", "defect_records", "clock_jumps")  # the reader's list: used
    attrs = {k: v for k, v in ds.attrs.items() if k not in drop}
    if spans:  # a day without defects keeps its attributes as they were
        attrs["defect_spans"] = "; ".join(span_text(s) for s in spans)
        attrs["defect_records"] = json.dumps(list(spans), separators=(",", ":"))
    out = ds.copy(deep=False)
    out.attrs = attrs
    return out


def flag_defects(
    ds: xr.Dataset, heater: xr.Dataset, temperature: xr.Dataset, cal, sclk
) -> xr.Dataset:
    """Add ``defect_flag``, ``defect_spans`` and ``defect_records`` for every defect found.

    Parameters
    ----------
    ds : xarray.Dataset
        Calibrated science (``et``, ``et_recorded``, ``rate``, ``range`` on ``time``;
        ``attrs["clock_jumps"]`` from the reader).
    heater, temperature : xarray.Dataset
        The streams as read (`read_heater`, `read_temperature`, `read_edr`), with
        ``stream_gaps`` and ``clock_jumps``; the temperature after
        `drop_temperature_glitches`.
    cal : MessengerCalibration
    sclk : SclkKernel
        MET -> ET of the recorded ends.

    Returns
    -------
    xarray.Dataset
        ``ds`` with ``defect_flag`` (uint8, bits of `DEFECT_FLAGS`) and the attributes
        (absent when there is no span).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-7, 12, 13.
    """
    et = np.asarray(ds["et"].values, dtype=float)
    rec = np.asarray(ds["et_recorded"].values if "et_recorded" in ds else et, dtype=float)
    flag = np.zeros(et.size, dtype=np.uint8)
    spans: list[dict] = []
    glitches = np.asarray(temperature.attrs.get("temperature_glitches", []), dtype=float)
    # (cause, stream, [[partition, met_a, met_b(, n)]], extra seconds, samples counted)
    sources = [
        ("heater_gap", "heater", heater.attrs.get("stream_gaps", []), heater_settle_s(cal)),
        ("temperature_gap", "temperature", temperature.attrs.get("stream_gaps", []), 0.0),
        ("temperature_glitch", "temperature", glitches.reshape(-1, 5)[:, :3], 0.0),
        ("clock_jump", "science", ds.attrs.get("clock_jumps", []), 0.0),
        ("clock_jump", "heater", heater.attrs.get("clock_jumps", []), 0.0),
        ("clock_jump", "temperature", temperature.attrs.get("clock_jumps", []), 0.0),
    ]
    for cause, stream, rows, extra in sources:
        rows = np.asarray(rows, dtype=float)
        if not rows.size:
            continue
        rows = rows.reshape(rows.shape[0], -1)
        part = rows[:, 0].astype(np.int64)
        t0 = sclk.to_et(part, rows[:, 1])
        t1 = sclk.to_et(part, rows[:, 2]) + extra
        for k, (a, b) in enumerate(zip(t0, t1, strict=True)):  # the few spans of a day
            inside = (rec >= a) & (rec <= b) if stream == "science" else (et >= a) & (et <= b)
            flag[inside] |= DEFECT_FLAGS[cause]
            n = int(rows[k, 3]) if cause == "clock_jump" else int(inside.sum())
            spans.append(_span(cause, a, b, n, stream))
    # a hole the dropped records leave is their clock_jump span, not a second science_gap
    dropped = [(s["start_et"], s["end_et"]) for s in spans
               if s["cause"] == "clock_jump" and s["stream"] == "science"]
    for gap in science_gaps(ds, cal):
        cause = gap["cause"]
        if cause == "science_gap" and any(
                abs(a - gap["a"]) < 1e-3 and abs(b - gap["b"]) < 1e-3 for a, b in dropped):
            continue
        if cause == "science_gap":
            flag[gap["i"] - 1:gap["i"] + 1] |= DEFECT_FLAGS[cause]
            spans.append(_span(cause, gap["a"], gap["b"], gap["missing"], "science"))
        else:
            inside = (rec >= gap["a"]) & (rec <= gap["b"])
            flag[inside] |= DEFECT_FLAGS[cause]
            spans.append(_span(cause, gap["a"], gap["b"], int(inside.sum()), "science"))
    spans.sort(key=lambda s: (s["start_et"], s["flag"]))
    for s in spans:
        log.warning("%s", span_text(s))
    out = ds.assign(defect_flag=(
        "time", flag,
        {"units": "1", "description": "local telemetry defects, bits: "
         + ", ".join(f"{v} {k}" for k, v in DEFECT_FLAGS.items())},
    ))
    return set_span_attrs(out, spans)


#: The name the pipeline called before the science defects were added (issue 23).
flag_stream_gaps = flag_defects
