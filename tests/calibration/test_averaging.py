"""The one averaging implementation: bins, centres, means and two-pass standard deviations.

Expected values: a brute-force grouping written with Python dicts (no numpy), and numpy's
``std`` evaluated in extended precision (``np.longdouble``) on the same samples.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration import averaging

#: Strategies of (times, bin width, origin): both signs of ``time - origin`` occur.
TIMES_WIDTH_ORIGIN = (
    st.lists(st.integers(-(10**12), 10**12), min_size=1, max_size=200),
    st.integers(1, 10**10),
    st.integers(-(10**11), 10**11),
)


def brute(epoch, values, width, origin):
    groups = {}
    for t, v in zip(epoch, values, strict=True):
        groups.setdefault((int(t) - origin) // width, []).append(v)
    keys = sorted(groups)
    return (
        [origin + k * width + width // 2 for k in keys],
        [sum(groups[k]) / len(groups[k]) for k in keys],
        [len(groups[k]) for k in keys],
    )


@settings(max_examples=60, deadline=None)
@given(*TIMES_WIDTH_ORIGIN)
def test_matches_brute_force(times, width, origin):
    epoch = np.array(times, dtype=np.int64)
    values = np.sin(epoch.astype(float) * 1e-9)
    centre, mean, count = averaging.boxcar_average(epoch, values, width, origin)
    bc, bm, bn = brute(epoch, values, width, origin)
    np.testing.assert_array_equal(centre, bc)
    # sums of <= 200 values of magnitude <= 1: rounding well below 1e-12
    np.testing.assert_allclose(mean, bm, atol=1e-12)
    np.testing.assert_array_equal(count, bn)


def test_vectors_and_max():
    epoch = np.array([0, 1, 5, 6], dtype=np.int64)
    bins = averaging.bin_index(epoch, 5)
    np.testing.assert_array_equal(
        averaging.bin_mean(bins, np.arange(8.0).reshape(4, 2)), [[1, 2], [5, 6]]
    )
    np.testing.assert_array_equal(averaging.bin_max(bins, np.array([0, 3, 1, 0])), [3, 1])


def test_bin_centres_are_exact_integers_near_2012():
    """Centres are origin + k w + w/2 in int64 ns, not floats (TT2000 ~4e17 ns)."""
    origin = 391_780_866_184_000_000  # a TT2000 midnight-like value
    width = 60_000_000_000
    epoch = origin + np.array([1, 59_999_999_999, 60_000_000_000, 3_600_000_000_123])
    bins = averaging.bin_index(epoch, width, origin)
    assert bins.centre.dtype == np.int64
    assert bins.centre.tolist() == [origin + 30_000_000_000, origin + 90_000_000_000,
                                    origin + 3_630_000_000_000]


@pytest.mark.parametrize("spread", [0.01, 0.001])
@pytest.mark.parametrize("level", [40_000.0, -40_000.0, 3.0])
def test_std_at_large_field_against_extended_precision(level, spread):
    """Issue 10: 0.01 nT spread on 40,000 nT.  E[b^2]-E[b]^2 was 1.4 % off here."""
    rng = np.random.default_rng(7)
    n_bins, per_bin = 50, 1200  # 60 s at 20 Hz
    epoch = np.repeat(np.arange(n_bins, dtype=np.int64) * 60_000_000_000, per_bin)
    epoch += np.tile(np.arange(per_bin, dtype=np.int64) * 50_000_000, n_bins)
    b = level + rng.uniform(-spread, spread, size=(epoch.size, 3))
    bins = averaging.bin_index(epoch, 60_000_000_000)
    mean, std = averaging.bin_mean_std(bins, b)
    exact = b.astype(np.longdouble).reshape(n_bins, per_bin, 3)
    ref_mean = exact.mean(axis=1)
    ref_std = np.sqrt(((exact - ref_mean[:, None, :]) ** 2).mean(axis=1))
    # the deviations are exact differences of doubles; rounding of ~1e-12 nT relative
    # to 40,000 nT on the mean is the floor, far below 1e-6 of the spread
    np.testing.assert_allclose(mean, ref_mean.astype(float), rtol=0, atol=1e-10)
    np.testing.assert_allclose(std, ref_std.astype(float), rtol=1e-9)
    # and numpy's own (two-pass) float64 std agrees on each bin
    np.testing.assert_allclose(std, b.reshape(n_bins, per_bin, 3).std(axis=1), rtol=1e-9)


def test_std_unsorted_input_single_sample_and_ddof():
    epoch = np.array([25, 3, 14, 1, 12], dtype=np.int64)  # bins 2, 0, 1, 0, 1
    v = np.array([7.0, 1.0, 5.0, 3.0, 2.0])
    bins = averaging.bin_index(epoch, 10)
    mean, std = averaging.bin_mean_std(bins, v)
    np.testing.assert_allclose(mean, [2.0, 3.5, 7.0])
    np.testing.assert_allclose(std, [1.0, 1.5, 0.0])
    _, std1 = averaging.bin_mean_std(bins, v, ddof=1)
    np.testing.assert_allclose(std1[:2], [np.sqrt(2.0), np.sqrt(4.5)])
    assert np.isnan(std1[2])


def test_empty():
    bins = averaging.bin_index(np.zeros(0, dtype=np.int64), 10)
    mean, std = averaging.bin_mean_std(bins, np.zeros((0, 3)))
    assert mean.shape == (0, 3) and std.shape == (0, 3)


@settings(max_examples=60, deadline=None)
@given(*TIMES_WIDTH_ORIGIN)
def test_sorted_times_one_pass_matches_brute_force(times, width, origin):
    """Times in order take the compiled single pass (no sort, no copy): same bins.

    Both signs of ``epoch - origin`` (floor division towards -inf) occur.
    """
    epoch = np.array(sorted(times), dtype=np.int64)
    bins = averaging.bin_index(epoch, width, origin)
    assert bins.order is None
    bc, _, bn = brute(epoch, np.zeros(epoch.size), width, origin)
    np.testing.assert_array_equal(bins.centre, bc)
    np.testing.assert_array_equal(bins.counts, bn)
    assert bins.starts.tolist() == np.cumsum([0] + bn[:-1]).tolist()


def test_mean_only_path_is_the_mean_of_mean_std():
    """`bin_mean` (no second pass) and `bin_mean_std` give the same bits; the mean of a
    bin of 3 samples matches the closed form exactly where it is exactly representable."""
    rng = np.random.default_rng(3)
    epoch = np.sort(rng.integers(0, 10**6, size=5000)).astype(np.int64)
    b = 40_000.0 + rng.normal(size=(epoch.size, 3))
    bins = averaging.bin_index(epoch, 1000)
    assert averaging.bin_mean(bins, b).tobytes() == averaging.bin_mean_std(bins, b)[0].tobytes()
    bins = averaging.bin_index(np.array([0, 1, 2], dtype=np.int64), 10)
    assert averaging.bin_mean(bins, np.array([1.0, 2.0, 6.0])).tolist() == [3.0]


def test_vector_columns_side_by_side_equal_one_column_at_a_time():
    """The three-column loop sums each column in the same order as a single column."""
    rng = np.random.default_rng(5)
    epoch = np.sort(rng.integers(0, 10**7, size=4000)).astype(np.int64)
    b = -40_000.0 + rng.normal(size=(epoch.size, 3))
    bins = averaging.bin_index(epoch, 10**5)
    for ddof in (0, 1):
        mean, std = averaging.bin_mean_std(bins, b, ddof=ddof)
        for j in range(3):
            m_j, s_j = averaging.bin_mean_std(bins, b[:, j], ddof=ddof)
            assert mean[:, j].tobytes() == m_j.tobytes()
            assert std[:, j].tobytes() == s_j.tobytes()


def test_average_dataset_means_flags_clock_and_coordinates():
    # hand-computed: two 10-s bins from origin 1000 ns; clock "obt" counts seconds with
    # epoch, so its bin value is the clock at the bin centre
    import xarray as xr

    from fluxcal.calibration.averaging import average_dataset, bin_index

    ns = 1_000_000_000
    origin = 1000
    epoch = origin + np.array([1, 3, 12, 14, 16]) * ns
    b = np.array([[1.0, 2, 3], [3, 4, 5], [10, 10, 10], [20, 20, 20], [30, 30, 30]])
    ds = xr.Dataset(
        {"b": (("time", "component"), b, {"units": "nT"}),
         "quality": ("time", np.array([0, 2, 1, 0, 0])),
         "obt": ("time", 100.0 + (epoch - origin) / ns),
         "sid": ("time", np.array([2, 2, 3, 3, 3])),
         "count_like": ("time", np.arange(5))},  # integers, not a flag: left out
        coords={"epoch": ("time", epoch, {"units": "ns"}), "component": ["x", "y", "z"]},
        attrs={"level": "A"})
    out = average_dataset(ds, bin_index(epoch, 10 * ns, origin), origin,
                          centred=("obt",), drop=("sid",))
    np.testing.assert_allclose(out["b"].values, [[2, 3, 4], [20, 20, 20]])
    assert out["quality"].values.tolist() == [2, 1]
    np.testing.assert_allclose(out["obt"].values, [105.0, 115.0])  # the centres 5 s, 15 s
    assert out["n_samples"].values.tolist() == [2, 3]
    assert out["epoch"].values.tolist() == [origin + 5 * ns, origin + 15 * ns]
    assert list(out.coords) == ["epoch", "component"] and out.attrs == {"level": "A"}
    assert "sid" not in out and "count_like" not in out and out["b"].attrs == {"units": "nT"}
