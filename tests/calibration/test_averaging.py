import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration import averaging


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
@given(
    st.lists(st.integers(-(10**12), 10**12), min_size=1, max_size=200),
    st.integers(1, 10**10),
    st.integers(-(10**11), 10**11),
)
def test_matches_brute_force(times, width, origin):
    epoch = np.array(times, dtype=np.int64)
    values = np.sin(epoch.astype(float) * 1e-9)
    centre, mean, count = averaging.boxcar_average(epoch, values, width, origin)
    bc, bm, bn = brute(epoch, values, width, origin)
    np.testing.assert_array_equal(centre, bc)
    np.testing.assert_allclose(mean, bm, atol=1e-12)
    np.testing.assert_array_equal(count, bn)


def test_vectors_and_max():
    epoch = np.array([0, 1, 5, 6], dtype=np.int64)
    bins = averaging.bin_index(epoch, 5)
    np.testing.assert_array_equal(
        averaging.bin_mean(bins, np.arange(8.0).reshape(4, 2)), [[1, 2], [5, 6]]
    )
    np.testing.assert_array_equal(averaging.bin_max(bins, np.array([0, 3, 1, 0])), [3, 1])
