"""RPC-MAG in-flight fits by variance minimisation of ``|B|`` (issue 21, estimator ``variance``).

The seed's estimators (`fluxcal.missions.rosetta.fit`) fix the offset by a long-term
average: the daily polynomial's ``P_0`` makes the day's mean field zero (sec. 4.2.3.3),
the Appendix B jumps make the CSEQ ``B_z`` average zero and take whatever follows the
attitude (sec. 4.2.3.4).  A solar wind with a mean field over the day (a sector, a
Parker spiral) puts that mean into the offsets.  These estimators assume instead that
the field's *magnitude* is nearly constant within intervals of tens of minutes while its
direction rotates (Alfvenic fluctuations, Davis and Smith 1968; Hedgecock 1975), and
assume nothing about its mean:

* `fit_extended_model_variance`: the daily polynomial ``P(T~)`` per axis (degree 0-5,
  the ``P_0 .. P_5`` of sec. 4.2.3.3) minimises the summed within-interval variance of
  ``|B^c - P(T~(t))|``.  Gauss-Newton: about the current curve, ``|B' - dP(T~(t))| ~
  |B'| - u . dP(T~(t))`` (``u`` the unit vector of ``B'``) is linear in the polynomial
  coefficients; each interval's mean is removed; the temperature moving inside an
  interval is in ``dP(T~(t))`` sample by sample.
* `fit_offset_jumps_variance`: one constant s/c offset per Appendix B interval by
  `fluxcal.calibration.variance_offsets.hedgecock_offsets` over the interval's
  sub-intervals (no attitude and no CSEQ frame needed: ``|B|`` does not depend on them).

Intervals are accepted by the named criteria of `fluxcal.calibration.variance_offsets`
(too_few_samples, ill_conditioned, small_fluctuations, compressive) evaluated on the
corrected field; each rejected interval is counted by its reason and the counts go into
the written file and any refusal.  Errors: bootstrap over blocks of intervals, the
selection re-made on each resample's curve (daily model), or over intervals (jumps).  A
fit whose error makes it meaningless, whose value is outside its physical range, or whose
intervals are mostly compressive is refused (`fluxcal.errors.FitRefusedError`), naming
the parameter, its value and error, and the data that would constrain it.  Decisions:
docs/decisions/rosetta_fit.md, entries 9-14.

References
----------
.. [1] I. Richter, "Step by Step Calibration Procedure for RPC-MAG Data", RO-IGEP-TR0028
   issue 3 rev. 1 (2015) (seed 003), sec. 4.2.3.3, 4.2.3.4, Appendix B.
.. [2] Davis, L. Jr. and Smith, E. J., EOS Trans. AGU 49, 257 (1968); Hedgecock, P. C.,
   Space Sci. Instrum. 1, 83-90 (1975); Leinweber, H. K. et al., Meas. Sci. Technol. 19,
   055104 (2008) (selection of pure rotations).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import xarray as xr

from fluxcal.calibration.segment_trends import (
    remove_segment_lines,
    segment_codes,
    segment_variance,
)
from fluxcal.calibration.solar_wind_offsets import count_reasons
from fluxcal.calibration.step_scan import JumpScan, scan_offset_step
from fluxcal.calibration.variance_offsets import (
    DEFAULT_MAX_COMPRESSIBILITY,
    DEFAULT_MIN_EIGENVALUE_RATIO,
    DEFAULT_MIN_RELATIVE_AMPLITUDE,
    hedgecock_offsets,
    interval_reasons,
)
from fluxcal.errors import FitRefusedError, FluxcalError
from fluxcal.geometry.time import tt2000_to_utc
from fluxcal.missions.rosetta.calib import check_sensor
from fluxcal.missions.rosetta.fit import (
    DEFAULT_DEGREE,
    MAX_DEGREE,
    NS,
    DailyModelFit,
    OffsetJumpFit,
    _power_basis,
    fit_extended_model,
    interval_bounds,
)

__all__ = ["ESTIMATORS", "GOAL_NT", "VarianceSettings", "curve_error_text",
           "fit_extended_model_variance", "fit_offset_jumps_variance", "predicted_error"]

#: Estimators of ``fluxcal rosetta fit --estimator``, named by what they assume.
ESTIMATORS = ("zero-mean", "variance")
#: Default goal (nT) of a Rosetta daily curve's figure of merit (issue 34).
GOAL_NT = 0.2


@dataclass(frozen=True)
class VarianceSettings:
    """Intervals, selection criteria, bootstrap and guard of the variance estimators.

    Attributes
    ----------
    interval_s : float
        Interval length (s) over which ``|B|`` is taken constant (tens of minutes, issue
        21; 1200 s, the correlation time of the calm-wind direction in the tests).
    min_samples : int
        ``too_few_samples`` below this many samples, or below half of what the interval
        holds at the data's median sampling interval (gaps, edges).
    min_eigenvalue_ratio, min_relative_amplitude, max_compressibility : float
        ``ill_conditioned``, ``small_fluctuations``, ``compressive`` (defaults of
        `fluxcal.calibration.variance_offsets`; docs/decisions/solar_wind_offsets.md).
    block_s : float
        Bootstrap block (s) of the daily model: blocks of intervals are resampled (the
        field is correlated over neighbouring intervals).
    n_bootstrap : int
        Bootstrap resamples.
    max_iterations : int
        Gauss-Newton steps allowed.
    tolerance : float
        Converged when the curve moves less than this (nT) and the selection is stable.
    max_sigma : float
        Refuse a curve (daily model) or jump whose standard error exceeds this (nT)
        anywhere over the fitted temperature range (1 nT: the jump fit's limit,
        rosetta_fit.md decision 4).
    max_offset : float
        Physical range of the daily curve (nT): refused where ``|P(T~)|`` exceeds it
        over the day's temperatures (the residual after the ground calibration; the
        ground laws change by at most ``|A_1|`` x 70 K = 116 nT between the calibrated
        -70 C and the -140 C of flight; rosetta_fit.md decision 13).
    max_jump : float
        Physical range of an Appendix B jump (nT): 4 x the largest shipped (25 nT).
    max_compressive_share : float
        Refuse a day (or jump interval) whose intervals are rejected as ``compressive``
        for more than this share of those passing the static criteria: the selection
        then depends on the fit and the errors understate (rosetta_fit.md decision 13).
    segment_s : float
        Daily model: ``|B|`` is taken constant up to a straight line in time within
        segments of this length inside each interval (the slow compressive changes of
        ``|B|`` are removed, the fast rotations kept; rosetta_fit.md decision 15); the
        ``compressive`` criterion compares the powers left within the segments.  A
        segment shorter than ``min_segment_samples`` samples at the data's median rate
        is lengthened to hold them.  ``interval_s`` or more: one segment per interval,
        its mean only removed (the estimator before issue 34).
    min_segment_samples : int
        Samples a segment holds at least (the line takes two of them).
    jump_min_side : int
        Daily model: the change-point scan (`scan_offset_step`) tries splits with at least
        this many accepted intervals on each side.
    max_jump_chi2 : float
        Daily model: refuse a day whose largest step ``chi2`` (3 dof) exceeds this: an
        offset jump inside the day, named with its time and size (rosetta_fit.md
        decision 16).
    goal : float
        Figure of merit (nT): refuse a daily curve whose predicted error of the
        recalibrated day, twice the rms of its stated error over the day's vectors, exceeds
        this in any axis (issue 34: 0.2 nT for Rosetta; rosetta_fit.md decision 17).  A
        larger value accepts a worse table and is written into it.
    """

    interval_s: float = 1200.0
    min_samples: int = 30
    min_eigenvalue_ratio: float = DEFAULT_MIN_EIGENVALUE_RATIO
    min_relative_amplitude: float = DEFAULT_MIN_RELATIVE_AMPLITUDE
    max_compressibility: float = DEFAULT_MAX_COMPRESSIBILITY
    block_s: float = 1200.0
    n_bootstrap: int = 1000
    max_iterations: int = 40
    tolerance: float = 1e-4
    max_sigma: float = 1.0
    max_offset: float = 200.0
    max_jump: float = 100.0
    max_compressive_share: float = 1.0 / 3.0
    segment_s: float = 60.0
    min_segment_samples: int = 8
    jump_min_side: int = 6
    max_jump_chi2: float = 25.0
    goal: float = GOAL_NT


def _intervals(epoch: np.ndarray, interval_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Interval label (from the first epoch) and its code per sample."""
    label = (epoch - epoch.min()) // int(round(interval_s * NS))
    labels, codes = np.unique(label, return_inverse=True)
    return labels, codes


