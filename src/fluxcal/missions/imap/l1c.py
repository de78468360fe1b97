"""IMAP MAG L1C: normal-mode L1B with its gaps filled from burst-mode L1B, per sensor.

The normal-mode samples are kept as they are (flag ``NORMAL``).  Where consecutive normal
samples are further apart than the cadence allows (more than `GAP_TOLERANCE` over
``1 / rate``), timestamps are laid out at the normal cadence inside the gap; burst samples
around the gap are filtered down to the normal rate by the flight software's CIC filter
(two cascaded boxcars of length ``burst_rate / normal_rate``, delay-compensated) and
interpolated linearly to those timestamps (flag ``INTERPOLATED``).  Gap timestamps that no
full burst filter window covers keep NaN (flag ``MISSING``).  With a ``day``, the edges of
the day (to 30 minutes either side, as the team's window) are filled the same way where
burst data covers them; edge timestamps without burst are not laid out.

References
----------
IMAP MAG L1C algorithm as described by the IMAP Science Operations Center's public
``imap_processing`` package (``mag/l1c``: gap tolerance 7.5 %, CIC filter then linear
interpolation, the generated flag 0 / 1 / -1), and the team's validation cases
T013-T016 (``../shared/data/imap/team/L1c``).  See docs/decisions/imap.md (L1C entries).
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from scipy.signal import lfilter

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import utc_day_start_tt2000
from fluxcal.missions.imap.cadence import GAP_TOLERANCE, SEC, interval_rates, nominal_rate
from fluxcal.products.timeindex import default_lsk

#: The team's L1C window: the UTC day plus 30 minutes either side.
EDGE_NS = 30 * 60 * 1_000_000_000
NORMAL, INTERPOLATED, MISSING = 0, 1, -1


def find_gaps(epoch: np.ndarray, rates: np.ndarray | None = None) -> np.ndarray:
    """Gaps of a normal-mode timeline: rows ``(start, end, rate)`` (int64 ns, vectors/s).

    ``start`` and ``end`` are the normal samples on either side; an interval is a gap
    when it is longer than ``(1 + GAP_TOLERANCE) / rate`` (`interval_rates` unless
    ``rates`` is given per interval).
    """
    epoch = np.asarray(epoch, dtype=np.int64)
    rates = interval_rates(epoch) if rates is None else np.asarray(rates, dtype=np.int64)
    d = np.diff(epoch)
    i = np.flatnonzero(d > (1 + GAP_TOLERANCE) * SEC / np.maximum(rates, 1))
    return np.stack([epoch[i], epoch[i + 1], rates[i]], axis=1).astype(np.int64)


def gap_times(gap: np.ndarray) -> np.ndarray:
    """Timestamps laid out in a gap: ``start + k / rate`` for k >= 1, before ``end``.

    A timestamp closer to ``end`` than `GAP_TOLERANCE` of a period is not laid out: that
    close, ``end`` is the sample due there, late by clock drift.
    """
    start, end, rate = (int(v) for v in gap)
    period = SEC // rate
    times = np.arange(start, end, period, dtype=np.int64)[1:]
    return times[end - times > GAP_TOLERANCE * period]


def cic_filter(t: np.ndarray, b: np.ndarray, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """Filter ``b`` (n, 3) by two cascaded boxcars of length ``factor``, delay removed.

    Returns the times and values where the whole filter (``2 factor - 1`` samples,
    centred) lies on data: sample ``i`` of the result is the triangular-weighted mean of
    input samples ``i - factor + 1 .. i + factor - 1`` at time ``t[i]``.
    """
    box = np.full(factor, 1.0 / factor)
    kernel = np.convolve(box, box)
    delay = factor - 1
    if t.size < kernel.size:
        return t[:0], b[:0]
    y = lfilter(kernel, 1.0, b, axis=0)[kernel.size - 1:]
    return t[delay:t.size - delay], y


def interpolate_filtered(times: np.ndarray, tf: np.ndarray, bf: np.ndarray) -> np.ndarray:
    """Linear interpolation of filtered samples ``(tf, bf)`` to ``times`` (NaN outside)."""
    out = np.full((times.size, 3), np.nan)
    if tf.size < 2 or times.size == 0:
        return out
    lo = max(int(np.searchsorted(tf, times[0])) - 1, 0)
    hi = int(np.searchsorted(tf, times[-1], side="right")) + 1
    tf, bf = tf[lo:hi], bf[lo:hi]  # only the samples around these times
    if tf.size < 2:
        return out
    inside = (times >= tf[0]) & (times <= tf[-1])
    x = (tf - tf[0]).astype(np.float64)
    xq = (times[inside] - tf[0]).astype(np.float64)
    for k in range(3):
        out[inside, k] = np.interp(xq, x, bf[:, k])
    return out


def _burst_rate(burst: xr.Dataset) -> int:
    """Burst vector rate: declared per sample, else the nominal rate of the median spacing."""
    if "vectors_per_second" in burst:
        return int(np.median(burst["vectors_per_second"].values))
    d = np.diff(burst["epoch"].values.astype(np.int64))
    return int(nominal_rate(np.array([np.median(d)]))[0]) if d.size else 0


def _segments(burst_t: np.ndarray) -> list[slice]:
    """Contiguous stretches of burst data (split where the spacing jumps)."""
    d = np.diff(burst_t)
    if d.size == 0:
        return [slice(0, burst_t.size)]
    cut = np.flatnonzero(d > (1 + GAP_TOLERANCE) * np.median(d)) + 1
    edges = np.r_[0, cut, burst_t.size]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def merge(norm: xr.Dataset, burst: xr.Dataset | None = None,
          day: np.datetime64 | str | None = None) -> xr.Dataset:
    """L1C of one sensor: the normal-mode L1B with its gaps filled from burst (see module).

    Parameters
    ----------
    norm, burst : xarray.Dataset
        L1B datasets of one sensor (``epoch`` int64 TT2000 along ``time``, ``b`` in nT,
        ``range``, ``compression``, ``compression_width``); ``burst`` may be None
        (then every gap timestamp is ``MISSING``).
    day : datetime64 or str, optional
        UTC day of the product: the day's edges (+-30 min) are filled where burst covers.

    Returns
    -------
    xarray.Dataset
        ``b``, ``range``, ``compression``, ``compression_width`` and ``generated``
        (0 normal, 1 interpolated from burst, -1 missing), sorted by ``epoch``.

    Raises
    ------
    InputFormatError
        The two inputs are of different sensors, or burst is not faster than normal.
    """
    sensor = norm.attrs.get("sensor")
    if burst is not None and burst.attrs.get("sensor") not in (None, sensor):
        raise InputFormatError(f"normal mode is {sensor}, burst is {burst.attrs['sensor']}: "
                               "L1C merges one sensor's two modes", field="--input")
    t = norm["epoch"].values.astype(np.int64)
    rates = interval_rates(t)
    gaps = find_gaps(t, rates)
    if day is not None and t.size:
        lo = utc_day_start_tt2000(np.datetime64(day, "D"), default_lsk()) - EDGE_NS
        hi = utc_day_start_tt2000(np.datetime64(day, "D") + 1, default_lsk()) + EDGE_NS
        first = rates[0] if rates.size else 2
        last = rates[-1] if rates.size else 2
        # edge gaps, as the team lays them: from the window's start (lo, lo + 1/rate, ...)
        # up to the first sample; after the last sample, continuing its cadence
        pre = np.array([[lo - SEC // first, t[0], first]], dtype=np.int64) if t[0] > lo \
            else np.zeros((0, 3), int)
        post = np.array([[t[-1], hi, last]], dtype=np.int64) if t[-1] < hi else \
            np.zeros((0, 3), int)
        edges = np.concatenate([pre, post]).astype(np.int64)
    else:
        edges = np.zeros((0, 3), dtype=np.int64)
    new_t, new_b, new_rng, new_cmp = [], [], [], []
    burst_t = burst["epoch"].values.astype(np.int64) if burst is not None else None
    has_burst = burst is not None and burst_t.size > 0
    brate = _burst_rate(burst) if has_burst else 0
    filtered: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}  # factor -> segments
    for gap, interior in [(g, True) for g in gaps] + [(g, False) for g in edges]:
        times = gap_times(gap)
        b = np.full((times.size, 3), np.nan)
        if has_burst:
            if brate <= int(gap[2]):
                raise InputFormatError(
                    f"burst mode has {brate} vectors/s, normal mode {int(gap[2])}: burst "
                    "must be faster to fill normal-mode gaps", field="--input")
            factor = brate // int(gap[2])
            if factor not in filtered:  # each burst stretch filtered once per rate ratio
                filtered[factor] = [cic_filter(burst_t[seg], burst["b"].values[seg], factor)
                                    for seg in _segments(burst_t)]
            for tf, bf in filtered[factor]:
                b = np.where(np.isnan(b), interpolate_filtered(times, tf, bf), b)
        keep = np.ones(times.size, bool) if interior else ~np.isnan(b[:, 0])
        times, b = times[keep], b[keep]
        new_t.append(times)
        new_b.append(b)
        if has_burst and times.size:  # range and compression of the nearest burst sample
            j = np.clip(np.searchsorted(burst_t, times), 1, burst_t.size - 1)
            j = np.where(times - burst_t[j - 1] < burst_t[j] - times, j - 1, j)
            new_rng.append(burst["range"].values[j])
            new_cmp.append(np.stack([burst["compression"].values[j],
                                     burst["compression_width"].values[j]], axis=1))
        else:
            new_rng.append(np.zeros(times.size, np.int64))
            new_cmp.append(np.zeros((times.size, 2), np.int64))
    gen_t = np.concatenate([np.zeros(0, np.int64), *new_t])
    gen_b = np.concatenate([np.zeros((0, 3)), *new_b])
    flag = np.where(np.isnan(gen_b[:, 0]), MISSING, INTERPOLATED).astype(np.int8)
    epoch = np.concatenate([t, gen_t])
    order = np.argsort(epoch, kind="stable")
    cmp = np.concatenate([np.stack([norm["compression"].values,
                                    norm["compression_width"].values], axis=1),
                          *new_cmp]).astype(np.int64) if new_cmp else \
        np.stack([norm["compression"].values, norm["compression_width"].values], axis=1)
    ds = xr.Dataset(
        {
            "b": (("time", "component"), np.concatenate([norm["b"].values, gen_b])[order],
                  dict(norm["b"].attrs)),
            "range": ("time", np.concatenate([norm["range"].values.astype(np.int64),
                                              *new_rng]).astype(np.int64)[order],
                      dict(norm["range"].attrs)),
            "compression": ("time", cmp[order, 0], dict(norm["compression"].attrs)),
            "compression_width": ("time", cmp[order, 1],
                                  dict(norm["compression_width"].attrs)),
            "generated": ("time", np.concatenate([np.zeros(t.size, np.int8), flag])[order],
                          {"units": "1", "flag_values": "0 1 -1",
                           "flag_meanings": "normal interpolated_from_burst missing",
                           "description": "Source of the row: normal-mode sample, burst "
                                          "filtered and interpolated, or missing"}),
        },
        coords={"epoch": ("time", epoch[order]), "component": norm["component"].values},
        attrs={**norm.attrs, "level": "l1c", "mode": "norm",
               "interpolation_method": "linear_filtered (CIC to the normal rate, linear)",
               "gaps": int(gaps.shape[0]),
               "rows_interpolated": int((flag == INTERPOLATED).sum()),
               "rows_missing": int((flag == MISSING).sum())},
    )
    return ds
