"""The heater waveform columns' stated errors against brute force (issue 34, entry 29).

Expected values come from the construction, never from the code: a known waveform plus
Gaussian noise of a known size, drawn many times; the truth is the fitted column less
the known waveform.  Tolerances are stated from the number of draws.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from fluxcal.calibration.binned_stats import BinnedMoments
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit import _fit_waveforms, few_folds_widening, fold_error
from fluxcal.missions.messenger.fit_reduce import (
    WAVEFORM_FOLDS,
    DayStatistics,
    FitSettings,
    interpolation_weights,
)

START = "2012-06-01T00:00:00"
PHASE = np.arange(100.0)


def _known(phase: np.ndarray) -> np.ndarray:
    """A heater-like waveform (counts): a smoothed step and a ripple, zero mean."""
    w = 6.0 * np.tanh((phase - 20.0) / 3.0) - 6.0 * np.tanh((phase - 70.0) / 3.0)
    w += 1.5 * np.sin(2 * np.pi * phase / 25.0)
    return w - w.mean()


def test_fold_error_is_the_pooled_means_error_by_brute_force():
    # unequal folds of n_k samples per phase, noise sigma per sample: each fold's mean
    # has variance sigma^2 / n_k and the pooled mean sigma^2 / N (the closed form);
    # the stated error squared must average to the true error squared.  4000 draws of
    # 100 phases: the ratio of the averages scatters by about 0.2 % (3 % allowed)
    rng = np.random.default_rng(34)
    n = np.array([40.0, 160.0, 300.0, 500.0])
    sigma = 2.0
    truth = _known(PHASE)
    h = np.array([0.05, 0.95]) * 1000.0  # two halves of 5 % and 95 %
    stated2, true2, halves2, stated_h2, true_h2 = [], [], [], [], []
    for _ in range(4000):
        x = truth + sigma / np.sqrt(n)[:, None] * rng.standard_normal((n.size, PHASE.size))
        stated2.append(fold_error(x, n) ** 2)
        true2.append(np.mean(((n[:, None] * x).sum(axis=0) / n.sum() - truth) ** 2))
        xh = truth + sigma / np.sqrt(h)[:, None] * rng.standard_normal((2, PHASE.size))
        halves2.append(np.mean((0.5 * (xh[0] - xh[1])) ** 2))  # the estimator before
        stated_h2.append(fold_error(xh, h) ** 2)
        true_h2.append(np.mean(((h[:, None] * xh).sum(axis=0) / h.sum() - truth) ** 2))
    assert np.mean(stated2) / np.mean(true2) == pytest.approx(1.0, abs=0.03)
    # the closed form of the pooled mean's variance, sigma^2 / N
    assert np.mean(true2) == pytest.approx(sigma ** 2 / n.sum(), rel=0.03)
    assert np.mean(stated_h2) / np.mean(true_h2) == pytest.approx(1.0, abs=0.03)
    # half the difference overstates the variance by N^2 / (4 n1 n2) = 5.26 (2.3x rms)
    assert np.mean(halves2) / np.mean(true_h2) == pytest.approx(1 / (4 * 0.05 * 0.95),
                                                                rel=0.03)


def _t_quantile(nu: int, q: float) -> float:
    """Student-t quantile from the closed-form CDFs of 1 and 3 degrees of freedom."""
    if nu == 1:
        return float(np.tan(np.pi * (q - 0.5)))
    assert nu == 3

    def cdf(t):
        s = np.sqrt(3.0)
        return 0.5 + (t / (s * (1 + t * t / 3.0)) + np.arctan(t / s)) / np.pi
    return float(brentq(lambda t: cdf(t) - q, 0.0, 10.0))


def test_few_folds_widening_is_the_student_t_ratio():
    q = 0.5 * (1.0 + 0.6826894921370859)  # one normal standard deviation: Phi(1)
    want = _t_quantile(1, q) / _t_quantile(3, q)
    # own samples in two equal folds of four: one comparison (nu = 1)
    assert few_folds_widening(np.array([5.0, 5.0, 0.0, 0.0]), 4) == pytest.approx(want, 1e-6)
    # in one fold: nu floored at 1, not infinite
    assert few_folds_widening(np.array([0.0, 7.0, 0.0, 0.0]), 4) == pytest.approx(want, 1e-6)
    # in all four equally: no widening (nu = K - 1)
    assert few_folds_widening(np.full(4, 3.0), 4) == pytest.approx(1.0, abs=1e-12)
    assert few_folds_widening(np.zeros(4), 4) == 1.0


def _statistics(rng: np.random.Generator, periods: np.ndarray, sigma: float,
                truth: np.ndarray, b: int) -> DayStatistics:
    """Statistics of heater periods all at bin ``b``'s centre, ``periods[k]`` in fold k."""
    s = FitSettings()
    centres = np.asarray(s.waveform_bins_percent)
    w = interpolation_weights(np.full(PHASE.size, centres[b]), centres)
    stats = DayStatistics.empty(s)
    edges = np.arange(101) - 0.5
    parts = []
    for k, n in enumerate(periods):
        if n == 0:
            continue
        value = truth[None, :, None] + sigma * rng.standard_normal((int(n), PHASE.size, 3))
        data = np.concatenate([np.column_stack([v, PHASE, w]) for v in value])
        stats.waveform_folds[k][b] = BinnedMoments.accumulate(data[:, 3], data, edges)
        parts.append(data)
    allp = np.concatenate(parts)
    stats.waveform[b] = BinnedMoments.accumulate(allp[:, 3], allp, edges)
    return stats


@pytest.mark.parametrize("periods", [(6, 10, 14, 20), (25, 25, 0, 0)])
def test_fitted_column_errors_cover_brute_force(periods):
    # one duty-cycle bin (28 %), its periods in unequal folds (or in two of the four),
    # sigma 3 counts per sample, a waveform with sharp edges (the splines' smoothing
    # bias is 1/3 of the noise error here); the pipeline's own fit (unmixing, splines,
    # folds) drawn 100 times: mean stated^2 against mean true^2 (the fitted column less
    # the known waveform), averaged over the three axes (independent draws).  Expected:
    # 1, times the Student-t widening squared where the column's samples lie in two
    # folds ((t_1 / t_3)^2 = 2.36, closed forms).  Allowed 0.78-1.3: 300 draws scatter
    # the ratio by about 5 %; the folds' own GCV splines smooth a little more than the
    # pooled one, so their spread runs 5-8 % short (rms) in this construction.  Without
    # the smoothing bias the ratio is 0.70-0.78 (checked by hand, not kept).
    assert len(periods) == WAVEFORM_FOLDS
    rng = np.random.default_rng(7)
    base = load_calibration(np.datetime64(START))
    truth = _known(PHASE)
    b = 4
    stated2, true2 = [], []
    for _ in range(100):
        stats = _statistics(rng, np.array(periods), 3.0, truth, b)
        table, fits, error = _fit_waveforms(stats, base)
        assert fits[0][b] is not None
        true2.append(np.mean((table[:, :100, b] - truth[None]) ** 2, axis=1))
        stated2.append(error[:, b] ** 2)
    q = 0.5 * (1.0 + 0.6826894921370859)
    expected = 1.0 if min(periods) > 0 else (_t_quantile(1, q) / _t_quantile(3, q)) ** 2
    ratio = np.mean(stated2) / np.mean(true2) / expected
    assert 0.78 < ratio < 1.3, ratio