def _min_count(epoch: np.ndarray, s: VarianceSettings) -> float:
    """Return the samples an interval must hold: ``min_samples``, half the nominal count."""
    step = np.median(np.diff(epoch)) / NS if epoch.size > 1 else s.interval_s
    return max(float(s.min_samples), 0.5 * s.interval_s / max(float(step), 1e-9))


@dataclass(frozen=True)
class _Segments:
    """Segments of the intervals: per-sample code ``0..m-1``, time (s), line removed.

    ``on`` False: one segment per interval, its mean only (the estimator before issue 34).
    """

    codes: np.ndarray
    m: int
    seconds: np.ndarray
    on: bool
    length_s: float

    @classmethod
    def of(cls, epoch: np.ndarray, codes: np.ndarray, labels: np.ndarray,
           s: VarianceSettings) -> _Segments:
        seconds = (epoch - epoch.min()) / NS
        length = _segment_length(epoch, s)
        if length is None:
            return cls(codes, int(labels.size), seconds, False, float(s.interval_s))
        seg, m = segment_codes(seconds, codes, labels * s.interval_s, length)
        return cls(seg, m, seconds, True, length)

    def residual(self, values: np.ndarray) -> np.ndarray:
        """``values`` less each segment's mean (and line)."""
        return remove_segment_lines(values, self.codes, self.m, self.seconds, line=self.on)

    def compressibility(self, b: np.ndarray, codes: np.ndarray, k: int) -> np.ndarray | None:
        """Per interval, power of ``|b|`` over that of ``b`` left within the segments."""
        if not self.on:
            return None
        mag = np.sqrt(np.einsum("ij,ij->i", b, b))
        with np.errstate(invalid="ignore", divide="ignore"):
            return (segment_variance(self.residual(mag), codes, k)
                    / segment_variance(self.residual(b), codes, k).sum(axis=1))


