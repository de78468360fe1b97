"""Time averages over fixed n-second bins (boxcar, non-overlapping).

All samples whose time falls in ``[origin + k w, origin + (k+1) w)`` are summed and
divided by their number; the average carries the time of the middle of the bin; bins
without samples are omitted.  Vectorized with ``np.add.reduceat`` over runs of equal bin
index (one sort only if the input is not already in time order).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.6-4.8 (LEVEL_E, F, G).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bins:
    """Result of `bin_index`: sample order, run starts, bin numbers and centre times."""

    order: np.ndarray | None
    starts: np.ndarray
    counts: np.ndarray
    number: np.ndarray
    centre: np.ndarray


def bin_index(epoch: np.ndarray, width_ns: int, origin: int = 0) -> Bins:
    """Group int64 times into bins of ``width_ns`` starting at ``origin``.

    Parameters
    ----------
    epoch : array_like of int64, shape (n,)
        Sample times (TT2000 ns).
    width_ns : int
        Bin width in nanoseconds (> 0).
    origin : int
        A bin edge (TT2000 ns), e.g. the UTC midnight of the first day.

    Returns
    -------
    Bins
    """
    if int(width_ns) <= 0:
        raise ValueError(f"width_ns must be positive, not {width_ns}")
    epoch = np.asarray(epoch, dtype=np.int64)
    number = (epoch - np.int64(origin)) // np.int64(width_ns)
    order = None
    if number.size > 1 and np.any(number[1:] < number[:-1]):
        order = np.argsort(number, kind="stable")
        number = number[order]
    if number.size == 0:
        starts = np.zeros(0, dtype=np.int64)
    else:
        starts = np.concatenate([[0], np.flatnonzero(number[1:] != number[:-1]) + 1])
    counts = np.diff(np.append(starts, number.size))
    uniq = number[starts]
    centre = np.int64(origin) + uniq * np.int64(width_ns) + np.int64(width_ns) // 2
    return Bins(order, starts, counts, uniq, centre)


def bin_mean(bins: Bins, values: np.ndarray) -> np.ndarray:
    """Mean of ``values`` (shape ``(n, ...)``) in each bin of `bin_index`, shape ``(m, ...)``."""
    v = np.asarray(values)
    if bins.order is not None:
        v = v[bins.order]
    if bins.starts.size == 0:
        return np.zeros((0,) + v.shape[1:])
    sums = np.add.reduceat(v.astype(float), bins.starts, axis=0)
    return sums / bins.counts.reshape((-1,) + (1,) * (v.ndim - 1))


def bin_max(bins: Bins, values: np.ndarray) -> np.ndarray:
    """Maximum of ``values`` in each bin (for flags)."""
    v = np.asarray(values)
    if bins.order is not None:
        v = v[bins.order]
    if bins.starts.size == 0:
        return np.zeros((0,) + v.shape[1:], dtype=v.dtype)
    return np.maximum.reduceat(v, bins.starts, axis=0)


def boxcar_average(
    epoch: np.ndarray, values: np.ndarray, width_ns: int, origin: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Average ``values`` over bins of ``width_ns``; return ``(centre, mean, count)``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.array([0, 400, 1200, 3100], dtype=np.int64)
    >>> centre, mean, count = boxcar_average(t, np.array([1.0, 3.0, 5.0, 7.0]), 1000)
    >>> centre.tolist(), mean.tolist(), count.tolist()
    ([500, 1500, 3500], [2.0, 5.0, 7.0], [2, 1, 1])
    """
    bins = bin_index(epoch, width_ns, origin)
    return bins.centre, bin_mean(bins, values), bins.counts
