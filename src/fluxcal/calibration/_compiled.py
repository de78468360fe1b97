"""Compiled per-sample loops of the MESSENGER calibration steps (numba).

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
       (Appendix Tables 6-8), sec. 7 (eq. 3a-7, Tables 2-3), sec. 8 (eq. 8, Table 4),
       sec. 13.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _bisect_right(nodes, x):
    """``np.searchsorted(nodes, x, side="right")`` (NaN sorts after every node)."""
    lo = 0
    hi = nodes.size
    while lo < hi:
        mid = (lo + hi) >> 1
        if x < nodes[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True, nogil=True, inline="always")
def count_le(nodes, x, hint):
    """``np.searchsorted(nodes, x, side="right")`` given the answer for a nearby ``x``.

    Parameters
    ----------
    nodes : ndarray, shape (m,)
        Non-decreasing.
    x : float
    hint : int
        An earlier answer (``0..m``); the next interval is tried before a bisection.
    """
    m = nodes.size
    k = hint
    if (k == 0 or nodes[k - 1] <= x) and (k == m or x < nodes[k]):
        return k
    if k < m and nodes[k] <= x and (k + 1 == m or x < nodes[k + 1]):
        return k + 1
    return _bisect_right(nodes, x)


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
def heater_signal_kernel(t, start, end, period_applied, duty, table, bin0, width, out, applied):
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
        if k == 0:
            decay = 1.0
        else:
            x = t - change_time[k - 1] - delay
            if x < 0.0:  # np.maximum(x, 0): NaN stays NaN
                x = 0.0
            decay = math.exp(-x / tau)
        for j in range(k_axes):
            c = target[k, j]
            out[i, j] = c - (c - state[k, j]) * decay


# ----------------------------------------------------------------------------------------
# sec. 8: counts -> nT
# ----------------------------------------------------------------------------------------
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
def largest_steps_kernel(offset, segment, use_segment, largest, index):
    """Largest ``|offset[i] - offset[i-1]|`` per column (seed 000 sec. 13).

    Steps across segments count as zero.  As ``np.argmax`` over the step array: the
    first maximum wins and the first NaN step, if any, is the maximum.  ``index`` is
    that of the sample after the step.

    Parameters
    ----------
    offset : ndarray, shape (n, k), n >= 2
    segment : ndarray, shape (n,)
        Segment label per sample (ignored unless ``use_segment``).
    use_segment : bool
    largest : ndarray, shape (k,)
        Written.
    index : ndarray of int64, shape (k,)
        Written.
    """
    n, k = offset.shape
    for j in range(k):
        largest[j] = -1.0
        index[j] = 1
    for i in range(1, n):
        cut = use_segment and segment[i] != segment[i - 1]
        for j in range(k):
            best = largest[j]
            if best != best:  # a NaN step already won
                continue
            step = 0.0 if cut else abs(offset[i, j] - offset[i - 1, j])
            if step > best or step != step:
                largest[j] = step
                index[j] = i
