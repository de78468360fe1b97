"""The heater waveforms of sec. 6 fitted from flight data, with their stated errors.

A duty-cycle bin of the statistics (`fluxcal.missions.messenger.fit_reduce.reduce_day`)
holds heater periods of several duty cycles, and each period's waveform is the
pipeline's linear interpolation between the columns of Tables 6-8 (sec. 6):

* `unmix_waveforms` solves, at each of the 100 phase bins, for the columns whose
  interpolation gives the bins' averages (`unmixing_variance`: how much a set of
  samples determines each column);
* `fit_waveforms` smooths each column with a periodic spline (zero mean over the heater
  cycle) and states its error from refits without each fold of 30-min blocks
  (`fluxcal.missions.messenger.fit_waveform_error`, widened by `few_folds_widening`);
  `waveform_column_errors` is that error alone, which `fit_passes.fit_days` states once
  after its passes;
* `supported_duty_range` is the duty-cycle range (``D_RANGE``) over which the fitted
  columns are determined.

`fluxcal.missions.messenger.fit` calls them for both estimators (`fit.fit_calibration`,
`fit.fit_variance_calibration`, `fit.FitResult.duty_range`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (4 % duty-cycle bins with
   centres 12-40 %, linear interpolation between bins), Appendix Tables 6-8.
.. [2] docs/decisions/messenger_fit.md entries 19, 25, 29, 33, 34, 37 and 40.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import stats as sps

from fluxcal.calibration.constrained_fits import (
    PeriodicSplineFit,
    fit_periodic_spline,
    fit_periodic_splines,
)
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.fit_merit import AXES
from fluxcal.missions.messenger.fit_reduce import MIN_BIN_SAMPLES, DayStatistics
from fluxcal.missions.messenger.fit_waveform_error import (
    effective_folds,
    jackknife_error,
    jackknife_scale,
    leave_one_out,
)

#: Fewest filled phase bins (of 100) for a heater-waveform column to be fitted.
MIN_PHASE_BINS = 50


def unmix_waveforms(stats: DayStatistics, waveform: Sequence | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per phase bin, the waveform columns whose interpolation gives the bin averages.

    A duty-cycle bin holds periods of several duty cycles; each period's waveform is the
    pipeline's linear interpolation between the columns (sec. 6), so the average of bin
    ``b`` at phase ``p`` is ``sum_j A[b, j] W_j(p)`` with ``A`` the mean interpolation
    weights (`fluxcal.missions.messenger.fit_reduce.interpolation_weights`).  Solved for
    ``W`` by weighted least squares (``sqrt(N)`` per bin) at each phase bin; a column no
    period leans on stays NaN.

    Returns
    -------
    phase : ndarray, shape (n_phase,)
        Mean phase of each phase bin (s).
    columns : ndarray, shape (n_phase, n_columns, 3)
        Unmixed waveform (counts), NaN where undetermined.
    support : ndarray, shape (n_phase, n_columns)
        Samples leaning on each column (sum of weights).
    """
    waveform = stats.waveform if waveform is None else waveform
    count, mean, usable, support = _unmixing_design(waveform)
    with np.errstate(invalid="ignore"):
        phase = np.nansum(np.where(usable, mean[:, :, 3] * count, 0.0), axis=0) / np.sum(
            np.where(usable, count, 0), axis=0)
    columns = np.full((count.shape[1], len(waveform), 3), np.nan)
    for p in range(count.shape[1]):  # phase bins (100), each a small least-squares problem
        got = _phase_system(count, mean, usable, support, p)
        if got is None:
            continue
        cols, a, y = got
        sol, *_ = np.linalg.lstsq(a, y, rcond=None)
        columns[p, cols] = sol
    return phase, columns, support


def _unmixing_design(waveform: Sequence) -> tuple[np.ndarray, ...]:
    """Return the counts, means, usable bins and samples leaning on each column.

    Shapes ``(nb, n_phase)``, ``(nb, n_phase, 4 + nb)``, ``(nb, n_phase)`` and
    ``(n_phase, nb)``: the design of `unmix_waveforms` and `unmixing_variance`.
    """
    count = np.stack([w.count for w in waveform])
    mean = np.stack([w.mean() for w in waveform])
    usable = count >= MIN_BIN_SAMPLES
    support = np.einsum("bp,bpj->pj", np.where(usable, count, 0).astype(float),
                        np.where(usable[:, :, None], np.abs(mean[:, :, 4:]), 0.0))
    return count, mean, usable, support


def _phase_system(count, mean, usable, support, p: int):
    """Return, at phase bin ``p``, the columns solved, the weighted design and the data.

    Each bin weighted by ``sqrt(N)``; None when nothing is solved there.
    """
    rows = usable[:, p]
    cols = support[p] >= MIN_BIN_SAMPLES
    if not rows.any() or not cols.any():
        return None
    w = np.sqrt(count[rows, p].astype(float))[:, None]
    return cols, mean[rows, p, 4:][:, cols] * w, mean[rows, p, :3] * w


