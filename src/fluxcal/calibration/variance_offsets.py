"""Offsets that make ``|B|`` least variable under Alfvenic fluctuations.

Two estimators over many intervals, both with the same interval selection:

* `davis_smith_offsets`: the linear least-squares form.  Within an interval of
  constant ``|B|``, ``|B_meas - O|^2 = const`` gives, for the fluctuations about the
  interval means, ``delta(|B_meas|^2) = 2 delta(B_meas) . O``; least squares over all
  samples of all accepted intervals leads to the 3x3 system
  ``sum_k n_k C_k (2 O) = sum_k n_k c_k`` with ``C_k`` the covariance matrix of
  ``B_meas`` and ``c_k`` the covariance of ``B_meas`` with ``|B_meas|^2`` in
  interval ``k`` [1]_, [4]_.
* `hedgecock_offsets`: minimises the variance of ``|B_meas - O|`` itself (not of its
  square) summed over the intervals, by Gauss-Newton steps: the step solves
  ``sum_k n_k Cov_k(u, u) dO = sum_k n_k Cov_k(u, |B'|)`` with ``u`` the unit vector
  of ``B' = B_meas - O``, i.e. it correlates the magnitude changes with the
  direction-cosine changes [3]_, as Belcher's variant does for the magnitude [2]_;
  the selection is re-evaluated on the corrected field at every step.

Selection criteria (each a parameter; an interval is rejected for the first one it
fails, in this order; see ``docs/decisions/solar_wind_offsets.md``):

1. ``too_few_samples``: fewer than ``min_samples`` valid samples.
2. ``ill_conditioned``: ``lambda_min / lambda_max`` of the interval's covariance
   matrix below ``min_eigenvalue_ratio`` -- the fluctuations do not sample all three
   directions, so the interval's own 3x3 system is singular (one-directional or
   planar fluctuations) [4]_.
3. ``small_fluctuations``: rms vector fluctuation ``sqrt(trace C)`` below
   ``min_relative_amplitude`` times ``|B - O|``: the offset leverage scales with
   ``dB / |B|`` [4]_, [5]_.
4. ``compressive``: compressibility ``var(|B - O|) / trace C`` above
   ``max_compressibility``: not a rotation at constant magnitude [4]_, [5]_.

Criteria 3 and 4 depend on the offset: they are evaluated at the current estimate,
and the selection is repeated until it no longer changes.  Without ``offset_guess``
the Davis-Smith start is a consensus: of the intervals' own 3x3 solutions (at most
`MAX_START_CANDIDATES`), the one under which most intervals pass criterion 4.  (A
pooled start would be dragged by strong compressive intervals far enough to turn
the selection against the Alfvenic ones.)  The Hedgecock iteration starts from
the Davis-Smith estimate.

References
----------
.. [1] Davis, L. Jr. and Smith, E. J., EOS Trans. AGU 49, 257 (1968).
.. [2] Belcher, J. W., J. Geophys. Res. 78, 6480 (1973).
.. [3] Hedgecock, P. C., Space Sci. Instrum. 1, 83-90 (1975).
.. [4] Leinweber, H. K. et al., Meas. Sci. Technol. 19, 055104 (2008): the
   Davis-Smith method as a correlation technique; selection of pure rotations.
.. [5] Plaschke, F., Geosci. Instrum. Method. Data Syst. 8, 285-291 (2019):
   accuracy versus amount of solar-wind data (0.2 nT from ~40 h of real data).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fluxcal.calibration.segment_trends import (
    interval_products,
    remove_segment_lines,
    segment_codes,
    segment_variance,
)
from fluxcal.calibration.solar_wind_offsets import (
    IntervalMoments,
    OffsetEstimate,
    bootstrap_covariance,
    check_offset_guess,
    eigenvalue_ratio,
    field_moments,
    first_failure,
    interval_moments,
    settle_selection,
    solve_pooled,
    split_intervals,
)
from fluxcal.errors import FluxcalError, InputFormatError

__all__ = ["davis_smith_offsets", "davis_smith_offsets_from_moments", "hedgecock_offsets",
           "interval_reasons"]

DEFAULT_MIN_SAMPLES = 60
DEFAULT_MIN_EIGENVALUE_RATIO = 1e-3
DEFAULT_MIN_RELATIVE_AMPLITUDE = 0.05
DEFAULT_MAX_COMPRESSIBILITY = 0.1
#: At most this many interval solutions are tried as the Davis-Smith start.
MAX_START_CANDIDATES = 500


def _segments_of(b, interval_index, seconds, segment_s, codes, k):
    """``(segment codes, count, seconds)`` of the valid samples, or ``None`` without segments."""
    if seconds is None or segment_s is None:
        return None
    keep = np.isfinite(np.asarray(b, dtype=float)).all(axis=1)
    if interval_index is not None:
        keep &= np.asarray(interval_index) >= 0
    t = np.asarray(seconds, dtype=float)
    if t.shape != keep.shape:
        raise InputFormatError(f"seconds has shape {t.shape}, expected {keep.shape}",
                               field="seconds")
    t = t[keep]
    start = np.full(k, np.inf)
    np.minimum.at(start, codes, t)
    seg, m = segment_codes(t, codes, start, float(segment_s))
    return seg, m, t


def _static_checks(count, cov, min_samples, min_eigenvalue_ratio):
    return [
        ("too_few_samples", count >= min_samples),
        ("ill_conditioned", eigenvalue_ratio(cov) >= min_eigenvalue_ratio),
    ]


def interval_reasons(
    b: NDArray[np.float64],
    codes: NDArray[np.intp],
    k: int,
    *,
    min_samples: float,
    min_eigenvalue_ratio: float,
    min_relative_amplitude: float,
    max_compressibility: float,
    static_only: bool = False,
    compressibility: NDArray[np.float64] | None = None,
) -> NDArray[np.str_]:
    """First failed selection criterion of each interval (``""``: accepted), on ``b``.

    The four named criteria of this module, in order: ``too_few_samples``,
    ``ill_conditioned`` (smallest/largest eigenvalue of the field's covariance),
    ``small_fluctuations`` (``sqrt(trace C) / <|B|>``) and ``compressive``
    (``var |B| / trace C``), evaluated on the vectors ``b`` (n, 3) as they are (offsets
    already removed); ``static_only``: the first two only (those that do not depend on
    the offsets). ``codes`` maps each sample to its interval ``0..k-1``.
    ``compressibility`` (k,), optional, replaces ``var |B| / trace C`` in the
    ``compressive`` criterion (e.g. the ratio of the powers left within short segments,
    `fluxcal.calibration.segment_trends`).
    """
    mag = np.sqrt(np.einsum("ij,ij->i", b, b))
    mom = interval_moments(np.column_stack([b, mag]), codes, k)
    cov = mom.cov[:, :3, :3]
    with np.errstate(invalid="ignore", divide="ignore"):  # empty or flat intervals
        checks = _static_checks(mom.count, cov, min_samples, min_eigenvalue_ratio)
        if not static_only:
            trace = np.trace(cov, axis1=1, axis2=2)
            ratio = mom.cov[:, 3, 3] / trace if compressibility is None else compressibility
            checks += [
                ("small_fluctuations",
                 np.sqrt(trace) >= min_relative_amplitude * mom.mean[:, 3]),
                ("compressive", ratio <= max_compressibility),
            ]
    return first_failure(checks, k)


def _criteria(min_samples, min_eigenvalue_ratio, min_relative_amplitude, max_compressibility):
    return {
        "min_samples": int(min_samples),
        "min_eigenvalue_ratio": float(min_eigenvalue_ratio),
        "min_relative_amplitude": float(min_relative_amplitude),
        "max_compressibility": float(max_compressibility),
    }


def davis_smith_offsets(
    b: ArrayLike,
    interval_index: ArrayLike | None = None,
    *,
    interval_length: int | None = None,
    **options: Any,
) -> OffsetEstimate:
    """Offsets from Alfvenic fluctuations by the Davis-Smith least-squares method.

    ``field_moments(b, ..., squared=True)`` followed by
    `davis_smith_offsets_from_moments`, whose keyword ``options`` it takes.

    Parameters
    ----------
    b : array_like, shape (n, 3)
        Measured field (offset not removed), any unit; rows with a NaN are gaps.
    interval_index : array_like of int, shape (n,), optional
        Interval label per sample (negative: not used).  Or give ``interval_length``.
    interval_length : int, optional
        Consecutive blocks of this many samples as intervals.
    **options
        Selection criteria, ``offset_guess``, ``max_selection_passes``,
        ``n_bootstrap``, ``seed`` of `davis_smith_offsets_from_moments`.

    Returns
    -------
    OffsetEstimate

    References
    ----------
    .. [1] Davis and Smith (1968); Leinweber et al. (2008), sec. 2-3 (see module).
    """
    moments = field_moments(b, interval_index, interval_length=interval_length, squared=True)
    return davis_smith_offsets_from_moments(moments, **options)


def davis_smith_offsets_from_moments(
    moments: IntervalMoments,
    *,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    min_eigenvalue_ratio: float = DEFAULT_MIN_EIGENVALUE_RATIO,
    min_relative_amplitude: float = DEFAULT_MIN_RELATIVE_AMPLITUDE,
    max_compressibility: float = DEFAULT_MAX_COMPRESSIBILITY,
    offset_guess: ArrayLike | None = None,
    max_selection_passes: int = 10,
    n_bootstrap: int = 1000,
    seed: int | np.random.Generator | None = None,
) -> OffsetEstimate:
    """Davis-Smith offsets from per-interval moments of ``(Bx, By, Bz, |B|^2)``.

    Parameters
    ----------
    moments : IntervalMoments
        From ``field_moments(b, ..., squared=True)``, or several of those joined by
        `concatenate_moments` (a month as a map-reduce over days).
    min_samples, min_eigenvalue_ratio, min_relative_amplitude, max_compressibility
        Selection criteria (module docstring); defaults and reasons in
        ``docs/decisions/solar_wind_offsets.md``.
    offset_guess : array_like, shape (3,), optional
        Offset at which the offset-dependent criteria are first evaluated.
    max_selection_passes : int
        Passes of select-then-solve before giving up on a stable selection.
    n_bootstrap : int
        Bootstrap resamples of the accepted intervals (0: no uncertainty).
    seed : int or Generator, optional
        For the bootstrap.

    Returns
    -------
    OffsetEstimate
        ``per_interval`` is the solution of each interval's own 3x3 system
        ``C_k (2 O_k) = c_k`` (intervals passing criteria 1-2, else NaN); the pooled
        offset is their weighted mean with weights ``n_k C_k``.

    Raises
    ------
    InputFormatError
        Bad shapes or arguments.
    FluxcalError
        The accepted intervals do not determine all three components, or the
        selection does not settle within ``max_selection_passes``.

    Notes
    -----
    Uses ``|B|^2``, which makes the problem linear in ``O`` (no iteration for a fixed
    selection).  The compressibility of criterion 4 is computed exactly from the
    interval moments for any ``O`` as ``var(|B'|^2) / (4 <|B'|^2> trace C)``, the
    squared-magnitude form of ``var(|B'|) / trace C``.  White sensor noise of
    variance ``s^2`` moves each interval's solution by ``s^2 C_k^-1 <B>`` (along its
    mean field); over intervals with different mean-field directions this averages
    out.

    References
    ----------
    .. [1] Davis and Smith (1968); Leinweber et al. (2008), sec. 2-3 (see module).
    """
    m = moments
    if m.mean.ndim != 2 or m.mean.shape[1] != 4:
        raise InputFormatError(
            f"expected moments of (B, |B|^2), dimension 4, got {m.mean.shape}", field="moments"
        )
    k = m.count.size
    labels = np.arange(k, dtype=np.int64) if m.labels is None else m.labels
    guess = check_offset_guess(offset_guess)
    n, cov, cov_bsq = m.count, m.cov[:, :3, :3], m.cov[:, :3, 3]
    var_bsq, mean, mean_bsq = m.cov[:, 3, 3], m.mean[:, :3], m.mean[:, 3]
    trace = np.trace(cov, axis1=1, axis2=2)
    static = _static_checks(n, cov, min_samples, min_eigenvalue_ratio)

    def solve(reason):
        use = reason == ""
        a = np.einsum("k,kij->ij", n[use], cov[use])
        r = 0.5 * np.einsum("k,ki->i", n[use], cov_bsq[use])
        return solve_pooled(a, r, "davis_smith", reason)

    def compressibility_at(o):
        """Criteria 3-4 quantities of every interval at offsets ``o`` (m, 3) -> (k, m).

        Compressibility ``var(|B'|^2) / (4 <|B'|^2> trace C)`` and relative amplitude
        ``sqrt(trace C / <|B'|^2>)``, exactly from the interval moments.
        """
        bsq = mean_bsq[:, None] - 2.0 * mean @ o.T + np.einsum("mi,mi->m", o, o)[None]
        var_o = var_bsq[:, None] - 4.0 * cov_bsq @ o.T + 4.0 * np.einsum("mi,kij,mj->km", o, cov, o)
        with np.errstate(invalid="ignore", divide="ignore"):
            return var_o / (4.0 * bsq * trace[:, None]), np.sqrt(trace[:, None] / bsq)

    def checks(o):
        compressibility, amplitude = compressibility_at(o[None])
        return first_failure(
            static
            + [
                ("small_fluctuations", amplitude[:, 0] >= min_relative_amplitude),
                ("compressive", compressibility[:, 0] <= max_compressibility),
            ],
            k,
        )

    good = first_failure(static, k) == ""
    own = np.full((k, 3), np.nan)
    own[good] = 0.5 * np.linalg.solve(cov[good], cov_bsq[good][:, :, None])[:, :, 0]
    if offset_guess is not None:
        o = guess
    else:
        # consensus start: the interval solution under which most intervals pass
        # criterion 4 (a pooled start would be dragged by strong compressive intervals)
        candidates = np.flatnonzero(good)
        if candidates.size == 0:
            solve(first_failure(static, k))  # raises, naming the reasons
        if candidates.size > MAX_START_CANDIDATES:
            pick = np.linspace(0, candidates.size - 1, MAX_START_CANDIDATES).astype(int)
            candidates = candidates[pick]
        compressibility = compressibility_at(own[candidates])[0]
        votes = np.count_nonzero(good[:, None] & (compressibility <= max_compressibility), axis=0)
        o = own[candidates[np.argmax(votes)]]
    o, reason, passes = settle_selection(checks, solve, o, max_selection_passes, "davis_smith")
    use = reason == ""
    covariance, n_boot = bootstrap_covariance(
        n[use, None, None] * cov[use],
        0.5 * n[use, None] * cov_bsq[use],
        n_bootstrap,
        seed,
        "davis_smith",
    )
    return OffsetEstimate(
        method="davis_smith",
        offset=o,
        covariance=covariance,
        labels=labels,
        reason=reason,
        per_interval=own,
        n_bootstrap=n_boot,
        iterations=passes,
        criteria=_criteria(
            min_samples, min_eigenvalue_ratio, min_relative_amplitude, max_compressibility
        ),
    )


def hedgecock_offsets(
    b: ArrayLike,
    interval_index: ArrayLike | None = None,
    *,
    interval_length: int | None = None,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    min_eigenvalue_ratio: float = DEFAULT_MIN_EIGENVALUE_RATIO,
    min_relative_amplitude: float = DEFAULT_MIN_RELATIVE_AMPLITUDE,
    max_compressibility: float = DEFAULT_MAX_COMPRESSIBILITY,
    offset_guess: ArrayLike | None = None,
    max_iterations: int = 50,
    tolerance: float = 1e-6,
    n_bootstrap: int = 1000,
    seed: int | np.random.Generator | None = None,
    seconds: ArrayLike | None = None,
    segment_s: float | None = None,
) -> OffsetEstimate:
    """Offsets that minimise the summed within-interval variance of ``|B_meas - O|``.

    Parameters
    ----------
    b, interval_index, interval_length
        As `davis_smith_offsets`.
    min_samples, min_eigenvalue_ratio, min_relative_amplitude, max_compressibility
        As `davis_smith_offsets`; criteria 3-4 use ``|B_meas - O|`` at the current
        iterate directly (``var(|B'|) / trace C`` and ``sqrt(trace C) / <|B'|>``).
    offset_guess : array_like, shape (3,), optional
        Starting offset; without it the iteration starts from `davis_smith_offsets`
        (same criteria).
    max_iterations : int
        Gauss-Newton steps allowed.
    tolerance : float
        Converged when a step is shorter than this (units of ``b``) and the selection
        did not change.
    n_bootstrap, seed
        Bootstrap of the intervals on the linearised system at convergence.
    seconds : array_like, shape (n,), optional
        Time of each sample (s); with ``segment_s``, ``|B_meas - O|`` is taken constant
        only up to a line in time within segments of ``segment_s`` inside each interval
        (`fluxcal.calibration.segment_trends`): a slow compressive trend is then not taken
        for an offset, and ``compressive`` compares the powers left within the segments.
        Without them (default) each interval's mean is removed, as before.
    segment_s : float, optional
        Segment length (s).

    Returns
    -------
    OffsetEstimate
        ``per_interval`` is ``O + dO_k`` with ``dO_k`` the step interval ``k`` alone
        would take from the converged ``O`` (criteria 1-2 passed, else NaN).

    Raises
    ------
    InputFormatError
        Bad shapes or arguments.
    FluxcalError
        Undetermined offsets, or no convergence in ``max_iterations``.

    Notes
    -----
    Minimising the variance of ``|B|`` rather than ``|B|^2`` weights intervals in
    strong and weak fields alike (the ``|B|^2`` form weights by ``|B|^2``); the price
    is iteration.  Each step costs one vectorised pass over the samples.

    References
    ----------
    .. [1] Hedgecock (1975); Belcher (1973); Leinweber et al. (2008) (see module).
    """
    bv, codes, labels = split_intervals(b, interval_index, interval_length)
    o = check_offset_guess(offset_guess)
    k = labels.size
    mb = interval_moments(bv, codes, k)
    n = mb.count
    trace = np.trace(mb.cov, axis1=1, axis2=2)
    static = _static_checks(n, mb.cov, min_samples, min_eigenvalue_ratio)
    segments = _segments_of(b, interval_index, seconds, segment_s, codes, k)
    trace_kept = trace if segments is None else segment_variance(
        remove_segment_lines(bv, *segments), codes, k).sum(axis=1)
    if offset_guess is None:
        o = davis_smith_offsets(
            bv,
            codes,
            min_samples=min_samples,
            min_eigenvalue_ratio=min_eigenvalue_ratio,
            min_relative_amplitude=min_relative_amplitude,
            max_compressibility=max_compressibility,
            n_bootstrap=0,
        ).offset
    reason = None
    step = 0
    for _ in range(max_iterations):
        step += 1
        bp = bv - o
        mag = np.sqrt(np.einsum("ij,ij->i", bp, bp))
        um = np.column_stack([bp / mag[:, None], mag])
        mu = interval_moments(um, codes, k)
        if segments is not None:  # the moments about each segment's line
            mu = IntervalMoments(count=mu.count, mean=mu.mean, cov=interval_products(
                remove_segment_lines(um, *segments), codes, k))
        cov_u, cov_um, var_m = mu.cov[:, :3, :3], mu.cov[:, :3, 3], mu.cov[:, 3, 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            amplitude = np.sqrt(trace) / mu.mean[:, 3]
            compressibility = var_m / trace_kept
        previous = reason
        reason = first_failure(
            static
            + [
                ("small_fluctuations", amplitude >= min_relative_amplitude),
                ("compressive", compressibility <= max_compressibility),
            ],
            k,
        )
        use = reason == ""
        a = np.einsum("k,kij->ij", n[use], cov_u[use])
        g = np.einsum("k,ki->i", n[use], cov_um[use])
        delta = solve_pooled(a, g, "hedgecock", reason)
        o = o + delta
        if np.linalg.norm(delta) < tolerance and np.array_equal(reason, previous):
            break
    else:
        raise FluxcalError(f"hedgecock: no convergence in {max_iterations} Gauss-Newton steps")
    good = first_failure(static, k) == ""
    per_interval = np.full((k, 3), np.nan)
    per_interval[good] = o + np.linalg.solve(cov_u[good], cov_um[good][:, :, None])[:, :, 0]
    covariance, n_boot = bootstrap_covariance(
        n[use, None, None] * cov_u[use],
        n[use, None] * cov_um[use],
        n_bootstrap,
        seed,
        "hedgecock",
    )
    return OffsetEstimate(
        method="hedgecock",
        offset=o,
        covariance=covariance,
        labels=labels,
        reason=reason,
        per_interval=per_interval,
        n_bootstrap=n_boot,
        iterations=step,
        criteria=_criteria(
            min_samples, min_eigenvalue_ratio, min_relative_amplitude, max_compressibility
        ),
    )
