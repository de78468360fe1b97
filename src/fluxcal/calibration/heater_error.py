"""The error a heater-signal table's columns leave in a day's field, from that day's duty cycles.

A heater-signal table holds one waveform column per duty-cycle bin (evenly spaced bin
centres; a period of duty cycle ``d`` belongs to the bin whose centre lies within half
a spacing, ``c - w/2 <= d < c + w/2``).  Each column carries a stated rms error (over
the phase); the columns' errors are independent.  Over a day's samples, of which
``n_k`` lie in heater periods of bin ``k``, the waveform's error per sample is then
``sum_k err_k^2 n_k / N`` (``N`` all the samples the rms is over), through a linear map
(counts to field) row by row as ``(M^2) @ var``.  The counts are the day's own: a day
whose duty cycles sit in the worse-determined bins carries more error than the days the
table was fitted on.

Whether that is worth saying (`exceeds_stated`): the day's own total, the stated total
with its waveform part replaced by the day's (`day_total`, the parts independent),
against the goal the table was accepted at, and against the stated total plus the
stated part's own scatter (`part_scatter`: the columns' errors are themselves estimates,
a delete-a-fold jackknife over ``K`` folds, ``K - 1`` degrees of freedom).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (duty-cycle bins, the
   interpolation of the columns), Appendix Tables 6-8.
"""

from __future__ import annotations

import numpy as np

__all__ = ["day_total", "duty_bin_counts", "duty_bin_index", "exceeds_stated",
           "part_scatter", "waveform_part"]


def duty_bin_index(duty_percent: np.ndarray, bins_percent: np.ndarray) -> np.ndarray:
    """Return the duty-cycle bin of each value, -1 for none (NaN, or beyond the end bins).

    Bin ``k`` holds ``c_k - w/2 <= d < c_k + w/2`` (``c`` the evenly spaced centres,
    ``w`` their spacing): 10..42 % for the centres 12..40 % (sec. 6's 4-% bins).
    """
    centres = np.asarray(bins_percent, dtype=float)
    width = centres[1] - centres[0]
    d = np.asarray(duty_percent, dtype=float)
    with np.errstate(invalid="ignore"):
        b = np.floor((d - (centres[0] - width / 2.0)) / width)
    ok = np.isfinite(b) & (b >= 0) & (b < centres.size)
    return np.where(ok, b, -1).astype(np.int64)


def duty_bin_counts(duty_percent: np.ndarray, bins_percent: np.ndarray
                    ) -> tuple[np.ndarray, int]:
    """Return the samples per duty-cycle bin (`duty_bin_index`) and those in no bin.

    ``duty_percent``: the duty cycle of each heater-on sample's period (NaN counts in no
    bin).
    """
    b = duty_bin_index(duty_percent, bins_percent)
    n = np.asarray(bins_percent).size
    return np.bincount(b[b >= 0], minlength=n).astype(float), int(np.count_nonzero(b < 0))


def waveform_part(column_error: np.ndarray, counts: np.ndarray, n_samples: float,
                  matrix: np.ndarray | None = None) -> np.ndarray:
    """Return the rms error (per output axis) the columns' stated errors leave over a day.

    ``sqrt((M^2) @ sum_k err_k^2 counts_k / n_samples)``: independent column errors
    ``column_error`` (shape ``(axes, bins)``, counts, rms over the phase), ``counts``
    samples in periods of each bin out of ``n_samples`` samples, through ``matrix``
    (``M``, element-wise squared: each output axis sums the variances of the input
    axes it mixes; None: the identity).  Zero where ``n_samples`` is not positive.
    """
    err = np.asarray(column_error, dtype=float)
    c = np.asarray(counts, dtype=float)
    if not n_samples > 0:
        return np.zeros(err.shape[0] if matrix is None else np.asarray(matrix).shape[0])
    var = (err ** 2 * (c / float(n_samples))[None, :]).sum(axis=1)
    m2 = np.eye(err.shape[0]) if matrix is None else np.asarray(matrix, dtype=float) ** 2
    return np.sqrt(m2 @ var)


def day_total(stated_total: np.ndarray, stated_part: np.ndarray,
              day_part: np.ndarray) -> np.ndarray:
    """Return a day's own total error: the stated total with its waveform part the day's.

    ``sqrt(max(T^2 - W_s^2, 0) + W_d^2)`` per axis: ``T`` the stated total (the waveform
    part independent of the rest and added in quadrature), ``W_s`` its waveform part,
    ``W_d`` the day's own (`waveform_part` over the day's duty-bin counts).  The other
    parts are kept as stated (over the fitted samples' temperatures).
    """
    t = np.asarray(stated_total, dtype=float)
    rest = np.maximum(t ** 2 - np.asarray(stated_part, dtype=float) ** 2, 0.0)
    return np.sqrt(rest + np.asarray(day_part, dtype=float) ** 2)


def part_scatter(stated_part: np.ndarray, folds: int) -> np.ndarray:
    """Return the stated waveform part's own scatter: ``W_s / sqrt(2 (K - 1))``.

    The relative standard error of a standard deviation estimated with ``K - 1`` degrees
    of freedom (a delete-a-fold jackknife over ``K`` folds), ``1 / sqrt(2 (K - 1))``:
    0.41 for 4 folds.  A part summed over several columns whose errors are estimated
    alike scatters at most that much relatively (a positive combination of estimates of
    one relative scatter, whatever their correlation), so this is the most the stated
    part may be off by at 1 sigma, in nT.
    """
    if folds < 2:
        raise ValueError(f"folds {folds}: a jackknife needs at least 2")
    return np.asarray(stated_part, dtype=float) / np.sqrt(2.0 * (folds - 1))


def exceeds_stated(day_part: np.ndarray, stated_part: np.ndarray, stated_total: np.ndarray,
                   goal: float, folds: int) -> tuple[np.ndarray, np.ndarray]:
    """Return which axes a day's own waveform part puts beyond what the table states.

    An axis is beyond when the day's own total (`day_total`) exceeds the goal, or
    exceeds the stated total by more than the stated part's scatter (`part_scatter`):
    ``T_d > goal`` or ``T_d - T > W_s / sqrt(2 (K - 1))``.  Returns ``(beyond, T_d)``
    per axis.  ``goal`` may be ``inf`` (none stated).
    """
    t_d = day_total(stated_total, stated_part, day_part)
    excess = t_d - np.asarray(stated_total, dtype=float)
    return (t_d > goal) | (excess > part_scatter(stated_part, folds)), t_d
