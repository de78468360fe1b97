"""Removal of square-wave (heater) steps from a vector time series.

Two methods, after the LEVEL_K procedure of seed 003:

* `remove_heater_steps` (method 1, automatic): rotate into the minimum variance frame
  of the steps, find the jumps of the maximum variance component with a moving
  variance and a robust threshold, estimate each jump's height from short fits just
  before and after it, flatten the disturbed levels, interpolate over the cut-out jump
  samples and rotate back.
* `remove_labelled_offsets` (method 2, assisted): another instrument (ROMAP in
  seed 003) supplies the disturbed intervals and which heater (label) was active; the
  offset of each label is subtracted inside its intervals (estimated from the data
  when not given).

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1),
   sec. 4.12 (LEVEL_K), 4.12.1 (method 1) and 4.12.2 (method 2).
"""

from __future__ import annotations

import logging
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.ndimage
from numpy.typing import ArrayLike, NDArray

from fluxcal.cleaning.minimum_variance import MinimumVarianceResult, minimum_variance
from fluxcal.errors import InputFormatError

__all__ = [
    "LabelledOffsetResult",
    "heater_off_segments",
    "StepRemovalResult",
    "moving_variance",
    "remove_heater_steps",
    "remove_labelled_offsets",
]

log = logging.getLogger(__name__)

#: Scale from the median absolute deviation to the standard deviation of a Gaussian.
MAD_TO_SIGMA = 1.4826
#: Shortest series for the second detection pass (its 99.9 % quantile needs >= 20
#: samples beyond it).
REFINE_MIN_SAMPLES = 20000


def _tail_threshold(mv: NDArray[np.float64], false_alarms: float = 1e-3) -> float:
    """Level exceeded ``false_alarms`` times per series under an exponential tail.

    The tail ``P(X > x) = 1e-3 exp(-(x - q999) / s)`` passes through the 99 % and
    99.9 % quantiles of ``mv`` (``s = (q999 - q99) / ln 10``; the moving variance of
    Gaussian noise is a quadratic form of Gaussians, whose tail is exponential); the
    returned ``x`` has ``n P(X > x) = false_alarms``.
    """
    q99, q999 = np.quantile(mv, [0.99, 0.999])
    scale = (q999 - q99) / np.log(10.0)
    return float(q999 + scale * np.log(1e-3 * mv.size / false_alarms))


def _as_vectors(values: ArrayLike, name: str = "values") -> NDArray[np.float64]:
    b = np.asarray(values, dtype=float)
    if b.ndim != 2 or b.shape[1] != 3:
        raise InputFormatError(f"expected an (n, 3) array, got shape {b.shape}", field=name)
    if not np.all(np.isfinite(b)):
        raise InputFormatError("contains non-finite values", field=name)
    return b


