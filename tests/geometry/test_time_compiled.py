"""The compiled SCLK conversion (`SclkKernel.to_et`, `to_et_and_tt2000`) against its numpy
reference (`encode`, `_parallel`, `LeapSecondTable`), and its TDB - TT expansion."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numba import njit

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import TDB_TT_NODE_SPACING, SclkKernel, _tdb_minus_tt_taylor


@pytest.fixture(scope="module")
def clocks(shared_kernels):
    with KernelPool(
        [shared_kernels / "messenger" / "messenger_2548.tsc",
         shared_kernels / "rosetta" / "ROS_160929_STEP.TSC"]
    ):
        msgr = SclkKernel.from_pool(-236)
        yield {
            "messenger": msgr,  # TT (TDT) parallel time, 2 partitions
            "rosetta": SclkKernel.from_pool(-226),  # TT, 1 partition
            # the same coefficients read as a TDB clock: the tdb_to_tt branch of TT2000
            "messenger_tdb": dataclasses.replace(msgr, time_system=1),
            # 3e6 ticks per count: 1e9 / tpc = 1000 / 3, the integer-division branch of
            # the exact TT2000 (the real clocks take the shift branch: den 1 and 128); the
            # records 1e9 ticks later, so readings before the first give negative counts
            "messenger_3mhz": dataclasses.replace(msgr, moduli=np.array([2.0**28, 3.0e6]),
                                                  ticks=msgr.ticks + 1e9),
        }


def _readings(clock, rng, n, *, sort=True):
    """Random readings over every partition, with each partition's first and last tick."""
    tpc = clock.ticks_per_count
    parts, secs = [], []
    for p in range(len(clock.partition_start)):
        lo, hi = clock.partition_start[p], clock.partition_end[p]
        sec = rng.uniform(lo, hi, n) / tpc
        sec = np.sort(sec) if sort else sec
        sec = np.concatenate([[lo / tpc, hi / tpc], sec])
        parts.append(np.full(sec.size, p + 1, dtype=np.int8))
        secs.append(sec)
    return np.concatenate(parts), np.concatenate(secs)


def _assert_et_close(got, ref):
    # identical arithmetic except TDB - TT (a cubic expansion, see
    # `_tdb_minus_tt_taylor`): they differ by < 1e-16 s, so the ET (ulp 6e-8 s) can
    # differ by one ulp in about one reading in 1e9
    assert np.all(np.abs(got - ref) <= np.spacing(np.abs(ref)))


@pytest.mark.parametrize("name", ["messenger", "rosetta", "messenger_tdb"])
@pytest.mark.parametrize("sort", [True, False])
def test_to_et_and_tt2000_match_reference(clocks, name, sort):
    clock = clocks[name]
    part, sec = _readings(clock, np.random.default_rng(len(name)), 40000, sort=sort)
    et, tt2000 = clock.to_et_and_tt2000(part, sec)
    ref_et, ref_tt = clock.to_et_and_tt2000_reference(part, sec)
    _assert_et_close(et, ref_et)
    assert tt2000.dtype == np.int64
    # TT clocks: the same operations (exact); TDB clock: TT from the expansion, whose
    # ~1e-17 s could move a rounding to the nanosecond in ~1 reading in 1e8
    assert np.all(np.abs(tt2000 - ref_tt) <= (0 if name != "messenger_tdb" else 1))
    _assert_et_close(clock.to_et(part, sec), clock.to_et_reference(part, sec))


def test_twenty_hertz_day_is_bit_identical(clocks):
    clock = clocks["messenger"]
    sec = 2.0e8 + np.arange(0.0, 86400.0, 0.05)
    part = np.ones(sec.size, dtype=np.int8)
    et, tt2000 = clock.to_et_and_tt2000(part, sec)
    ref_et, ref_tt = clock.to_et_and_tt2000_reference(part, sec)
    np.testing.assert_array_equal(tt2000, ref_tt)
    # observed bit-identical; one-ulp differences are allowed (see _assert_et_close)
    assert np.count_nonzero(et != ref_et) <= 1
    _assert_et_close(et, ref_et)


def test_scalars_lists_float_partitions_and_empty(clocks):
    clock = clocks["messenger"]
    for p, s in [(1, 2.0e8), ([1, 2], [2.0e8, 1.0e7]), (np.array([1.0, 2.0]), [3.0, 4.0e3])]:
        got, ref = clock.to_et(p, s), clock.to_et_reference(p, s)
        assert np.shape(got) == np.shape(ref)
        _assert_et_close(np.asarray(got), np.asarray(ref))
        got2, ref2 = clock.to_et_and_tt2000(p, s), clock.to_et_and_tt2000_reference(p, s)
        assert np.shape(got2[1]) == np.shape(ref2[1])
        assert np.all(got2[1] == ref2[1])
    assert isinstance(clock.to_et(1, 2.0e8), np.floating)
    et, tt = clock.to_et_and_tt2000(np.empty(0, int), np.empty(0))
    assert et.shape == tt.shape == (0,) and tt.dtype == np.int64


