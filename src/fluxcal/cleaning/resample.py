"""Put two sensors' series on a common time base by gap-aware linear interpolation.

Two magnetometers sampled by different clocks (or with different tag conventions)
rarely share their time tags.  Before a two-sensor comparison (`two_sensor_pca`)
both series are brought onto one time base:

* the **common time base** lies inside the overlap of the two series; by default it
  is the primary sensor's own tags there (no interpolation of the primary), or a
  regular grid of a given step starting at the overlap start;
* each sensor is **linearly interpolated** onto it (`numpy.interp`, per component,
  vectorized); a base time that coincides with a sensor's own tag takes that sample
  unchanged, so identical tags reproduce the input exactly;
* no value is interpolated **across a data gap**: a base time strictly between two
  consecutive samples of a sensor that are more than ``max_gap`` apart is dropped
  (and counted).

Times are int64 nanoseconds (e.g. TT2000).  Interpolation runs on float seconds
relative to a reference epoch, obtained from **int64 differences** (exact for spans
below 2**53 ns, 104 days), never on float64 nanoseconds, which at TT2000 values near
5e17 ns resolve only 64 ns.

Linear interpolation is a low-pass filter: a tone of frequency f sampled every h and
interpolated at the fraction u of an interval keeps the amplitude
``|(1 - u) + u exp(2 pi i f h)|`` (``cos(pi f h)`` at u = 1/2), and white noise keeps the
variance fraction ``(1 - u)**2 + u**2`` (1/2 at u = 1/2).  Signals well below the
Nyquist frequency pass almost unchanged; broadband noise of the interpolated sensor
does not.

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1),
   sec. 4.11 (LEVEL_J: PCA of the OB and IB sensors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fluxcal.errors import InputFormatError

__all__ = [
    "TwoSensorResample",
    "common_time_base",
    "interpolate_linear",
    "resample_two_sensors",
    "sample_interval",
]


def _times(t: ArrayLike, name: str) -> NDArray[np.int64]:
    arr = np.asarray(t)
    if arr.ndim != 1:
        raise InputFormatError(f"expected a 1-D array of times, got shape {arr.shape}", field=name)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InputFormatError(
            f"expected int64 nanoseconds (e.g. TT2000), got dtype {arr.dtype}", field=name
        )
    arr = arr.astype(np.int64, copy=False)
    if arr.size > 1 and np.any(np.diff(arr) <= 0):
        k = int(np.flatnonzero(np.diff(arr) <= 0)[0])
        raise InputFormatError(
            f"times must increase strictly; sample {k + 1} ({arr[k + 1]} ns) follows {arr[k]} ns",
            field=name,
        )
    return arr


def sample_interval(t: ArrayLike) -> int:
    """Median spacing (ns) of strictly increasing int64 times (0 for fewer than 2).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.11.
    """
    arr = _times(t, "t")
    if arr.size < 2:
        return 0
    return int(np.median(np.diff(arr)))


def common_time_base(
    t_primary: ArrayLike, t_secondary: ArrayLike, *, step_ns: int | None = None
) -> NDArray[np.int64]:
    """Build the common time base of two series, inside their overlap.

    Parameters
    ----------
    t_primary, t_secondary : array_like of int64
        Strictly increasing time tags (ns) of the two sensors.
    step_ns : int, optional
        Without it, the primary's own tags inside the overlap; with it, the regular
        grid ``start + k * step_ns`` (k = 0, 1, ...) up to the overlap end, where
        ``start`` is the overlap start.

    Returns
    -------
    ndarray of int64
        The base times (empty when the series do not overlap).

    Raises
    ------
    InputFormatError
        If the times are not strictly increasing integers or ``step_ns <= 0``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.11.
    """
    ta = _times(t_primary, "t_primary")
    tb = _times(t_secondary, "t_secondary")
    if ta.size == 0 or tb.size == 0:
        return np.empty(0, np.int64)
    start, stop = max(int(ta[0]), int(tb[0])), min(int(ta[-1]), int(tb[-1]))
    if stop < start:
        return np.empty(0, np.int64)
    if step_ns is None:
        return ta[(ta >= start) & (ta <= stop)]
    step = int(step_ns)
    if step <= 0:
        raise InputFormatError(f"must be > 0 ns, got {step_ns}", field="step_ns")
    return start + np.arange((stop - start) // step + 1, dtype=np.int64) * step


def interpolate_linear(
    times: ArrayLike,
    values: ArrayLike,
    targets: ArrayLike,
    *,
    max_gap_ns: int | None = None,
    reference: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """Linearly interpolate samples onto target times without bridging long gaps.

    Parameters
    ----------
    times : array_like of int64, shape (n,)
        Strictly increasing sample times (ns).
    values : array_like, shape (n,) or (n, k)
        Samples; each column is interpolated with `numpy.interp`.
    targets : array_like of int64, shape (m,)
        Target times (ns), in any order.
    max_gap_ns : int, optional
        A target strictly between two samples more than this apart is invalid
        (default: no limit).
    reference : int, optional
        Reference epoch (ns) of the float seconds used internally (default: the
        first target); only int64 differences are converted to float.

    Returns
    -------
    out : ndarray, shape (m,) or (m, k)
        Interpolated values; NaN where not valid.
    valid : ndarray of bool, shape (m,)
        Inside the samples' span and not inside a gap longer than ``max_gap_ns``.
    on_sample : ndarray of bool, shape (m,)
        The target coincides with a sample time (its value is that sample's, exactly).

    Raises
    ------
    InputFormatError
        If times are not strictly increasing integers or the shapes disagree.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.11.
    """
    t = _times(times, "times")
    tq = np.asarray(targets)
    if tq.ndim != 1 or (tq.size and not np.issubdtype(tq.dtype, np.integer)):
        raise InputFormatError(
            f"expected 1-D int64 nanoseconds, got shape {tq.shape}, dtype {tq.dtype}",
            field="targets",
        )
    tq = tq.astype(np.int64, copy=False)
    v = np.asarray(values, dtype=float)
    if v.shape[:1] != t.shape:
        raise InputFormatError(
            f"values have {v.shape[0] if v.ndim else 0} samples, times {t.size}", field="values"
        )
    cols = v.reshape(t.size, -1)
    m = tq.size
    out = np.full((m, cols.shape[1]), np.nan)
    if t.size == 0 or m == 0:
        return out.reshape((m,) + v.shape[1:]), np.zeros(m, bool), np.zeros(m, bool)
    ref = int(tq[0]) if reference is None else int(reference)
    # int64 differences first, then float seconds: exact for |t - ref| < 2**53 ns
    x = (t - ref).astype(np.float64) / 1e9
    xq = (tq - ref).astype(np.float64) / 1e9
    left = np.searchsorted(t, tq, side="right") - 1  # t[left] <= tq < t[left + 1]
    inside = (tq >= t[0]) & (tq <= t[-1])
    lc = np.clip(left, 0, t.size - 1)
    on_sample = inside & (t[lc] == tq)
    valid = inside.copy()
    if max_gap_ns is not None and t.size > 1:
        gap = np.diff(t) > int(max_gap_ns)  # gap[j]: between samples j and j + 1
        between = inside & ~on_sample
        valid[between] = ~gap[np.clip(left[between], 0, t.size - 2)]
    for c in range(cols.shape[1]):  # per component; vectorized over samples
        out[valid, c] = np.interp(xq[valid], x, cols[:, c])
    # a target on a sample takes it unchanged (np.interp already does; made explicit)
    out[on_sample] = cols[lc[on_sample]]
    return out.reshape((m,) + v.shape[1:]), valid, on_sample


@dataclass(frozen=True)
class TwoSensorResample:
    """Output of `resample_two_sensors` (primary sensor ``a`` first, then ``b``).

    Attributes
    ----------
    times : ndarray of int64, shape (m,)
        The kept common time base (ns).
    a, b : ndarray, shape (m, k)
        Each sensor on ``times``.
    primary_index : ndarray of int64, shape (m,)
        Index of each kept time in the primary's tags, or -1 where it is not one of
        them (regular grid).
    base_size : int
        Number of base times before dropping.
    dropped_in_gaps : tuple of int
        Per sensor, base times dropped because they fall inside that sensor's gap
        (a time inside gaps of both is counted for both).
    dropped : int
        Base times dropped in all (``base_size - times.size``).
    interpolated : tuple of int
        Per sensor, kept times not on one of its own tags (actually interpolated).
    max_gap_ns : tuple of int
        Per sensor, the longest spacing bridged by interpolation.
    sample_interval_ns : tuple of int
        Per sensor, the median spacing of its tags.
    reference : int
        Reference epoch (ns) of the internal float seconds (first base time).
    """

    times: NDArray[np.int64]
    a: NDArray[np.float64]
    b: NDArray[np.float64]
    primary_index: NDArray[np.int64]
    base_size: int
    dropped_in_gaps: tuple[int, int]
    dropped: int
    interpolated: tuple[int, int]
    max_gap_ns: tuple[int, int]
    sample_interval_ns: tuple[int, int]
    reference: int


def resample_two_sensors(
    t_a: ArrayLike,
    a: ArrayLike,
    t_b: ArrayLike,
    b: ArrayLike,
    *,
    step_ns: int | None = None,
    max_gap_samples: float = 2.0,
    max_gap_ns: int | None = None,
) -> TwoSensorResample:
    """Put two sensors on a common time base (overlap; primary tags or a grid).

    Parameters
    ----------
    t_a, t_b : array_like of int64
        Strictly increasing time tags (ns) of the primary ``a`` and secondary ``b``.
    a, b : array_like, shape (n_a, k), (n_b, k)
        The sensors' samples (e.g. field vectors).
    step_ns : int, optional
        Regular grid step of the base (default: the primary's tags, see
        `common_time_base`).
    max_gap_samples : float
        Longest spacing bridged by interpolation, in units of each sensor's own median
        sample interval (default 2: one missing sample is bridged, two are not).
    max_gap_ns : int, optional
        Longest spacing bridged, in ns, for both sensors (overrides
        ``max_gap_samples``).

    Returns
    -------
    TwoSensorResample

    Raises
    ------
    InputFormatError
        If the times are not strictly increasing integers, shapes disagree, or
        ``max_gap_samples`` is negative.

    Notes
    -----
    Base times inside a gap of either sensor are dropped from both. With identical
    tags (and no ``step_ns``) the output is the input, sample for sample.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.11.
    """
    ta = _times(t_a, "t_a")
    tb = _times(t_b, "t_b")
    va = np.asarray(a, dtype=float)
    vb = np.asarray(b, dtype=float)
    for name, v, t in (("a", va, ta), ("b", vb, tb)):
        if v.ndim != 2 or v.shape[0] != t.size:
            raise InputFormatError(f"expected ({t.size}, k), got {v.shape}", field=name)
    if va.shape[1] != vb.shape[1]:
        raise InputFormatError(
            f"sensors have {va.shape[1]} and {vb.shape[1]} components", field="b"
        )
    if not max_gap_samples >= 0:
        raise InputFormatError(f"must be >= 0, got {max_gap_samples}", field="max_gap_samples")
    dts = (sample_interval(ta), sample_interval(tb))
    if max_gap_ns is not None:
        gaps = (int(max_gap_ns), int(max_gap_ns))
    else:
        gaps = (int(round(max_gap_samples * dts[0])), int(round(max_gap_samples * dts[1])))
    base = common_time_base(ta, tb, step_ns=step_ns)
    ref = int(base[0]) if base.size else 0
    ra, ok_a, on_a = interpolate_linear(ta, va, base, max_gap_ns=gaps[0], reference=ref)
    rb, ok_b, on_b = interpolate_linear(tb, vb, base, max_gap_ns=gaps[1], reference=ref)
    keep = ok_a & ok_b
    if step_ns is None:
        primary_index = np.searchsorted(ta, base)
    else:
        primary_index = np.where(on_a, np.searchsorted(ta, base), -1)
    return TwoSensorResample(
        times=base[keep],
        a=ra[keep],
        b=rb[keep],
        primary_index=primary_index[keep].astype(np.int64),
        base_size=int(base.size),
        dropped_in_gaps=(int(np.count_nonzero(~ok_a)), int(np.count_nonzero(~ok_b))),
        dropped=int(np.count_nonzero(~keep)),
        interpolated=(
            int(np.count_nonzero(keep & ~on_a)),
            int(np.count_nonzero(keep & ~on_b)),
        ),
        max_gap_ns=gaps,
        sample_interval_ns=dts,
        reference=ref,
    )
