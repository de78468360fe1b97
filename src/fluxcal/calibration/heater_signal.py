"""Sensor-heater periods from the 1-s heater bit, and the heater signal they leave.

A heater period starts at each rising edge of the heater request bit (or, while the bit
stays on or an edge falls in a short gap, on the 100-s grid of the last edge) and lasts
one heater period (100 s) or until the next start.  Its duty cycle is the fraction of
its one-second bits that are on.  The periodic heater signal (tabulated versus seconds
since the edge for duty-cycle bins) is applied only when the bit stayed on for at least
the persistence time (10 s).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluxcal.calibration._compiled import heater_signal_kernel


@dataclass(frozen=True)
class HeaterPeriods:
    """Heater periods found in a heater-bit series.

    Attributes
    ----------
    start : ndarray, shape (k,)
        Time of each rising edge (s, same scale as the bit times).
    end : ndarray, shape (k,)
        End of each period: ``min(start + period, next start)``.
    duty_cycle : ndarray, shape (k,)
        Fraction (0..1) of the period's one-second bits that are on.
    on_duration : ndarray, shape (k,)
        Length (s) of the run of ones that begins at the edge.
    applied : ndarray of bool, shape (k,)
        ``on_duration >= min_on`` (heater signal subtracted for this period).
    complete : ndarray of bool, shape (k,), optional
        The whole on-phase was seen (``duty_cycle`` measured, not inherited or a lower
        bound); None: all complete.
    duty_bounds : ndarray, shape (k, 2), optional
        Least and largest duty cycle the seen bits allow (equal when complete).
    """

    start: np.ndarray
    end: np.ndarray
    duty_cycle: np.ndarray
    on_duration: np.ndarray
    applied: np.ndarray
    complete: np.ndarray | None = None
    duty_bounds: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.start.size)


def persistent_bits(
    times: np.ndarray, bits: np.ndarray, *, persistence: int = 10, bit_step: float = 1.0
) -> np.ndarray:
    """Return the heater request bits with the changes shorter than ``persistence`` removed.

    The spacecraft turns the heater on or off only after the request bit has held its new
    value for ``persistence`` consecutive counts (sec. 6), so a run of equal bits shorter
    than that (one 0 inside an on-phase, one 1 inside an off-phase) is no heater change:
    a run that persisted (``>= persistence`` records, or touching a gap or an end of the
    series, where its length is not known) is *decisive*; the short runs between two
    decisive runs of the same value take that value; between two of different values
    they hold the one transition, placed where it changes the fewest bits (the
    earliest such place on a tie).

    Parameters
    ----------
    times : ndarray, shape (n,)
        Increasing times (s) of the bits.
    bits : ndarray of {0, 1}, shape (n,)
        Heater request bit.
    persistence : int
        Counts a change must persist; ``<= 1`` returns ``bits`` unchanged.
    bit_step : float
        Time each bit stands for (s); a gap is a missing record (consecutive records more
        than 1.5 ``bit_step`` apart).

    Returns
    -------
    ndarray of int8, shape (n,)

    Notes
    -----
    Runs are counted in records, not seconds, so a clock running fast or slow does not
    change which runs persist.  A request shorter than the persistence (a duty cycle
    below 10 %) is no heater period: the spacecraft ignored it (sec. 6).  The controller
    sets the bit once per period; a short run is read as a telemetry bit error, so the
    fewest bits are changed (the edges of the clean request stay where they were).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 ("a 10-count persistence in a
       change of the heater state bit before turning the heater either on or off").

    Examples
    --------
    >>> t = np.arange(12.0)
    >>> persistent_bits(t, np.array([0] * 5 + [1] + [0] * 6), persistence=3).tolist()
    [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    """
    times = np.asarray(times, dtype=float)
    out = np.asarray(bits).astype(np.int8)
    if out.size == 0 or persistence <= 1:
        return out
    gap = np.diff(times) > 1.5 * bit_step  # a missing record (clock rates differ by ppm)
    start = np.r_[0, np.flatnonzero((np.diff(out) != 0) | gap) + 1]
    length = np.diff(np.r_[start, out.size])
    value = out[start]
    gap_before = np.r_[True, gap[start[1:] - 1]]
    gap_after = np.r_[gap_before[1:], True]
    decisive = (length >= persistence) | gap_before | gap_after
    if decisive.all():
        return out
    idx = np.arange(start.size)
    prev = np.maximum.accumulate(np.where(decisive, idx, -1))  # first run is decisive
    nxt = np.minimum.accumulate(np.where(decisive, idx, start.size)[::-1])[::-1]
    new = value.copy()
    short = ~decisive
    new[short] = value[nxt[short]]  # same value on both sides: a glitch, filled
    # a transition among short runs (different values either side, no gap: the runs
    # alternate): cut where the fewest bits change; few such places, a loop over them
    for p in np.unique(prev[short & (value[prev] != value[nxt])]):
        q = nxt[p + 1]
        lens, vals = length[p + 1:q], value[p + 1:q]
        a = value[p]
        before = np.r_[0, np.cumsum(np.where(vals != a, lens, 0))]  # flipped to a
        after = np.r_[np.cumsum(np.where(vals == a, lens, 0)[::-1])[::-1], 0]  # flipped to b
        cut = int(np.argmin(before + after))
        new[p + 1:p + 1 + cut] = a
        new[p + 1 + cut:q] = value[q]
    return np.repeat(new, length)


def _hidden_edges(
    times: np.ndarray, bits: np.ndarray, t_seen: np.ndarray, period: float, bit_step: float,
    tolerance: float, on_until: np.ndarray,
) -> np.ndarray:
    """Rising edges hidden in gaps of the bit series, on the 100-s grid of the last edge.

    A gap (consecutive records more than ``bit_step`` apart; the reader allows gaps up to
    one period) hides an edge when the grid point ``e + period`` of the last edge ``e``
    seen before the gap lies inside it and the heater was still cycling across it: the
    first bit after the gap is on, or the next seen edge is one period after the grid
    point.  Otherwise, when the first bit after the gap is on and a grid point ``n``
    periods before the next seen edge lies in the gap (the heater started in the gap;
    ``n > 1`` only when the bit stays on from the gap until a period before that edge,
    ``on_until`` per record: end of its run of ones), that grid point.  Returns the
    times of those grid points, unsorted (the V10 controller starts one heater period
    every 100 s, sec. 6, 7).
    """
    eps = 1e-6 * bit_step
    gap = np.flatnonzero(np.diff(times) > bit_step + eps) + 1  # index of the record after
    if gap.size == 0 or t_seen.size == 0:
        return np.empty(0)
    k = np.searchsorted(t_seen, times[gap - 1], side="right") - 1  # last edge before the gap
    has = k >= 0
    anchor = np.where(has, t_seen[np.maximum(k, 0)], np.nan)
    grid = anchor + period
    nxt = np.where(k + 1 < t_seen.size, t_seen[np.minimum(k + 1, t_seen.size - 1)], np.inf)
    inside = (grid > times[gap - 1] + eps) & (grid <= times[gap] + tolerance)
    cycling = (bits[gap] == 1) | (np.abs(nxt - grid - period) <= tolerance)
    # a grid point after the gap at a record whose bit is off is no edge (the heater was
    # on across the gap from the period before; a real edge there is seen on the bits)
    at = np.minimum(np.searchsorted(times, np.where(has, grid, -np.inf) - eps), times.size - 1)
    off_there = (grid > times[gap] + eps) & (np.abs(times[at] - grid) <= eps) & (bits[at] == 0)
    forward = has & inside & cycling & (nxt > grid + tolerance) & ~off_there
    # no such grid point (the heater was quiet before): the bit after the gap is on -> the
    # grid point n periods before the next start (n > 1 only if the bit stays on till then)
    finite = np.isfinite(nxt)
    n = np.where(finite, np.floor((np.where(finite, nxt, 0.0) - times[gap - 1] - eps)
                                  / period), 0.0)
    back = np.where(finite, nxt - n * period, np.nan)
    backward = (~forward & (bits[gap] == 1) & np.isfinite(nxt) & (n >= 1)
                & (back > times[gap - 1] + eps) & (back <= times[gap] + tolerance)
                & ((n == 1) | (on_until[gap] >= nxt - period - tolerance)))
    return np.concatenate([grid[forward], back[backward]])


def _hidden_restarts(
    times: np.ndarray, bits: np.ndarray, start: np.ndarray, period: float, bit_step: float,
    tolerance: float, evaluation_s: float,
) -> np.ndarray:
    """Restarts after a quiet spell whose whole first on-phase a gap hid (sec. 6, 7).

    The V10 controller changes the duty cycle only at its evaluations, every
    ``evaluation_s`` (10 periods), so the heater restarts after a quiet spell on that
    grid.  The grid's phase is that of a restart seen whole: a start preceded by a full
    period of records, all off.  A start ``E`` that follows a quiet spell but lies off
    the grid, while ``E - period`` lies on it and inside a gap, started one period late
    in the data: the restart was at ``E - period``, its on-phase in the gap.  Returns
    those grid points (the caller checks that the on-phase fits the gap).
    """
    eps = 1e-6 * bit_step
    if start.size == 0 or not evaluation_s > 0:
        return np.empty(0)
    csum = np.concatenate([[0], np.cumsum(bits, dtype=np.int64)])
    i0 = np.searchsorted(times, start - period - eps)
    i1 = np.searchsorted(times, start - eps)
    quiet = ((i1 - i0) >= np.round(period / bit_step) - 0.5) & (csum[i1] == csum[i0])
    if not quiet.any():
        return np.empty(0)
    anchor = start[np.flatnonzero(quiet)[0]]

    def off_grid(x: np.ndarray) -> np.ndarray:
        r = np.mod(x - anchor, evaluation_s)
        return np.minimum(r, evaluation_s - r)

    prev = np.r_[-np.inf, start[:-1]]
    grid = start - period
    j = np.clip(np.searchsorted(times, grid - eps), 1, max(times.size - 1, 1))
    missing = np.abs(times[np.minimum(j, times.size - 1)] - grid) > eps
    in_gap = missing & (times[j] - times[j - 1] > 1.5 * bit_step) & (times[j - 1] < grid)
    hidden = ((start - prev > 2 * period - tolerance) & (off_grid(start) > tolerance)
              & (off_grid(grid) <= tolerance) & in_gap)
    return grid[hidden]


def heater_periods(
    times: np.ndarray,
    bits: np.ndarray,
    *,
    period: float = 100.0,
    min_on: float = 10.0,
    bit_step: float = 1.0,
    tolerance: float = 1.5,
    persistence: int | None = None,
    evaluation_periods: int = 10,
) -> HeaterPeriods:
    """Find the heater periods of a heater-bit series (sec. 6).

    Parameters
    ----------
    times : ndarray, shape (n,)
        Increasing times (s) of the bits, nominally one per second.
    bits : ndarray of {0, 1}, shape (n,)
        Heater request bit.
    period : float
        Heater period (s).
    min_on : float
        Persistence (s) the bit must stay on for the signal to be applied.  The on-time
        is a whole number of bits measured in the time scale of ``times`` (ET): a clock
        running slow or fast by parts per million makes ten on-bits last 9.9999995 s, so
        the comparison allows half a ``bit_step`` (docs/decisions/messenger.md).
    bit_step : float
        Time each bit stands for (s); a bit at ``t`` covers ``[t, t + bit_step)``.
    tolerance : float
        Slack (s) when deciding that two periods are contiguous.
    persistence : int, optional
        Counts a change of the bit must persist before the heater follows it
        (`persistent_bits`); default ``round(min_on / bit_step)`` (10, sec. 6).  ``1``
        takes every bit change as it comes.
    evaluation_periods : int
        Heater periods per controller evaluation (10: 1000 s, sec. 7); the heater
        restarts after a quiet spell on that grid (`_hidden_restarts`; ``0`` disables).

    Returns
    -------
    HeaterPeriods

    Notes
    -----
    A rising edge is a 0 -> 1 step between *consecutive* bits (``bit_step`` apart).  A
    step across a gap is not an edge: the edge lies somewhere in the gap.  When the grid
    point one period after the last seen edge lies in the gap and the heater kept cycling
    (see `_hidden_edges`) the period starts there; with no grid point known, at the
    first on-bit after the gap (the change time is then late by less than the gap).

    The bits are first reduced to the changes that persisted ``persistence`` counts
    (`persistent_bits`): a single 0 inside an on-phase or a single 1 inside an off-phase
    makes no edge, and a request shorter than the persistence makes no period.

    A bit that stays on for longer than a period (duty cycle 100 %) has no rising edge
    after the first: the periods go on every ``period`` seconds while the bit is on.  A
    period with the bit on throughout (no off phase) gets no heater signal (``applied``
    False): the heater-cycle waveform of Tables 6-8 is the response to switching the
    heater on and off within the period, and there is none (docs/decisions/messenger.md).

    A series that starts with the bit on has no known rising edge there: that partial
    period is not a heater period.  The duty cycle counts the bits with times in
    ``[start, end)`` and divides by ``period / bit_step`` (100 bits).

    A period whose on-phase was not fully seen -- cut by the end of the series (a day's
    heater file ends wherever the day ends) or with missing bits (a gap shorter than a
    period) before an observed 1 -> 0 transition -- has only bounds on its duty cycle:
    the bits seen on, up to those plus the missing ones.  When it follows a contiguous
    period (edges at most ``period + tolerance`` apart) whose duty cycle lies within
    these bounds it keeps that duty cycle and on-time: the V10 controller changes the
    duty cycle only every ten periods, so a truncated on-phase must not read as a new
    duty cycle.  A period whose bit was seen going off with no missing bit before is
    complete (the controller switches on once per period, at its start).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7.
    """
    times = np.asarray(times, dtype=float)
    bits = np.asarray(bits).astype(np.int8)
    if times.shape != bits.shape or times.ndim != 1:
        raise ValueError("times, bits: must be 1-D arrays of equal length")
    if persistence is None:
        persistence = int(round(min_on / bit_step))
    bits = persistent_bits(times, bits, persistence=persistence, bit_step=bit_step)
    eps = 1e-6 * bit_step
    step = np.diff(bits)
    consecutive = np.diff(times) <= bit_step + eps
    seen = np.flatnonzero((step == 1) & consecutive) + 1
    falling = np.flatnonzero(step == -1) + 1
    # the run of ones from each edge ends at the next 1 -> 0 step (or after the series)
    t_fall = times[falling]
    end_of_data = times[-1] + bit_step if times.size else 0.0

    def fall_after(t: np.ndarray) -> np.ndarray:
        j = np.searchsorted(t_fall, t, side="right")
        return np.where(j < t_fall.size, t_fall[np.minimum(j, max(t_fall.size - 1, 0))]
                        if t_fall.size else end_of_data, end_of_data)

    # duty cycle 100 %: periods go on every `period` s while the bit is seen on (up to
    # the end of the last on-bit before the fall, not across a gap hiding the fall)
    last_on = np.concatenate([times[falling - 1] + bit_step, [end_of_data]])

    def continued(start: np.ndarray) -> np.ndarray:
        run = last_on[np.searchsorted(t_fall, start, side="right")] - start
        extra = np.maximum(np.ceil((run - eps) / period).astype(np.int64) - 1, 0)
        k = np.arange(extra.sum()) - np.repeat(np.cumsum(extra) - extra, extra) + 1
        return np.repeat(start, extra) + k * period

    def merged(*parts: np.ndarray) -> np.ndarray:
        out = np.unique(np.concatenate(parts))
        if out.size > 1:  # a hidden edge may coincide with a continued period
            out = out[np.concatenate([[True], np.diff(out) > tolerance])]
        return out

    on_until = last_on[np.searchsorted(t_fall, times, side="right")]
    start = times[seen]
    for _ in range(8):  # continued periods and hidden edges anchor further hidden edges
        grown = merged(start, continued(start),
                       _hidden_edges(times, bits, start, period, bit_step, tolerance,
                                     on_until))
        if grown.size == start.size:
            break
        start = grown
    # a 0 -> 1 step across a gap with no grid point known (no edge before or after to
    # anchor it, e.g. a bit that then stays on): the period starts at the first on-bit
    gap = np.flatnonzero(~consecutive & (step == 1)) + 1
    if gap.size:
        j = np.searchsorted(start, times[gap - 1], side="right")
        jj = np.minimum(j, max(start.size - 1, 0))
        covered = ((j < start.size) & (start[jj] <= times[gap] + tolerance) if start.size
                   else np.zeros(gap.size, dtype=bool))
        lone = times[gap[~covered]]
        start = merged(start, lone, continued(lone))
    else:
        lone = np.empty(0)
    restarts = _hidden_restarts(times, bits, start, period, bit_step, tolerance,
                                evaluation_periods * period)
    if restarts.size:
        start = merged(start, restarts)
    nxt = np.append(start[1:], np.inf)
    end = np.minimum(start + period, nxt)
    # bits on within [start, end): cumulative count, searched by time
    csum = np.concatenate([[0], np.cumsum(bits, dtype=np.int64)])
    i0 = np.searchsorted(times, start - eps, side="left")
    i1 = np.searchsorted(times, end - eps, side="left")
    n_on = csum[i1] - csum[i0]
    duty = n_on * bit_step / period
    fall_time = fall_after(start)
    on = np.minimum(fall_time, end) - start
    # periods whose on-phase was not fully seen: cut by the end of the data, or with
    # missing bits (a short gap) before the observed fall of the bit
    missing = np.round((end - start) / bit_step).astype(np.int64) - (i1 - i0)
    j = np.searchsorted(t_fall, start, side="right")
    fall_seen = j < falling.size  # a 1 -> 0 transition after the edge, on consecutive bits
    if falling.size:
        f = falling[np.minimum(j, falling.size - 1)]
        fall_seen &= times[f] - times[f - 1] <= bit_step + eps
    # every bit of the on-run present: records in [start, fall) = its length in bits
    i_fall = np.searchsorted(times, fall_time - eps, side="left")
    whole_run = (i_fall - i0) == np.round((fall_time - start) / bit_step)
    # the controller switches on once per period, at its start: with the start on the
    # grid (not a lone first on-bit) and the fall seen inside the period, the on-phase is
    # [start, fall) even where a gap hid some of its bits
    known_start = ~np.isin(start, lone)
    single_run = fall_seen & known_start & (fall_time < end + eps) & ~whole_run
    duty = np.where(single_run, (fall_time - start) / period, duty)
    uncertain = (missing > 0) & ~(fall_seen & (whole_run | single_run))
    bounds = np.column_stack([duty, np.where(uncertain, (n_on + missing) * bit_step / period,
                                             duty)])
    for k in np.flatnonzero(uncertain):  # a loop over the few uncertain periods
        if k > 0 and start[k] - start[k - 1] <= period + tolerance:
            if duty[k] <= duty[k - 1] <= bounds[k, 1] + eps:
                duty[k] = duty[k - 1]
                on[k] = max(on[k], on[k - 1])
    # a restart hidden in a gap: the period after it lies in the same evaluation block
    # (one duty cycle) and, if its on-phase fits the gap, gives the duty cycle
    for k in np.flatnonzero(np.isin(start, restarts)):
        after = times[min(np.searchsorted(times, start[k] + eps), times.size - 1)]
        if (k + 1 < start.size and bounds[k, 1] >= duty[k + 1] - eps
                and after >= start[k] + on[k + 1] - tolerance):
            duty[k], on[k] = duty[k + 1], on[k + 1]
    always_on = duty >= 1.0 - eps  # no off phase: no heater-cycle waveform
    return HeaterPeriods(
        start=start, end=end, duty_cycle=duty, on_duration=on,
        applied=(on >= min_on - 0.5 * bit_step) & ~always_on, complete=~uncertain,
        duty_bounds=bounds,
    )


def heater_waveform(
    cycle_time: np.ndarray,
    duty_percent: np.ndarray,
    table: np.ndarray,
    bins_percent: np.ndarray,
) -> np.ndarray:
    """Interpolate a heater-signal table in heater-cycle time and duty cycle.

    Linear in ``cycle_time`` between the tabulated whole seconds (t = 100 equals t = 0)
    and linear in duty cycle between bins; below the first bin the slope between the
    first two bins is extended, above the last bin the slope between the last two.

    Parameters
    ----------
    cycle_time : ndarray, shape (n,)
        Seconds since the period's rising edge, in ``[0, 100]``.
    duty_percent : ndarray, shape (n,)
        Duty cycle of the period (percent).
    table : ndarray, shape (n_axes, 101, n_bins) or (101, n_bins)
        Signal (counts) at t = 0..100 s for each bin (Tables 6-8).
    bins_percent : ndarray, shape (n_bins,)
        Evenly spaced bin centres (12..40 %).

    Returns
    -------
    ndarray, shape (n, n_axes) or (n,)

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    table = np.asarray(table, dtype=float)
    squeeze = table.ndim == 2
    if squeeze:
        table = table[None]
    t = np.clip(np.asarray(cycle_time, dtype=float), 0.0, table.shape[1] - 1.0)
    i = np.minimum(np.floor(t).astype(np.int64), table.shape[1] - 2)
    ft = t - i
    bins = np.asarray(bins_percent, dtype=float)
    width = bins[1] - bins[0]
    w = (np.asarray(duty_percent, dtype=float) - bins[0]) / width
    j = np.clip(np.floor(w).astype(np.int64), 0, bins.size - 2)
    fd = w - j  # < 0 or > 1 in the extrapolation zones
    out = np.empty((t.size, table.shape[0]))
    nb = table.shape[2]
    flat = i * nb + j  # index of (i, j) in a flattened (101, n_bins) table
    w00, w10 = (1 - ft) * (1 - fd), ft * (1 - fd)
    w01, w11 = (1 - ft) * fd, ft * fd
    for axis in range(table.shape[0]):
        tab = table[axis].ravel()
        out[:, axis] = (tab.take(flat) * w00 + tab.take(flat + nb) * w10
                        + tab.take(flat + 1) * w01 + tab.take(flat + nb + 1) * w11)
    return out[:, 0] if squeeze else out


def period_index(sample_times: np.ndarray, periods: HeaterPeriods) -> np.ndarray:
    """Return the index of the heater period holding each sample, or -1 when none."""
    t = np.asarray(sample_times, dtype=float)
    k = np.searchsorted(periods.start, t, side="right") - 1
    inside = k >= 0
    kk = np.maximum(k, 0)
    if len(periods):
        inside &= t < periods.end[kk]
    else:
        inside[:] = False
    return np.where(inside, k, -1)


def heater_signal(
    sample_times: np.ndarray,
    periods: HeaterPeriods,
    table: np.ndarray,
    bins_percent: np.ndarray,
    *,
    applies_from: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return the heater signal (counts) at every sample and a mask where it applies.

    One compiled pass over the samples (`fluxcal.calibration._compiled.heater_signal_kernel`)
    doing what `heater_signal_reference` does with `period_index` and `heater_waveform`.

    Parameters
    ----------
    sample_times : ndarray, shape (n,)
        Sample times (s, same scale as the heater bits).
    periods : HeaterPeriods
    table : ndarray, shape (3, 101, n_bins)
    bins_percent : ndarray, shape (n_bins,)
    applies_from : float, optional
        No signal before this time: samples with ``not t >= applies_from`` are not
        applied (zero signal), e.g. before MAG FSW V10 (2007-03-09, sec. 6).

    Returns
    -------
    signal : ndarray, shape (n, 3)
        Zero outside applied periods.
    applied : ndarray of bool, shape (n,)

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    t = np.asarray(sample_times, dtype=float)
    tab = np.asarray(table, dtype=float)
    bins = np.asarray(bins_percent, dtype=float)
    start = np.asarray(periods.start, dtype=float)
    if (t.ndim != 1 or tab.ndim != 3 or tab.shape[0] != 3 or tab.shape[1] < 2
            or bins.size < 2 or bins.size != tab.shape[2] or np.isnan(start).any()):
        return heater_signal_reference(sample_times, periods, table, bins_percent,
                                       applies_from=applies_from)
    out = np.empty((t.size, 3))
    applied = np.empty(t.size, dtype=bool)
    bad = heater_signal_kernel(
        t, start, np.asarray(periods.end, dtype=float),
        np.asarray(periods.applied, dtype=bool), np.asarray(periods.duty_cycle, dtype=float),
        np.ascontiguousarray(tab.transpose(1, 2, 0)),  # (101, n_bins, 3): corners adjacent
        float(bins[0]), float(bins[1] - bins[0]),
        -np.inf if applies_from is None else float(applies_from), out, applied,
    )
    if bad >= 0:  # a non-finite cycle time or duty cycle: the reference decides
        return heater_signal_reference(sample_times, periods, table, bins_percent,
                                       applies_from=applies_from)
    return out, applied


def heater_signal_reference(
    sample_times: np.ndarray,
    periods: HeaterPeriods,
    table: np.ndarray,
    bins_percent: np.ndarray,
    *,
    applies_from: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Numpy reference of `heater_signal`: `period_index`, then `heater_waveform`.

    Several whole-array passes; the tests compare the compiled `heater_signal` with it.

    Parameters and returns as `heater_signal`.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6.
    """
    t = np.asarray(sample_times, dtype=float)
    k = period_index(t, periods)
    applied = k >= 0
    if len(periods):
        applied &= periods.applied[np.maximum(k, 0)]
    if applies_from is not None:
        applied &= t >= applies_from
    out = np.zeros((t.size, np.asarray(table).shape[0]))
    if applied.any():
        kk = k[applied]
        out[applied] = heater_waveform(
            t[applied] - periods.start[kk],
            periods.duty_cycle[kk] * 100.0,
            table,
            bins_percent,
        )
    return out, applied
