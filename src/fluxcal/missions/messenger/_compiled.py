"""Compiled per-sample loops of MESSENGER-specific steps (numba).

`clock_kernel` fuses the sec. 5 lag lookup with both sec. 9 clock conversions of
`fluxcal.missions.messenger.levels.correct_time` (the lag-corrected MET to ET and
TT2000, the recorded MET to ET); `quality_kernel` computes the Table 5 flags of
`fluxcal.missions.messenger.levels.quality_flags`.  Both repeat the operations of the
numpy code they replace, in the same order (IEEE double precision, no ``fastmath``),
so the results are bit-identical; the numpy versions stay beside the callers as the
references the tests compare with.

`clock_kernel` inlines helpers of other modules (`fluxcal.calibration._compiled.count_le`,
`fluxcal.geometry.time._tdb_minus_tt_taylor`) and repeats the per-reading arithmetic of
``fluxcal.geometry.time._sclk_kernel``.  numba's on-disk cache checks only this file
(numba issue #1833): after editing those helpers, delete this module's cache
(``__pycache__/_compiled.*.nbi``, ``*.nbc``) or touch this file.
``tests/missions/messenger/test_compiled_levels.py`` compares `correct_time` with the
`fluxcal.geometry.time.SclkKernel` conversions bit for bit, so a change of
``_sclk_kernel``'s arithmetic that this kernel does not follow fails there.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 5 (Table 1), sec. 9,
       sec. 12 (Table 5).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from fluxcal.calibration._compiled import count_le
from fluxcal.geometry.time import _NS, _tdb_minus_tt_taylor


# ----------------------------------------------------------------------------------------
# sec. 5, 9: net lag, MET -> ET and TT2000 (corrected), MET -> ET (recorded)
# ----------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def clock_kernel(
    partition, met, rate_setting, lags, n_part, ticks_per_count, part_start, part_end,
    part_offsets, ticks, parallel, rate, tt_clock, k, eb, m0, m1,
    lag, met_corrected, et, tt2000, et_recorded,
):
    """Net lag, corrected MET, its ET and TT2000, and the ET of the recorded MET.

    Per sample, ``lag = lags[rate_setting]`` (sec. 5, Table 1, as
    `fluxcal.calibration.rate_latency.per_sample_lag`), ``met_corrected = met - lag``,
    then for the corrected and for the recorded reading the type 1 SCLK arithmetic of
    `fluxcal.geometry.time.SclkKernel.to_et_and_tt2000` and `~.SclkKernel.to_et`
    (``_sclk_kernel``: encode, parallel time, TDB - TT from the same cubic expansion
    `fluxcal.geometry.time._tdb_minus_tt_taylor`, TT2000 split into whole seconds and
    rounded nanoseconds), operation by operation.  The two readings keep their own
    interval hint and TDB - TT cache (results depend on the reading alone).

    Parameters
    ----------
    partition, met : ndarray, shape (n,)
        Clock readings (partition number, seconds of the most significant field).
    rate_setting : ndarray of int, shape (n,)
        Index into ``lags``.
    lags : ndarray, shape (r,)
        Net lag per rate setting (s, Table 1).
    n_part : float
        Number of partitions.
    ticks_per_count : float
    part_start, part_end, part_offsets : ndarray
        Partition limits (ticks) and encoded ticks at each partition start.
    ticks, parallel, rate : ndarray
        SCLK01 coefficient triplets.
    tt_clock : bool
        Parallel time is TT (TDT); else TDB.
    k, eb, m0, m1 : float
        DELTET constants of the leapseconds kernel.
    lag, met_corrected, et, et_recorded : ndarray, shape (n,)
        Written.
    tt2000 : ndarray of int64, shape (n,)
        Written.

    Returns
    -------
    int
        -1, or the index of the first sample with a rate setting outside ``lags``, an
        unknown partition or a reading (corrected or recorded) outside its partition,
        NaN included (the loop stops; the caller runs the numpy code, which raises or
        decides).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 5 Table 1, sec. 9.
    .. [2] NAIF, "SCLK Required Reading" (type 1), "Time Required Reading" (TDT-TDB).
    """
    last = ticks.size - 1
    n_lags = lags.size
    hint = 0
    hint_rec = 0
    cache = np.full(5, np.nan)  # node index and Taylor coefficients of TDB - TT
    cache_rec = np.full(5, np.nan)
    for i in range(met.size):
        r = rate_setting[i]
        if r < 0 or r >= n_lags:
            return i
        pv = partition[i]
        if not (pv >= 1 and pv <= n_part):
            return i
        p = int(pv) - 1
        start = part_start[p]
        end = part_end[p]
        recorded = met[i]
        dt_lag = lags[r]
        seconds = recorded - dt_lag
        lag[i] = dt_lag
        met_corrected[i] = seconds
        # corrected reading: ET and TT2000
        reading = seconds * ticks_per_count
        if not (reading >= start and reading <= end):
            return i
        encoded = part_offsets[p] + (reading - start)
        c = count_le(ticks, encoded, hint)
        hint = c
        j = min(max(c - 1, 0), last)
        par = parallel[j] + (encoded - ticks[j]) * (rate[j] / ticks_per_count)
        if tt_clock:
            et[i] = par + _tdb_minus_tt_taylor(par, k, eb, m0, m1, cache)
            tt = par
        else:
            et[i] = par
            inner = par - _tdb_minus_tt_taylor(par, k, eb, m0, m1, cache)
            tt = par - _tdb_minus_tt_taylor(inner, k, eb, m0, m1, cache)
        whole = np.floor(tt)
        tt2000[i] = np.int64(whole) * _NS + np.int64(np.rint((tt - whole) * 1e9))
        # recorded reading: ET only
        reading = recorded * ticks_per_count
        if not (reading >= start and reading <= end):
            return i
        encoded = part_offsets[p] + (reading - start)
        c = count_le(ticks, encoded, hint_rec)
        hint_rec = c
        j = min(max(c - 1, 0), last)
        par = parallel[j] + (encoded - ticks[j]) * (rate[j] / ticks_per_count)
        if tt_clock:
            et_recorded[i] = par + _tdb_minus_tt_taylor(par, k, eb, m0, m1, cache_rec)
        else:
            et_recorded[i] = par
    return -1


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
