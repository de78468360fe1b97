"""Offsets that relax toward a new steady state after each heater duty-cycle change.

Implements the assignment sequence 6a-6f of the seed 000 procedure: the offset at a
sample time ``t_s`` is built from the steady-state offsets ``c*_0..c*_5`` set at the
last six duty-cycle changes ``t_0 > t_1 > ... > t_5``, starting from zero at ``t_5``,
each relaxing with time constant ``tau`` after a delay ``dt``::

    c_t4 <- c*_5 (1 - exp(-max(t_4 - t_5 - dt, 0) / tau))                (6a)
    c_tk <- c*_(k+1) - (c*_(k+1) - c_t(k+1)) exp(-max(t_k - t_(k+1) - dt, 0) / tau)
    c(t_s) <- c*_0 - (c*_0 - c_t0) exp(-max(t_s - t_0 - dt, 0) / tau)    (6f)

The state at each change (``c_t0`` for that change) is computed once per change with a
loop over the look-back depth (vectorized over changes); samples are then evaluated in
one compiled pass (`relaxed_offset`; `relaxed_offset_reference` is the numpy version).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 5a, 5b, 6a-6f, 7, Table 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluxcal.calibration._compiled import duty_cycle_levels_kernel, relaxed_offset_kernel
from fluxcal.calibration.heater_signal import HeaterPeriods


@dataclass(frozen=True)
class DutyCycleChanges:
    """Times at which the heater duty cycle changed and the new duty cycle.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Change times (s), increasing.
    duty_cycle_ppt : ndarray, shape (m,)
        New duty cycle in parts per 1000.
    """

    time: np.ndarray
    duty_cycle_ppt: np.ndarray

    def __len__(self) -> int:
        return int(self.time.size)


def duty_cycle_changes(
    periods: HeaterPeriods,
    *,
    period: float = 100.0,
    data_end: float | None = None,
    data_start: float | None = None,
    tolerance: float = 1.5,
    evaluation_periods: int = 10,
) -> DutyCycleChanges:
    """Return the duty-cycle changes implied by a sequence of heater periods.

    The V10 controller evaluates the duty cycle every ``evaluation_periods`` heater
    periods (1000 s, sec. 7); a change is where the commanded duty cycle changes, found
    by `fluxcal.calibration._compiled.duty_cycle_levels_kernel`: a period whose on-count
    differs from the level in force changes it only when the new value is the most
    frequent among it and the following periods of one evaluation interval (a +-1-bit
    jitter of single periods is no change); the change is at that period's rising edge
    and takes the most frequent value.  The heater going quiet (no rising edge within
    ``period + tolerance`` after the last one) is a change to zero at the end of its last
    period.  The heater is assumed quiet before the first period when the series shows
    it: more than ``period + tolerance`` of heater data before the first rising edge (an
    earlier edge would have been seen).  Otherwise (the series starts inside heater
    operation, e.g. a day processed without the previous day's heater file) the first
    period's duty cycle is taken as in force since the distant past: a change at
    ``-inf``, i.e. its steady state (the initial assumption of sec. 7's look-back), not a
    step from zero.

    Parameters
    ----------
    periods : HeaterPeriods
    period : float
        Heater period (s).
    data_end : float, optional
        End of the heater-bit series; a final period ending after it is not followed
        by a change to zero.
    data_start : float, optional
        Time of the first heater bit.  ``None`` assumes the heater quiet before the
        first period.
    tolerance : float
        Slack (s) when deciding that two periods are contiguous.
    evaluation_periods : int
        Heater periods per controller evaluation (10).

    Returns
    -------
    DutyCycleChanges

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (fluxcal reading recorded in
       docs/decisions/messenger.md).
    """
    start = np.asarray(periods.start, dtype=float)
    ppt = np.round(np.asarray(periods.duty_cycle, dtype=float) * 1000.0)
    if start.size == 0:
        return DutyCycleChanges(np.empty(0), np.empty(0))
    gap_after = np.append(start[1:] - start[:-1] > period + tolerance, True)
    if data_end is not None:
        gap_after[-1] = start[-1] + period + tolerance <= data_end
    run_start = np.concatenate([[True], gap_after[:-1]])
    level = np.empty_like(ppt)
    new = np.empty(ppt.size, dtype=bool)
    seen = ppt.copy()  # periods whose on-phase was not fully seen do not vote
    if periods.complete is not None:
        seen[~np.asarray(periods.complete, dtype=bool)] = np.nan
    bounds = (np.column_stack([ppt, ppt]) if periods.duty_bounds is None
              else np.ascontiguousarray(np.round(np.asarray(periods.duty_bounds) * 1000.0)))
    cut = data_start is not None and start[0] - data_start <= period + tolerance
    duty_cycle_levels_kernel(seen, ppt, bounds, run_start, int(evaluation_periods), cut,
                             not bool(gap_after[-1]), level, new)
    change_at = start.copy()
    if cut:
        change_at[0] = -np.inf  # the duty cycle before the data is unknown: steady since -inf
    times = [change_at[new], start[gap_after] + period]
    values = [level[new], np.zeros(int(gap_after.sum()))]
    t = np.concatenate(times)
    v = np.concatenate(values)
    order = np.argsort(t, kind="stable")
    return DutyCycleChanges(time=t[order], duty_cycle_ppt=v[order])


def steady_state_offset(
    duty_cycle_ppt: np.ndarray, slope: np.ndarray, threshold_ppt: float = 100.0
) -> np.ndarray:
    """Return the steady-state offset shift ``D0_j d`` (``d >= 100``) or 0 (eq. 5a, 5b).

    The intercept ``C0`` of eq. 5a is not included: fluxcal adds the temperature line
    ``cT(T)`` instead, and ``C0 = cT(-50 C)`` (see docs/decisions/messenger.md).

    Parameters
    ----------
    duty_cycle_ppt : ndarray, shape (m,)
    slope : ndarray, shape (3,)
        ``D0`` per axis (counts per part per 1000, Table 3).
    threshold_ppt : float
        Duty cycles below this give zero.

    Returns
    -------
    ndarray, shape (m, 3)
    """
    d = np.asarray(duty_cycle_ppt, dtype=float)[:, None]
    return np.where(d >= threshold_ppt, d * np.asarray(slope, dtype=float)[None, :], 0.0)


def look_back_depth(change_time: np.ndarray, look_back: int, look_back_s: float) -> np.ndarray:
    """Return the number of earlier changes each change looks back over (sec. 7).

    At least ``look_back`` changes, and back to the first change at least ``look_back_s``
    before it (or to the first change of all): sec. 7 looks back over a 5000-s interval
    with five changes, which span 5000 s when the V10 controller changes the duty cycle
    at most every 1000 s; changes closer together (the heater going quiet and starting
    again) must not shorten the look-back below 5000 s.

    Returns
    -------
    ndarray of int, shape (m,)
        Depth ``D`` per change: the state is zero at ``t_D`` (eq. 6a starts there).
    """
    t = np.asarray(change_time, dtype=float)
    idx = np.arange(t.size)
    depth = np.full(t.size, int(look_back), dtype=np.int64)
    if look_back_s > 0 and t.size:
        # last change at or before t_0 - look_back_s (-1: none, look back to the start)
        j = np.searchsorted(t, t - look_back_s, side="right") - 1
        depth = np.maximum(depth, np.where(j >= 0, idx - j, idx + look_back))
    return depth


def state_at_changes(
    change_time: np.ndarray,
    target: np.ndarray,
    *,
    tau: float,
    delay: float,
    look_back: int = 5,
    look_back_s: float = 0.0,
) -> np.ndarray:
    """Return ``c_t0`` of eq. 6e for each change taken as the most recent one ``t_0``.

    Parameters
    ----------
    change_time : ndarray, shape (m,)
    target : ndarray, shape (m, k)
        Steady-state offset set at each change.
    tau, delay : float
        Relaxation time and heater delay (s).
    look_back : int
        Least number of earlier changes used (5: t_1..t_5).
    look_back_s : float
        Least look-back interval (s, 5000): more changes are used when ``look_back``
        changes span less (`look_back_depth`).

    Returns
    -------
    ndarray, shape (m, k)
    """
    change_time = np.asarray(change_time, dtype=float)
    target = np.asarray(target, dtype=float)
    m = change_time.size
    depth = look_back_depth(change_time, look_back, look_back_s)
    most = int(depth.max()) if m else int(look_back)
    # pad with `most` changes at -inf to zero: the state is zero before t_D
    pad_t = np.concatenate([np.full(most, -np.inf), change_time])
    pad_c = np.concatenate([np.zeros((most, target.shape[1])), target])
    idx = np.arange(m) + most  # index of t_0 in the padded arrays
    state = np.zeros((m, target.shape[1]))  # value at t_D, zero
    for lag in range(most, 0, -1):
        older = idx - lag  # t_(lag)
        newer = older + 1  # t_(lag-1)
        real = np.isfinite(pad_t[older]) & (lag <= depth)
        dt = np.where(real, pad_t[newer] - np.where(real, pad_t[older], 0.0) - delay, 0.0)
        decay = np.where(real, np.exp(-np.maximum(dt, 0.0) / tau), 0.0)
        c_star = np.where((lag <= depth)[:, None], pad_c[older], 0.0)
        state = c_star - (c_star - state) * decay[:, None]
    return state


def relaxed_offset(
    sample_time: np.ndarray,
    change_time: np.ndarray,
    target: np.ndarray,
    *,
    tau: float,
    delay: float,
    look_back: int = 5,
    look_back_s: float = 0.0,
) -> np.ndarray:
    """Return the duty-cycle offset ``c(t_s)`` of eq. 6f at every sample.

    Parameters
    ----------
    sample_time : ndarray, shape (n,)
    change_time : ndarray, shape (m,)
        Duty-cycle change times, increasing.
    target : ndarray, shape (m, k)
        Steady-state offsets (eq. 5) set at each change.
    tau : float
        Relaxation time (872 s).
    delay : float
        Delay ``dt`` between heater request and heater power (10 s).
    look_back : int
        Least number of earlier changes (5).
    look_back_s : float
        Least look-back interval (s; 5000 in the seed 000 processing constants, 0: five
        changes whatever their span), see `look_back_depth`.

    Returns
    -------
    ndarray, shape (n, k)
        Zero before the first change.

    Notes
    -----
    The states at the changes come from `state_at_changes` (numpy, one row per change);
    the samples are evaluated in one compiled pass
    (`fluxcal.calibration._compiled.relaxed_offset_kernel`).  `relaxed_offset_reference`
    is the numpy version the tests compare with.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 6a-6f, 7.
    """
    ts = np.ascontiguousarray(sample_time, dtype=float)
    change_time = np.ascontiguousarray(change_time, dtype=float)
    target = np.asarray(target, dtype=float)
    if ts.ndim != 1 or target.ndim != 2 or np.isnan(change_time).any():
        return relaxed_offset_reference(sample_time, change_time, target, tau=tau,
                                        delay=delay, look_back=look_back,
                                        look_back_s=look_back_s)
    out = np.zeros((ts.size, target.shape[1]))
    if change_time.size == 0:
        return out
    if np.any(change_time[1:] < change_time[:-1]):
        raise ValueError("change_time: must be increasing")
    state = state_at_changes(change_time, target, tau=tau, delay=delay, look_back=look_back,
                             look_back_s=look_back_s)
    # row 0 of the padded tables is "before the first change": zero target and state
    pad = np.zeros((1, target.shape[1]))
    relaxed_offset_kernel(ts, change_time, np.concatenate([pad, target]),
                          np.concatenate([pad, state]), float(tau), float(delay), out)
    return out


def relaxed_offset_reference(
    sample_time: np.ndarray,
    change_time: np.ndarray,
    target: np.ndarray,
    *,
    tau: float,
    delay: float,
    look_back: int = 5,
    look_back_s: float = 0.0,
) -> np.ndarray:
    """Numpy reference of `relaxed_offset` (whole-array passes; the tests compare).

    Parameters and returns as `relaxed_offset`.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 6a-6f, 7.
    """
    ts = np.asarray(sample_time, dtype=float)
    change_time = np.asarray(change_time, dtype=float)
    target = np.asarray(target, dtype=float)
    out = np.zeros((ts.size, target.shape[1] if target.ndim == 2 else 3))
    if change_time.size == 0:
        return out
    if np.any(np.diff(change_time) < 0):
        raise ValueError("change_time: must be increasing")
    state = state_at_changes(change_time, target, tau=tau, delay=delay, look_back=look_back,
                             look_back_s=look_back_s)
    # row 0 of the padded tables is "before the first change": zero target and state
    k = np.searchsorted(change_time, ts, side="right")
    t_pad = np.concatenate([[0.0], change_time])
    decay = np.exp(-np.maximum(ts - t_pad.take(k) - delay, 0.0) / tau)
    decay[k == 0] = 1.0
    pad = np.zeros((1, target.shape[1]))
    tgt = np.concatenate([pad, target])
    st = np.concatenate([pad, state])
    for j in range(target.shape[1]):
        tj = tgt[:, j].take(k)
        out[:, j] = tj - (tj - st[:, j].take(k)) * decay
    return out