def _segment_length(epoch: np.ndarray, s: VarianceSettings) -> float | None:
    """Segment length (s): ``segment_s``, or ``min_segment_samples`` at the median rate.

    ``None`` when that is an interval or more (one segment per interval, mean only).
    """
    step = float(np.median(np.diff(epoch)) / NS) if epoch.size > 1 else s.interval_s
    length = max(float(s.segment_s), s.min_segment_samples * step)
    return None if length >= s.interval_s else length


def _select(b: np.ndarray, codes: np.ndarray, k: int, min_count: float,
            s: VarianceSettings, static_only: bool = False,
            segments: _Segments | None = None) -> np.ndarray:
    """First failed criterion per interval (``""``: accepted), evaluated on ``b``."""
    ratio = None if segments is None or static_only else segments.compressibility(b, codes, k)
    return interval_reasons(b, codes, k, min_samples=min_count,
                            min_eigenvalue_ratio=s.min_eigenvalue_ratio,
                            min_relative_amplitude=s.min_relative_amplitude,
                            max_compressibility=s.max_compressibility, static_only=static_only,
                            compressibility=ratio)


def _history_text(history: list[tuple[float, int, int]]) -> str:
    """Return the steps as ``curve moved, accepted, flipped`` text."""
    return "; ".join(f"{m:.3g} nT, {a} accepted, {f} flipped" for m, a, f in history) or "none"


def _reasons_text(reason: np.ndarray) -> str:
    counts = count_reasons(reason)
    return ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) or "none"


def _normal_equations(b: np.ndarray, powers: np.ndarray, codes: np.ndarray, k: int,
                      accepted: np.ndarray, block: np.ndarray, nb: int, segments: _Segments
                      ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Per-block normal equations of the linearised variance of ``|b - dP|``.

    Columns ``u_i x^k`` (axis-major); target ``|b|``; both with each segment's mean (and
    line in time) removed.  Returns ``(normal (nb, p, p), rhs (nb, p), residual sum,
    samples)``.
    """
    ok = accepted[codes]
    b, powers, block = b[ok], powers[ok], block[ok]
    part = _Segments(segments.codes[ok], segments.m, segments.seconds[ok], segments.on,
                     segments.length_s)
    mag = np.sqrt(np.einsum("ij,ij->i", b, b))
    u = b / mag[:, None]
    x = part.residual((u[:, :, None] * powers[:, None, :]).reshape(mag.size, -1))
    y = part.residual(mag)
    p = x.shape[1]
    normal = np.zeros((nb, p, p))
    rhs = np.zeros((nb, p))
    order = np.argsort(block, kind="stable")
    bounds = np.searchsorted(block[order], np.arange(nb + 1))
    for i in range(nb):  # bootstrap blocks (about 24 a day), one matrix product each
        rows = order[bounds[i]:bounds[i + 1]]
        normal[i] = x[rows].T @ x[rows]
        rhs[i] = x[rows].T @ y[rows]
    return normal, rhs, float(y @ y), int(mag.size)


def _solve(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Solve (stacked) normal equations after scaling by the diagonal."""
    d = np.sqrt(np.abs(np.diagonal(a, axis1=-2, axis2=-1)))
    d = np.where(d > 0, d, 1.0)
    scaled = a / (d[..., :, None] * d[..., None, :])
    if a.ndim == 2:
        return np.linalg.lstsq(scaled, v / d, rcond=1e-12)[0] / d
    eye = 1e-12 * np.eye(a.shape[-1])
    return np.linalg.solve(scaled + eye, (v / d)[..., None])[..., 0] / d


