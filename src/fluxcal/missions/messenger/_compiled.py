"""Compiled per-sample loops of the MESSENGER calibration chain (numba).

`offset_chain_kernel` runs temperature interpolation, the offset model of sec. 7 and
the offset removal in one pass (`fluxcal.missions.messenger.levels.correct_offsets`);
`quality_kernel` computes the Table 5 flags of
`fluxcal.missions.messenger.levels.quality_flags`.  Both use the operations of the
numpy code they replace, in the same order (no ``fastmath``), so the results are
bit-identical (but for libm's ``exp``, at most one unit in the last place); the
``*_reference`` functions stay beside the callers as what the tests compare with.  The
generic kernels they build on are in `fluxcal.calibration._compiled`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 7 (eq. 1-7, Tables 2-3),
       sec. 12 (Table 5).
"""

from __future__ import annotations

from numba import njit

from fluxcal.calibration._compiled import decay_kernel
from fluxcal.geometry.compiled import count_le


# ----------------------------------------------------------------------------------------
# sec. 7: offsets
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def offset_chain_kernel(
    et, fixed, temp_et, temp_c, interpolate, margin, model_start, fixed_temp, coefficients,
    t_break, change_time, target, state, tau, delay, heater, range_flag, coarse, counts, full,
    temperature, offset, duty, applied, corrected,
):
    """Temperature, offset model and offset removal per sample (seed 000 sec. 7, eq. 1-7).

    In one pass, per sample ``t = et[i]``, with the operations of the numpy chain
    ``np.interp`` -> `fluxcal.calibration.offsets.two_segment_offset` (eq. 3a, 3b, 4,
    Table 2) -> `fluxcal.calibration.relaxation.relaxed_offset` (eq. 6f, Table 3) ->
    range conversion -> subtraction (eq. 1), in the same order:

    - ``T``: the temperature, linearly interpolated in ``(temp_et, temp_c)`` exactly as
      ``np.interp`` does (NaN for a NaN time, the end values outside, ``temp_c[j]`` at a
      node) when ``interpolate``, else ``temperature[i]`` (input);
    - ``model = t >= model_start`` (MAG FSW V10 for MESSENGER, sec. 7 last paragraph);
      before it there is no duty-cycle term, and samples with ``fixed[i]`` (deployed
      sensor in sunlight) use ``fixed_temp`` (22.4 C) instead of ``T``;
    - ``cT_j = A0 + B0 T'`` for ``T' <= T_m``, else ``A1 + B1 T'`` with ``T' = T`` or
      ``fixed_temp``;
    - ``Delta_j = c*_0 - (c*_0 - c_t0) exp(-max(t - t_0 - dt, 0) / tau)`` with ``t_0``
      the last change at or before ``t`` (row 0 of ``target``/``state``, zero, before the
      first change; ``exp`` is libm's, as `relaxed_offset_kernel`), 0 before
      ``model_start``;
    - ``offset = cT + Delta``;
    and when ``full``: ``fine = offset + heater[i]``, ``applied = coarse @ fine`` where
    ``range_flag[i] == 1`` (``(c0 f0 + c1 f1) + c2 f2`` per row, the order of
    ``np.einsum("ij,nj->ni", ...)``), else ``fine``; ``corrected = counts[i] - applied``.

    Parameters
    ----------
    et : ndarray, shape (n,)
        Sample times (ET s).
    fixed : ndarray of bool, shape (n,)
        Before ``model_start``: the offset uses ``fixed_temp`` (else the temperature).
    temp_et, temp_c : ndarray, shape (m,)
        Temperature stream (``m >= 2``, ``temp_et`` non-decreasing, no NaN) when
        ``interpolate``; unused otherwise.
    interpolate : bool
    margin : float
        How far (s) samples may lie outside the temperature stream (see Returns).
    model_start : float
        Start of the temperature-and-duty-cycle model (V10 ET).
    fixed_temp : float
        Temperature (degC) of the offset before ``model_start``.
    coefficients : ndarray, shape (3, 4)
        ``A0, B0, A1, B1`` per axis (Table 2).
    t_break : ndarray, shape (3,)
        ``T_m`` per axis (eq. 4).
    change_time : ndarray, shape (c,)
        Increasing duty-cycle change times (``-inf`` allowed), no NaN.
    target, state : ndarray, shape (c + 1, 3)
        ``c*_0`` and ``c_t0`` per change, row 0 zero (see `relaxed_offset_kernel`).
    tau, delay : float
        Relaxation time and heater delay (s, Table 3).
    heater : ndarray, shape (n, 3)
        Heater signal (fine-range counts, sec. 6); used when ``full``.
    range_flag : ndarray of int, shape (n,)
        Range per sample (1: coarse); used when ``full``.
    coarse : ndarray, shape (3, 3)
        ``M_coarse^-1 M_fine`` (fine counts -> coarse counts); used when ``full``.
    counts : ndarray, shape (n, 3)
        Raw counts; used when ``full``.
    full : bool
        Compute ``applied`` and ``corrected``.
    temperature : ndarray, shape (n,)
        Written (the interpolated temperature) when ``interpolate``, else read.
    offset : ndarray, shape (n, 3)
        Written: ``cT + Delta`` (fine-range counts).
    duty : ndarray, shape (n, 3)
        Written: ``Delta`` (fine-range counts, zero before ``model_start``).
    applied, corrected : ndarray, shape (n, 3)
        Written when ``full``.

    Returns
    -------
    bool
        ``et`` has no NaN and some sample lies outside ``[temp_et[0] - margin,
        temp_et[-1] + margin]`` (when ``interpolate``; what `interpolate_temperature` of
        `fluxcal.missions.messenger.levels` rejects through ``et.min()``/``et.max()``).
    """
    m = temp_et.size
    if interpolate:
        x_first = temp_et[0]
        x_last = temp_et[m - 1]
        f_first = temp_c[0]
        f_last = temp_c[m - 1]
        lo_limit = x_first - margin
        hi_limit = x_last + margin
    else:
        x_first = x_last = f_first = f_last = lo_limit = hi_limit = 0.0
    outside = False
    seen_nan = False
    hint_t = 0
    hint_c = 0
    c00 = coarse[0, 0]
    c01 = coarse[0, 1]
    c02 = coarse[0, 2]
    c10 = coarse[1, 0]
    c11 = coarse[1, 1]
    c12 = coarse[1, 2]
    c20 = coarse[2, 0]
    c21 = coarse[2, 1]
    c22 = coarse[2, 2]
    for i in range(et.size):
        t = et[i]
        # temperature: np.interp (compiled_base.c arr_interp, len(xp) >= 2)
        if interpolate:
            if t != t:
                seen_nan = True
                temp = t
            else:
                if t < lo_limit or t > hi_limit:
                    outside = True
                if t > x_last:
                    temp = f_last
                elif t < x_first:
                    temp = f_first
                else:
                    j = count_le(temp_et, t, hint_t)
                    hint_t = j
                    j -= 1
                    if j == m - 1 or temp_et[j] == t:
                        temp = temp_c[j]
                    else:
                        slope = (temp_c[j + 1] - temp_c[j]) / (temp_et[j + 1] - temp_et[j])
                        temp = slope * (t - temp_et[j]) + temp_c[j]
                        if temp != temp:
                            temp = slope * (t - temp_et[j + 1]) + temp_c[j + 1]
                            if temp != temp and temp_c[j] == temp_c[j + 1]:
                                temp = temp_c[j]
            temperature[i] = temp
        else:
            temp = temperature[i]
        # offset model: cT(T) + Delta(t), or cT(fixed) + 0 before the model start
        model = t >= model_start
        if not model and fixed[i]:
            temp = fixed_temp
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        if model:
            k = count_le(change_time, t, hint_c)
            hint_c = k
            decay = decay_kernel(change_time, k, t, delay, tau)
            g = target[k, 0]
            d0 = g - (g - state[k, 0]) * decay
            g = target[k, 1]
            d1 = g - (g - state[k, 1]) * decay
            g = target[k, 2]
            d2 = g - (g - state[k, 2]) * decay
        if temp <= t_break[0]:
            o0 = coefficients[0, 0] + coefficients[0, 1] * temp
        else:
            o0 = coefficients[0, 2] + coefficients[0, 3] * temp
        if temp <= t_break[1]:
            o1 = coefficients[1, 0] + coefficients[1, 1] * temp
        else:
            o1 = coefficients[1, 2] + coefficients[1, 3] * temp
        if temp <= t_break[2]:
            o2 = coefficients[2, 0] + coefficients[2, 1] * temp
        else:
            o2 = coefficients[2, 2] + coefficients[2, 3] * temp
        duty[i, 0] = d0
        duty[i, 1] = d1
        duty[i, 2] = d2
        o0 = o0 + d0
        o1 = o1 + d1
        o2 = o2 + d2
        offset[i, 0] = o0
        offset[i, 1] = o1
        offset[i, 2] = o2
        if not full:
            continue
        f0 = o0 + heater[i, 0]
        f1 = o1 + heater[i, 1]
        f2 = o2 + heater[i, 2]
        if range_flag[i] == 1:
            a0 = (c00 * f0 + c01 * f1) + c02 * f2
            a1 = (c10 * f0 + c11 * f1) + c12 * f2
            a2 = (c20 * f0 + c21 * f1) + c22 * f2
        else:
            a0 = f0
            a1 = f1
            a2 = f2
        applied[i, 0] = a0
        applied[i, 1] = a1
        applied[i, 2] = a2
        corrected[i, 0] = counts[i, 0] - a0
        corrected[i, 1] = counts[i, 1] - a1
        corrected[i, 2] = counts[i, 2] - a2
    return outside and not seen_nan


