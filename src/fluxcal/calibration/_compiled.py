"""Compiled per-sample loops of the calibration building blocks (numba).

Each kernel does in one pass over the samples, writing into preallocated outputs, what
a chain of whole-array numpy expressions does in the public function that calls it; the
numpy expressions stay beside those functions as the reference implementations
(``*_reference``), and the tests compare the two on random inputs.

The kernels reproduce the reference arithmetic operation by operation (same operands,
same order, IEEE double precision, no ``fastmath``), so they agree with it bit for bit
except where ``exp`` is involved (libm versus numpy's own ``exp``: at most one unit in
the last place).  Inputs the reference would reject or treat specially (out-of-range
indices, NaN times) make a kernel stop and report the sample; the caller then runs the
reference, which raises its own error or returns what it returns.

Interval look-ups walk sorted sample times with a moving hint (O(1) per sample) and
fall back to a binary search; they return what ``np.searchsorted(..., side="right")``
returns, NaN included (after every node).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 5 (Table 1), sec. 6
       (Appendix Tables 6-8), sec. 7 (eq. 1-7, Tables 2-3), sec. 8 (eq. 8, Table 4),
       sec. 13.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from fluxcal.geometry.compiled import count_le


# ----------------------------------------------------------------------------------------
# sec. 5: per-sample lag
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def per_sample_lag_kernel(rate, lags, out):
    """``out[i] = lags[rate[i]]`` (seed 000 sec. 5, Table 1).

    Returns
    -------
    int
        -1, or the index of the first rate setting outside ``0..lags.size - 1`` (the
        loop stops there).
    """
    m = lags.size
    for i in range(rate.size):
        r = rate[i]
        if r < 0 or r >= m:
            return i
        out[i] = lags[r]
    return -1


# ----------------------------------------------------------------------------------------
# sec. 6: heater signal
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def heater_signal_kernel(
    t, start, end, period_applied, duty, table, bin0, width, applies_from, out, applied
):
    """Heater period of each sample and the bilinear heater waveform (seed 000 sec. 6).

    Fuses `fluxcal.calibration.heater_signal.period_index` (period ``k`` with
    ``start[k] <= t < end[k]``), the persistence test and
    `fluxcal.calibration.heater_signal.heater_waveform` (bilinear in heater-cycle time and
    duty cycle, the 12-16 % and 36-40 % slopes extended outside 12..40 %) of Appendix
    Tables 6-8, with the reference's operations in the same order.  The duty-cycle
    weights are computed once per period.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times.
    start, end, period_applied, duty : ndarray, shape (k,)
        `HeaterPeriods` fields (``duty`` as a fraction 0..1); ``start`` increasing.
    table : ndarray, shape (n_t, n_bins, 3)
        Heater signal (counts) at cycle times ``0..n_t - 1`` s per duty-cycle bin and
        axis: Tables 6-8 with the axis last (``table_6_8.transpose(1, 2, 0)``).
    bin0, width : float
        First bin centre and bin spacing (percent).
    applies_from : float
        No signal before this time (``-inf``: none), e.g. MAG FSW V10 (sec. 6): samples
        with ``not t >= applies_from`` are not applied.
    out : ndarray, shape (n, 3)
        Written: the signal where a period applies, zero elsewhere.
    applied : ndarray of bool, shape (n,)
        Written: inside a period whose heater bit stayed on for the persistence time.

    Returns
    -------
    int
        -1, or the index of the first applied sample whose cycle time or duty cycle is
        not finite (the loop stops; the reference indexes out of its table there).
    """
    t_max = table.shape[0] - 1.0
    i_max = table.shape[0] - 2
    j_max = table.shape[1] - 2.0
    hint = 0
    current = -1
    j = 0
    w = 0.0
    fd = 0.0
    for s in range(t.size):
        ts = t[s]
        if not ts >= applies_from:
            applied[s] = False
            out[s, 0] = 0.0
            out[s, 1] = 0.0
            out[s, 2] = 0.0
            continue
        k = count_le(start, ts, hint)
        hint = k
        k -= 1
        if k < 0 or not ts < end[k] or not period_applied[k]:
            applied[s] = False
            out[s, 0] = 0.0
            out[s, 1] = 0.0
            out[s, 2] = 0.0
            continue
        applied[s] = True
        if k != current:  # duty-cycle bin j = clip(floor(w), 0, n_bins - 2), fd = w - j
            current = k
            w = (duty[k] * 100.0 - bin0) / width
            jf = np.floor(w)
            if jf < 0.0:
                jf = 0.0
            elif jf > j_max:
                jf = j_max
            j = int(jf) if math.isfinite(jf) else 0
            fd = w - j  # < 0 or > 1 in the extrapolation zones
        cycle = ts - start[k]
        if not (math.isfinite(cycle) and math.isfinite(w)):
            return s
        # cycle time: np.clip(cycle, 0, n_t - 1), i = min(floor(.), n_t - 2)
        tc = cycle
        if tc < 0.0:
            tc = 0.0
        elif tc > t_max:
            tc = t_max
        i = min(int(np.floor(tc)), i_max)
        ft = tc - i
        w00 = (1 - ft) * (1 - fd)
        w10 = ft * (1 - fd)
        w01 = (1 - ft) * fd
        w11 = ft * fd
        c00 = table[i, j]
        c10 = table[i + 1, j]
        c01 = table[i, j + 1]
        c11 = table[i + 1, j + 1]
        out[s, 0] = c00[0] * w00 + c10[0] * w10 + c01[0] * w01 + c11[0] * w11
        out[s, 1] = c00[1] * w00 + c10[1] * w10 + c01[1] * w01 + c11[1] * w11
        out[s, 2] = c00[2] * w00 + c10[2] * w10 + c01[2] * w01 + c11[2] * w11
    return -1


# ----------------------------------------------------------------------------------------
# sec. 7: duty-cycle levels of the V10 controller
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _mode(values, lo, hi, ref):
    """Most frequent value of ``values[lo:hi]``, its count, and the count of ``ref``.

    Ties: the first value to occur wins.
    """
    best = values[lo]
    best_count = 0
    ref_count = 0
    for a in range(lo, hi):
        v = values[a]
        if v == ref:
            ref_count += 1
        c = 0
        for b in range(lo, hi):
            if values[b] == v:
                c += 1
        if c > best_count:
            best = v
            best_count = c
    return best, best_count, ref_count


@njit(cache=True, nogil=True)
def duty_cycle_levels_kernel(ppt, fallback, bounds, run_start, window, first_run_cut,
                             last_run_open, level, change):
    """Duty cycle commanded by the controller in each heater period (seed 000 sec. 7).

    The V10 controller sets a new duty cycle only at its evaluations, every ten heater
    periods, so a commanded duty cycle holds for ``window`` (10) periods while the
    on-count of single periods may jitter by a bit.  Walking the periods in order:

    - the first period of a contiguous run starts a level (a change): a run after the
      heater was quiet starts at an evaluation, so its level is the most frequent seen
      value of its first ``window`` periods; a first run cut by the start of the data
      (``first_run_cut``) may hold the end of an earlier level: its level is the first
      value repeated by the next period among its first ``window`` periods (else the
      most frequent);
    - a later period ``k`` whose duty cycle differs from the level changes it only when
      the most frequent value ``v`` among it and the ``window - 1`` periods after it
      (same run; ties: the first to occur) is another value, more frequent there than
      the level and holding more than half of the seen periods there.  The change is
      at the first of those periods whose duty cycle is closer to ``v`` than to the
      level (so a jittered period just before a real change does not move it earlier),
      or at an unseen period just before that one whose ``bounds`` allow ``v`` and not
      the level (or allow ``v`` where the level needs that period to hold ``window``
      periods before a quiet end, or to start on the evaluation grid of a run that began
      after quiet: a gap cutting an on-run), and takes the value ``v``; otherwise ``k``
      is jitter (no change).
      A run that ends with the heater going quiet ends at an evaluation, so its last
      level holds ``window`` periods: fewer than ``window - 1`` periods before that end
      cannot start a level.  The last run may be cut by the end of the data instead
      (``last_run_open``): there the periods that are left decide.

    Parameters
    ----------
    ppt : ndarray, shape (n,)
        Duty cycle of each period (parts per 1000, whole numbers); NaN for a period
        whose on-phase was not fully seen (it does not vote and starts no level).
    fallback : ndarray, shape (n,)
        Duty cycle (bounds-resolved) of every period: the level of a run none of whose
        periods has a seen value.
    bounds : ndarray, shape (n, 2)
        Least and largest duty cycle (ppt) the seen bits of each period allow.
    run_start : ndarray of bool, shape (n,)
        First period of a contiguous run (period 0 always starts one).
    window : int
        Periods per controller evaluation (10).
    first_run_cut : bool
        The first run is cut by the start of the data (heater operating at the start).
    last_run_open : bool
        The last run is cut by the end of the data (not ended by the heater going quiet).
    level : ndarray, shape (n,)
        Written: the commanded duty cycle in force in each period.
    change : ndarray of bool, shape (n,)
        Written: the level changes at this period.
    """
    n = ppt.size
    current = 0.0
    run_end = 0
    r0 = 0
    phase_known = False
    k = 0
    while k < n:
        change[k] = False
        if run_start[k] or k == 0:
            r0 = k  # evaluations at r0 + m * window when the run starts after quiet
            phase_known = not (k == 0 and first_run_cut)
            run_end = k + 1
            while run_end < n and not run_start[run_end]:
                run_end += 1
            hi = min(k + window, run_end)
            v, cv, cl = _mode(ppt, k, hi, ppt[k])
            current = v if cv > 0 else fallback[k]  # a run after quiet: one evaluation
            if k == 0 and first_run_cut:  # cut by the data start: the first repeated value
                m = k
                while m + 1 < hi and not (ppt[m] == ppt[m + 1]):
                    m += 1
                if m + 1 < hi:
                    current = ppt[m]
            level[k] = current
            change[k] = True
            k += 1
            continue
        level[k] = current
        if ppt[k] == ppt[k] and ppt[k] != current:
            hi = min(k + window, run_end)
            quiet_end = not (last_run_open and run_end == n)
            v, cv, cl = _mode(ppt, k, hi, current)
            m = k  # unseen periods just before k that allow v may belong to the new level
            while (m - 1 > 0 and not run_start[m - 1] and ppt[m - 1] != ppt[m - 1]
                   and bounds[m - 1, 0] <= v <= bounds[m - 1, 1]):
                m -= 1
            if hi - m < window - 1 and quiet_end:
                k += 1  # too close to a quiet end for a new level
                continue
            n_seen = 0
            for a in range(k, hi):
                if ppt[a] == ppt[a]:
                    n_seen += 1
            if v != current and cv > cl and 2 * cv > n_seen:
                j = k  # v holds the majority of [k, hi): some period there is closer
                while ppt[j] != ppt[j] or abs(ppt[j] - v) >= abs(ppt[j] - current):
                    change[j] = False
                    level[j] = current
                    j += 1
                # unseen periods just before it whose bounds allow the new value belong
                # to it when they exclude the old one, or when the new level needs them
                # to hold `window` periods before a quiet end
                while (j - 1 > 0 and not run_start[j - 1] and ppt[j - 1] != ppt[j - 1]
                       and bounds[j - 1, 0] <= v <= bounds[j - 1, 1]
                       and (not bounds[j - 1, 0] <= current <= bounds[j - 1, 1]
                            or (quiet_end and run_end - j < window)
                            or (phase_known and (j - r0) % window != 0))):
                    j -= 1
                change[j] = True
                level[j] = v
                current = v
                k = j + 1
                continue
        k += 1


# ----------------------------------------------------------------------------------------
# sec. 7: offsets
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def two_segment_kernel(temp, coefficients, t_break, out):
    """Two-segment temperature offset per sample and axis (seed 000 sec. 7, Table 2).

    ``out[i, j] = A0 + B0 T`` for ``T <= T_m``, else ``A1 + B1 T`` (eq. 3a, 3b, 4).

    Parameters
    ----------
    temp : ndarray, shape (n,)
    coefficients : ndarray, shape (k, 4)
        ``A0, B0, A1, B1`` per axis.
    t_break : ndarray, shape (k,)
        ``T_m`` per axis (eq. 4).
    out : ndarray, shape (n, k)
    """
    k = coefficients.shape[0]
    for i in range(temp.size):
        t = temp[i]
        for j in range(k):
            if t <= t_break[j]:
                out[i, j] = coefficients[j, 0] + coefficients[j, 1] * t
            else:
                out[i, j] = coefficients[j, 2] + coefficients[j, 3] * t


@njit(cache=True, nogil=True, inline="always")
def decay_kernel(change_time, k, t, delay, tau):
    """``exp(-max(t - t_0 - dt, 0) / tau)`` of eq. 6f, ``t_0 = change_time[k - 1]``.

    ``k`` is the number of changes at or before ``t`` (`count_le`); 1 before the first.
    """
    if k == 0:
        return 1.0
    x = t - change_time[k - 1] - delay
    if x < 0.0:  # np.maximum(x, 0): NaN stays NaN
        x = 0.0
    return math.exp(-x / tau)


@njit(cache=True, nogil=True)
def relaxed_offset_kernel(ts, change_time, target, state, tau, delay, out):
    """Eq. 6f at every sample from the states ``c_t0`` at the changes (seed 000 sec. 7).

    ``out[i] = c*_0 - (c*_0 - c_t0) exp(-max(t_s - t_0 - dt, 0) / tau)`` with ``t_0`` the
    last change at or before ``t_s``; zero before the first change.

    Parameters
    ----------
    ts : ndarray, shape (n,)
        Sample times.
    change_time : ndarray, shape (m,)
        Increasing change times (``-inf`` allowed).
    target, state : ndarray, shape (m + 1, k)
        Steady-state offset ``c*_0`` and state ``c_t0`` per change, row 0 (before the
        first change) zero.
    tau, delay : float
        Relaxation time and heater delay (s, Table 3).
    out : ndarray, shape (n, k)
    """
    k_axes = target.shape[1]
    hint = 0
    for i in range(ts.size):
        t = ts[i]
        k = count_le(change_time, t, hint)
        hint = k
        decay = decay_kernel(change_time, k, t, delay, tau)
        for j in range(k_axes):
            c = target[k, j]
            out[i, j] = c - (c - state[k, j]) * decay


@njit(cache=True, nogil=True)
def apply_per_range_kernel(vectors, range_flag, matrices, used, out):
    """``out[i] = matrices[range_flag[i]] @ vectors[i]`` (seed 000 sec. 8, eq. 8, Table 4).

    Terms ``(r, c)`` with ``used[r, c]`` False (zero in every matrix) are skipped, as the
    reference does, so an infinite count does not turn into NaN through ``0 * inf``.

    Returns
    -------
    int
        -1, or the index of the first range flag outside ``0..m - 1`` (the loop stops).
    """
    n_mat = matrices.shape[0]
    for i in range(vectors.shape[0]):
        r = range_flag[i]
        if r < 0 or r >= n_mat:
            return i
        for row in range(3):
            acc = 0.0
            for col in range(3):
                if used[row, col]:
                    acc += matrices[r, row, col] * vectors[i, col]
            out[i, row] = acc
    return -1


# ----------------------------------------------------------------------------------------
# sec. 13: largest offset step
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def largest_steps_kernel(offset, segment, use_segment, times, max_gap, use_gaps, time_scale,
                         largest, index):
    """Largest ``|offset[i] - offset[i-1]|`` per column (seed 000 sec. 13).

    Steps across segments, and across gaps ``times[i] - times[i-1] > max_gap[i]``, count
    as zero.  With ``time_scale > 0`` a step over ``dt = times[i] - times[i-1]`` longer
    than ``time_scale`` is divided by ``dt / time_scale`` (a rate per ``time_scale``).
    As ``np.argmax`` over the step array: the first maximum wins and the first NaN step,
    if any, is the maximum.  ``index`` is that of the sample after the step.

    Parameters
    ----------
    offset : ndarray, shape (n, k), n >= 2
    segment : ndarray, shape (n,)
        Segment label per sample (ignored unless ``use_segment``).
    use_segment : bool
    times : ndarray, shape (n,)
        Sample times (ignored unless ``use_gaps``).
    max_gap : ndarray, shape (n,) or (1,)
        Longest step in ``times`` within a segment, for the step ending at each sample
        (one value for all when of size 1; a NaN difference is no gap, as
        ``np.diff(times) > max_gap``).
    use_gaps : bool
    time_scale : float
        Steps over longer times are scaled down (0: no scaling; needs ``use_gaps``).
    largest : ndarray, shape (k,)
        Written.
    index : ndarray of int64, shape (k,)
        Written.
    """
    n, k = offset.shape
    one_gap = max_gap.size == 1
    for j in range(k):
        largest[j] = -1.0
        index[j] = 1
    for i in range(1, n):
        cut = use_segment and segment[i] != segment[i - 1]
        scale = 1.0
        if use_gaps:
            dt = times[i] - times[i - 1]
            if dt > max_gap[0 if one_gap else i]:
                cut = True
            if time_scale > 0.0 and dt > time_scale:
                scale = dt / time_scale
        for j in range(k):
            best = largest[j]
            if best != best:  # a NaN step already won
                continue
            step = 0.0 if cut else abs(offset[i, j] - offset[i - 1, j]) / scale
            if step > best or step != step:
                largest[j] = step
                index[j] = i
