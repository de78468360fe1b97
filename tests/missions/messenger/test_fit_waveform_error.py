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
from fluxcal.missions.messenger.fit_reduce import (
    WAVEFORM_FOLDS,
    DayStatistics,
    FitSettings,
    interpolation_weights,
)
from fluxcal.missions.messenger.fit_waveform_error import (
    jackknife_error,
    jackknife_scale,
    leave_one_out,
)
from fluxcal.missions.messenger.fit_waveforms import (
    few_folds_widening,
    fit_waveforms,
    unmix_waveforms,
    unmixing_variance,
)

START = "2012-06-01T00:00:00"
PHASE = np.arange(100.0)


def _known(phase: np.ndarray) -> np.ndarray:
    """A heater-like waveform (counts): a smoothed step and a ripple, zero mean."""
    w = 6.0 * np.tanh((phase - 20.0) / 3.0) - 6.0 * np.tanh((phase - 70.0) / 3.0)
    w += 1.5 * np.sin(2 * np.pi * phase / 25.0)
    return w - w.mean()


def _fold_moments(values: list[np.ndarray]) -> tuple[BinnedMoments, list[BinnedMoments]]:
    """Pooled and per-fold phase-binned moments of one duty bin at its centre (column 0).

    ``values[k]``: fold k's samples, shape (n_k, phase, 3); the weights columns put the
    whole sample on the first waveform column."""
    edges = np.arange(101) - 0.5
    nb = 8
    folds = []
    for v in values:
        w = np.zeros((v.shape[0] * PHASE.size, nb))
        w[:, 0] = 1.0
        data = np.column_stack([v.reshape(-1, 3), np.tile(PHASE, v.shape[0]), w])
        folds.append(BinnedMoments.accumulate(data[:, 3], data, edges))
    pooled = folds[0]
    for f in folds[1:]:
        pooled = pooled.merge(f)
    return pooled, folds