def fit_extended_model_variance(
    level_a: xr.Dataset,
    temperature: np.ndarray,
    *,
    degree: int = DEFAULT_DEGREE,
    settings: VarianceSettings | None = None,
    day: np.datetime64 | str | None = None,
    seed: int = 0,
) -> DailyModelFit:
    """Fit the daily polynomial ``P_0 .. P_5`` (sec. 4.2.3.3) by variance minimisation.

    Minimises ``sum_k sum_{t in k} (|B^c(t) - P(T~(t))| - mean_k)^2`` over the accepted
    intervals ``k`` of ``settings.interval_s``: the offset curve that makes the field
    magnitude least variable within each interval.  Starts from the seed's zero-mean fit
    (`fluxcal.missions.rosetta.fit.fit_extended_model`, blocks of the interval length), takes
    Gauss-Newton steps with only the sample-count and conditioning criteria until the
    curve settles, then with all four criteria until curve and selection are stable.
    The covariance is that of the Gauss-Newton solution over bootstrap resamples of
    ``settings.block_s`` blocks, each resample's ``compressive`` selection re-made on its
    own curve (linearised), times ``n / (n - p)``.

    Parameters
    ----------
    level_a : xarray.Dataset
        LEVEL_A from the ground calibration alone, as for `fit_extended_model`.
    temperature : ndarray, shape (n,)
        Reduced temperature ``T~`` (deg C) of each vector.
    degree : int
        0 .. 5.
    settings : VarianceSettings, optional
    day : datetime64[D] or str, optional
        Day of the file; default the UTC day of the first vector.
    seed : int
        Of the bootstrap.

    Returns
    -------
    DailyModelFit
        ``estimator = "variance"``; ``n_blocks`` counts the accepted intervals,
        ``block_s`` is the interval length, ``rms`` the rms of ``|B'|`` about its
        interval means (same for the three axes), ``chi2`` NaN; ``notes`` hold the
        rejected intervals by reason.

    Raises
    ------
    FluxcalError
        Input errors of `fit_extended_model` (not LEVEL_A, model already applied,
        degree, non-finite values, too few blocks for the start).
    FitRefusedError
        Too few intervals for the parameters, a temperature with fewer distinct values
        than coefficients, too few accepted intervals (naming the rejections), more than
        ``settings.max_compressive_share`` of them compressive, no convergence (naming
        why), a curve whose standard error exceeds ``settings.max_sigma`` or whose value
        exceeds ``settings.max_offset`` somewhere in the fitted temperature range (naming
        axis, temperature, value and error).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (six parameters per component).
    .. [2] Hedgecock (1975); Leinweber et al. (2008) (see module).
    """
    s = settings or VarianceSettings()
    _check_determined(level_a, temperature, degree, s, day)
    start = fit_extended_model(level_a, temperature, degree=degree, day=day,
                               block_s=s.interval_s)
    degree, sensor, day = start.degree, start.sensor, start.day
    source = start.notes.get("source", "LEVEL_A dataset")
    what = f"{source}: extended model {sensor} {day} (variance, degree {degree})"
    b = np.asarray(level_a["b"].values, dtype=float)
    t = np.asarray(temperature, dtype=float)
    epoch = np.asarray(level_a["epoch"].values, dtype=np.int64)
    x = (t - start.centre) / start.scale
    powers = np.vander(x, degree + 1, increasing=True)
    labels, codes = _intervals(epoch, s.interval_s)
    k = labels.size
    min_count = _min_count(epoch, s)
    block_of_interval = (labels * s.interval_s // s.block_s).astype(np.int64)
    block_ids, block_code = np.unique(block_of_interval, return_inverse=True)
    nb = block_ids.size
    block = block_code[codes]
    segments = _Segments.of(epoch, codes, labels, s)
    q = start.q.copy()
    p = 3 * (degree + 1)
    reason = previous = None
    converged = False
    static_phase = True
    history: list[tuple[float, int, int]] = []  # per step: curve moved (nT), accepted, flips
    for _ in range(s.max_iterations):  # Gauss-Newton steps
        bp = b - powers @ q
        previous, reason = reason, _select(bp, codes, k, min_count, s, static_only=static_phase,
                                           segments=segments)
        accepted = reason == ""
        if np.count_nonzero(accepted) < p + 1:
            raise FitRefusedError(
                f"{what}: {np.count_nonzero(accepted)} of {k} intervals of "
                f"{s.interval_s:g} s accepted for {p} parameters, need {p + 1} (rejected: "
                f"{_reasons_text(reason)}); give a longer stretch with more rotating "
                "(Alfvenic) intervals or a lower --degree, or use --estimator zero-mean if "
                "the field averages to zero"
            )
        normal, rhs, _, _ = _normal_equations(bp, powers, codes, k, accepted, block, nb,
                                              segments)
        step = _solve(normal.sum(axis=0), rhs.sum(axis=0)).reshape(3, degree + 1).T
        q = q + step
        moved = float(np.abs(powers @ step).max())
        history.append((moved, int(np.count_nonzero(accepted)),
                        0 if previous is None else int(np.count_nonzero(reason != previous))))
        if moved < s.tolerance and np.array_equal(reason, previous):
            if not static_phase:
                converged = True
                break
            static_phase = False
    if not converged:
        bp = b - powers @ q
        full = _select(bp, codes, k, min_count, s, segments=segments)
        too_compressive = _compressive_refusal(
            what, full, _select(bp, codes, k, min_count, s, static_only=True) == "", s)
        if too_compressive:
            raise FitRefusedError(f"{too_compressive} (no convergence in "
                                  f"{s.max_iterations} Gauss-Newton steps)")
        flipped = 0 if previous is None else int(np.count_nonzero(reason != previous))
        cause = (f"the selection still changes ({flipped} of {k} intervals flipped between "
                 "accepted and rejected on the last step: intervals at the compressive "
                 "limit)" if flipped else
                 f"the curve still moves (last step {moved:.3g} nT, tolerance "
                 f"{s.tolerance:g} nT)")
        raise FitRefusedError(
            f"{what}: no convergence in {s.max_iterations} Gauss-Newton steps: {cause}; "
            f"last steps {_history_text(history[-3:])}; "
            f"rejected intervals at the last curve: {_reasons_text(full)}; give a day with "
            "more rotating "
            "(Alfvenic) intervals, a lower --degree, or use --estimator zero-mean if the "
            "field averages to zero"
        )
    accepted = reason == ""
    n_acc = int(np.count_nonzero(accepted))
    bp = b - powers @ q
    static = _select(bp, codes, k, min_count, s, static_only=True) == ""
    too_compressive = _compressive_refusal(what, reason, static, s)
    if too_compressive:
        raise FitRefusedError(too_compressive)
    # per-interval normal equations of every interval that passes the static criteria
    normal, rhs, _, _ = _normal_equations(bp, powers, codes, k, static, codes, k, segments)
    mag = np.sqrt(np.einsum("ij,ij->i", bp, bp))
    count = np.bincount(codes, minlength=k).astype(float)
    yy_k = segment_variance(segments.residual(mag), codes, k) * count
    trace_k = segment_variance(segments.residual(bp), codes, k).sum(axis=1)
    yy, n_used = float(yy_k[accepted].sum()), int(count[accepted].sum())
    eligible = static & (reason != "small_fluctuations")  # kept as selected
    scan = scan_offset_step(normal, rhs, accepted, np.arange(3) * (degree + 1), s.jump_min_side)

    def compressive_ok(d: np.ndarray) -> np.ndarray:
        """Intervals passing ``compressive`` after the curve moves by ``d`` (linearised)."""
        var = (yy_k - 2.0 * d @ rhs.T + np.einsum("ri,kij,rj->rk", d, normal, d)) / np.maximum(
            count, 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return eligible & (var / trace_k <= s.max_compressibility)

    rng = np.random.default_rng(seed)
    picks = np.stack([np.bincount(rng.integers(0, nb, nb), minlength=nb)
                      for _ in range(s.n_bootstrap)]).astype(float)[:, block_code]
    # resample blocks of intervals; the selection is re-made on each resample's curve
    # (twice, linearised), so the errors include the selection's dependence on the fit
    boot = _solve(np.einsum("rk,kij->rij", picks * accepted, normal), (picks * accepted) @ rhs)
    for _ in range(2):
        use = picks * compressive_ok(boot)
        boot = _solve(np.einsum("rk,kij->rij", use, normal), use @ rhs)
    # finite-sample correction of the pairs bootstrap (like the n - p of a regression)
    n_blocks_used = np.unique(block_code[accepted]).size
    inflate = n_blocks_used / max(n_blocks_used - p, 1)
    cov_full = inflate * np.cov(boot, rowvar=False).reshape(3, degree + 1, 3, degree + 1)
    cov = np.stack([cov_full[i, :, i, :] for i in range(3)])
    c = _power_basis(start.centre, start.scale, degree)
    coefficients = np.zeros((MAX_DEGREE + 1, 3))
    sigma = np.zeros((MAX_DEGREE + 1, 3))
    coefficients[: degree + 1] = c @ q
    for i in range(3):
        sigma[: degree + 1, i] = np.sqrt(np.diag(c @ cov[i] @ c.T))
    rms = np.sqrt(yy / max(n_used, 1))
    fit = dataclasses.replace(
        start, coefficients=coefficients, sigma=sigma, q=q, covariance_q=cov,
        n_blocks=n_acc, block_s=float(s.interval_s), rms=np.full(3, rms),
        chi2=np.full(3, np.nan), dof=n_used - p - n_acc, noise=None, estimator="variance",
        notes={**start.notes,
               "intervals": f"{n_acc} of {k} accepted; rejected: {_reasons_text(reason)}",
               "bootstrap": f"{s.n_bootstrap} resamples of {nb} blocks of {s.block_s:g} s",
               "jump scan": (f"largest change-point chi2 {scan.statistic:.1f} (limit "
                             f"{s.max_jump_chi2:g}, 3 dof) at interval {scan.split} step "
                             + " ".join(f"{v:.3f}" for v in scan.step) + " +- "
                             + " ".join(f"{v:.3f}" for v in scan.sigma) + " nT"),
               "segments": (f"|B| constant up to a line in time within {segments.length_s:g}-s "
                            f"segments ({segments.m})" if segments.on else
                            f"|B| constant within each {s.interval_s:g}-s interval"),
               "convergence": (f"{len(history)} Gauss-Newton steps; stopped: the curve moved "
                               f"{history[-1][0]:.2g} nT < {s.tolerance:g} nT with the "
                               "selection unchanged; per step (curve moved, accepted, "
                               f"flipped): {_history_text(history)}")})
    if scan.statistic > s.max_jump_chi2:
        size, first, last, stats = _jump_found(scan, int(epoch.min()), labels, s)
        raise FitRefusedError(
            f"{what}: {size} between {first} and {last} UTC {stats}: the daily polynomial "
            "cannot hold a jump and would spread it over the day; fit the part of the day "
            "before or after it alone (the jump itself belongs in an Appendix B table, "
            "fluxcal rosetta fit --jumps)"
        )
    grid = np.linspace(*fit.temperature_range, 101)
    curve_sigma = fit.offset_sigma(grid)
    worst = np.unravel_index(np.argmax(curve_sigma), curve_sigma.shape)
    if not curve_sigma[worst] <= s.max_sigma:
        tw, axis = float(grid[worst[0]]), int(worst[1])
        value = float(fit.offset(np.array([tw]))[0, axis])
        raise FitRefusedError(
            f"{what}: offset curve {'xyz'[axis]} = {value:.3g} +- {curve_sigma[worst]:.3g} nT "
            f"at T~ = {tw:.1f} C (limit {s.max_sigma:g} nT; {n_acc} of {k} intervals "
            f"accepted, rejected: {_reasons_text(reason)}); constrain it with more rotating "
            "intervals over the temperature range, a lower --degree, or --max-sigma"
        )
    curve = fit.offset(grid)
    worst = np.unravel_index(np.argmax(np.abs(curve)), curve.shape)
    if not abs(curve[worst]) <= s.max_offset:
        tw, axis = float(grid[worst[0]]), int(worst[1])
        raise FitRefusedError(
            f"{what}: offset curve {'xyz'[axis]} = {curve[worst]:.4g} +- "
            f"{curve_sigma[worst]:.3g} nT at T~ = {tw:.1f} C is outside the physical range "
            f"+-{s.max_offset:g} nT of a residual offset after the ground calibration (a "
            "field taken for an offset, or a wrong ground calibration); check --calib, "
            "or fit a day with rotating field over the temperature range"
        )
    merit = predicted_error(fit, t)
    if not np.all(merit <= s.goal):
        axis = int(np.argmax(merit))
        raise FitRefusedError(
            f"{what}: predicted error of the recalibrated day " + " ".join(
                f"{v:.3f}" for v in merit) + f" nT (x y z; twice the rms of the curve's stated "
            f"error over the day's vectors) is above the goal {s.goal:g} nT in "
            f"{'xyz'[axis]} ({n_acc} of {k} intervals accepted, rejected: "
            f"{_reasons_text(reason)}; |B| rms within {segments.length_s:g}-s segments "
            f"{rms:.3g} nT); give a day with more rotation and less compression, a lower "
            "--degree, or accept a worse table with --goal (written into the file)"
        )
    return dataclasses.replace(fit, notes={
        **fit.notes, "curve error": curve_error_text(fit, t),
        "figure of merit": (
            "predicted error of the recalibrated day (2 x rms stated error over its "
            "vectors) x y z " + " ".join(f"{v:.3f}" for v in merit) + f" nT; goal {s.goal:g} nT"
            + ("" if s.goal <= GOAL_NT else f" (ACCEPTED ABOVE THE DEFAULT GOAL {GOAL_NT:g} "
               "nT by --goal)"))})


def predicted_error(fit: DailyModelFit, temperature: np.ndarray) -> np.ndarray:
    """Twice the rms of the curve's stated error over ``temperature`` (nT, x y z).

    The figure of merit of a daily curve (issue 34): the error a day recalibrated with it
    is expected to stay within (95 %), from the fit's covariance alone.
    """
    return 2.0 * np.sqrt(np.mean(fit.offset_sigma(np.asarray(temperature)) ** 2, axis=0))


def curve_error_text(fit: DailyModelFit, temperature: np.ndarray) -> str:
    """Return the curve's stated error: rms over the day's vectors, largest over the range."""
    grid = np.linspace(*fit.temperature_range, 101)
    rms = np.sqrt(np.mean(fit.offset_sigma(np.asarray(temperature)) ** 2, axis=0))
    worst = fit.offset_sigma(grid).max(axis=0)
    return ("1-sigma x y z: rms over the day " + " ".join(f"{v:.3f}" for v in rms)
            + " nT, largest over the range " + " ".join(f"{v:.3f}" for v in worst) + " nT")


def _jump_found(scan: JumpScan, origin: int, labels: np.ndarray, s: VarianceSettings,
                lsk=None) -> tuple[str, str, str, str]:
    """Return a detected jump's size, its interval's first and last time (UTC), statistics.

    The intervals start at ``labels`` x ``s.interval_s`` from ``origin`` (TT2000).
    """
    at = origin + int(round(labels[scan.split] * s.interval_s * NS))
    when = tt2000_to_utc(np.array([at - int(round(s.interval_s * NS)), at]), digits=0, lsk=lsk)
    size = ("an offset jump of " + " ".join(f"{v:+.2f}" for v in scan.step) + " +- "
            + " ".join(f"{v:.2f}" for v in scan.sigma) + " nT (x y z)")
    stats = (f"(change-point chi2 {scan.statistic:.0f} for 3 dof over {scan.splits} splits, "
             f"limit {s.max_jump_chi2:g})")
    return size, str(when[0]), str(when[1]), stats


def _scan_jump_interval(epoch: np.ndarray, b: np.ndarray, sub: np.ndarray, est,
                        start: int, s: VarianceSettings) -> JumpScan:
    """`scan_offset_step` over the sub-intervals of one Appendix B interval.

    The per-sub-interval normal equations of a constant offset (the daily model's with
    degree 0) at the fitted offset, with the segments `hedgecock_offsets` used.
    """
    labels, codes = np.unique(sub, return_inverse=True)
    k = labels.size
    seconds = (epoch - start) / NS
    length = _segment_length(epoch, s)
    if length is None:
        segments = _Segments(codes, k, seconds, False, float(s.interval_s))
    else:
        first = np.full(k, np.inf)
        np.minimum.at(first, codes, seconds)
        seg, m = segment_codes(seconds, codes, first, length)
        segments = _Segments(seg, m, seconds, True, length)
    accepted = np.isin(labels, est.labels[est.accepted])
    normal, rhs, _, _ = _normal_equations(b - est.offset, np.ones((b.shape[0], 1)), codes, k,
                                          accepted, codes, k, segments)
    return scan_offset_step(normal, rhs, accepted, np.arange(3), s.jump_min_side)


def _compressive_refusal(what: str, reason: np.ndarray, static: np.ndarray,
                         s: VarianceSettings) -> str:
    """Return the refusal text when too many intervals are compressive, else ``""``."""
    n_compressive = int(np.count_nonzero(reason == "compressive"))
    n_static = int(np.count_nonzero(static))
    if n_compressive <= s.max_compressive_share * n_static:
        return ""
    return (f"{what}: {n_compressive} of {n_static} intervals of {s.interval_s:g} s rejected "
            f"as compressive (limit {s.max_compressive_share:.0%}): |B| varies too much "
            "within the intervals; the selection then depends on the fitted curve and the "
            "stated errors would be too small (rosetta_fit.md decision 13); give a calmer "
            "(Alfvenic) day, or use --estimator zero-mean if the field averages to zero")


def _check_determined(level_a: xr.Dataset, temperature: np.ndarray, degree: int,
                      s: VarianceSettings, day) -> None:
    """Refuse, before any fit, data that cannot determine the daily polynomial.

    Names the actual cause: too few intervals of ``s.interval_s`` for the parameters, or
    a temperature that takes fewer distinct values than the polynomial has coefficients.
    """
    t = np.asarray(temperature, dtype=float)
    if ("epoch" not in level_a.coords and "epoch" not in level_a) or t.ndim != 1 \
            or t.size != level_a["epoch"].size or t.size == 0 \
            or not 0 <= int(degree) <= MAX_DEGREE:
        return  # input errors are named by fit_extended_model
    epoch = np.asarray(level_a["epoch"].values, dtype=np.int64)
    if day is None:
        day = str(tt2000_to_utc(epoch[:1], digits=0)[0])[:10]
    label = (f"{level_a.attrs.get('source', 'LEVEL_A dataset')}: extended model "
             f"{level_a.attrs.get('sensor', '')} {np.datetime64(day, 'D')} (variance, degree "
             f"{degree})")
    p = 3 * (int(degree) + 1)
    _, codes = _intervals(epoch, s.interval_s)
    full = int(np.count_nonzero(np.bincount(codes) >= _min_count(epoch, s)))
    if full < p + 1:
        raise FitRefusedError(
            f"{label}: {full} interval(s) of {s.interval_s:g} s hold enough samples "
            f"(>= {_min_count(epoch, s):.0f}) for {p} parameters, need {p + 1}; give at least "
            f"{(p + 1) * s.interval_s / 3600:.1f} h of data, a lower --degree, or shorter "
            "--block-seconds"
        )
    distinct = np.unique(t[np.isfinite(t)]).size
    if 0 < distinct < int(degree) + 1:
        raise FitRefusedError(
            f"{label}: the reduced temperature takes {distinct} distinct value(s) "
            f"({np.nanmin(t):.2f} .. {np.nanmax(t):.2f} C), a degree-{degree} polynomial needs "
            f"{int(degree) + 1}: P_1 .. P_{degree} are not determined; give a day over which "
            f"the temperature changes, or --degree {distinct - 1}"
        )


def fit_offset_jumps_variance(
    epoch: np.ndarray,
    b_sc: np.ndarray,
    start_utc: np.ndarray,
    end_utc: np.ndarray,
    *,
    sensor: str,
    settings: VarianceSettings | None = None,
    lsk=None,
    seed: int = 0,
) -> OffsetJumpFit:
    """Fit the Appendix B offset of each interval by variance minimisation (sec. 4.2.3.4).

    Per jump interval, the constant s/c offset ``J`` that makes ``|B_sc - J|`` least
    variable within its sub-intervals of ``settings.interval_s``
    (`fluxcal.calibration.variance_offsets.hedgecock_offsets`, criteria as
    `VarianceSettings`; bootstrap over the sub-intervals).  Unlike the seed's estimator
    (`fluxcal.missions.rosetta.fit.fit_offset_jumps`) it needs no attitude and assumes no
    zero mean of CSEQ ``B_z``.

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        TT2000 ns of the LEVEL_B vectors (several files concatenated in time order).
    b_sc : ndarray, shape (n, 3)
        LEVEL_B field (nT, s/c coordinates) without offset jumps subtracted.
    start_utc, end_utc : array of str
        Intervals (UTC, ISO), sorted and disjoint, ``[start, end)``.
    sensor : {"OB", "IB"}
    settings : VarianceSettings, optional
        ``max_sigma`` is the refusal limit (nT).
    seed : int
        Of the bootstrap.

    Returns
    -------
    OffsetJumpFit
        ``mean_field`` NaN (no CSEQ frame), ``rms`` the rms of ``|B_sc - J|`` about
        its sub-interval means, ``n_blocks`` the accepted sub-intervals.

    Raises
    ------
    FluxcalError
        Shapes, intervals, an interval without data.
    FitRefusedError
        An interval whose sub-intervals do not determine ``J`` (naming the rejections),
        are mostly compressive, or whose ``J`` has a standard error above
        ``settings.max_sigma`` or a value above ``settings.max_jump``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.4 and Appendix B.
    .. [2] Hedgecock (1975); Leinweber et al. (2008) (see module).
    """
    s = settings or VarianceSettings()
    sensor = check_sensor(sensor)
    start_utc, end_utc = np.asarray(start_utc, dtype=str), np.asarray(end_utc, dtype=str)
    epoch = np.asarray(epoch, dtype=np.int64)
    b_sc = np.asarray(b_sc, dtype=float)
    if b_sc.shape != (epoch.size, 3):
        raise FluxcalError(f"offset jumps: shapes epoch {epoch.shape}, b_sc {b_sc.shape}; "
                           "expected (n,), (n, 3)")
    starts, ends = interval_bounds(start_utc, end_utc, lsk)
    m = starts.size
    jumps, sigma = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    rms = np.full(m, np.nan)
    n_blocks, n_samples = np.zeros(m, dtype=int), np.zeros(m, dtype=int)
    for j in range(m):  # loop over jump intervals
        what = f"offset jump {sensor} {start_utc[j]} .. {end_utc[j]} (variance)"
        sel = (epoch >= starts[j]) & (epoch < ends[j])
        if not sel.any():
            raise FluxcalError(f"{what}: no vectors in the interval (leave it out)")
        e, b = epoch[sel], b_sc[sel]
        sub = (e - starts[j]) // int(round(s.interval_s * NS))
        try:
            est = hedgecock_offsets(
                b, sub, min_samples=int(np.ceil(_min_count(e, s))),
                min_eigenvalue_ratio=s.min_eigenvalue_ratio,
                min_relative_amplitude=s.min_relative_amplitude,
                max_compressibility=s.max_compressibility,
                max_iterations=s.max_iterations, n_bootstrap=s.n_bootstrap, seed=seed,
                seconds=(e - starts[j]) / NS, segment_s=_segment_length(e, s))
        except FluxcalError as exc:
            raise FitRefusedError(
                f"{what}: the sub-intervals of {s.interval_s:g} s do not determine the "
                f"offset ({exc}); give more rotating (Alfvenic) data in the interval, or "
                "use --estimator zero-mean with an attitude that varies"
            ) from None
        jumps[j], sigma[j] = est.offset, est.standard_error
        eligible = ~np.isin(est.reason, ("too_few_samples", "ill_conditioned"))
        n_compressive = int(np.count_nonzero(est.reason == "compressive"))
        if n_compressive > s.max_compressive_share * np.count_nonzero(eligible):
            raise FitRefusedError(
                f"{what}: {n_compressive} of {np.count_nonzero(eligible)} sub-intervals of "
                f"{s.interval_s:g} s rejected as compressive (limit "
                f"{s.max_compressive_share:.0%}): |B| varies too much; the selection then "
                "depends on the fitted offset and its error would be too small "
                "(rosetta_fit.md decision 13); give calmer data in the interval"
            )
        over_sigma = not np.all(sigma[j] <= s.max_sigma)
        if over_sigma or not np.all(2.0 * sigma[j] <= s.goal):
            why, advice = ((f"limit {s.max_sigma:g} nT", "raise --max-sigma") if over_sigma else
                           (f"twice the error is above the goal {s.goal:g} nT",
                            "accept a worse table with --goal (written into the file)"))
            raise FitRefusedError(
                f"{what}: J = " + " ".join(f"{v:.3g}" for v in jumps[j]) + " +- "
                + " ".join(f"{v:.3g}" for v in sigma[j])
                + f" nT ({why}; {est.n_used} of {est.labels.size} "
                f"sub-intervals accepted, rejected: {_reasons_text(est.reason)}); give more "
                f"rotating data in the interval, or {advice}"
            )
        if not np.all(np.abs(jumps[j]) <= s.max_jump):
            axis = int(np.argmax(np.abs(jumps[j])))
            raise FitRefusedError(
                f"{what}: J_{'xyz'[axis]} = {jumps[j, axis]:.4g} +- {sigma[j, axis]:.3g} nT is "
                f"outside the physical range +-{s.max_jump:g} nT of an Appendix B jump (the "
                "largest shipped is 25 nT): a field taken for an offset or data of another "
                "sensor state; check the interval's data and --calib"
            )
        scan = _scan_jump_interval(e, b, sub, est, starts[j], s)
        if scan.statistic > s.max_jump_chi2:
            size, first, last, stats = _jump_found(scan, int(starts[j]), est.labels, s, lsk)
            raise FitRefusedError(
                f"{what}: {size} inside the interval, between {first} and {last} UTC "
                f"{stats}: one constant offset would spread it; split the interval at about "
                f"{last} (--intervals CSV) and fit again"
            )
        used = np.isin(sub, est.labels[est.accepted])
        mag = np.linalg.norm(b[used] - est.offset, axis=1)
        _, codes = np.unique(sub[used], return_inverse=True)
        mean = np.bincount(codes, mag) / np.bincount(codes)
        rms[j] = float(np.sqrt(np.mean((mag - mean[codes]) ** 2)))
        n_blocks[j], n_samples[j] = est.n_used, int(sel.sum())
    return OffsetJumpFit(sensor, start_utc, end_utc, jumps, sigma, np.full((m, 2), np.nan),
                         rms, n_blocks, n_samples, float(s.interval_s), estimator="variance")
