"""The heater waveform columns' stated errors: each fold's part of the pooled unmixing (issue 34).

The waveform columns (sec. 6) are unmixed from the duty-cycle bins' phase-binned means
by weighted least squares at each phase (`fluxcal.missions.messenger.fit.unmix_waveforms`);
the samples are split into folds of 30-min blocks (`fit_reduce.WAVEFORM_FOLDS`).
`fold_parts` writes the pooled solution's error as a sum over the folds,
``W - W_true = sum_k (A'NA)^-1 A' N_k e_k`` (``e_k``: fold k's bin means less the
columns' truth; the pooled means are the folds' count-weighted sums), and estimates each
fold's term by its residuals from the pooled solution.  The sum of their squares is
the cluster-robust ("sandwich") variance with the folds as clusters, each term divided
by one less the fold's leverage on the column (the CR2 correction; for a plain mean of
folds of ``n_k`` samples the leverage is ``n_k / N`` and the estimate is unbiased).

Why not the spread of waveforms fitted to each fold on its own (entry 29): a fold whose
own samples barely reach a column (an edge column seen through its neighbour's bin)
solves it badly, yet the pooled fit hardly leans on that fold there; the spread counted
such a fold at the weight of the samples leaning on the column and stated the 40-%
column of calm seed 7003 at 9.3 counts against 1.7 true.  Here every fold is seen
through the pooled design, and a fold with noisier data than the others (a disturbed
hour) is counted with its own residuals (docs/decisions/messenger_fit.md, entry
"3x-calm").

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (waveform columns per 4-% duty
   bin, linear interpolation between them).
.. [2] Bell, R. M. and McCaffrey, D. F. (2002), Bias reduction in standard errors for
   linear regression with multi-stage samples, Survey Methodology 28(2), 169-181 (CR2).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fluxcal.calibration.binned_stats import BinnedMoments


def fold_parts(waveform: Sequence[BinnedMoments], folds: Sequence[Sequence[BinnedMoments]],
               min_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Each fold's part of the pooled waveform columns' error, per phase bin.

    Parameters
    ----------
    waveform : sequence of BinnedMoments
        The pooled phase-binned statistics per duty-cycle bin (columns: 3 counts, phase,
        then the interpolation weight on each waveform column).
    folds : sequence of sequence of BinnedMoments
        The same split into folds (``folds[k][b]``); their sums are ``waveform``.
    min_samples : int
        Fewest samples of a bin at a phase (and leaning on a column) to enter the
        unmixing, as in `fit.unmix_waveforms`.

    Returns
    -------
    parts : ndarray, shape (n_folds, n_phase, n_columns, 3)
        ``(A'NA)^-1 A' N_k (ybar_k - A_k W)``: fold k's residuals from the pooled
        solution ``W`` through the pooled unmixing (counts); the folds' parts sum to
        zero.  NaN where the column is not unmixed.
    share : ndarray, shape (n_folds, n_phase, n_columns)
        Fold k's leverage on each column, ``[(A'NA)^-1 A'N_k A]_jj``: the column's
        part of the trace of the fold's block of the hat matrix (CR2), which sums to
        one over the folds (``n_k / N`` for a plain mean of folds).
    """
    count = np.stack([w.count for w in waveform]).astype(float)     # (nb, n_phase)
    mean = np.stack([w.mean() for w in waveform])                   # (nb, n_phase, 4 + nb)
    f_count = np.stack([np.stack([w.count for w in h]) for h in folds]).astype(float)
    f_mean = np.nan_to_num(np.stack([np.stack([w.mean() for w in h]) for h in folds]))
    n_folds, nb, n_phase = f_count.shape
    usable = count >= min_samples
    support = np.einsum("bp,bpj->pj", np.where(usable, count, 0.0),
                        np.where(usable[:, :, None], np.abs(mean[:, :, 4:]), 0.0))
    parts = np.full((n_folds, n_phase, nb, 3), np.nan)
    share = np.full((n_folds, n_phase, nb), np.nan)
    for p in range(n_phase):  # phase bins (100), each a small least-squares problem
        rows = usable[:, p]
        cols = support[p] >= min_samples
        if not rows.any() or not cols.any():
            continue
        a = mean[rows, p, 4:][:, cols]
        n = count[rows, p]
        inv = np.linalg.pinv(a.T @ (n[:, None] * a))
        w = inv @ (a.T @ (n[:, None] * mean[rows, p, :3]))
        nk = f_count[:, rows, p]                                     # (K, rows)
        resid = f_mean[:, rows, p, :3] - f_mean[:, rows, p, 4:][:, :, cols] @ w
        parts[:, p, cols] = np.einsum("jr,kr,krc->kjc", inv @ a.T, nk, resid)
        share[:, p, cols] = np.einsum("jr,kr,rj->kj", inv @ a.T, nk, a)
    return parts, share


def cluster_robust_error(parts: np.ndarray, share: np.ndarray) -> tuple[float, np.ndarray]:
    """Rms over the phase of the pooled column's error from its folds' parts (counts).

    ``parts`` (folds, phase): each fold's part of the error, as fitted (`fold_parts`,
    smoothed as the column was); ``share`` (folds,): each fold's leverage on the column
    (`fold_parts`).  The variance at each phase is ``sum_k part_k^2 / (1 - share_k)``: for the
    count-weighted mean of folds of ``n_k`` samples, share ``n_k / N``, its expectation
    is ``s^2 / N`` whatever the sizes (CR2).  Returns the error and each fold's
    contribution to the variance (mean over the phase), whose spread says how many
    folds the estimate really rests on.  NaN when fewer than two folds carry a share.
    """
    h = np.clip(np.asarray(share, dtype=float), 0.0, None)
    if np.count_nonzero(h > 1e-9) < 2 or h.max() >= 1.0 - 1e-9:
        return float("nan"), np.zeros(h.size)
    var = (np.asarray(parts, dtype=float) ** 2) / (1.0 - h)[:, None]
    return float(np.sqrt(np.mean(var.sum(axis=0)))), var.mean(axis=1)
