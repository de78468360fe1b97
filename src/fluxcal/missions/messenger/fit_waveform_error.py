"""The heater waveform columns' stated errors: the pooled fit refitted without each fold (issue 34).

The waveform columns (sec. 6) are unmixed from the duty-cycle bins' phase-binned means
by weighted least squares at each phase (`fluxcal.missions.messenger.fit_waveforms.unmix_waveforms`)
and smoothed by a periodic spline; the samples are split into folds of 30-min blocks
(`fit_reduce.WAVEFORM_FOLDS`).  The column's error is the delete-a-group jackknife of
that whole fit: refitted on the statistics without fold k (`leave_one_out`, the other
folds merged), ``var = (K - 1) / K sum_k (x_(-k) - mean)^2`` at each phase
(`jackknife_error`).

Why not the spread of the waveforms fitted to each fold alone (entry 29): a fold whose
own samples barely reach a column (an edge column seen through its neighbour's bin)
solves it badly, yet the pooled fit hardly leans on that fold there; the spread counted
such a fold at the weight of all the samples leaning on the column, and stated the 40-%
column of calm seed 7003 at 9.3 counts against 1.7 true.  Refitted without a fold, the
column is still solved through the other folds, so a fold moves it only as much as it
moved the pooled fit; a fold noisier than the others (a disturbed hour) counts with its
own noise, and a column that leans on a poorly determined neighbour carries the
neighbour's error into its own refits (docs/decisions/messenger_fit.md, entry 34).

A column whose own samples fill fewer than three effective folds (`effective_folds`)
scales the jackknife by what each fold tells it (`jackknife_scale`): ``(K - 1) / K``
counts a fold holding none of its samples as a whole group, 1.5x the variance for a
column in two folds of four, on top of the few-folds widening (entry 37).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (waveform columns per 4-% duty
   bin, linear interpolation between them).
.. [2] Efron, B. and Stein, C. (1981), The jackknife estimate of variance, Annals of
   Statistics 9(3), 586-596 (delete-a-group: ``(K - 1) / K`` times the spread).
.. [3] Hausman, J. A. (1978), Specification tests in econometrics, Econometrica 46(6),
   1251-1271 (Lemma 2.1: an efficient estimator is uncorrelated with its difference
   from any other consistent one, so the difference's variance is the difference of
   the variances).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import reduce

import numpy as np

from fluxcal.calibration.binned_stats import BinnedMoments

#: Effective folds (`effective_folds`) below which a column's jackknife is scaled by the
#: information each fold gives it (`jackknife_scale`): fewer than two comparisons.
FEW_FOLDS = 3.0


def leave_one_out(folds: Sequence[Sequence[BinnedMoments]]
                  ) -> list[list[BinnedMoments] | None]:
    """Per fold, the waveform statistics of all the other folds merged (one per duty bin).

    ``folds[k][b]``: fold k's phase-binned moments of duty bin ``b``.  A fold with no
    samples in any bin gives None (leaving it out changes nothing, so it is not a
    group of the jackknife).
    """
    out: list[list[BinnedMoments] | None] = []
    for k, fold in enumerate(folds):
        if not any(int(w.count.sum()) for w in fold):
            out.append(None)
            continue
        others = [h for i, h in enumerate(folds) if i != k]
        out.append([reduce(BinnedMoments.merge, [h[b] for h in others])
                    for b in range(len(fold))])
    return out


def jackknife_error(values: np.ndarray, scale: float | None = None) -> float:
    """Rms over the phase of the delete-a-group jackknife error (counts).

    ``values`` (groups, phase): the column refitted without each group.  The variance
    at each phase is ``c sum_k (x_(-k) - mean)^2`` with ``c = (K - 1) / K`` (``scale``
    None); for the mean of ``K`` equal groups it is the mean's variance exactly, and for
    unequal or unequally noisy groups it errs on the high side (delete-a-group is the
    CR3 sandwich of a linear fit).  ``scale``: another ``c`` (`jackknife_scale`).  NaN
    with fewer than two groups.
    """
    x = np.asarray(values, dtype=float)
    k = x.shape[0]
    if k < 2:
        return float("nan")
    c = (k - 1) / k if scale is None else float(scale)
    var = c * ((x - x.mean(axis=0)) ** 2).sum(axis=0)
    return float(np.sqrt(np.mean(var)))


def effective_folds(own: np.ndarray) -> float:
    """Return Kish's effective number of folds of a column's own samples.

    ``N^2 / sum n_k^2`` (``n_k`` the samples in fold k); 0 without samples.
    """
    n = np.asarray(own, dtype=float)
    return float(n.sum() ** 2 / (n ** 2).sum()) if n.sum() > 0 else 0.0


def jackknife_scale(own: np.ndarray, variance: np.ndarray, without: np.ndarray
                    ) -> float | None:
    """Return the jackknife's ``c`` for a column seen in few folds, None for ``(K - 1) / K``.

    ``own`` (K,): the column's own samples per fold; ``variance`` (phase,) and
    ``without`` (K, phase): its unmixing variance per unit sample variance
    (`fit_waveforms.unmixing_variance`) with all folds and without each.  For a linear fit with
    weights right up to a common factor, the refit without fold k differs from the
    pooled one by an amount uncorrelated with the pooled one, so
    ``E[(x_(-k) - x)^2] = V_(-k) - V`` and ``c = V / sum_k (V_(-k) - V)`` makes the
    jackknife the pooled variance ``V`` (Hausman 1978; ``(K - 1) / K`` for K equal
    folds).  Where a fold holds none of the column's own samples (it determines the
    column only through a neighbour, or not at all) ``(K - 1) / K`` counts it as a
    whole group: two equal folds of four give 1.5x the variance.  Used only where the
    column's own samples fill fewer than `FEW_FOLDS` effective folds: there
    `fit_waveforms.few_folds_widening` already states the estimate's own scatter (Student t of
    fewer than two comparisons, >= 1.10x), and the conservative side of ``(K - 1) / K``
    would count it a second time (entry 37).  Elsewhere (None) the jackknife
    keeps it (entry 34).  ``V`` and the differences are averaged over the phases where
    every fit solves the column; a difference below zero (a pseudo-inverse artefact:
    taking samples away cannot determine a column better) counts as zero; ``c`` is at
    most ``(K - 1) / K``.
    """
    k = len(own)
    if effective_folds(own) >= FEW_FOLDS or k < 2:
        return None
    v = np.asarray(variance, dtype=float)
    vk = np.asarray(without, dtype=float)
    ok = np.isfinite(v) & np.all(np.isfinite(vk), axis=0)
    if not ok.any():
        return None
    lost = np.maximum(vk[:, ok] - v[ok][None, :], 0.0).mean(axis=1).sum()
    if not lost > 0:
        return None
    return float(min(v[ok].mean() / lost, (k - 1) / k))
