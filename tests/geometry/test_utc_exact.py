"""Exact (1 ns) TT2000 <-> UTC against outside tools: cdflib (its own leap-second table and
integer arithmetic) and SPICE ``timout``; round trips by hypothesis.

Oracles: ``cdflib.cdfepoch.compute_tt2000`` / ``breakdown_tt2000`` / ``encode_tt2000`` /
``to_datetime`` and ``spiceypy.timout``; none shares code with fluxcal.geometry.time.
"""

from __future__ import annotations

import numpy as np
import pytest
from cdflib.epochs import CDFepoch
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import (
    TT2000_FILL,
    TT2000_PAD,
    datetime64_to_tt2000,
    leapseconds,
    tt2000_to_datetime64,
)

NS = 1_000_000_000
#: Leap seconds since 1999 (the last second of each of these days is 23:59:60).
LEAP_DAYS = [(2005, 12, 31), (2008, 12, 31), (2012, 6, 30), (2015, 6, 30), (2016, 12, 31)]


@pytest.fixture(scope="module")
def lsk():
    with KernelPool([]):  # the package's generic LSK (naif0012)
        yield leapseconds()


def _cdf(fields: list[int]) -> int:
    return int(CDFepoch.compute_tt2000(fields))


@pytest.fixture(scope="module")
def epochs() -> np.ndarray:
    """20,000 random epochs 1999-2030 plus +-3 s around every leap second since 1999
    (every 0.1 s, and one ns either side of each step), as int64 TT2000."""
    rng = np.random.default_rng(20260)
    lo = _cdf([1999, 1, 1, 0, 0, 0, 0, 0, 0])
    hi = _cdf([2030, 1, 1, 0, 0, 0, 0, 0, 0])
    parts = [rng.integers(lo, hi, 20_000)]
    for y, m, d in LEAP_DAYS:
        leap = _cdf([y, m, d, 23, 59, 60, 0, 0, 0])
        grid = np.arange(leap - 3 * NS, leap + 3 * NS, NS // 10)
        parts += [grid, grid - 1, grid + 1, rng.integers(leap - NS, leap + 2 * NS, 200)]
    return np.concatenate(parts).astype(np.int64)


def test_datetime64_matches_cdflib_outside_leap_seconds(lsk, epochs):
    ours = tt2000_to_datetime64(epochs, lsk=lsk)
    ref = CDFepoch.to_datetime(epochs)
    in_leap = CDFepoch.breakdown_tt2000(epochs)[:, 5] == 60
    assert in_leap.sum() > 400  # the leap seconds are really sampled
    np.testing.assert_array_equal(ours[~in_leap], ref[~in_leap])
    # back to TT2000, exact to the nanosecond
    np.testing.assert_array_equal(datetime64_to_tt2000(ref[~in_leap], lsk=lsk), epochs[~in_leap])


def test_datetime64_clamps_inside_a_leap_second(lsk, epochs):
    in_leap = CDFepoch.breakdown_tt2000(epochs)[:, 5] == 60
    ours = tt2000_to_datetime64(epochs[in_leap], lsk=lsk)
    # closed form: the last nanosecond of the day the leap second ends
    days = np.array([f"{y:04d}-{m:02d}-{d:02d}" for y, m, d in CDFepoch.breakdown_tt2000(
        epochs[in_leap])[:, :3]], dtype="M8[D]")
    expected = days.astype("M8[ns]") + np.timedelta64(86_400 * NS - 1, "ns")
    np.testing.assert_array_equal(ours, expected)
    # a whole index stays sorted across each leap second (cdflib's to_datetime does not)
    s = np.sort(epochs)
    assert (np.diff(tt2000_to_datetime64(s, lsk=lsk)) >= np.timedelta64(0, "ns")).all()


def test_datetime64_fill_and_nat(lsk):
    out = tt2000_to_datetime64(np.array([[TT2000_FILL, TT2000_PAD]]), lsk=lsk)
    assert out.shape == (1, 2) and np.isnat(out).all()
    back = datetime64_to_tt2000(np.array(["NaT", "2000-01-01T11:58:55.816"], dtype="M8[ms]"),
                                lsk=lsk)
    # 2000-01-01T11:58:55.816 UTC is TT2000 0 (J2000 TT = 12:00:00 TT, 64.184 s = 32 + 32.184)
    np.testing.assert_array_equal(back, [TT2000_FILL, 0])
    with pytest.raises(InputFormatError, match="does not fit"):
        datetime64_to_tt2000(np.array(["3000-01-01"], dtype="M8[s]"), lsk=lsk)
    with pytest.raises(InputFormatError, match="datetime64"):
        datetime64_to_tt2000(np.array([1, 2]), lsk=lsk)
    with pytest.raises(InputFormatError, match="2262"):  # 2270: a TT2000, not a datetime64[ns]
        tt2000_to_datetime64(np.array([_cdf([2270, 1, 1, 0, 0, 0, 0, 0, 0])]), lsk=lsk)
    with pytest.raises(InputFormatError, match="outside the supported range"):
        tt2000_to_datetime64(np.array([np.iinfo(np.int64).max]), lsk=lsk)


@settings(max_examples=300, deadline=None)
@given(st.integers(min_value=-(2**62), max_value=2**62))  # ~1854 .. 2146
def test_datetime64_round_trip_outside_leap_seconds(lsk, tt2000):
    t = np.array([tt2000], dtype=np.int64)
    dt = tt2000_to_datetime64(t, lsk=lsk)
    back = datetime64_to_tt2000(dt, lsk=lsk)
    leaps = lsk.leap_tt2000()
    if np.any((t[0] >= leaps - NS) & (t[0] < leaps)):
        assert back[0] < t[0]  # clamped to 23:59:59.999999999, before the leap second
    else:
        assert back[0] == t[0]
