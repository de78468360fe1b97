"""Offsets of a fluxgate from natural field fluctuations: shared machinery.

The ambient field seen by a fluxgate is ``B = B_meas - O``; the offset ``O`` can be
found without any reference instrument because natural fluctuations have known
geometry:

* **Alfvenic fluctuations** (solar wind) rotate the field at nearly constant
  magnitude, so the right ``O`` makes ``|B_meas - O|`` least variable within each
  interval (`fluxcal.calibration.variance_offsets`: Davis-Smith and Hedgecock-type).
* **Mirror modes** (compressive, linearly polarised) change ``|B|`` while the field
  direction stays fixed, so within an interval the measured vectors lie on a line
  through ``O`` (`fluxcal.calibration.mirror_mode_offsets`).

This module holds what the methods share: the result type `OffsetEstimate`, the
reduction of samples to per-interval moments (`field_moments`: one vectorised pass,
no loop per sample or per interval), their exact joining across chunks
(`concatenate_moments`, so Davis-Smith and mirror-mode offsets of a month run as a
map-reduce over days), the bookkeeping of rejected intervals and the bootstrap over
intervals.  The three entry points are importable from here as well
(``from fluxcal.calibration.solar_wind_offsets import davis_smith_offsets``).

Everything works in the units of the input (nT, or counts of a linear sensor).

References
----------
.. [1] Davis, L. Jr. and Smith, E. J., "The in-flight determination of spacecraft
   magnetic field zero levels", EOS Trans. AGU 49, 257 (1968).
.. [2] Belcher, J. W., "A variation of the Davis-Smith method for in-flight
   determination of spacecraft magnetic fields", J. Geophys. Res. 78, 6480 (1973).
.. [3] Hedgecock, P. C., "A correlation technique for magnetometer zero level
   determination", Space Sci. Instrum. 1, 83-90 (1975).
.. [4] Leinweber, H. K., Russell, C. T., Torkar, K., Zhang, T. L. and Angelopoulos,
   V., "An advanced approach to finding magnetometer zero levels in the
   interplanetary magnetic field", Meas. Sci. Technol. 19, 055104 (2008).
.. [5] Plaschke, F., "How many solar wind data are sufficient for accurate fluxgate
   magnetometer offset determinations?", Geosci. Instrum. Method. Data Syst. 8,
   285-291 (2019).
.. [6] Plaschke, F. and Narita, Y., "On determining fluxgate magnetometer spin axis
   offsets from mirror mode observations", Ann. Geophys. 34, 759-766 (2016).
.. [7] Schmid, D. et al., "Magnetometer in-flight offset accuracy for the
   BepiColombo spacecraft", Ann. Geophys. 38, 823-832 (2020).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fluxcal.errors import FluxcalError, InputFormatError

__all__ = [
    "IntervalMoments",
    "OffsetEstimate",
    "concatenate_moments",
    "field_moments",
    "interval_moments",
    "split_intervals",
]

#: A pooled 3x3 system with a larger condition number cannot fix all three offsets.
MAX_POOLED_CONDITION = 1e6


@dataclass(frozen=True)
class OffsetEstimate:
    """An offset vector determined from many intervals, with its uncertainty.

    Attributes
    ----------
    method : str
        ``"davis_smith"``, ``"hedgecock"`` or ``"mirror_mode"``.
    offset : ndarray, shape (3,)
        The offset ``O`` (units of the input); the field is ``B_meas - O``.
    standard_error : ndarray, shape (3,)
        Bootstrap standard error per component (``sqrt(diag(covariance))``); NaN when
        ``n_bootstrap == 0``.
    covariance : ndarray, shape (3, 3)
        Bootstrap covariance of the offset over intervals resampled with replacement.
    n_used, n_rejected : int
        Intervals used in the final estimate / rejected by a selection criterion.
    rejections : dict of str to int
        Number of rejected intervals per reason (the first criterion an interval fails,
        in the order the method documents).
    labels : ndarray, shape (k,)
        The interval labels (``interval_index`` values, or block numbers for
        ``interval_length``) of the intervals that hold at least one valid sample.
    accepted : ndarray of bool, shape (k,)
        Whether each interval entered the final estimate.
    reason : ndarray of str, shape (k,)
        Why each interval was rejected (``""`` if accepted).
    per_interval : ndarray, shape (k, 3)
        Per-interval estimate (what the method can say from that interval alone, see
        the method's Notes); NaN where the interval could not give one.
    n_bootstrap : int
        Bootstrap resamples that entered ``covariance``.
    iterations : int
        Selection passes (Davis-Smith, mirror mode) or Gauss-Newton steps (Hedgecock).
    criteria : dict
        The selection parameters used (for provenance).
    """

    method: str
    offset: NDArray[np.float64]
    covariance: NDArray[np.float64]
    labels: NDArray[np.int64]
    reason: NDArray[np.str_]
    per_interval: NDArray[np.float64]
    n_bootstrap: int
    iterations: int
    criteria: dict[str, Any] = field(default_factory=dict)

    @property
    def standard_error(self) -> NDArray[np.float64]:
        """Bootstrap standard error per component, ``sqrt(diag(covariance))``."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def accepted(self) -> NDArray[np.bool_]:
        """Whether each interval entered the final estimate (no rejection reason)."""
        return self.reason == ""

    @property
    def n_used(self) -> int:
        """Intervals used in the final estimate."""
        return int(np.count_nonzero(self.accepted))

    @property
    def n_rejected(self) -> int:
        """Intervals rejected by a selection criterion."""
        return int(self.reason.size - self.n_used)

    @property
    def rejections(self) -> dict[str, int]:
        """Number of rejected intervals per reason."""
        return count_reasons(self.reason)


@dataclass(frozen=True)
class IntervalMoments:
    """Per-interval sample count, mean and (population) covariance of a d-vector.

    Attributes
    ----------
    count : ndarray, shape (k,)
    mean : ndarray, shape (k, d)
    cov : ndarray, shape (k, d, d)
        ``<(x - <x>)(x - <x>)^T>`` over the interval (divided by the count).
    labels : ndarray of int64, shape (k,), optional
        Interval labels (see `split_intervals`).
    """

    count: NDArray[np.float64]
    mean: NDArray[np.float64]
    cov: NDArray[np.float64]
    labels: NDArray[np.int64] | None = None


def field_moments(
    b: ArrayLike,
    interval_index: ArrayLike | None = None,
    *,
    interval_length: int | None = None,
    squared: bool = False,
) -> IntervalMoments:
    """Reduce a field series to per-interval moments (the "map" step of a batch).

    Parameters
    ----------
    b, interval_index, interval_length
        As `split_intervals`.
    squared : bool
        Moments of ``(Bx, By, Bz, |B|^2)`` (what Davis-Smith needs) instead of
        ``(Bx, By, Bz)`` (mirror mode).

    Returns
    -------
    IntervalMoments
        With ``labels``.  Moments of separate chunks (e.g. days) join exactly with
        `concatenate_moments` when no interval spans two chunks (give each chunk its
        own labels).
    """
    bv, codes, labels = split_intervals(b, interval_index, interval_length)
    x = np.column_stack([bv, np.einsum("ij,ij->i", bv, bv)]) if squared else bv
    m = interval_moments(x, codes, labels.size)
    return IntervalMoments(count=m.count, mean=m.mean, cov=m.cov, labels=labels)


def concatenate_moments(parts: list[IntervalMoments]) -> IntervalMoments:
    """Join per-interval moments of several chunks (the "reduce" step).

    Raises
    ------
    InputFormatError
        Parts of different dimension, or a label that occurs in two parts.
    """
    if not parts or len({p.mean.shape[1] for p in parts}) != 1:
        raise InputFormatError("expected parts of one dimension", field="parts")
    labels = np.concatenate(
        [np.arange(p.count.size) if p.labels is None else p.labels for p in parts]
    )
    if np.unique(labels).size != labels.size:
        raise InputFormatError("an interval label occurs in more than one part", field="labels")
    return IntervalMoments(
        count=np.concatenate([p.count for p in parts]),
        mean=np.concatenate([p.mean for p in parts]),
        cov=np.concatenate([p.cov for p in parts]),
        labels=labels.astype(np.int64),
    )


def split_intervals(
    b: ArrayLike,
    interval_index: ArrayLike | None = None,
    interval_length: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.int64]]:
    """Drop gaps and label every remaining sample with its interval.

    Parameters
    ----------
    b : array_like, shape (n, 3)
        Measured field; a row with any non-finite component is a gap and is dropped.
    interval_index : array_like of int, shape (n,), optional
        Interval label of each sample (any integers, need not be sorted or
        contiguous); a negative label leaves the sample out.
    interval_length : int, optional
        Instead of ``interval_index``: consecutive blocks of this many samples
        (counted before dropping gaps, so a gap does not shift the blocks).

    Returns
    -------
    b_valid : ndarray, shape (m, 3)
    codes : ndarray of intp, shape (m,)
        ``0..k-1``, the position of each sample's interval in ``labels``.
    labels : ndarray of int64, shape (k,)
        Sorted labels of the intervals holding at least one valid sample.

    Raises
    ------
    InputFormatError
        Wrong shapes, both or neither of ``interval_index`` / ``interval_length``, or
        no valid sample.
    """
    arr = np.asarray(b, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputFormatError(f"expected shape (n, 3), got {arr.shape}", field="b")
    if (interval_index is None) == (interval_length is None):
        raise InputFormatError(
            "give exactly one of interval_index and interval_length", field="interval_index"
        )
    if interval_length is not None:
        if int(interval_length) != interval_length or interval_length < 2:
            raise InputFormatError(
                f"must be an integer >= 2, got {interval_length!r}", field="interval_length"
            )
        index = np.arange(arr.shape[0], dtype=np.int64) // int(interval_length)
    else:
        index = np.asarray(interval_index)
        if index.shape != (arr.shape[0],) or not np.issubdtype(index.dtype, np.integer):
            raise InputFormatError(
                f"expected integers of shape ({arr.shape[0]},), got {index.dtype} {index.shape}",
                field="interval_index",
            )
    keep = np.isfinite(arr).all(axis=1) & (index >= 0)
    if not keep.any():
        raise InputFormatError("no finite sample inside an interval", field="b")
    index = index[keep]
    if np.all(index[1:] >= index[:-1]):  # sorted labels (the usual case): no sort needed
        new = np.empty(index.size, dtype=bool)
        new[0] = True
        np.not_equal(index[1:], index[:-1], out=new[1:])
        labels, codes = index[new], np.cumsum(new) - 1
    else:
        labels, codes = np.unique(index, return_inverse=True)
    return arr[keep], codes.astype(np.intp), labels.astype(np.int64)


def interval_moments(x: NDArray[np.float64], codes: NDArray[np.intp], k: int) -> IntervalMoments:
    """Count, mean and covariance of ``x`` within each interval (two-pass, vectorised).

    The mean is removed before the products are summed (numerically stable for
    large offsets), and each sum is one `numpy.bincount` over all samples.

    Parameters
    ----------
    x : ndarray, shape (m, d)
    codes : ndarray of intp, shape (m,)
        Interval of each row, ``0..k-1``.
    k : int
        Number of intervals.
    """
    count = np.bincount(codes, minlength=k).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = np.where(count > 0, 1.0 / count, np.nan)
    d = x.shape[1]
    mean = np.stack([np.bincount(codes, x[:, j], k) for j in range(d)], axis=1) * inv[:, None]
    centred = x - mean[codes]
    cov = np.empty((k, d, d))
    for i in range(d):
        for j in range(i, d):
            cov[:, i, j] = cov[:, j, i] = np.bincount(codes, centred[:, i] * centred[:, j], k) * inv
    return IntervalMoments(count=count, mean=mean, cov=cov)


def eigenvalue_ratio(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return ``lambda_min / lambda_max`` of each covariance (0 for a zero matrix)."""
    w = np.linalg.eigvalsh(cov)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(w[:, 2] > 0, w[:, 0] / w[:, 2], 0.0)
    return ratio


def first_failure(checks: list[tuple[str, NDArray[np.bool_]]], k: int) -> NDArray[np.str_]:
    """Return, per interval, the name of the first failed check (``""`` if none).

    NaN comparisons are ``False``, so an undefined quantity fails its check.
    """
    reason = np.full(k, "", dtype="<U24")
    for name, ok in reversed(checks):
        reason[~ok] = name
    return reason


def count_reasons(reason: NDArray[np.str_]) -> dict[str, int]:
    """Return ``{reason: count}`` over the rejected intervals."""
    names, counts = np.unique(reason[reason != ""], return_counts=True)
    return {str(n): int(c) for n, c in zip(names, counts, strict=True)}


def solve_pooled(
    matrix: NDArray[np.float64], vector: NDArray[np.float64], method: str, reason: NDArray[np.str_]
) -> NDArray[np.float64]:
    """Solve the pooled 3x3 system, refusing one that cannot fix all three offsets.

    Raises
    ------
    FluxcalError
        No accepted interval, or condition number above `MAX_POOLED_CONDITION`; the
        message counts the rejection reasons.
    """
    n_used = int(np.count_nonzero(reason == ""))
    cond = np.linalg.cond(matrix) if n_used else np.inf
    if not np.isfinite(cond) or cond > MAX_POOLED_CONDITION:
        raise FluxcalError(
            f"{method}: {n_used} accepted intervals do not determine all three offset "
            f"components (condition number {cond:.3g}); rejected: {count_reasons(reason)}"
        )
    return np.linalg.solve(matrix, vector)


def settle_selection(
    checks: Callable[[NDArray[np.float64]], NDArray[np.str_]],
    solve: Callable[[NDArray[np.str_]], NDArray[np.float64]],
    offset: NDArray[np.float64],
    max_passes: int,
    method: str,
) -> tuple[NDArray[np.float64], NDArray[np.str_], int]:
    """Select the intervals at ``offset``, solve, repeat until the selection repeats.

    Returns the offset, the per-interval rejection reasons of the last selection and
    the number of passes.

    Raises
    ------
    FluxcalError
        The selection does not settle within ``max_passes``.
    """
    previous = None
    for passes in range(1, max_passes + 1):
        reason = checks(offset)
        offset = solve(reason)
        if previous is not None and np.array_equal(reason, previous):
            return offset, reason, passes
        previous = reason
    raise FluxcalError(
        f"{method}: the interval selection did not settle in {max_passes} passes"
    )


def bootstrap_covariance(
    matrices: NDArray[np.float64],
    vectors: NDArray[np.float64],
    n_bootstrap: int,
    seed: int | np.random.Generator | None,
    method: str,
) -> tuple[NDArray[np.float64], int]:
    """Covariance of ``(sum_k A_k)^-1 sum_k r_k`` when intervals are resampled.

    Each resample draws the accepted intervals with replacement (counts per interval),
    so the pooled system of a resample is a weighted sum of the per-interval systems:
    all resamples are solved at once.  Resamples whose system is singular (condition
    number above `MAX_POOLED_CONDITION`) are left out and not counted.

    Parameters
    ----------
    matrices : ndarray, shape (k, 3, 3)
    vectors : ndarray, shape (k, 3)
    n_bootstrap : int
        Number of resamples; 0 returns a NaN covariance.
    seed : int, Generator or None
        Seed of `numpy.random.default_rng`.
    method : str
        Method name for error messages.

    Returns
    -------
    covariance : ndarray, shape (3, 3)
    n_ok : int
        Resamples used.
    """
    if n_bootstrap == 0:
        return np.full((3, 3), np.nan), 0
    if n_bootstrap < 0 or int(n_bootstrap) != n_bootstrap:
        raise InputFormatError(f"must be an integer >= 0, got {n_bootstrap!r}", field="n_bootstrap")
    k = matrices.shape[0]
    if k < 2:
        raise FluxcalError(
            f"{method}: the bootstrap needs at least 2 accepted intervals, got {k} "
            "(pass n_bootstrap=0 for no uncertainty)"
        )
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, k, size=(int(n_bootstrap), k))  # k intervals per resample
    rows = np.arange(int(n_bootstrap))[:, None] * k
    weights = np.bincount((rows + draws).ravel(), minlength=draws.size)
    weights = weights.reshape(draws.shape).astype(float)  # times each interval is drawn
    a = np.einsum("bk,kij->bij", weights, matrices)
    r = weights @ vectors
    ok = np.linalg.cond(a) < MAX_POOLED_CONDITION
    if ok.sum() < 2:
        raise FluxcalError(f"{method}: fewer than 2 bootstrap resamples are solvable")
    solutions = np.linalg.solve(a[ok], r[ok][:, :, None])[:, :, 0]
    return np.cov(solutions, rowvar=False), int(ok.sum())


def check_offset_guess(offset_guess: ArrayLike | None) -> NDArray[np.float64]:
    """Return the starting offset as a (3,) float array (zeros if None)."""
    if offset_guess is None:
        return np.zeros(3)
    guess = np.asarray(offset_guess, dtype=float)
    if guess.shape != (3,) or not np.isfinite(guess).all():
        raise InputFormatError(f"expected 3 finite values, got {guess!r}", field="offset_guess")
    return guess


def __getattr__(name: str) -> Any:
    """Give the entry points from here as well (PEP 562, no import cycle)."""
    modules = {
        "davis_smith_offsets": "variance_offsets",
        "davis_smith_offsets_from_moments": "variance_offsets",
        "hedgecock_offsets": "variance_offsets",
        "mirror_mode_offsets": "mirror_mode_offsets",
        "mirror_mode_offsets_from_moments": "mirror_mode_offsets",
    }
    if name in modules:
        module = importlib.import_module(f"fluxcal.calibration.{modules[name]}")
        return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
