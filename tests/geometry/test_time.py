"""SCLK, TT2000 and UTC conversions against SPICE itself (the oracle) and published values."""

from __future__ import annotations

import numpy as np
import pytest
import spiceypy
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import (
    SclkKernel,
    et_to_tt2000,
    et_to_utc,
    leapseconds,
    tt2000_to_et,
    tt2000_to_utc,
    utc_to_et,
    utc_to_tt2000,
)


@pytest.fixture(scope="module")
def real_clocks(shared_kernels):
    with KernelPool(
        [shared_kernels / "messenger" / "messenger_2548.tsc",
         shared_kernels / "rosetta" / "ROS_160929_STEP.TSC"]
    ):
        yield


def _msgr_string(p: int, micro: int) -> str:
    return f"{p}/{micro // 1_000_000:010d}:{micro % 1_000_000:06d}"


@pytest.mark.parametrize("partition", [1, 2])
def test_messenger_sclk_matches_scs2e(real_clocks, partition):
    clock = SclkKernel.from_pool(-236)
    rng = np.random.default_rng(partition)
    lo = int(clock.partition_start[partition - 1])
    hi = int(min(clock.partition_end[partition - 1], lo + 3.5e14))
    # readings on the clock's own microsecond grid, so SPICE sees exactly the same value
    micro = rng.integers(lo, hi, 3000)
    ours = clock.to_et(np.full(micro.size, partition), micro / 1e6)
    ref = np.array([spiceypy.scs2e(-236, _msgr_string(partition, int(m))) for m in micro])
    # requirement: <= 1 microsecond; float64 ET resolution (~6e-8 s) is the real limit
    assert np.max(np.abs(ours - ref)) < 1e-6


def test_messenger_sclk_published_checks(real_clocks):
    clock = SclkKernel.from_pool(-236)
    # MANIFEST.md (checked with spiceypy 8.3): 1/0 -> 2004-08-03T05:59:16 UTC,
    # 2/0066000000 -> 2015-02-11T17:33:24 UTC
    # (published to the second, so agreement within half a second)
    ours = clock.to_et([1, 2], [0.0, 66000000.0])
    published = utc_to_et(["2004-08-03T05:59:16", "2015-02-11T17:33:24"])
    assert np.max(np.abs(ours - published)) <= 0.5


def test_messenger_sclk_inverse_matches_sce2c(real_clocks):
    clock = SclkKernel.from_pool(-236)
    et = np.linspace(spiceypy.str2et("2004-09-01"), spiceypy.str2et("2015-04-01"), 500)
    part, sec = clock.from_et(et)
    for e, p, _s in zip(et[::25], part[::25], sec[::25], strict=True):
        ticks = spiceypy.sce2c(-236, float(e))  # continuous encoded ticks
        p_ref, _ = _decode_partition(clock, ticks)
        assert p == p_ref
    # and the round trip is exact to float64 resolution
    assert np.max(np.abs(clock.to_et(part, sec) - et)) < 1e-6


def _decode_partition(clock, ticks):
    offsets = clock.partition_offsets
    p = int(np.searchsorted(offsets, ticks, side="right"))
    return p, ticks - offsets[p - 1]


def test_rosetta_sclk_matches_scs2e(real_clocks):
    clock = SclkKernel.from_pool(-226)
    rng = np.random.default_rng(7)
    start = int(clock.partition_start[0])
    # the Rosetta range: from the first coefficient to 2016-10 (end of mission)
    stop = int(clock.encode([1], [spiceypy.sce2c(-226, spiceypy.str2et("2016-09-30"))
                                  / 65536.0 + start / 65536.0])[0] + start)
    ticks = rng.integers(start, stop, 3000)
    ours = clock.to_et(np.ones(ticks.size), ticks / 65536.0)
    ref = np.array(
        [spiceypy.scs2e(-226, f"1/{t // 65536}.{t % 65536}") for t in ticks]
    )
    assert np.max(np.abs(ours - ref)) < 1e-6
    # MANIFEST.md: 1/0370000000 -> 2014-09-22T09:47:49.694 UTC
    assert et_to_utc(clock.to_et([1], [370000000.0]))[0] == "2014-09-22T09:47:49.694"