def test_jackknife_error_covers_unequal_and_unequally_noisy_folds():
    # one column seen alone (weights 1), folds of 2 / 6 / 12 / 20 samples per phase; the
    # smallest fold is 4x noisier (a disturbed hour, the 7003 pattern).  The pooled
    # column is the count-weighted mean of the folds (w_k = n_k / N), its true variance
    # V = sum w_k^2 v_k, v_k = s_k^2 / n_k.  Closed forms: leaving fold k out gives
    # L x with L_ki = n_i / (N - n_k) (i != k), so the jackknife variance averages to
    # (K - 1) / K sum_i (M'M)_ii v_i, M = (I - 1/K) L: 1.38 V here (exactly V for equal
    # folds of equal noise); the folds' spread weighted by their sizes (entry 29's
    # estimator, written out here) to sum w_k (v_k (1 - 2 w_k) + V) / (K - 1) = 3.3 V:
    # it counts the noisy small fold at its own variance, the pooled mean at w_0^2 of
    # it.  400 draws of 100 phases scatter each ratio by about 2 % (5 % allowed).
    rng = np.random.default_rng(3434)
    n = np.array([2, 6, 12, 20])
    s = np.array([8.0, 2.0, 2.0, 2.0])
    k = n.size
    w = n / n.sum()
    v = s ** 2 / n
    truth = _known(PHASE)
    stated2, true2, spread2 = [], [], []
    for _ in range(400):
        values = [truth[None, :, None] + s[i] * rng.standard_normal((n[i], PHASE.size, 3))
                  for i in range(k)]
        pooled, folds = _fold_moments(values)
        none = [BinnedMoments.empty(pooled.edges, pooled.n_comp)] * 7  # other bins
        without = leave_one_out([[f, *none] for f in folds])
        refit = np.stack([h[0].mean()[:, 0] for h in without])  # (K, phase), axis x
        stated2.append(jackknife_error(refit) ** 2)
        fold_mean = np.stack([f.mean()[:, 0] for f in folds])
        column = (n[:, None] * fold_mean).sum(axis=0) / n.sum()
        true2.append(np.mean((column - truth) ** 2))
        spread2.append(np.mean((n[:, None] * (fold_mean - column) ** 2).sum(axis=0)
                               / ((k - 1) * n.sum())))
    big_v = (w ** 2 * v).sum()
    assert np.mean(true2) == pytest.approx(big_v, rel=0.05)
    big_l = np.where(np.eye(k) > 0, 0.0, n[None, :] / (n.sum() - n)[:, None])
    m = (np.eye(k) - 1.0 / k) @ big_l
    jack = (k - 1) / k * ((m.T @ m).diagonal() * v).sum() / big_v
    spread = (w * (v * (1 - 2 * w) + big_v)).sum() / (k - 1) / big_v
    assert 1.0 < jack < 1.6 and spread > 3.0
    assert np.mean(stated2) / np.mean(true2) == pytest.approx(jack, rel=0.05)
    assert np.mean(spread2) / np.mean(true2) == pytest.approx(spread, rel=0.05)
    # four equal folds of equal noise: the jackknife is the pooled mean's variance
    m4 = (np.eye(4) - 0.25) @ np.where(np.eye(4) > 0, 0.0, 1.0 / 3.0)
    assert 0.75 * (m4.T @ m4).diagonal().sum() * 1.0 == pytest.approx(4 * (0.25 ** 2))


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
    # refits without each fold) drawn 100 times: mean stated^2 against mean true^2 (the
    # fitted column less the known waveform), averaged over the three axes (independent
    # draws).  Expected: 1, times the Student-t widening squared where the column's
    # samples lie in two folds ((t_1 / t_3)^2 = 2.36, closed forms).  Allowed 0.78-1.3:
    # 300 draws scatter the ratio by about 5 %.  The jackknife of unequal folds errs on
    # the high side (entry 34): 1.14 and 0.87 here (entry 29's fold spread: within
    # 0.78-1.3 too; without the smoothing bias it was 0.70-0.78; by hand, not kept).
    assert len(periods) == WAVEFORM_FOLDS
    rng = np.random.default_rng(7)
    base = load_calibration(np.datetime64(START))
    truth = _known(PHASE)
    b = 4
    stated2, true2 = [], []
    for _ in range(100):
        stats = _statistics(rng, np.array(periods), 3.0, truth, b)
        table, fits, error = fit_waveforms(stats, base)
        assert fits[0][b] is not None
        true2.append(np.mean((table[:, :100, b] - truth[None]) ** 2, axis=1))
        stated2.append(error[:, b] ** 2)
    q = 0.5 * (1.0 + 0.6826894921370859)
    expected = 1.0 if min(periods) > 0 else (_t_quantile(1, q) / _t_quantile(3, q)) ** 2
    ratio = np.mean(stated2) / np.mean(true2) / expected
    assert 0.78 < ratio < 1.3, ratio


def _edge_statistics(rng: np.random.Generator, groups, truth: dict) -> DayStatistics:
    """Statistics of heater periods ``(fold, duty %, periods, sigma)``: each period one
    sample per phase bin, the pipeline's interpolation (sec. 6) of the known columns
    ``truth`` (bin index -> waveform) plus noise of ``sigma`` counts."""
    s = FitSettings()
    centres = np.asarray(s.waveform_bins_percent)
    stats = DayStatistics.empty(s)
    edges = np.arange(101) - 0.5
    rows: dict[tuple[int, int], list[np.ndarray]] = {}
    for fold, duty, periods, sigma in groups:
        w = interpolation_weights(np.full(PHASE.size, duty), centres)
        mean = sum(w[:, j] * col for j, col in truth.items())
        value = mean[None, :, None] + sigma * rng.standard_normal((periods, PHASE.size, 3))
        b = int(np.floor((duty - (centres[0] - 2.0)) / 4.0))
        rows.setdefault((fold, b), []).extend(np.column_stack([v, PHASE, w]) for v in value)
    for (fold, b), parts in rows.items():
        data = np.concatenate(parts)
        stats.waveform_folds[fold][b] = stats.waveform_folds[fold][b].merge(
            BinnedMoments.accumulate(data[:, 3], data, edges))
        stats.waveform[b] = stats.waveform[b].merge(
            BinnedMoments.accumulate(data[:, 3], data, edges))
    return stats


