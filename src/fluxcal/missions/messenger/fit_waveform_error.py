"""The heater waveform columns' stated errors: the pooled fit refitted without each fold (issue 34).

The waveform columns (sec. 6) are unmixed from the duty-cycle bins' phase-binned means
by weighted least squares at each phase (`fluxcal.missions.messenger.fit.unmix_waveforms`)
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

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (waveform columns per 4-% duty
   bin, linear interpolation between them).
.. [2] Efron, B. and Stein, C. (1981), The jackknife estimate of variance, Annals of
   Statistics 9(3), 586-596 (delete-a-group: ``(K - 1) / K`` times the spread).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import reduce

import numpy as np

from fluxcal.calibration.binned_stats import BinnedMoments


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


def jackknife_error(values: np.ndarray) -> float:
    """Rms over the phase of the delete-a-group jackknife error (counts).

    ``values`` (groups, phase): the column refitted without each group.  The variance
    at each phase is ``(K - 1) / K sum_k (x_(-k) - mean)^2``; for the mean of ``K``
    equal groups it is the mean's variance exactly, and for unequal or unequally noisy
    groups it errs on the high side (delete-a-group is the CR3 sandwich of a linear
    fit).  NaN with fewer than two groups.
    """
    x = np.asarray(values, dtype=float)
    k = x.shape[0]
    if k < 2:
        return float("nan")
    var = (k - 1) / k * ((x - x.mean(axis=0)) ** 2).sum(axis=0)
    return float(np.sqrt(np.mean(var)))
