"""Binned / superposed-epoch sufficient statistics (issue 13; MESSENGER sec. 6, 7).

Expected values come from brute-force per-bin loops over plain Python lists and
``numpy.mean`` / ``numpy.var(ddof=1)`` on the selected samples, never from the
bincount path under test.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration import binned_stats
from fluxcal.calibration.binned_stats import BinnedMoments, phase_binned, superposed_epoch
from fluxcal.errors import InputFormatError


def brute_bins(x, values, edges):
    """Per-bin (count, mean, var ddof=1) by looping over bins and samples."""
    values = np.atleast_2d(np.asarray(values, dtype=float).T).T
    out_n, out_m, out_v = [], [], []
    for i in range(len(edges) - 1):
        rows = [
            values[j]
            for j in range(len(x))
            if edges[i] <= x[j] < edges[i + 1] and np.all(np.isfinite(values[j]))
            and np.isfinite(x[j])
        ]
        out_n.append(len(rows))
        arr = np.array(rows).reshape(len(rows), values.shape[1])
        out_m.append(arr.mean(axis=0) if rows else np.full(values.shape[1], np.nan))
        out_v.append(arr.var(axis=0, ddof=1) if len(rows) > 1 else np.full(values.shape[1], np.nan))
    return np.array(out_n), np.array(out_m), np.array(out_v)


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 400),
    n_comp=st.integers(1, 3),
    k=st.integers(1, 7),
    offset=st.sampled_from([0.0, 4.3e2, -3.7e6, 1e9]),
    scale=st.sampled_from([1e-3, 1.0, 50.0]),
)
def test_merge_of_random_parts_equals_one_pass(seed, n, n_comp, k, offset, scale):
    """Split data randomly into k parts (own default shifts), merge == all at once.

    Tolerance 1e-9 relative (the brief's): the merge re-expresses each part about the
    first part's shift; the rounding of that is ~1e-16 * (offset/scale)^0 because both
    shifts lie within the data, far below 1e-9 even for a 1e9 offset on unit scatter.
    """
    rng = np.random.default_rng(seed)
    x = rng.uniform(-70.0, 45.0, n)
    v = offset + scale * rng.standard_normal((n, n_comp))
    v[rng.random(n) < 0.05, rng.integers(0, n_comp)] = np.nan  # NaN samples ignored
    edges = np.arange(-60.0, 41.0, 10.0)  # some x fall outside the edges
    part = rng.integers(0, k, n)
    pieces = [BinnedMoments.accumulate(x[part == j], v[part == j], edges) for j in range(k)]
    rng.shuffle(pieces)
    merged = pieces[0]
    for p in pieces[1:]:
        merged = merged + p
    whole = BinnedMoments.accumulate(x, v, edges)
    np.testing.assert_array_equal(merged.count, whole.count)
    have = whole.count > 0
    np.testing.assert_allclose(merged.mean()[have], whole.mean()[have], rtol=1e-9, atol=0)
    two = whole.count > 1
    np.testing.assert_allclose(
        merged.variance()[two], whole.variance()[two], rtol=1e-9, atol=1e-12 * scale**2
    )
    # and against the brute-force per-bin numbers.  numpy.var's mean of m values near
    # the offset is off by delta <= (ceil(log2 m) + 1) ulp(offset) (pairwise summation:
    # one rounding of a partial sum, at most 2 m ulp(offset), per level, then the
    # division), and mean((x - mean)^2) is then off by delta^2: at 1e9, ulp 1.2e-7 and
    # m <= 400 bin samples, (10 ulp)^2 = 1.4e-12, on top of 1e-9 relative (4 ulp, the
    # earlier allowance, failed 17 of 20000 random draws at 1e9 offset, 1e-3 scatter:
    # 2.8e-13 off).
    bn, bm, bv = brute_bins(x, v, edges)
    np.testing.assert_array_equal(whole.count, bn)
    np.testing.assert_allclose(merged.mean()[have], bm[have], rtol=1e-9)
    ulps = np.ceil(np.log2(max(n, 2))) + 1
    atol = 1e-12 * scale**2 + (ulps * np.spacing(abs(offset))) ** 2
    np.testing.assert_allclose(merged.variance()[two], bv[two], rtol=1e-9, atol=atol)


def test_large_offset_variance_does_not_cancel():
    """Unit scatter on a 1e9 offset: a raw sum of squares would lose all digits.

    Naive S2/n - (S1/n)^2 has rounding ~ 1e18 * 1e-16 = 100 >> 1; the shifted sums give
    the variance to ~1e-9 relative, checked against numpy.var(ddof=1).
    """
    rng = np.random.default_rng(3)
    v = 1e9 + rng.standard_normal(10_000)
    x = np.zeros(v.size)
    parts = [BinnedMoments.accumulate(x[i::3], v[i::3], [-1.0, 1.0]) for i in range(3)]
    m = parts[0] + parts[1] + parts[2]
    np.testing.assert_allclose(m.variance()[0, 0], np.var(v, ddof=1), rtol=1e-9)
    np.testing.assert_allclose(m.mean()[0, 0], np.mean(v), rtol=1e-15)
    np.testing.assert_allclose(
        m.standard_error()[0, 0], np.std(v, ddof=1) / np.sqrt(v.size), rtol=1e-9
    )


def test_fixed_shift_merge_is_bit_exact_in_counts_and_sums():
    """With one fixed shift, merging adds the sums: equal to one pass up to sum order."""
    rng = np.random.default_rng(4)
    x = rng.uniform(0, 10, 1000)
    v = rng.normal(400, 5, (1000, 3))
    e = np.arange(0, 11.0)
    a = BinnedMoments.accumulate(x[:300], v[:300], e, shift=400.0)
    b = BinnedMoments.accumulate(x[300:], v[300:], e, shift=400.0)
    w = BinnedMoments.accumulate(x, v, e, shift=400.0)
    m = a.merge(b)
    np.testing.assert_array_equal(m.shift, [400.0] * 3)
    np.testing.assert_array_equal(m.count, w.count)
    # summation order only: a few ulp of the sums
    np.testing.assert_allclose(m.total, w.total, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(m.total_sq, w.total_sq, rtol=1e-12)


def _merged_by_the_algebra(a, b):
    """The module docstring's merge, written out: the larger operand's shift (``a`` on
    a tie), ``sum (v-s) = sum (v-t) + n (t-s)`` and ``sum (v-s)**2 = sum (v-t)**2
    + 2 (t-s) sum (v-t) + n (t-s)**2``, built through the validating constructor."""
    base, extra = (b, a) if b.count.sum() > a.count.sum() else (a, b)
    d = extra.shift - base.shift
    n = extra.count[:, None].astype(np.float64)
    return BinnedMoments(base.edges.copy(), base.count + extra.count,
                         base.total + (extra.total + n * d),
                         base.total_sq + (extra.total_sq + 2.0 * d * extra.total + n * d * d),
                         base.shift.copy(), a.label or b.label, a.units or b.units,
                         a.value_units or b.value_units)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_a=st.integers(0, 300), n_b=st.integers(0, 300),
       n_comp=st.integers(1, 4), same_shift=st.booleans(), labelled=st.booleans())
def test_merge_is_the_algebra_bit_for_bit(seed, n_a, n_b, n_comp, same_shift, labelled):
    """`merge` and `reshifted` (built without re-validating their sums: entry 54)
    equal the shifted-sum algebra evaluated through the validating constructor, bit for
    bit (both signs of zero included), and their results are valid reductions."""
    rng = np.random.default_rng(seed)
    e = np.linspace(-3.0, 3.0, 8)
    v_a = rng.normal(50.0, 2.0, (n_a, n_comp))
    v_a[rng.random(n_a) < 0.1] = -0.0
    a = BinnedMoments.accumulate(rng.normal(0.0, 1.5, n_a), v_a, e,
                                 label="lag" if labelled else "")
    b = BinnedMoments.accumulate(rng.normal(0.0, 1.5, n_b), rng.normal(51.0, 2.0, (n_b, n_comp)),
                                 e.copy(), shift=a.shift if same_shift else None, units="s")
    for x, y in ((a, b), (b, a), (a, a)):
        got, want = x.merge(y), _merged_by_the_algebra(x, y)
        for name in ("edges", "count", "total", "total_sq", "shift"):
            g, w = getattr(got, name), getattr(want, name)
            assert g.dtype == w.dtype and g.shape == w.shape
            assert g.tobytes() == w.tobytes(), name
        assert (got.label, got.units, got.value_units) == (want.label, want.units,
                                                           want.value_units)
        BinnedMoments(got.edges, got.count, got.total, got.total_sq, got.shift)  # valid
    moved = a.reshifted(a.shift + 0.25)
    d = a.shift - (a.shift + 0.25)
    n = a.count[:, None].astype(np.float64)
    assert moved.total.tobytes() == (a.total + n * d).tobytes()
    assert moved.total_sq.tobytes() == (a.total_sq + 2.0 * d * a.total + n * d * d).tobytes()
    assert moved.count is not a.count and moved.label == a.label


def test_bins_are_half_open_and_outside_ignored():
    edges = np.array([0.0, 1.0, 2.0])
    x = np.array([0.0, 0.999, 1.0, 2.0, -1e-9, np.nan, 1.5])
    v = np.array([1.0, 2.0, 3.0, 100.0, 100.0, 100.0, np.nan])
    m = BinnedMoments.accumulate(x, v, edges)
    np.testing.assert_array_equal(m.count, [2, 1])  # 2.0 (last edge) excluded
    np.testing.assert_allclose(m.mean()[:, 0], [1.5, 3.0])
    assert np.isnan(m.variance()[1, 0])  # one sample: no unbiased variance
    np.testing.assert_allclose(m.variance()[0, 0], 0.5)


def test_empty_bins_and_identity():
    e = np.linspace(0, 5, 6)
    m = BinnedMoments.accumulate([0.5, 0.6], [[1.0, 2.0], [3.0, 4.0]], e)
    assert m.count.tolist() == [2, 0, 0, 0, 0]
    assert np.all(np.isnan(m.mean()[1:])) and np.all(np.isnan(m.standard_error()[1:]))
    z = BinnedMoments.empty(e, 2)
    for got in (z + m, m + z):
        np.testing.assert_array_equal(got.count, m.count)
        np.testing.assert_allclose(got.mean()[0], [2.0, 3.0], rtol=1e-15)
    # nothing at all: every statistic NaN, count zero
    nothing = BinnedMoments.accumulate(np.array([]), np.empty((0, 2)), e)
    assert nothing.count.sum() == 0 and np.all(np.isnan(nothing.mean()))


def test_merge_refuses_different_edges_or_components():
    a = BinnedMoments.empty([0.0, 1.0, 2.0], 3)
    with pytest.raises(InputFormatError, match="different bin edges"):
        a + BinnedMoments.empty([0.0, 1.0, 2.5], 3)
    with pytest.raises(InputFormatError, match="different bin edges"):
        a + BinnedMoments.empty([0.0, 1.0], 3)
    with pytest.raises(InputFormatError, match="components"):
        a + BinnedMoments.empty([0.0, 1.0, 2.0], 2)
    with pytest.raises(InputFormatError, match="strictly increasing"):
        BinnedMoments.accumulate([0.0], [1.0], [0.0, 0.0, 1.0])
    with pytest.raises(InputFormatError, match="shape"):
        BinnedMoments.accumulate([0.0, 1.0], [1.0, 2.0, 3.0], [0.0, 2.0])


def test_netcdf_round_trip_then_merge(tmp_path):
    """A per-day reduction saved to netCDF and merged later equals the in-memory merge."""
    rng = np.random.default_rng(5)
    edges = np.arange(-70.0, 41.0, 10.0)
    days = [
        BinnedMoments.accumulate(
            rng.uniform(-70, 40, 500), rng.normal(-70, 3, (500, 3)), edges,
            label="temperature", units="degC", value_units="count",
        )
        for _ in range(3)
    ]
    for i, d in enumerate(days):
        d.to_dataset().to_netcdf(tmp_path / f"day{i}.nc")
    loaded = [
        BinnedMoments.from_dataset(xr.load_dataset(tmp_path / f"day{i}.nc")) for i in range(3)
    ]
    for d, got in zip(days, loaded, strict=True):
        np.testing.assert_array_equal(got.edges, d.edges)
        np.testing.assert_array_equal(got.count, d.count)
        np.testing.assert_array_equal(got.total, d.total)
        np.testing.assert_array_equal(got.total_sq, d.total_sq)
        np.testing.assert_array_equal(got.shift, d.shift)
        assert (got.label, got.units, got.value_units) == ("temperature", "degC", "count")
        assert got.count.dtype == np.int64
    a = loaded[0] + loaded[1] + loaded[2]
    b = days[0] + days[1] + days[2]
    np.testing.assert_array_equal(a.mean(), b.mean())
    with pytest.raises(InputFormatError, match="total_sq"):
        BinnedMoments.from_dataset(days[0].to_dataset().drop_vars("total_sq"))


def brute_epoch(t, v, events, weights, lag_edges):
    """(lag, weighted value) pairs by a double loop over events and samples."""
    lags, vals = [], []
    for e, w in zip(events, weights, strict=True):
        for ti, vi in zip(t, v, strict=True):
            lag = ti - e
            if lag_edges[0] <= lag < lag_edges[-1]:
                lags.append(lag)
                vals.append(np.asarray(vi) * w)
    return np.array(lags), np.array(vals).reshape(len(vals), np.shape(v)[1])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 300),
    m=st.integers(0, 8),
    chunk=st.sampled_from([1, 7, 4_000_000]),
)
def test_superposed_epoch_equals_brute_force(seed, n, m, chunk):
    """Overlapping windows, unsorted times, weights of both signs, NaN samples, chunking.

    Tolerance: counts exact; means 1e-9 relative (sums in a different order).
    """
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, 3000.0, n)  # unsorted on purpose
    t[: n // 10] = np.round(t[: n // 10])  # some samples exactly on bin edges
    v = rng.normal(5.0, 2.0, (n, 2))
    if n:
        v[rng.integers(0, n), 0] = np.nan
    events = np.round(rng.uniform(-300.0, 3300.0, m))  # overlapping windows, edges of data
    weights = rng.choice([-1.0, 1.0], m) / rng.uniform(10, 300, m)  # +-1/delta_d
    lag_edges = np.arange(-200.0, 1001.0, 50.0)
    old = binned_stats._EPOCH_CHUNK
    binned_stats._EPOCH_CHUNK = chunk
    try:
        got = superposed_epoch(t, v, events, lag_edges, weights)
    finally:
        binned_stats._EPOCH_CHUNK = old
    lags, vals = brute_epoch(t, v, events, weights, lag_edges)
    bn, bm, bv = brute_bins(lags, vals, lag_edges)
    np.testing.assert_array_equal(got.count, bn)
    have = bn > 0
    np.testing.assert_allclose(got.mean()[have], bm[have], rtol=1e-9, atol=1e-12)
    two = bn > 1
    np.testing.assert_allclose(got.variance()[two], bv[two], rtol=1e-9, atol=1e-12)
    assert got.label == "lag" and got.units == "s"


def test_superposed_epoch_normalised_steps_of_both_signs_combine():
    """Steps of +-delta with weight 1/delta give one unit step (sec. 7 normalisation).

    Noise-free closed form: every bin mean is exactly the unit step (after the change)
    or zero (before), whatever the sign and size of each step: 1e-12.
    """
    t = np.arange(0.0, 12000.0, 1.0)
    change = np.array([1000.0, 4000.0, 7000.0, 10000.0])
    level = np.array([0.0, 30.0, -10.0, 20.0, 50.0])  # offsets before/after each change
    v = level[np.searchsorted(change, t, side="right")]
    delta = np.diff(level)
    pre = level[:-1]
    epoch = superposed_epoch(t, v, change, np.arange(-200.0, 1000.1, 100.0), 1.0 / delta)
    mean = epoch.mean()[:, 0]
    expect_after = np.mean(level[1:] / delta)
    expect_before = np.mean(pre / delta)
    np.testing.assert_allclose(mean[:2], expect_before, rtol=1e-12)
    np.testing.assert_allclose(mean[2:], expect_after, rtol=1e-12)
    np.testing.assert_allclose(expect_after - expect_before, 1.0, rtol=1e-12)


def brute_phase(t, v, starts, period, n_bins, centered):
    step = period / n_bins
    xs, vs = [], []
    for ti, vi in zip(t, v, strict=True):
        prior = [s for s in starts if s <= ti]
        if not prior:
            continue
        ph = ti - max(prior)
        if ph >= period:
            continue
        if centered and ph >= period - step / 2:
            ph -= period
        xs.append(ph)
        vs.append(vi)
    edges = (np.arange(n_bins + 1) - (0.5 if centered else 0.0)) * step
    return np.array(xs), np.array(vs), edges


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    centered=st.booleans(),
    n_bins=st.sampled_from([4, 10, 100]),
)
def test_phase_binned_equals_brute_force(seed, centered, n_bins):
    """Irregular cycle starts (short and long cycles, a gap), samples before the first."""
    rng = np.random.default_rng(seed)
    starts = np.cumsum(rng.choice([60.0, 100.0, 100.0, 100.0, 350.0], 12)) + 50.0
    t = np.sort(rng.uniform(0.0, starts[-1] + 150.0, 250))
    v = rng.normal(0.0, 1.0, t.size)
    got = phase_binned(t, v, starts, 100.0, n_bins, centered=centered)
    xs, vs, edges = brute_phase(t, v, starts, 100.0, n_bins, centered)
    np.testing.assert_allclose(got.edges, edges, rtol=0, atol=1e-12)
    bn, bm, _ = brute_bins(xs, vs, edges)
    np.testing.assert_array_equal(got.count, bn)
    have = bn > 0
    np.testing.assert_allclose(got.mean()[have], bm[have], rtol=1e-9, atol=1e-12)


def test_phase_binned_centred_on_table_grid():
    """1-Hz samples of a periodic waveform land on bin centres t = 0..99 s (Tables 6-8)."""
    period = 100.0
    starts = np.arange(0.0, 10_000.0, period)
    t = np.arange(0.0, 10_000.0, 1.0)
    ph = np.mod(t, period)
    wave = np.sin(2 * np.pi * ph / period) + 0.3 * np.cos(6 * np.pi * ph / period)
    m = phase_binned(t, wave, starts, period, 100)
    np.testing.assert_allclose(m.centers, np.arange(100.0), atol=1e-12)
    expect = np.sin(2 * np.pi * m.centers / period) + 0.3 * np.cos(6 * np.pi * m.centers / period)
    np.testing.assert_allclose(m.mean()[:, 0], expect, atol=1e-12)
    assert np.all(m.count == 100)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), max_gap=st.sampled_from([1.5, 5.0, 40.0]))
def test_superposed_epoch_max_gap_keeps_only_covered_windows(seed, max_gap):
    """Events whose window meets a data gap or the data ends are dropped (brute force)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 5000.0, 1.0)
    cut = rng.uniform(500, 4500, 3)
    width = rng.choice([3.0, 30.0, 300.0], 3)
    keep = np.ones(t.size, bool)
    for c, wdt in zip(cut, width, strict=True):
        keep &= ~((t > c) & (t < c + wdt))
    t = t[keep]
    v = rng.normal(0.0, 1.0, t.size)
    events = np.round(rng.uniform(-100.0, 5100.0, 12))
    lag_edges = np.arange(-200.0, 801.0, 100.0)
    got = superposed_epoch(t, v, events, lag_edges, max_gap=max_gap)
    covered = []
    for e in events:  # brute force: every gap between consecutive samples in the window
        inside = t[(t >= e + lag_edges[0]) & (t < e + lag_edges[-1])]
        ok = inside.size > 0
        if ok:
            pts = np.concatenate(([e + lag_edges[0]], inside, [e + lag_edges[-1]]))
            ok = bool(np.all(np.diff(inside) <= max_gap)) and inside[0] - pts[0] <= max_gap
            ok = ok and pts[-1] - inside[-1] <= max_gap
        covered.append(ok)
    want = superposed_epoch(t, v, events[np.array(covered, bool)], lag_edges)
    np.testing.assert_array_equal(got.count, want.count)
    np.testing.assert_allclose(got.mean(), want.mean(), rtol=1e-12, equal_nan=True)