def test_edge_column_seen_through_its_neighbour_is_not_overstated():
    # the pattern of calm seed 7003 at 2 days (entry 34): the 40-% column's own
    # periods lie in folds 2 and 3 (15 and 18) and 4 (at 39 %) in fold 0, whose data
    # are 4x noisier (sigma 12 counts against 3); fold 1 reaches the column only
    # through 37-% periods of the 36-% bin (weight 0.25).  Every fold holds 36-% periods.  The
    # truth: two known columns (36 and 40 %), the others empty.  The pipeline's own fit,
    # 60 draws, three axes each: the 40-% column's stated error must cover its true
    # error (mean stated^2 / true^2 at least 1; stated >= true in at least 70 % of the
    # 180 column draws) and not be grossly conservative (the ratio at most 3, stated
    # rms at most 1.7x; 2.0 in 20 draws; 2.1 in these 60 draws, covering 99 %, on main
    # 5fb8022; 1.52, covering 93 %, with entry 37's scale for the 40-% column's
    # 2.4 effective folds: its fold 0 is the noisy one and the scale assumes equal
    # noise, yet it still covers).  The folds' spread (entry 29) gave 7.9
    # here, 2.8x in rms (20 draws, checked by hand on main f6aae58, not kept): fold
    # 0's own 40-% solution is poor, and the spread counted it at the weight of all
    # the samples leaning on the column there.
    rng = np.random.default_rng(7003)
    base = load_calibration(np.datetime64(START))
    truth = {6: _known(PHASE), 7: 0.8 * _known((PHASE + 35.0) % 100.0)}
    groups = [(0, 36.0, 10, 12.0), (0, 39.0, 4, 12.0),
              (1, 36.0, 8, 3.0), (1, 37.0, 12, 3.0),
              (2, 36.0, 10, 3.0), (2, 40.0, 15, 3.0),
              (3, 36.0, 12, 3.0), (3, 40.0, 18, 3.0)]
    stated, true = [], []
    for _ in range(60):
        stats = _edge_statistics(rng, groups, truth)
        table, fits, error = fit_waveforms(stats, base)
        assert fits[0][7] is not None and fits[0][0] is None
        true.append(np.sqrt(np.mean((table[:, :100, 7] - truth[7][None]) ** 2, axis=1)))
        stated.append(error[:, 7])
    stated, true = np.concatenate(stated), np.concatenate(true)
    ratio = np.mean(stated ** 2) / np.mean(true ** 2)
    assert 1.0 <= ratio <= 3.0, ratio
    assert np.mean(stated >= true) >= 0.7