def test_reading_outside_partitions_is_named(real_clocks):
    clock = SclkKernel.from_pool(-236)
    with pytest.raises(InputFormatError, match="partition 3 does not exist"):
        clock.to_et([1, 3], [10.0, 10.0])
    with pytest.raises(InputFormatError, match="1/268000000.000000.*outside partition 1"):
        clock.to_et([1], [268000000.0])


def test_tt2000_matches_unitim():
    with KernelPool([]):
        et = np.random.default_rng(3).uniform(-3e8, 9e8, 2000)
        tt = et_to_tt2000(et)
        assert tt.dtype == np.int64
        ref = np.array([spiceypy.unitim(float(e), "TDB", "TDT") for e in et])
        assert np.max(np.abs(tt * 1e-9 - ref)) < 2e-7  # float64 ET resolution
        assert np.max(np.abs(tt2000_to_et(tt) - et)) < 1e-6


@pytest.mark.parametrize(
    ("style", "picture"),
    [("doy", "YYYY DOY HR MN SC.### ::UTC"), ("iso", "YYYY-MM-DDTHR:MN:SC.### ::UTC")],
)
def test_utc_strings_match_timout(style, picture):
    with KernelPool([]):
        rng = np.random.default_rng(11)
        et = rng.uniform(-3e8, 9e8, 3000)
        # and the last seconds around two leap seconds (2008-12-31, 2016-12-31)
        for leap in ("2009-01-01T00:00:00", "2017-01-01T00:00:00"):
            base = spiceypy.str2et(leap)
            et = np.concatenate([et, base + np.arange(-3.0, 2.0, 0.25) + 0.0001])
        ours = et_to_utc(et, style=style)
        ref = np.array([spiceypy.timout(float(e), picture) for e in et])
        assert (ours == ref).all(), list(zip(ours[ours != ref], ref[ours != ref], strict=True))[:3]


def test_leap_second_is_shown_as_60():
    with KernelPool([]):
        tt = utc_to_tt2000(["2016-12-31T23:59:60.500"])
        assert tt2000_to_utc(tt, digits=3)[0] == "2016-12-31T23:59:60.500"
        before = utc_to_tt2000(["2016-12-31T23:59:59.500"])
        assert tt[0] - before[0] == 1_000_000_000


def test_utc_parse_matches_str2et():
    with KernelPool([]):
        text = ["2004-08-03T06:15:56.500", "2012-06-01T00:00:00", "2014-09-22T09:47:49.694Z"]
        ref = [spiceypy.str2et(s.rstrip("Z")) for s in text]
        assert np.max(np.abs(utc_to_et(text) - ref)) < 1e-6


def test_bad_utc_string_is_named():
    with KernelPool([]), pytest.raises(InputFormatError, match="2014-13-01"):
        utc_to_tt2000(["2014-01-01T00:00:00", "2014-13-01T00:00:00"])


@pytest.fixture(scope="module")
def lsk():
    with KernelPool([]):
        return leapseconds()


@settings(max_examples=300, deadline=None)
@given(st.integers(min_value=-10**17, max_value=10**18))
def test_utc_round_trip_is_exact_to_the_nanosecond(lsk, tt2000):
    text = tt2000_to_utc(np.array([tt2000]), digits=9, lsk=lsk)
    assert utc_to_tt2000(text, lsk=lsk)[0] == tt2000


def test_sclk_to_tt2000_direct_matches_spice(real_clocks):
    """The TT2000 epoch taken straight from the TDT clock correlation equals SPICE's
    scs2e followed by unitim(TDB -> TDT)."""
    clock = SclkKernel.from_pool(-236)
    micro = np.random.default_rng(5).integers(int(2e14), int(2.6e14), 500)
    et, tt2000 = clock.to_et_and_tt2000(np.ones(micro.size, dtype=int), micro / 1e6)
    ref_et = np.array([spiceypy.scs2e(-236, _msgr_string(1, int(m))) for m in micro])
    ref_tt = np.array([spiceypy.unitim(e, "TDB", "TDT") for e in ref_et])
    assert np.max(np.abs(et - ref_et)) < 1e-6
    assert np.max(np.abs(tt2000 * 1e-9 - ref_tt)) < 1e-6