def unmixing_variance(waveform: Sequence) -> np.ndarray:
    """Return the variance of `unmix_waveforms`' solution per unit sample variance.

    Per phase bin and column: ``diag(A+ A+')`` of the weighted design (``A+`` its
    pseudo-inverse, the solution `numpy.linalg.lstsq` gives), shape
    ``(n_phase, n_columns)``, NaN where the column is not solved.  It depends on the
    counts and interpolation weights alone: how much a set of samples determines each
    column (`fit_waveform_error.jackknife_scale`).
    """
    count, mean, usable, support = _unmixing_design(waveform)
    out = np.full(support.shape, np.nan)
    for p in range(count.shape[1]):
        got = _phase_system(count, mean, usable, support, p)
        if got is not None:
            cols, a, _ = got
            out[p, cols] = (np.linalg.pinv(a) ** 2).sum(axis=1)
    return out


def few_folds_widening(own: np.ndarray, folds: int) -> float:
    """Factor (>= 1) on a waveform column's jackknife error when its own samples lie in few folds.

    ``own`` holds the column's own samples (its duty-cycle bin's) in each fold.  The
    refits' spread pools 100 phases, so for a column whose own samples fill every fold
    it covers the truth as it is (entries 29 and 34).  With its own samples in
    ``K_eff = N^2 / sum n_k^2`` effective folds (Kish), the spread compares
    ``K_eff - 1`` of them: widened by the Student-t ratio
    ``t_nu(0.841) / t_{K-1}(0.841)``, ``nu = max(K_eff - 1, 1)``, the t quantile of one
    normal standard deviation (two equal folds: 1.54 for four folds).
    """
    k_eff = effective_folds(own)
    if k_eff <= 0 or folds < 2:
        return 1.0
    q = sps.norm.cdf(1.0)
    nu = max(k_eff - 1.0, 1.0)
    return float(max(sps.t.ppf(q, nu) / sps.t.ppf(q, folds - 1), 1.0))


def fit_waveforms(
    stats: DayStatistics, base: MessengerCalibration, *, errors: bool = True
) -> tuple[np.ndarray, list[list[PeriodicSplineFit | None]], np.ndarray | None]:
    """Fit the waveform columns (sec. 6), and state their error by refitting without each fold.

    Returns the table, the splines (None where kept from ``base``) and, per axis and
    duty bin, the rms (counts, over the phase) of the delete-a-fold jackknife error of
    the fitted column (the same fit on the statistics without each fold of 30-min
    blocks, `DayStatistics.waveform_folds`, `fit_waveform_error.leave_one_out`,
    `fit_waveform_error.jackknife_error`), widened when the column's own samples lie in
    few folds (`few_folds_widening`; scaled by the information each fold gives the
    column where those are fewer than three, `fit_waveform_error.jackknife_scale`,
    entry 37), and the spline's smoothing bias added in
    quadrature (the smoothing applied once more to the fitted curve, ``(S - I) f_hat``:
    common to the refits, so not in their spread); a column kept from ``base`` is given
    its own rms (its error unknown, entries 19 and 29), and a fitted column that some
    fold's removal leaves unfitted (it rests on one fold), or with fewer than two folds
    holding samples, the larger of its rms and the shipped column's (entry 34).

    With ``errors=False`` the refits are not done and the error is None: no pass
    reads it, so `fit_passes.fit_days` states it once, from the last pass's statistics
    and table (entry 33).
    """
    table = np.array(base.heater_signal, dtype=float)
    nb = len(stats.waveform)
    fits: list[list[PeriodicSplineFit | None]] = [[None] * nb for _ in AXES]
    error = np.sqrt(np.mean(table[:, :100, :] ** 2, axis=1))  # (axis, bin): base's own rms
    phase, columns, support = unmix_waveforms(stats)
    loo = [h for h in leave_one_out(stats.waveform_folds) if h is not None] if errors else []
    without = [unmix_waveforms(stats, h) for h in loo]
    if errors:  # how much each fold determines each column (jackknife_scale)
        info = unmixing_variance(stats.waveform)
        info_without = np.stack([unmixing_variance(h) for h in loo]) if loo else None
    own = np.array([[w.count.sum() for w in h] for h in stats.waveform_folds], dtype=float)

    def splines(ph, col, sup, b):
        # the three axes of a column share its phases and weights: one decomposition
        # (`fit_periodic_splines`, the same fits as one at a time; entry 40)
        ok = np.isfinite(ph) & np.all(np.isfinite(col[:, b]), axis=1)
        if ok.sum() < MIN_PHASE_BINS:
            return [None] * 3
        out = []
        for fit in fit_periodic_splines(ph[ok], [col[ok, b, j] for j in range(3)],
                                        np.sqrt(sup[ok, b]), 100.0):
            values = fit.table(1.0)[1]
            out.append((fit, values - values[:-1].mean()))
        return out

    def smoothing_bias(fit, ph, col, sup, b):
        # the spline's own smoothing applied to the fitted curve: (S - I) f_hat, the
        # plug-in estimate of (S - I) f, a bias the folds share (entry 29)
        ok = np.isfinite(ph) & np.all(np.isfinite(col[:, b]), axis=1)
        f_hat = fit(ph[ok])
        again = fit_periodic_spline(ph[ok], f_hat, np.sqrt(sup[ok, b]), 100.0,
                                    smoothing=fit.lam, n_knots=fit.n_knots)
        return float(np.sqrt(np.mean((again(ph[ok]) - f_hat) ** 2)))

    for b in range(nb):
        got_b = splines(phase, columns, support, b)
        refits_b = ([splines(*h, b) for h in without]
                    if errors and got_b[0] is not None else [])
        for j in range(3):
            got = got_b[j]
            if got is None:
                continue
            fits[j][b], table[j, :, b] = got
            if not errors:
                continue
            refits = [r[j] for r in refits_b]
            err = float("nan")
            if len(refits) >= 2 and all(r is not None for r in refits):
                scale = jackknife_scale(own[:, b], info[:, b], info_without[:, :, b])
                err = jackknife_error(np.stack([r[1][:-1] for r in refits]), scale)
                err *= few_folds_widening(own[:, b], len(stats.waveform_folds))
                err = np.hypot(err, smoothing_bias(fits[j][b], phase, columns, support, b))
            # unknown (the column rests on one fold): as large as the column itself,
            # fitted or shipped, not the shipped one's rms alone (entry 34)
            error[j, b] = err if np.isfinite(err) else max(
                error[j, b], float(np.sqrt(np.mean(table[j, :100, b] ** 2))))
    return table, fits, (error if errors else None)