def _mean_variances(own: np.ndarray, phases: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """A column seen alone (a weighted mean of its samples): per unit sample variance
    ``V = 1 / N`` with every fold and ``1 / (N - n_k)`` without fold k, at every phase."""
    n = np.asarray(own, dtype=float)
    v = np.full(phases, 1.0 / n.sum())
    with np.errstate(divide="ignore"):
        vk = np.repeat((1.0 / (n.sum() - n))[:, None], phases, axis=1)
    return v, vk


def test_jackknife_scale_is_the_weighted_means_closed_form():
    # a weighted mean of folds holding shares w_k of the column's samples: leaving fold
    # k out moves it by w_k (mean - y_k) / (1 - w_k), so sum_k (x_(-k) - x)^2 averages
    # to V sum_k w_k / (1 - w_k) and the unbiased c is 1 / sum_k w_k / (1 - w_k)
    # (worked by hand below); (K - 1) / K = 3/4 counts an empty fold as a whole group
    v, vk = _mean_variances([5, 5, 0, 0])
    assert jackknife_scale(np.array([5, 5, 0, 0]), v, vk) == pytest.approx(0.5, rel=1e-12)
    own = np.array([1, 3, 6, 0])  # K_eff = 100 / 46 = 2.17
    v, vk = _mean_variances(own)
    want = 1.0 / (0.1 / 0.9 + 0.3 / 0.7 + 0.6 / 0.4)  # 0.49027
    assert jackknife_scale(own, v, vk) == pytest.approx(want, rel=1e-12)
    # three or more effective folds: the default (K - 1) / K (entry 34), None
    assert jackknife_scale(np.array([4, 4, 4, 0]), *_mean_variances([4, 4, 4, 0])) is None
    assert jackknife_scale(np.full(4, 3), *_mean_variances(np.full(4, 3))) is None
    # a difference below zero counts as zero, a phase some fit leaves unsolved is
    # skipped, and c never exceeds (K - 1) / K
    v = np.ones(4)
    vk = np.array([[2.0, 2.0, 2.0, np.nan], [1.2, 1.2, 1.2, 9.0],
                   [0.9, 0.9, 0.9, 0.9], [1.0, 1.0, 1.0, 1.0]])
    own = np.array([5, 5, 0, 0])
    assert jackknife_scale(own, v, vk) == pytest.approx(0.75)        # 1 / 1.2 capped
    vk[1, :3] = 4.0
    assert jackknife_scale(own, v, vk) == pytest.approx(1.0 / 4.0)   # 1 / (1 + 3)
    assert jackknife_scale(own, np.full(4, np.nan), vk) is None
    # the jackknife with that c: two refits +-d about their mean, c (2 d^2)
    assert jackknife_error(np.array([[1.0, 1.0], [-1.0, -1.0]]), 0.5) == pytest.approx(1.0)
    assert jackknife_error(np.array([[1.0, 1.0], [-1.0, -1.0]])) == pytest.approx(1.0)


def test_unmixing_variance_matches_brute_force():
    # the 36-% and 40-% columns unmixed from periods at 36, 37, 39 and 40 % (each
    # leaning on both columns), unit noise per sample: the scatter of the unmixed
    # columns over 300 draws against the closed form diag(A+ A+').  300 draws scatter
    # a variance by about 8 % (1/sqrt(150)); averaged over 100 phases and 3 axes the
    # comparison holds to 3 % (5 % allowed).
    rng = np.random.default_rng(36)
    truth = {6: _known(PHASE), 7: 0.8 * _known((PHASE + 35.0) % 100.0)}
    groups = [(0, 36.0, 4, 1.0), (1, 37.0, 3, 1.0), (2, 39.0, 2, 1.0), (3, 40.0, 5, 1.0)]
    draws = []
    for _ in range(300):
        stats = _edge_statistics(rng, groups, truth)
        draws.append(unmix_waveforms(stats)[1][:, 6:8, :])
    empirical = np.var(np.stack(draws), axis=0).mean(axis=(0, 2))  # per column
    closed = unmixing_variance(stats.waveform)[:, 6:8].mean(axis=0)
    assert np.all(np.isfinite(closed))
    assert empirical == pytest.approx(closed, rel=0.05)


def test_a_fold_without_the_columns_own_samples_changes_nothing():
    # the 28-% column's periods in folds 0 and 1 only (25 each, sigma 3 counts).  The
    # same draws once alone (folds 2 and 3 empty: a jackknife of two groups, c = 1/2)
    # and once with 12-% periods filling folds 2 and 3 (four groups; the 12-% bin
    # shares no column with the 28-% one).  Leaving fold 2 or 3 out does not move the
    # 28-% column, so its stated error must be the same: 0.1-2.6 % apart measured (the
    # two extra groups pull the refits' mean towards the pooled fit), 4 % allowed.
    # (K - 1) / K states it 1.22x larger (sqrt(0.75 / 0.5); 1.21-1.25 measured on main
    # 5fb8022) with the filled folds: the calm 2-day fits' columns seen in few folds
    # (entry 37).
    base = load_calibration(np.datetime64(START))
    truth = {4: _known(PHASE), 0: 0.5 * _known((PHASE + 20.0) % 100.0)}
    alone = [(0, 28.0, 25, 3.0), (1, 28.0, 25, 3.0)]
    filler = [(2, 12.0, 25, 3.0), (3, 12.0, 25, 3.0)]
    for seed in (1, 2):
        two = fit_waveforms(_edge_statistics(np.random.default_rng(seed), alone, truth),
                             base)[2][:, 4]
        rng = np.random.default_rng(seed)
        four = fit_waveforms(_edge_statistics(rng, alone + filler, truth), base)[2][:, 4]
        assert four == pytest.approx(two, rel=0.04), (four / two)