def moving_variance(u: ArrayLike, width: int) -> NDArray[np.float64]:
    """Compute the population variance of ``width`` samples centred on each sample.

    Sample ``i`` gets the variance of ``u[i - width//2 : i - width//2 + width]``; at the
    start the window begins at sample 0 instead, at the end it is truncated.

    Examples
    --------
    >>> moving_variance([0.0, 0.0, 0.0, 1.0, 1.0, 1.0], 2)
    array([0.  , 0.  , 0.  , 0.25, 0.  , 0.  ])
    """
    x = np.asarray(u, dtype=float)
    if width < 2:
        raise InputFormatError(f"width must be >= 2 samples, got {width}", field="width")
    n = x.size
    lo = np.clip(np.arange(n) - width // 2, 0, n)
    hi = np.clip(lo + width, 0, n)
    x0 = x - (x.mean() if n else 0.0)  # centring reduces round-off in the cumulative sums
    c1 = np.concatenate([[0.0], np.cumsum(x0)])
    c2 = np.concatenate([[0.0], np.cumsum(x0 * x0)])
    m = hi - lo
    mean = (c1[hi] - c1[lo]) / m
    return np.maximum((c2[hi] - c2[lo]) / m - mean**2, 0.0)


@dataclass(frozen=True)
class StepRemovalResult:
    """Output of `remove_heater_steps`.

    Attributes
    ----------
    values : ndarray (n, 3)
        Cleaned vectors, in the input frame.
    direction : ndarray (3,)
        Unit vector of the disturbance (maximum variance axis of the jumps).
    mva : MinimumVarianceResult
        Minimum variance analysis of the first differences used for detection.
    jump_indices : ndarray (m,)
        Index of the first sample on the new level, for each jump.
    heights : ndarray (m,)
        Jump heights along ``direction`` (input units, e.g. nT).
    disturbance : ndarray (n,)
        Subtracted disturbance along ``direction``.
    cut : ndarray (n,) of bool
        Samples cut out around the jumps and replaced by interpolation.
    moving_variance : ndarray (n,)
        Detection indicator (moving variance of the maximum variance component).
    threshold : float
        Detection threshold applied to ``moving_variance``.
    heater_sign : int
        +1 if the heater field points along ``direction`` (heater-off segments are the
        low levels), -1 if against it, 0 when no step was found.
    off_rule : str
        How the heater-off level was identified (see `heater_off_segments`).
    """

    values: NDArray[np.float64]
    direction: NDArray[np.float64]
    mva: MinimumVarianceResult
    jump_indices: NDArray[np.int64]
    heights: NDArray[np.float64]
    disturbance: NDArray[np.float64]
    cut: NDArray[np.bool_]
    moving_variance: NDArray[np.float64]
    threshold: float
    heater_sign: int = 0
    off_rule: str = ""


def _runs(flag: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Start and stop (exclusive) indices of the runs of True in ``flag``."""
    d = np.diff(np.concatenate([[0], flag.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _jump_fits(
    b: NDArray[np.float64],
    jumps: NDArray[np.int64],
    left_end: NDArray[np.int64],
    right_start: NDArray[np.int64],
    left_limit: NDArray[np.int64],
    right_limit: NDArray[np.int64],
    m: int,
) -> NDArray[np.float64]:
    """Joint least-squares fit of a sloped step around each jump.

    For jump ``k`` the model ``b = p0 + p1 * (i - j_k) + h * [i >= j_k]`` (common level,
    common slope, step ``h``) is fitted per component to up to ``m`` samples before the
    cut (``[left_end - m, left_end)``, not before ``left_limit``) and after it
    (``[right_start, right_start + m)``, not beyond ``right_limit``).  The common slope
    removes the bias a changing background field gives plain before/after averages.
    Returns the parameters ``(J, 3, c)``: level, slope and step per component.
    """
    k = np.arange(m)
    before = left_end[:, None] - m + k  # (J, m)
    after = right_start[:, None] + k
    ok_b = before >= np.maximum(left_limit, 0)[:, None]
    ok_a = after < right_limit[:, None]
    idx = np.concatenate([before, after], axis=1)
    ok = np.concatenate([ok_b, ok_a], axis=1)
    idx = np.clip(idx, 0, b.shape[0] - 1)
    x = (idx - jumps[:, None]).astype(float)
    step = np.concatenate([np.zeros_like(ok_b), np.ones_like(ok_a)], axis=1).astype(float)
    w = ok.astype(float)
    design = np.stack([np.ones_like(x), x, step], axis=-1) * w[..., None]  # (J, 2m, 3)
    gram = np.einsum("jsa,jsb->jab", design, design)
    rhs = np.einsum("jsa,jsc->jac", design, b[idx] * w[..., None])  # (J, 3, 3 comps)
    # a single slope is undetermined when one side has < 1 sample; regularise lightly
    gram = gram + 1e-9 * np.eye(3)
    return np.linalg.solve(gram, rhs)  # (J, 3 params [level, slope, step], components)


def _off_candidates(
    level: NDArray[np.float64], heights: NDArray[np.float64], sign: int, window: int
) -> NDArray[np.bool_]:
    """Segments at the local heater-off extreme for heater sign ``sign``.

    A segment is "off" when ``sign * level`` lies within half of its smaller adjacent
    jump of the minimum of ``sign * level`` over +/- ``window`` segments.
    """
    s = sign * level
    base = scipy.ndimage.minimum_filter1d(s, 2 * window + 1, mode="nearest")
    h = np.abs(heights)
    adjacent = np.minimum(np.concatenate([[np.inf], h]), np.concatenate([h, [np.inf]]))
    return (s - base) < 0.5 * adjacent


def _extremes(heights: NDArray[np.float64], sign: int) -> NDArray[np.bool_]:
    """Segments below both adjacent levels of ``sign * level`` (one neighbour at the ends).

    For a switching heater these are all the segments of one side (off or on), with no
    tolerance: the constancy test compares every off level with every on level.  (The
    tolerant ``_off_candidates`` keep, on the on side, only the on levels near a local
    extreme, whose steps are smaller than those of all on levels: issue 11 follow-up.)
    """
    s = sign * heights
    falls = np.concatenate([[True], s < 0])  # the jump into the segment goes down
    rises = np.concatenate([s > 0, [True]])  # the jump out of it goes up
    return falls & rises


def heater_off_segments(
    level: ArrayLike,
    heights: ArrayLike,
    lengths: ArrayLike,
    *,
    window: int = 2,
    quiet_factor: float = 3.0,
    constancy_ratio: float = 0.35,
    sign: int | None = None,
) -> tuple[int, NDArray[np.bool_], str]:
    """Identify the heater sign and the heater-off segments, whatever the field direction.

    Heater fields are all on one side of "off" (currents do not reverse), so the off
    level is the local minimum of the cumulative levels if the heater field points
    along the analysis axis and the local maximum if it points against it.  The axis
    sign is a convention of the minimum variance analysis, so the heater sign is read
    from the data, by the first rule that decides:

    1. ``quiet``: a segment at least ``quiet_factor`` times longer than the median
       cycle (two consecutive segments) is a stretch without heater activity, i.e.
       off; each votes with the side (below or above its neighbours) it lies on.
    2. ``constancy``: the off level repeats from period to period while the on levels
       change with the heater (several heaters, different currents: seed sec. 4.12.1);
       the sign whose troughs (segments below both neighbours of ``sign * level``)
       have the smaller median step between consecutive levels wins if it is below
       ``constancy_ratio`` times the other's; failing
       that, the sign with at most half as many (minus one) steps beyond 10 robust
       standard deviations of that median (rare heater changes).
    3. ``first segment``: the data before the first jump are undisturbed, as in the
       seed's step-by-step flattening from the start of the series.

    Parameters
    ----------
    level : array_like (m + 1,)
        Cumulative level of each segment between jumps (any origin).
    heights : array_like (m,)
        Jump heights (``level[k + 1] - level[k]``).
    lengths : array_like (m + 1,)
        Segment lengths in samples.
    window : int
        Segments on each side searched for the local off level.
    quiet_factor, constancy_ratio : float
        Parameters of rules 1 and 2.
    sign : int, optional
        Known heater sign (skips the rules).

    Returns
    -------
    sign : int
        +1 (off = low levels) or -1 (off = high levels).
    off : ndarray of bool (m + 1,)
        Heater-off segments.
    rule : str
        ``"given"``, ``"quiet"``, ``"constancy"`` or ``"first segment"``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12.1 ("flatten all the infected levels");
       the sign rules are a fluxcal decision (docs/decisions/cleaning.md, issue 11).
    """
    lev = np.asarray(level, dtype=float)
    h = np.asarray(heights, dtype=float)
    lengths = np.asarray(lengths, dtype=float)
    if sign is not None:
        if sign not in (1, -1):
            raise InputFormatError(f"heater sign must be +1 or -1, got {sign}", field="sign")
        return sign, _off_candidates(lev, h, sign, window), "given"
    m = lev.size
    if m >= 3:
        # a cycle (on + off) is two consecutive segments, whatever the duty cycle
        quiet = lengths >= quiet_factor * np.median(lengths[:-1] + lengths[1:])
        if quiet.any():
            k = np.flatnonzero(quiet)
            nb = np.stack([lev[np.maximum(k - 1, 0)], lev[np.minimum(k + 1, m - 1)]])
            own = np.where(k == 0, nb[1], np.where(k == m - 1, nb[0], nb.mean(axis=0)))
            vote = int(np.sign(np.sum(np.sign(own - lev[k]))))
            if vote != 0:
                return vote, _off_candidates(lev, h, vote, window), "quiet"
    steps = {}
    for sg in (1, -1):
        off = _extremes(h, sg)
        if np.count_nonzero(off) >= 3:
            steps[sg] = np.abs(np.diff(lev[off]))
    if len(steps) == 2:
        med = {sg: float(np.median(d)) for sg, d in steps.items()}
        lo, hi = sorted(med, key=med.get)
        if med[lo] < constancy_ratio * med[hi]:
            return lo, _off_candidates(lev, h, lo, window), "constancy"
        # rare changes of the on level (a heater switched every few periods): count
        # the steps beyond 10 robust standard deviations of the quieter candidate
        limit = 10.0 * MAD_TO_SIGMA * max(med[lo], np.finfo(float).tiny)
        count = {sg: int(np.count_nonzero(d > limit)) for sg, d in steps.items()}
        lo, hi = sorted(count, key=count.get)
        if count[hi] >= 2 * count[lo] + 1:
            return lo, _off_candidates(lev, h, lo, window), "constancy"
    first = 1 if h.size == 0 or h[0] >= 0 else -1
    return first, _off_candidates(lev, h, first, window), "first segment"


def remove_heater_steps(
    values: ArrayLike,
    *,
    width: int = 4,
    threshold: float | None = None,
    k_mad: float = 40.0,
    average_samples: int = 5,
    baseline_segments: int | None = 2,
    transition_sigma: float = 4.0,
    direction: ArrayLike | None = None,
    refine_threshold: bool = True,
    heater_sign: int | None = None,
) -> StepRemovalResult:
    """Detect and remove square-wave steps (heater switching) from a vector series.

    Parameters
    ----------
    values : array_like, shape (n, 3)
        Uniformly sampled field vectors (e.g. nT), without gaps.
    width : int
        Samples in the moving variance window ("a few samples").
    threshold : float, optional
        Detection threshold on the moving variance (input units squared).  Default:
        ``median + k_mad * 1.4826 * MAD`` of the moving variance (robust to the few
        samples disturbed by jumps).
    k_mad : float
        Multiplier of the robust spread for the automatic threshold.  The default 40
        leaves a factor of about two between the threshold and the largest moving
        variance of a realistic red-noise (f^-2) background over a day, while a step
        of height h still peaks at about h^2/4, i.e. steps of about 12 times the rms
        sample-to-sample noise are found.
    average_samples : int
        Samples on each side of a jump used to estimate its height (joint fit of a
        common level and slope plus the step).  Few samples suit a red (random-walk
        like) background, whose wander grows with the distance from the jump; the
        default 5 was chosen on the f^-2 background of the tests (height error
        0.05 nT rms, against 0.07 nT with 10 samples).
    baseline_segments : int or None
        Heater-off reference.  Heater disturbances return to zero when the heater is
        off: the heater-off segments are identified (`heater_off_segments`, within
        +/- ``baseline_segments`` segments, whatever the sign of the heater field
        along ``direction``) and left unchanged; every other segment is referred to
        the off level interpolated between the nearest off segments before and after
        it, so height errors never accumulate.  ``None`` flattens by the plain
        cumulative sum, the first segment being taken as undisturbed (the literal
        step-by-step flattening; height errors then accumulate).
    transition_sigma : float
        A sample near a jump is an intermediate (transition) value, cut out and
        interpolated, when it lies more than this many noise standard deviations
        from both the level before and the level after the jump.  Instantaneous
        jumps thus lose no sample.
    direction : array_like (3,), optional
        Known disturbance direction; by default the maximum variance axis of the
        first differences, refined as the principal axis of the detected 3-D jumps.
    heater_sign : int, optional
        Known sign (+1/-1) of the heater field along ``direction`` (only with
        ``direction``); by default it is identified from the data.
    refine_threshold : bool
        Second pass (automatic threshold only, series of at least
        `REFINE_MIN_SAMPLES` samples, when the first pass found jumps): the moving
        variance of the *cleaned* series, now free of the steps, gives the
        background's own tail; its 99 % and 99.9 % quantiles define an exponential
        tail that is extrapolated to 0.001 expected false alarms in the series.
        Where that threshold is lower than the MAD one, detection is redone with it
        (along the direction already found).  This recovers the smallest steps on a
        white-noise background, whose moving variance has a lighter tail than the red
        background the MAD factor ``k_mad`` is set for.

    Returns
    -------
    StepRemovalResult
        Cleaned vectors and the detection/estimation details.

    Notes
    -----
    The minimum variance frame is computed from the *first differences* of the series:
    there the steps dominate, while the slowly varying background field (which would
    dominate the variance of the series itself) contributes little.  Only the
    component along the disturbance direction is modified; the two other components
    of the minimum variance frame are returned unchanged, as in the seed.

    References
    ----------
    .. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028), sec. 4.12.1.
    """
    b = _as_vectors(values)
    n = b.shape[0]
    if n < 2 * width + 2:
        raise InputFormatError(f"series of {n} samples too short for width {width}", field="values")
    if average_samples < 2:
        raise InputFormatError(
            f"average_samples must be >= 2, got {average_samples}", field="average_samples"
        )
    mva = minimum_variance(np.diff(b, axis=0))
    if heater_sign is not None and direction is None:
        raise InputFormatError("heater_sign needs a given direction", field="heater_sign")
    if direction is None:
        e = mva.eigenvectors[:, 0]
    else:
        e = np.asarray(direction, dtype=float)
        if e.shape != (3,) or not np.linalg.norm(e) > 0:
            raise InputFormatError("direction must be a non-zero 3-vector", field="direction")
        e = e / np.linalg.norm(e)
    u = b @ e
    mv = moving_variance(u, width)
    if threshold is None:
        med = float(np.median(mv))
        mad = float(np.median(np.abs(mv - med)))
        thr = med + k_mad * MAD_TO_SIGMA * max(mad, np.finfo(float).tiny)
    else:
        thr = float(threshold)
    start, stop = _runs(mv > thr)
    if start.size == 0:
        log.info("no heater steps found (threshold %.3g)", thr)
        return StepRemovalResult(
            values=b.copy(), direction=e, mva=mva, jump_indices=np.zeros(0, np.int64),
            heights=np.zeros(0), disturbance=np.zeros(n), cut=np.zeros(n, bool),
            moving_variance=mv, threshold=thr,
        )  # fmt: skip

    # jump position: largest first difference in (and around) each run
    du = np.abs(np.diff(u))  # du[i-1] = |u[i] - u[i-1]|
    lo = np.clip(start - width // 2, 1, n - 1)
    hi = np.clip(stop + width // 2, 2, n)
    span = int(np.max(hi - lo))
    cand = lo[:, None] + np.arange(span)[None, :]
    valid = cand < hi[:, None]
    score = np.where(valid, du[np.clip(cand - 1, 0, n - 2)], -np.inf)
    jumps = cand[np.arange(cand.shape[0]), np.argmax(score, axis=1)].astype(np.int64)
    # First fit, excluding the whole run plus the samples bracketing the jump.
    run_lo = np.minimum(start, jumps - 1)
    run_hi = np.maximum(stop, jumps + 1)
    prev_end = np.concatenate([[0], run_hi[:-1]])
    next_start = np.concatenate([run_lo[1:], [n]])
    params = _jump_fits(b, jumps, run_lo, run_hi, prev_end, next_start, average_samples)
    # Cut out only the intermediate samples of the run: those further than
    # `transition_sigma` noise levels from both the level before and the level after.
    sigma = MAD_TO_SIGMA * float(np.median(np.abs(np.diff(u) - np.median(np.diff(u))))) / np.sqrt(2)
    pu = params @ e  # (J, 3) along e
    span2 = int(np.max(run_hi - run_lo))
    pos = run_lo[:, None] + np.arange(span2)[None, :]
    in_run = pos < run_hi[:, None]
    pos_c = np.clip(pos, 0, n - 1)
    xrel = (pos_c - jumps[:, None]).astype(float)
    line_before = pu[:, 0, None] + pu[:, 1, None] * xrel
    line_after = line_before + pu[:, 2, None]
    off_both = (np.abs(u[pos_c] - line_before) > transition_sigma * sigma) & (
        np.abs(u[pos_c] - line_after) > transition_sigma * sigma
    )
    inter = in_run & off_both
    has = inter.any(axis=1)
    first = np.where(has, pos[np.arange(pos.shape[0]), np.argmax(inter, axis=1)], jumps)
    last = np.where(
        has, pos[np.arange(pos.shape[0]), span2 - 1 - np.argmax(inter[:, ::-1], axis=1)], jumps - 1
    )
    cut_lo = np.minimum(first, jumps)
    cut_hi = np.maximum(last + 1, jumps)
    marks = np.zeros(n + 1, dtype=np.int64)
    np.add.at(marks, np.clip(cut_lo, 0, n), 1)
    np.add.at(marks, np.clip(cut_hi, 0, n), -1)
    cut = np.cumsum(marks[:-1]) > 0
    # A jump with fewer than 2 samples between it and the series edge cannot be
    # measured (the fit on that side is undetermined): the edge piece is cut out and
    # filled from the nearest corrected sample instead.
    edge = np.zeros(jumps.size, dtype=bool)
    edge[0] |= cut_lo[0] < 2
    edge[-1] |= n - cut_hi[-1] < 2
    if edge[0]:
        cut[: cut_hi[0]] = True
    if edge[-1]:
        cut[cut_lo[-1] :] = True
    jumps, cut_lo, cut_hi = jumps[~edge], cut_lo[~edge], cut_hi[~edge]

    prev_end = np.concatenate([[0], cut_hi[:-1]])
    next_start = np.concatenate([cut_lo[1:], [n]])
    h3 = _jump_fits(b, jumps, cut_lo, cut_hi, prev_end, next_start, average_samples)[:, 2, :]
    if direction is None and h3.shape[0] >= 1:
        # principal axis of the jump vectors (uncentred: jumps alternate in sign)
        _, vecs = np.linalg.eigh(h3.T @ h3)
        e_ref = vecs[:, -1]
        e = e_ref if float(e_ref @ e) >= 0 else -e_ref
        u = b @ e
    heights = h3 @ e

    level = np.concatenate([[0.0], np.cumsum(heights)])  # per segment
    bounds = np.concatenate([[0], jumps, [n]])
    sign, rule = 0, "first segment (plain cumulative flattening)"
    if baseline_segments is not None:
        sign, off, rule = heater_off_segments(
            level, heights, np.diff(bounds), window=baseline_segments, sign=heater_sign
        )
        centre = 0.5 * (bounds[:-1] + bounds[1:])
        off_level = np.interp(centre, centre[off], level[off])
        level = np.where(off, 0.0, level - off_level)
    segment = np.searchsorted(jumps, np.arange(n), side="right")
    disturbance = level[segment]
    corrected = u - disturbance
    good = ~cut
    corrected[cut] = np.interp(np.flatnonzero(cut), np.flatnonzero(good), corrected[good])
    out = b + (corrected - u)[:, None] * e[None, :]
    log.info("removed %d heater steps (threshold %.3g)", jumps.size, thr)
    if threshold is None and refine_threshold and n >= REFINE_MIN_SAMPLES:
        thr2 = _tail_threshold(moving_variance(out @ e, width))
        if thr2 < thr:
            log.info("second pass with the cleaned series' tail threshold %.3g", thr2)
            return remove_heater_steps(
                b,
                width=width,
                threshold=thr2,
                average_samples=average_samples,
                baseline_segments=baseline_segments,
                transition_sigma=transition_sigma,
                direction=e,
                heater_sign=heater_sign,
            )
    log.info("heater sign %+d along the disturbance axis (%s)", sign, rule)
    return StepRemovalResult(
        values=out,
        direction=e,
        mva=mva,
        jump_indices=jumps,
        heights=heights,
        disturbance=disturbance,
        cut=cut,
        moving_variance=mv,
        threshold=thr,
        heater_sign=sign,
        off_rule=rule,
    )


@dataclass(frozen=True)
class LabelledOffsetResult:
    """Output of `remove_labelled_offsets`.

    Attributes
    ----------
    values : ndarray (n, 3)
        Vectors with each label's offset subtracted inside its intervals.
    offsets : dict
        Offset vector (3,) subtracted for each label (given or estimated).
    label_of_sample : ndarray (n,) of object
        Label active at each sample (None outside all intervals).
    """

    values: NDArray[np.float64]
    offsets: dict[Hashable, NDArray[np.float64]]
    label_of_sample: NDArray[np.object_]


def remove_labelled_offsets(
    times: ArrayLike,
    values: ArrayLike,
    intervals: Sequence[tuple[float, float, Hashable]],
    offsets: Mapping[Hashable, ArrayLike] | None = None,
    *,
    reference_samples: int = 20,
    edge_samples: int = 1,
) -> LabelledOffsetResult:
    """Subtract per-label offsets inside externally identified disturbed intervals.

    Parameters
    ----------
    times : array_like, shape (n,)
        Sample times (any increasing numeric scale, e.g. TT2000 ns or seconds).
    values : array_like, shape (n, 3)
        Field vectors.
    intervals : sequence of (start, stop, label)
        Disturbed intervals ``start <= t < stop`` (same scale as ``times``), each with
        the label of the disturbance source (e.g. which heaters were on).
    offsets : mapping label -> (3,), optional
        Known offset per label.  Labels missing here are estimated from the data: for
        each interval, the mean inside (without ``edge_samples`` at each end) minus
        the mean of ``reference_samples`` undisturbed samples before and after it; the
        label's offset is the component-wise median over its intervals.
    reference_samples : int
        Undisturbed samples on each side used for the estimate.
    edge_samples : int
        Samples at each end of an interval ignored by the estimate (transitions).

    Returns
    -------
    LabelledOffsetResult

    Raises
    ------
    InputFormatError
        On malformed input, or if a label's offset cannot be estimated (no interval
        with undisturbed reference samples).

    References
    ----------
    .. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028), sec. 4.12.2.
    """
    b = _as_vectors(values)
    t = np.asarray(times)
    n = b.shape[0]
    if t.shape != (n,):
        raise InputFormatError(f"times has shape {t.shape}, expected ({n},)", field="times")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise InputFormatError("times must be strictly increasing", field="times")
    labels_of = np.full(n, None, dtype=object)
    disturbed = np.zeros(n, dtype=bool)
    spans: list[tuple[int, int, Hashable]] = []
    for k, item in enumerate(intervals):
        try:
            t0, t1, label = item
        except (TypeError, ValueError) as exc:
            raise InputFormatError(
                f"interval {k} must be (start, stop, label), got {item!r}", field="intervals"
            ) from exc
        if not t1 > t0:
            raise InputFormatError(f"interval {k} has stop <= start", field="intervals")
        i0, i1 = np.searchsorted(t, [t0, t1], side="left")
        if i1 > i0:
            labels_of[i0:i1] = label
            disturbed[i0:i1] = True
            spans.append((int(i0), int(i1), label))
    known = {lab: np.asarray(v, dtype=float).reshape(3) for lab, v in (offsets or {}).items()}
    estimates: dict[Hashable, list[NDArray[np.float64]]] = {}
    for i0, i1, label in spans:
        if label in known:
            continue
        inner = b[i0 + edge_samples : i1 - edge_samples]
        ref_idx = np.concatenate(
            [np.arange(i0 - reference_samples, i0), np.arange(i1, i1 + reference_samples)]
        )
        ref_idx = ref_idx[(ref_idx >= 0) & (ref_idx < n)]
        ref_idx = ref_idx[~disturbed[ref_idx]]
        before = ref_idx[ref_idx < i0]
        after = ref_idx[ref_idx >= i1]
        if inner.shape[0] == 0 or before.size == 0 or after.size == 0:
            continue
        # mean of the before and after means: a linear background trend cancels
        ref = 0.5 * (b[before].mean(axis=0) + b[after].mean(axis=0))
        estimates.setdefault(label, []).append(inner.mean(axis=0) - ref)
    result = dict(known)
    for label in {s[2] for s in spans} - set(known):
        if label not in estimates:
            raise InputFormatError(
                f"cannot estimate the offset of label {label!r}: no interval has "
                "undisturbed samples on both sides",
                field="intervals",
            )
        result[label] = np.median(np.stack(estimates[label]), axis=0)
    out = b.copy()
    for i0, i1, label in spans:
        out[i0:i1] -= result[label]
    return LabelledOffsetResult(values=out, offsets=result, label_of_sample=labels_of)
