"""Exact (1 ns) TT2000 <-> UTC against outside tools: cdflib (its own leap-second table and
integer arithmetic) and SPICE ``timout``; round trips by hypothesis.

Oracles: ``cdflib.cdfepoch.compute_tt2000`` / ``breakdown_tt2000`` / ``encode_tt2000`` /
``to_datetime`` and ``spiceypy.timout``; none shares code with fluxcal.geometry.time.
"""

from __future__ import annotations

import datetime

import numpy as np
import pytest
import spiceypy
from cdflib.epochs import CDFepoch
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError, KernelError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import (
    TT2000_FILL,
    TT2000_PAD,
    LeapSecondTable,
    SclkKernel,
    datetime64_to_tt2000,
    leapseconds,
    tt2000_to_datetime64,
    tt2000_to_utc,
    tt2000_to_utc_fields,
    utc_day_start_tt2000,
    utc_fields_to_tt2000,
    utc_to_tt2000,
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


# ----------------------------------------------------------------------------------------
# UTC fields and strings against cdflib (exact, both directions)
# ----------------------------------------------------------------------------------------
def test_fields_match_cdflib_breakdown(lsk, epochs):
    ours = tt2000_to_utc_fields(epochs, lsk=lsk)
    ref = CDFepoch.breakdown_tt2000(epochs)  # y, m, d, h, mi, s, ms, us, ns
    for k, name in enumerate(["year", "month", "day", "hour", "minute", "second"]):
        np.testing.assert_array_equal(ours[name], ref[:, k], err_msg=name)
    np.testing.assert_array_equal(
        ours["nanosecond"], ref[:, 6] * 1_000_000 + ref[:, 7] * 1000 + ref[:, 8])
    # day of year from the standard library's proleptic Gregorian calendar
    doy = [datetime.date(*map(int, r[:3])).timetuple().tm_yday for r in ref]
    np.testing.assert_array_equal(ours["doy"], doy)
    assert (ours["second"] == 60).sum() > 400


def test_cdflib_compute_tt2000_of_our_fields_is_the_epoch(lsk, epochs):
    f = tt2000_to_utc_fields(epochs, lsk=lsk)
    ns = f["nanosecond"]
    fields = np.stack([f["year"], f["month"], f["day"], f["hour"], f["minute"], f["second"],
                       ns // 1_000_000, ns // 1000 % 1000, ns % 1000], axis=1)
    np.testing.assert_array_equal(np.asarray(CDFepoch.compute_tt2000(fields)), epochs)


def test_fields_with_float_seconds_give_cdflib_epoch(lsk, epochs):
    # the table form (MESSENGER CDR): year, day of year, hour, minute, float second; the
    # fields come from cdflib's breakdown and the day of year from the standard library,
    # so nothing of fluxcal's forward conversion is involved.  Exact to the ns: a float
    # second below 61 s carries < 1e-14 s of representation error.
    ref = CDFepoch.breakdown_tt2000(epochs)  # y, m, d, h, mi, s, ms, us, ns
    doy = np.array([datetime.date(*map(int, r[:3])).timetuple().tm_yday for r in ref])
    second = ref[:, 5] + (ref[:, 6] * 1_000_000 + ref[:, 7] * 1000 + ref[:, 8]) / 1e9
    got = utc_fields_to_tt2000(ref[:, 0], doy, ref[:, 3], ref[:, 4], second, lsk)
    np.testing.assert_array_equal(got, epochs)
    assert (ref[:, 5] == 60).sum() > 400  # leap seconds are in the sample


@pytest.mark.parametrize("y, m, d", [*LEAP_DAYS, (2012, 7, 1), (2000, 2, 29), (2011, 3, 21)])
def test_day_start_is_cdflibs_midnight(lsk, y, m, d):
    day = np.datetime64(f"{y:04d}-{m:02d}-{d:02d}")
    start = utc_day_start_tt2000(day, lsk)
    assert start == _cdf([y, m, d, 0, 0, 0, 0, 0, 0])
    nxt = (datetime.date(y, m, d) + datetime.timedelta(days=1)).timetuple()[:3]
    length = utc_day_start_tt2000(day + 1, lsk) - start
    assert length == (86_401 if (y, m, d) in LEAP_DAYS else 86_400) * NS
    assert utc_day_start_tt2000(day + 1, lsk) == _cdf([*nxt, 0, 0, 0, 0, 0, 0])


def test_fill_and_pad_fields_match_cdflib(lsk):
    special = np.array([TT2000_FILL, TT2000_PAD, 0], dtype=np.int64)
    f = tt2000_to_utc_fields(special, lsk=lsk)
    ref = CDFepoch.breakdown_tt2000(special)
    np.testing.assert_array_equal(f["second"], ref[:, 5])
    np.testing.assert_array_equal(f["year"], ref[:, 0])
    assert list(tt2000_to_utc(special, digits=9, lsk=lsk)) == [
        "9999-12-31T23:59:59.999999999", "0000-01-01T00:00:00.000000000",
        CDFepoch.encode_tt2000(0)]


def test_iso_strings_match_cdflib_encode(lsk, epochs):
    # encode_tt2000 is a Python loop (~1 ms a value): every leap-second epoch, 2,000 others
    sample = np.concatenate([epochs[:2000], epochs[20_000:]])
    ref = np.array(CDFepoch.encode_tt2000(sample))
    ours = tt2000_to_utc(sample, digits=9, lsk=lsk)
    np.testing.assert_array_equal(ours, ref)
    np.testing.assert_array_equal(tt2000_to_utc(sample, digits=9, lsk=lsk, as_bytes=True),
                                  np.char.encode(ref, "ascii"))
    # fewer digits are cdflib's string truncated (timout truncates, never rounds)
    for digits in (0, 1, 3, 4, 6, 8):
        width = 19 + (digits + 1 if digits else 0)
        np.testing.assert_array_equal(tt2000_to_utc(sample, digits=digits, lsk=lsk),
                                      np.array([s[:width] for s in ref]))
    # and back: parsing cdflib's strings gives the epochs
    np.testing.assert_array_equal(utc_to_tt2000(ref, lsk=lsk), sample)


def test_doy_strings_from_cdflib_fields(lsk, epochs):
    ref = CDFepoch.breakdown_tt2000(epochs[::7])
    expected = [
        f"{y:04d} {datetime.date(y, m, d).timetuple().tm_yday:03d} {h:02d} {mi:02d} {s:02d}."
        f"{ms:03d}{us:03d}{ns:03d}"[: 17 + 1 + 7]
        for y, m, d, h, mi, s, ms, us, ns in ref.tolist()
    ]
    np.testing.assert_array_equal(tt2000_to_utc(epochs[::7], "doy", 7, lsk=lsk), expected)


def test_shape_is_kept(lsk, epochs):
    grid = epochs[:12].reshape(3, 4)
    assert tt2000_to_utc(grid, lsk=lsk).shape == (3, 4)
    assert tt2000_to_utc(grid[0, 0], lsk=lsk).shape == (1,)
    assert tt2000_to_utc_fields(grid, lsk=lsk)["doy"].shape == (3, 4)
    assert tt2000_to_utc(np.array([], dtype=np.int64), lsk=lsk).shape == (0,)


# ----------------------------------------------------------------------------------------
# Millisecond strings against SPICE timout
# ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def messenger_clock(shared_kernels):
    with KernelPool([shared_kernels / "messenger" / "messenger_2548.tsc"]):
        yield SclkKernel.from_pool(-236)


def _timout(tt2000: np.ndarray, picture: str) -> np.ndarray:
    """SPICE's own string of a TT2000 epoch: TT seconds -> TDB by ``unitim``, then ``timout``."""
    return np.array([spiceypy.timout(spiceypy.unitim(float(t) / 1e9, "TDT", "TDB"), picture)
                     for t in tt2000.tolist()])


@pytest.mark.parametrize(
    ("style", "picture"),
    [("doy", "YYYY DOY HR MN SC.### ::UTC"), ("iso", "YYYY-MM-DDTHR:MN:SC.### ::UTC")],
)
def test_millisecond_strings_match_timout(messenger_clock, style, picture):
    clock = messenger_clock
    rng = np.random.default_rng(216)
    parts = []
    for p in (1, 2):  # both MESSENGER clock partitions (before / after the 2013-01-08 reset)
        lo = clock.partition_start[p - 1] / 1e6
        hi = min(clock.partition_end[p - 1] / 1e6, lo + 3.3e8)
        sec = rng.integers(int(lo * 1e6), int(hi * 1e6), 5000) / 1e6  # on the us tick grid
        parts.append(clock.to_tt2000(np.full(sec.size, p), sec))
    parts.append(rng.integers(_cdf([1999, 1, 1, 0, 0, 0, 0, 0, 0]),
                              _cdf([2030, 1, 1, 0, 0, 0, 0, 0, 0]), 5000))
    for y, m, d in LEAP_DAYS:  # every 50 ms across each leap second, off the ms grid
        leap = _cdf([y, m, d, 23, 59, 60, 0, 0, 0])
        parts.append(np.arange(leap - 2 * NS, leap + 2 * NS, NS // 20) + 123_457)
    tt = np.concatenate(parts).astype(np.int64)
    # timout takes a float64 ET: at these epochs (|ET| < 1e9 s) its resolution is 60 ns and
    # TT -> TDB adds a rounding, so SPICE cannot tell on which side of a millisecond a time
    # within ~30 ns of it lies.  Times within 100 ns of a millisecond are left out (and
    # counted: with random ns about 2 in 10,000); the exact case is tested below.
    sub_ms = tt % 1_000_000
    near = (sub_ms < 100) | (sub_ms > 1_000_000 - 100)
    assert near.sum() < 20, near.sum()  # 5 of 15,400 here
    tt = tt[~near]
    ours = tt2000_to_utc(tt, style=style, digits=3)
    ref = _timout(tt, picture)
    assert (np.char.find(ref, ":60.") > 0).sum() + (np.char.find(ref, " 60.") > 0).sum() >= 100
    bad = ours != ref
    assert not bad.any(), list(zip(ours[bad], ref[bad], strict=True))[:5]


def test_messenger_launch_second_prints_16_000(lsk):
    # 2004-08-03T05:59:16.000 UTC (MESSENGER SCLK 1/0000000000), an integer TT2000 exactly
    # on the millisecond: truncation keeps .000 (a float ET 15 ns early printed 15.999)
    tt = np.array([_cdf([2004, 8, 3, 5, 59, 16, 0, 0, 0])], dtype=np.int64)
    assert tt2000_to_utc(tt, "doy", lsk=lsk)[0] == "2004 216 05 59 16.000"
    assert tt2000_to_utc(tt - 1, "doy", lsk=lsk)[0] == "2004 216 05 59 15.999"
    assert tt2000_to_utc(tt, "iso", 9, lsk=lsk)[0] == "2004-08-03T05:59:16.000000000"
    with KernelPool([]):
        assert _timout(tt, "YYYY DOY HR MN SC.### ::UTC")[0] == "2004 216 05 59 16.000"


# ----------------------------------------------------------------------------------------
# Round trips (hypothesis), leap seconds included
# ----------------------------------------------------------------------------------------
_near_leaps = st.builds(
    lambda i, off: _cdf([*LEAP_DAYS[i], 23, 59, 60, 0, 0, 0]) + off,
    st.integers(0, len(LEAP_DAYS) - 1), st.integers(-2 * NS, 2 * NS),
)


@settings(max_examples=400, deadline=None)
@given(st.one_of(st.integers(min_value=-(2**62), max_value=2**62), _near_leaps))
def test_string_round_trip_is_exact(lsk, tt2000):
    t = np.array([tt2000], dtype=np.int64)
    assert utc_to_tt2000(tt2000_to_utc(t, digits=9, lsk=lsk), lsk=lsk)[0] == tt2000
    # and truncation to ms never moves later, nor more than 1 ms earlier
    back = utc_to_tt2000(tt2000_to_utc(t, digits=3, lsk=lsk), lsk=lsk)[0]
    assert 0 <= tt2000 - back < 1_000_000


def test_utc_parse_rejects_a_false_leap_second(lsk):
    with pytest.raises(InputFormatError, match="2015-01-01T12:00:60"):
        utc_to_tt2000(["2016-12-31T23:59:60.5", "2015-01-01T12:00:60"], lsk=lsk)
    with pytest.raises(InputFormatError, match="2014-12-31T23:59:60"):
        utc_to_tt2000(["2014-12-31T23:59:60"], lsk=lsk)  # no leap second that day


def test_utc_parse_fraction_is_exact(lsk):
    # nine decimals are read as integer nanoseconds (no float): compare with cdflib
    text = ["2004-08-03T05:59:16.000000001", "2012-06-30T23:59:60.999999999",
            "2030-12-31T23:59:59.123456789"]
    np.testing.assert_array_equal(utc_to_tt2000(text, lsk=lsk),
                                  [CDFepoch.parse(s) for s in text])


def test_lsk_with_a_two_second_step_is_refused(tmp_path):
    # the UTC conversions show one inserted second (23:59:60) before each LSK epoch
    odd = tmp_path / "odd.tls"
    odd.write_text("KPL/LSK\n\\begindata\nDELTET/DELTA_AT = ( 10, @1972-JAN-1\n"
                   "                    12, @1973-JAN-1 )\n\\begintext\n")
    with KernelPool([odd]), pytest.raises(KernelError, match="step by \\+1 s"):
        LeapSecondTable.from_pool()
