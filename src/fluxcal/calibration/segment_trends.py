"""Segments of an interval and the line in time removed within each (variance estimators).

A variance estimator of offsets takes ``|B|`` as constant while the direction rotates.  A
slow compressive change of ``|B|`` inside an interval (a trend over tens of minutes) then
enters the fit as noise that the rotations of the same interval cannot average out.
Taking ``|B|`` constant only up to a straight line in time within short *segments* keeps
the fast rotations (the signal) and drops the slow changes (the noise).  For a change of
``|B|`` with an ``f^-2`` spectrum, the power left after a line per segment falls as the
segment's length squared; for rotations with an ``f^-5/3`` spectrum as the length to the
2/3 (docs/decisions/messenger_fit.md entry 17, docs/decisions/rosetta_fit.md entry 15).

Generic: arrays and labels in, arrays out; no mission.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["interval_products", "remove_segment_lines", "segment_codes", "segment_variance"]


def segment_codes(
    seconds: NDArray[np.float64], interval_codes: NDArray[np.intp], interval_start_s: NDArray,
    segment_s: float,
) -> tuple[NDArray[np.intp], int]:
    """Code of the segment of ``segment_s`` each sample is in, counted over all intervals.

    Parameters
    ----------
    seconds : ndarray, shape (n,)
        Time of each sample (s, any origin shared with ``interval_start_s``).
    interval_codes : ndarray of int, shape (n,)
        Interval of each sample, ``0..k-1``.
    interval_start_s : ndarray, shape (k,)
        Start of each interval (s).
    segment_s : float
        Segment length (s), > 0; an interval splits into ``ceil(interval / segment)``.

    Returns
    -------
    codes : ndarray of int, shape (n,)
        ``0..m-1``, in the order (interval, segment).
    m : int
        Number of segments holding samples.
    """
    if not segment_s > 0:
        raise ValueError(f"segment length must be positive, not {segment_s}")
    within = np.floor((np.asarray(seconds, dtype=float)
                       - np.asarray(interval_start_s, dtype=float)[interval_codes])
                      / float(segment_s)).astype(np.int64)
    per = int(within.max()) + 1 if within.size else 1
    _, codes = np.unique(np.asarray(interval_codes, dtype=np.int64) * per + within,
                         return_inverse=True)
    return codes, int(codes.max()) + 1 if codes.size else 0


def remove_segment_lines(
    values: NDArray[np.float64], codes: NDArray[np.intp], m: int,
    seconds: NDArray[np.float64], *, line: bool = True,
) -> NDArray[np.float64]:
    """Remove each segment's mean (and least-squares line in time) from every column.

    Parameters
    ----------
    values : ndarray, shape (n,) or (n, d)
    codes : ndarray of int, shape (n,)
        Segment of each sample, ``0..m-1``.
    m : int
    seconds : ndarray, shape (n,)
        Time of each sample (s).
    line : bool
        Remove the line too (else the mean only).

    Returns
    -------
    ndarray, the shape of ``values``
        The residuals: within each segment orthogonal to 1 (and to time).  A segment of
        one sample becomes 0.
    """
    v = np.asarray(values, dtype=float)
    flat = v.reshape(v.shape[0], -1)
    n_k = np.bincount(codes, minlength=m).astype(float)
    inv = np.where(n_k > 0, 1.0 / np.maximum(n_k, 1.0), 0.0)
    sums = np.stack([np.bincount(codes, flat[:, j], m) for j in range(flat.shape[1])], axis=1)
    out = flat - (sums * inv[:, None])[codes]
    if line:
        t = np.asarray(seconds, dtype=float)
        tc = t - (np.bincount(codes, t, m) * inv)[codes]
        tt = np.bincount(codes, tc * tc, m)
        tinv = np.where(tt > 0, 1.0 / np.where(tt > 0, tt, 1.0), 0.0)
        slope = np.stack([np.bincount(codes, tc * out[:, j], m) for j in range(out.shape[1])],
                         axis=1) * tinv[:, None]
        out = out - tc[:, None] * slope[codes]
    return out.reshape(v.shape)


def segment_variance(
    residual: NDArray[np.float64], interval_codes: NDArray[np.intp], k: int,
) -> NDArray[np.float64]:
    """Mean square of segment residuals (`remove_segment_lines`) per interval, (k,) or (k, d).

    The variance that is left within an interval once every segment's mean (and line) is
    removed; summed over the columns of a field it is the rotation power the segments
    keep (``trace C``), of ``|B|`` the compressive power they keep.
    """
    r = np.asarray(residual, dtype=float)
    n_k = np.bincount(interval_codes, minlength=k).astype(float)
    inv = np.where(n_k > 0, 1.0 / np.maximum(n_k, 1.0), np.nan)
    if r.ndim == 1:
        return np.bincount(interval_codes, r * r, k) * inv
    return np.stack([np.bincount(interval_codes, r[:, j] ** 2, k) for j in range(r.shape[1])],
                    axis=1) * inv[:, None]


def interval_products(
    residual: NDArray[np.float64], interval_codes: NDArray[np.intp], k: int,
) -> NDArray[np.float64]:
    """Mean products of segment residuals per interval, shape (k, d, d).

    The covariance of the columns within an interval once every segment's mean (and line)
    is removed (`remove_segment_lines`); its diagonal is `segment_variance`.
    """
    r = np.asarray(residual, dtype=float)
    n_k = np.bincount(interval_codes, minlength=k).astype(float)
    inv = np.where(n_k > 0, 1.0 / np.maximum(n_k, 1.0), np.nan)
    d = r.shape[1]
    out = np.empty((k, d, d))
    for i in range(d):  # columns, not samples
        for j in range(i, d):
            out[:, i, j] = out[:, j, i] = np.bincount(interval_codes, r[:, i] * r[:, j], k) * inv
    return out
