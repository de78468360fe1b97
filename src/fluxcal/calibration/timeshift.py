"""Mode-dependent time-stamp corrections (filter group delays).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.5.
"""

from __future__ import annotations

import numpy as np


def mode_shifts(
    mode: np.ndarray, table_modes: np.ndarray, table_shifts_s: np.ndarray
) -> np.ndarray:
    """Look up the shift (s) of each sample's mode in a table.

    Parameters
    ----------
    mode : array_like of int, shape (n,)
        Mode identifier per sample (e.g. the filter mode SID of seed 003).
    table_modes : array_like of int, shape (m,)
        Modes of the table.
    table_shifts_s : array_like of float, shape (m,)
        Shift of each mode; NaN where the table has no value.

    Returns
    -------
    ndarray of float, shape (n,)

    Raises
    ------
    KeyError
        Whose ``args[0]`` is the index of the first sample whose mode is not in the table
        (or has no value) and ``args[1]`` that mode.
    """
    modes = np.asarray(table_modes, dtype=np.int64)
    shifts = np.asarray(table_shifts_s, dtype=float)
    order = np.argsort(modes)
    modes, shifts = modes[order], shifts[order]
    mode = np.asarray(mode, dtype=np.int64)
    pos = np.clip(np.searchsorted(modes, mode), 0, max(len(modes) - 1, 0))
    ok = (
        (modes[pos] == mode) & np.isfinite(shifts[pos])
        if len(modes)
        else np.zeros(mode.shape, bool)
    )
    if not np.all(ok):
        first = int(np.flatnonzero(~ok)[0])
        raise KeyError(first, int(mode[first]))
    return shifts[pos]


def shift_epoch(epoch: np.ndarray, shift_s: np.ndarray) -> np.ndarray:
    """Add ``shift_s`` seconds to int64 ns times, rounding the shift to the nearest ns."""
    return np.asarray(epoch, dtype=np.int64) + np.rint(np.asarray(shift_s) * 1e9).astype(np.int64)