def waveform_column_errors(stats: DayStatistics, base: MessengerCalibration) -> np.ndarray:
    """Stated error (counts) of each waveform column, shape (3, n_duty_bins).

    What `fit_waveforms` states for the fit of ``stats`` from ``base``:
    `fit_passes.fit_days` calls it once after its passes, for the last one, whose fit
    skipped it (entry 33).
    """
    return fit_waveforms(stats, base)[2]


def supported_duty_range(count: np.ndarray, fitted: np.ndarray, centres: np.ndarray
                         ) -> tuple[float, float] | None:
    """Return the duty-cycle range (percent) over which the heater waveforms are determined.

    A duty-cycle bin (4 % wide around each column's centre, sec. 6) is *supported* when
    its own heater-on samples fill at least `MIN_PHASE_BINS` of its phase bins with
    `MIN_BIN_SAMPLES` each (the rule `fit_waveforms` fits a column by, applied to the
    bin's own samples, not to those of its neighbours that lean on the column through
    the interpolation) and its column was fitted on every axis.  The range is the
    contiguous run of supported bins around the one holding the most samples, from the
    lower edge of its first bin to the upper edge of its last (``lo <= d < hi``: the fit
    bins a period of duty ``d`` by ``floor((d - lo) / 4)``).  Between two supported
    columns the pipeline interpolates two fitted columns; within half a bin beyond the
    last centre it extends the last two (sec. 6), as it did for the bin's own samples
    in the fit; further out it extrapolates what no sample determined (issue 34,
    docs/decisions/messenger_fit.md entry 25).

    Parameters
    ----------
    count : ndarray, shape (n_bins, n_phase)
        Samples per phase bin of each duty-cycle bin (`DayStatistics.waveform` counts).
    fitted : ndarray of bool, shape (n_axes, n_bins)
        Whether each axis's column was fitted (not kept from the base table).
    centres : ndarray, shape (n_bins,)
        Evenly spaced bin centres (percent; 12..40 in Tables 6-8).

    Returns
    -------
    tuple of float or None
        ``(lo, hi)`` in percent; None when no bin is supported.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (4 % bins, centres 12-40 %,
       linear between bins, the 36-40 % slope extended above 40 %).
    """
    count = np.asarray(count)
    centres = np.asarray(centres, dtype=float)
    filled = (count >= MIN_BIN_SAMPLES).sum(axis=1) >= MIN_PHASE_BINS
    ok = filled & np.all(np.asarray(fitted, dtype=bool), axis=0)
    if not ok.any():
        return None
    total = np.where(ok, count.sum(axis=1), -1)
    a = b = int(np.argmax(total))
    while a > 0 and ok[a - 1]:
        a -= 1
    while b < ok.size - 1 and ok[b + 1]:
        b += 1
    half = 0.5 * float(centres[1] - centres[0])
    return float(centres[a] - half), float(centres[b] + half)