@settings(max_examples=80, deadline=None)
@given(
    e0=st.sampled_from([-70.0, 0.0, 0.3, -200.5]),
    step=st.sampled_from([0.1, 1.0, 4.0 / 3.0, 10.0, 40.0]),
    n_bins=st.integers(1, 30),
    picks=st.lists(st.integers(-3, 33), min_size=1, max_size=40),
    jitter=st.lists(st.sampled_from([0.0, 1e-12, -1e-12, 0.5, -0.5]), min_size=40,
                    max_size=40),
)
def test_uniform_edge_fast_path_matches_definition(e0, step, n_bins, picks, jitter):
    """Floor-based bin index == the half-open definition, also exactly on edges."""
    edges = e0 + step * np.arange(n_bins + 1)
    x = np.array([e0 + step * p + jitter[k] * step for k, p in enumerate(picks)])
    x = np.concatenate((x, edges, [np.nan, np.inf, -np.inf]))
    m = BinnedMoments.accumulate(x, np.ones(x.size), edges)
    want = [sum(1 for v in x if edges[i] <= v < edges[i + 1]) for i in range(n_bins)]
    np.testing.assert_array_equal(m.count, want)


def test_non_finite_events_weights_or_cycle_starts_are_refused():
    """No silent dropping: a 1/0 weight (zero step) or a NaN event time names the field."""
    t = np.arange(100.0)
    with pytest.raises(InputFormatError, match="weights.*first at event 1"):
        superposed_epoch(t, t, [10.0, 20.0], [-5.0, 0.0, 5.0], weights=[1.0, np.inf])
    with pytest.raises(InputFormatError, match="event_t"):
        superposed_epoch(t, t, [np.nan], [-5.0, 0.0, 5.0])
    with pytest.raises(InputFormatError, match="cycle_start_t"):
        phase_binned(t, t, [0.0, np.nan], 100.0, 10)
    with pytest.raises(InputFormatError, match="max_gap"):
        superposed_epoch(t, t, [10.0], [-5.0, 0.0, 5.0], max_gap=0.0)
