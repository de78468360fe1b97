"""Compiled per-sample loop of the MESSENGER quality flags (numba).

`quality_kernel` computes the Table 5 flags of
`fluxcal.missions.messenger.levels.quality_flags` with the operations of the numpy code
it replaces, in the same order (no ``fastmath``), so the results are bit-identical;
`quality_flags_reference` stays beside the caller as the reference the tests compare with.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 12 (Table 5).
"""

from __future__ import annotations

from numba import njit


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