# ----------------------------------------------------------------------------------------
# sec. 8: counts -> nT
# ----------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------
# sec. 12: quality flags
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def quality_kernel(et, sun_y_sc, heater_applied, boom, v9, v10, out):
    """Three-digit SHC flag of Table 5 per sample (seed 000 sec. 7, 12).

    ``S``: 0 before boom deployment (``not et >= boom``, NaN included), else 1 when
    ``sun_y_sc > 0``, 2 otherwise.  ``H``: 2 from V10, 1 from V9, else 0.  ``C``: 1
    before boom deployment and, before V10, where ``S = 2``; else 2 where the heater
    signal was removed; else 0.  ``out[i] = 100 S + 10 H + C``.

    Parameters
    ----------
    et : ndarray, shape (n,)
    sun_y_sc : ndarray, shape (n,)
        Y component of the Sun direction in MSGR_SPACECRAFT (any stride).
    heater_applied : ndarray of bool, shape (n,)
    boom, v9, v10 : float
        ET of boom deployment, MAG FSW V9 and V10.
    out : ndarray of int, shape (n,)
        Written.
    """
    for i in range(et.size):
        t = et[i]
        after_v10 = t >= v10
        if not t >= boom:
            s = 0
        elif sun_y_sc[i] > 0:
            s = 1
        else:
            s = 2
        if after_v10:
            h = 2
        elif t >= v9:
            h = 1
        else:
            h = 0
        if s == 0 or (s == 2 and not after_v10):
            c = 1
        elif heater_applied[i]:
            c = 2
        else:
            c = 0
        out[i] = 100 * s + 10 * h + c