def test_rejected_readings_raise_the_reference_errors(clocks):
    clock = clocks["messenger"]
    with pytest.raises(InputFormatError, match="partition 3 does not exist"):
        clock.to_et([1, 3], [10.0, 10.0])
    with pytest.raises(InputFormatError, match="partition 0 does not exist"):
        clock.to_et_and_tt2000([0], [10.0])
    with pytest.raises(InputFormatError, match="1/268000000.000000.*outside partition 1"):
        clock.to_et_and_tt2000(np.ones(3, np.int8), [1.0, 2.0, 268000000.0])
    with pytest.raises(InputFormatError, match="outside partition 1"):
        clock.to_et([1], [-1e-3])  # just below the first tick


def test_nan_reading_gives_what_the_reference_gives(clocks):
    clock = clocks["messenger"]
    sec = np.array([2.0e8, np.nan, 2.1e8])
    got, ref = clock.to_et(np.ones(3, int), sec), clock.to_et_reference(np.ones(3, int), sec)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    _assert_et_close(got[[0, 2]], ref[[0, 2]])


@njit
def _taylor_many(t, k, eb, m0, m1, out):
    cache = np.full(5, np.nan)
    for i in range(t.size):
        out[i] = _tdb_minus_tt_taylor(t[i], k, eb, m0, m1, cache)


def _expansion(t, lsk):
    out = np.empty_like(t)
    _taylor_many(t, lsk.k, lsk.eb, lsk.m0, lsk.m1, out)
    return out


def test_tdb_minus_tt_expansion_against_the_formula(clocks):
    lsk = clocks["messenger"].lsk
    rng = np.random.default_rng(9)
    half = TDB_TT_NODE_SPACING / 2
    nodes = TDB_TT_NODE_SPACING * rng.integers(-2e7, 2e7, 200).astype(float)
    # around the nodes and their cell edges (|t - node| = 64 s is the worst truncation)
    local = np.concatenate([nodes, nodes + half, np.nextafter(nodes + half, -np.inf),
                            nodes - half, nodes + rng.uniform(-half, half, 200)])
    for t, tol in [
        # near J2000 the argument M = M0 + M1 t is exact to ~1e-15 rad: the expansion
        # and the formula then agree to the rounding of TDB - TT (ulp 2.2e-19 s)
        (rng.uniform(-1000.0, 1000.0, 20000), 4e-18),
        # 2004-2015: both round M to ~1.4e-14 rad, ~1e-17 s of TDB - TT each
        (np.sort(rng.uniform(1e8, 5e8, 20000)), 1e-16),
        (local, 6e-16),  # |t| up to 2.6e9 s: M ~ 500 rad, its rounding ~1e-16 s
    ]:
        got = _expansion(t, lsk)
        ref = lsk.tdb_minus_tt(t)
        assert np.max(np.abs(got - ref)) < tol
        # and the result depends on t only, not on the order of the calls
        perm = rng.permutation(t.size)
        np.testing.assert_array_equal(_expansion(t[perm], lsk), got[perm])


def test_tdb_minus_tt_expansion_against_extended_precision(clocks):
    """Against an 80-bit evaluation (x86 long double) the expansion is as good as numpy."""
    if np.finfo(np.longdouble).eps > 1e-18:
        pytest.skip("no extended precision long double on this platform")
    lsk = clocks["messenger"].lsk
    t = np.random.default_rng(10).uniform(-1000.0, 1000.0, 50000)
    big = np.longdouble
    m = big(lsk.m0) + big(lsk.m1) * t.astype(big)
    exact = big(lsk.k) * np.sin(m + big(lsk.eb) * np.sin(m))
    err = float(np.max(np.abs(_expansion(t, lsk) - exact)))
    err_numpy = float(np.max(np.abs(lsk.tdb_minus_tt(t) - exact)))
    assert err < 3e-18 and err < 2 * err_numpy  # truncation (< 1e-23 s) invisible


def test_expansion_of_non_finite_times_is_nan(clocks):
    lsk = clocks["messenger"].lsk
    got = _expansion(np.array([np.nan, np.inf, -np.inf, 0.0]), lsk)
    assert np.isnan(got[:3]).all() and np.isfinite(got[3])


@pytest.mark.parametrize("name", ["messenger", "rosetta", "messenger_3mhz"])
def test_whole_tick_readings_match_reference(clocks, name):
    # the compiled integer-tick path against the numpy reference fed the same readings
    # as float seconds (exact for Rosetta's 1/65536 s, snapped for MESSENGER's us)
    clock = clocks[name]
    rng = np.random.default_rng(3)
    tpc = int(clock.ticks_per_count)
    part, ticks = [], []
    for p in range(len(clock.partition_start)):
        lo, hi = int(clock.partition_start[p]), int(clock.partition_end[p])
        ticks.append(np.concatenate([[lo, hi], rng.integers(lo, hi, 20000)]))
        part.append(np.full(20002, p + 1))
    part, ticks = np.concatenate(part), np.concatenate(ticks)
    et, tt2000 = clock.to_et_and_tt2000_ticks(part, ticks)
    ref_et, ref_tt = clock.to_et_and_tt2000_reference(part, ticks / tpc)
    np.testing.assert_array_equal(tt2000, ref_tt)
    _assert_et_close(et, ref_et)
