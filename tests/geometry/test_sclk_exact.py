"""Exact SCLK -> TT2000 (int64 ns) of the two TDT clocks (MESSENGER -236, Rosetta -226).

Oracles, none sharing code with fluxcal.geometry.time:

* the kernel files' own text, parsed here with ``re``/``decimal``/``datetime`` and
  evaluated in exact rational arithmetic (``fractions.Fraction``);
* SPICE ``sct2e`` + ``timout`` millisecond strings (float64 ET: readings within 100 ns of
  a millisecond are left out, as in test_utc_exact.py).
"""

from __future__ import annotations

import dataclasses
import datetime
import re
from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import spiceypy

from fluxcal.errors import InputFormatError, KernelError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel, tt2000_to_utc

NS = 1_000_000_000
FILES = {-236: ("messenger", "messenger_2548.tsc"), -226: ("rosetta", "ROS_160929_STEP.TSC")}


@dataclasses.dataclass
class TextClock:
    """A type 1 SCLK as written in its kernel file: ints and exact fractions."""

    tpc: int
    starts: list[int]
    ends: list[int]
    ticks: list[int]
    parallel_ns: list[int]
    rates: list[Fraction]

    def encoded(self, partition: int, tick: int) -> int:
        lengths = [e - s for s, e in zip(self.starts, self.ends, strict=True)]
        return sum(lengths[: partition - 1]) + tick - self.starts[partition - 1]

    def tt2000(self, encoded: int) -> Fraction:
        """Exact TT ns past J2000 of an encoded tick (the type 1 formula)."""
        j = max([i for i, t in enumerate(self.ticks) if t <= encoded] or [0])
        return self.parallel_ns[j] + Fraction((encoded - self.ticks[j]) * NS, self.tpc) * (
            self.rates[j])


def _data_values(path: Path, name: str) -> list[str]:
    """Tokens of ``name = ( ... )`` inside the \\begindata blocks of a text kernel."""
    blocks = re.split(r"\\begin(data|text)", path.read_text())
    data = " ".join(blocks[i + 1] for i in range(len(blocks) - 1) if blocks[i] == "data")
    match = re.search(rf"{re.escape(name)}\s*=\s*\(([^)]*)\)", data)
    assert match, name
    return match.group(1).split()


def _exact_int(token: str) -> int:
    value = Decimal(token)
    assert value == value.to_integral_value(), token
    return int(value)


def _parallel_ns(token: str) -> int:
    if token.startswith("@"):  # @DD-MON-YYYY-HR:MN:SC.ffffff, formal calendar seconds
        when = datetime.datetime.strptime(token[1:], "%d-%b-%Y-%H:%M:%S.%f")
        return (when - datetime.datetime(2000, 1, 1, 12)) // datetime.timedelta(
            microseconds=1) * 1000
    return _exact_int(str(Decimal(token) * NS))


def _text_clock(path: Path, sc_id: int) -> TextClock:
    cid = abs(sc_id)
    moduli = [_exact_int(v) for v in _data_values(path, f"SCLK01_MODULI_{cid}")]
    coeff = _data_values(path, f"SCLK01_COEFFICIENTS_{cid}")
    return TextClock(
        tpc=int(np.prod(moduli[1:])),
        starts=[_exact_int(v) for v in _data_values(path, f"SCLK_PARTITION_START_{cid}")],
        ends=[_exact_int(v) for v in _data_values(path, f"SCLK_PARTITION_END_{cid}")],
        ticks=[_exact_int(v) for v in coeff[0::3]],
        parallel_ns=[_parallel_ns(v) for v in coeff[1::3]],
        rates=[Fraction(Decimal(v)) for v in coeff[2::3]],
    )


@pytest.fixture(scope="module")
def clocks(shared_kernels):
    paths = {sc: shared_kernels / folder / name for sc, (folder, name) in FILES.items()}
    with KernelPool(list(paths.values())):
        yield {sc: (SclkKernel.from_pool(sc), _text_clock(paths[sc], sc)) for sc in paths}


def _random_readings(text: TextClock, rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Whole-tick readings in every partition, from before the first record to 30 days
    after the last (where the clock is defined by the kernel's records)."""
    hi_encoded = text.ticks[-1] + 30 * 86400 * text.tpc
    parts, ticks = [], []
    for p, (start, end) in enumerate(zip(text.starts, text.ends, strict=True), 1):
        lo_enc = text.encoded(p, start)
        if lo_enc > hi_encoded:
            continue
        top = min(end, start + (hi_encoded - lo_enc))
        ticks.append(rng.integers(start, top + 1, n))
        ticks.append(np.array([start, top]))
        parts.append(np.full(n + 2, p))
    return np.concatenate(parts), np.concatenate(ticks)


@pytest.mark.parametrize("sc_id", [-236, -226])
def test_every_coefficient_record_gives_its_parallel_time_exactly(clocks, sc_id):
    # a reading exactly at a record's encoded tick is that record's stated TDT epoch
    # (to the microsecond in both files), so its TT2000 is known exactly: 2,545 and 181
    clock, text = clocks[sc_id]
    assert len(set(text.ticks)) == len(text.ticks)  # distinct records
    lengths = np.cumsum([e - s for s, e in zip(text.starts, text.ends, strict=True)])
    enc = np.array(text.ticks, dtype=np.int64)
    part = np.searchsorted(lengths, enc, side="right") + 1  # a partition end starts the next
    offsets = np.concatenate([[0], lengths[:-1]])
    tick = enc - offsets[part - 1] + np.array(text.starts, dtype=np.int64)[part - 1]
    got = clock.to_tt2000_ticks(part, tick)
    np.testing.assert_array_equal(got, np.array(text.parallel_ns, dtype=np.int64))
    # the same readings as float seconds (the nearest float64 to each) give the same
    np.testing.assert_array_equal(clock.to_tt2000(part, tick / text.tpc), got)


@pytest.mark.parametrize("sc_id", [-236, -226])
def test_random_readings_equal_exact_rational_arithmetic(clocks, sc_id):
    clock, text = clocks[sc_id]
    part, tick = _random_readings(text, np.random.default_rng(abs(sc_id)), 1500)
    got = clock.to_tt2000_ticks(part, tick)
    n_tie = 0
    for p, k, g in zip(part.tolist(), tick.tolist(), got.tolist(), strict=True):
        exact = text.tt2000(text.encoded(p, k))
        # one rounding to the ns; the only float term (fraction + nominal * (rate - 1))
        # carries < 1e-3 ns of error, so a value that close to a half ns may round either way
        tie = abs(exact - int(exact) - Fraction(1, 2)) < Fraction(1, 1000)
        n_tie += tie
        assert g == round(exact) or (tie and abs(g - exact) < 1), (p, k, g, float(exact))
    assert n_tie <= 0.01 * got.size  # random values: 0.2 % expected


@pytest.mark.parametrize("sc_id", [-236, -226])
def test_millisecond_strings_match_sct2e_timout(clocks, sc_id):
    clock, text = clocks[sc_id]
    part, tick = _random_readings(text, np.random.default_rng(7 + abs(sc_id)), 3000)
    got = clock.to_tt2000_ticks(part, tick)
    # SPICE's float64 ET (ulp 6e-8 s at 5e8 s) cannot place a time within ~60 ns of a
    # millisecond on the right side: those (about 2 in 10,000) are left out and counted
    sub_ms = got % 1_000_000
    keep = (sub_ms >= 100) & (sub_ms <= 1_000_000 - 100)
    assert (~keep).sum() < 10
    picture = "YYYY-MM-DDTHR:MN:SC.### ::UTC"
    ref = np.array([
        spiceypy.timout(spiceypy.sct2e(sc_id, float(text.encoded(p, k))), picture)
        for p, k in zip(part[keep].tolist(), tick[keep].tolist(), strict=True)
    ])
    ours = tt2000_to_utc(got[keep], "iso", 3)
    bad = ours != ref
    assert not bad.any(), list(zip(ours[bad], ref[bad], strict=True))[:5]


def test_messenger_first_tick_is_launch_second_exactly(clocks):
    # SCLK 1/0000000000:000000 is the first record, TDT 2004-08-03T06:00:20.184000, i.e.
    # UTC 05:59:16.000 (TT - UTC = 32.184 + 32 s); float MET seconds gave 15 ns early
    clock, _ = clocks[-236]
    expected = (datetime.datetime(2004, 8, 3, 6, 0, 20, 184000)
                - datetime.datetime(2000, 1, 1, 12)) // datetime.timedelta(microseconds=1) * 1000
    for got in (clock.to_tt2000([1], [0.0]), clock.to_tt2000_ticks([1], [0]),
                clock.to_et_and_tt2000(1, 0.0)[1]):
        assert int(np.ravel(got)[0]) == expected
    assert tt2000_to_utc(clock.to_tt2000([1], [0.0]), "doy")[0] == "2004 216 05 59 16.000"
    assert spiceypy.timout(spiceypy.scs2e(-236, "1/0000000000:000000"),
                           "YYYY DOY HR MN SC.### ::UTC") == "2004 216 05 59 16.000"


@pytest.mark.parametrize("sc_id", [-236, -226])
def test_float_seconds_from_text_equal_whole_ticks(clocks, sc_id):
    # MET/OBT seconds parsed from decimal text are the nearest float64 of a whole-tick
    # reading: they are snapped to it (both signs of the float error occur)
    clock, text = clocks[sc_id]
    part, tick = _random_readings(text, np.random.default_rng(11), 3000)
    if text.tpc == 1_000_000:
        sec = np.array([float(f"{k // 10**6}.{k % 10**6:06d}") for k in tick.tolist()])
    else:
        sec = np.array([float(Fraction(k, text.tpc)) for k in tick.tolist()])
    raw = sec * text.tpc - tick
    if text.tpc == 1_000_000:
        assert (raw > 0).any() and (raw < 0).any()
    np.testing.assert_array_equal(clock.to_tt2000(part, sec), clock.to_tt2000_ticks(part, tick))


def test_off_grid_reading_keeps_its_fraction(clocks):
    # half a microsecond past a record of MESSENGER: the fraction is kept (500 ns times
    # the record's rate, 1.00001013271 -> 500.005 ns, rounded to 500)
    clock, text = clocks[-236]
    base = clock.to_tt2000_ticks([1], [text.ticks[1]])[0]
    got = clock.to_tt2000([1], [(text.ticks[1] + 0.5) / 1e6])[0]
    assert got - base == 500


def test_exact_path_errors(clocks):
    clock, _ = clocks[-236]
    with pytest.raises(InputFormatError, match="integers"):
        clock.to_tt2000_ticks([1], [1.5])
    with pytest.raises(InputFormatError, match="outside partition 1"):
        clock.to_tt2000_ticks([1], [-1])
    with pytest.raises(InputFormatError, match="partition 3 does not exist"):
        clock.to_tt2000_ticks([3], [0])
    with pytest.raises(KernelError, match="TDB"):
        dataclasses.replace(clock, time_system=1).to_tt2000_ticks([1], [0])
    shifted = dataclasses.replace(clock, ticks=clock.ticks + 0.5)
    with pytest.raises(KernelError, match=r"SCLK01_COEFFICIENTS.*value 1 .*whole number"):
        shifted.to_tt2000([1], [0.0])


def test_messenger_lag_is_subtracted_in_whole_nanoseconds(clocks):
    # levels.correct_time: TT2000 of the recorded MET (exact) minus the Table 1 net lag,
    # whole milliseconds (0.042 s at rate setting 10, 2.358 s at 0) taken to int64 ns
    import xarray as xr

    from fluxcal.missions.messenger import levels
    from fluxcal.missions.messenger.calibration_data import load_calibration

    clock, text = clocks[-236]
    ds = xr.Dataset({"partition": ("time", np.array([1, 1])),
                     "met": ("time", np.array([0.042, 2.358])),
                     "rate": ("time", np.array([10, 0]))})
    out = levels.correct_time(ds, load_calibration("2004-08-04"), clock)
    # record 0 rate 1.00001013271 s/s: 42 ms of clock are 42,000,425.57 ns of TT
    want = [round(text.parallel_ns[0] + Fraction(m * 1000) * text.rates[0]) - m * 1000
            for m in (42_000, 2_358_000)]
    np.testing.assert_array_equal(out["epoch"].values, want)
    assert want[0] - text.parallel_ns[0] == 426


@pytest.mark.parametrize("sc_id", [-236, -226])
def test_readings_before_the_first_record_extrapolate_exactly(clocks, sc_id):
    # negative tick differences (floor division and remainder of a negative count): the
    # records moved 1e9 ticks later, readings in the first 1e9 ticks of partition 1
    clock, text = clocks[sc_id]
    late = dataclasses.replace(clock, ticks=clock.ticks + 1e9)
    late_text = dataclasses.replace(text, ticks=[t + 10**9 for t in text.ticks])
    tick = text.starts[0] + np.random.default_rng(1).integers(0, 10**9, 500)
    got = late.to_tt2000_ticks(np.ones(tick.size, dtype=int), tick)
    for k, g in zip(tick.tolist(), got.tolist(), strict=True):
        exact = late_text.tt2000(late_text.encoded(1, k))
        assert exact < late_text.parallel_ns[0]  # really before the first record
        assert abs(g - exact) <= Fraction(1, 2) + Fraction(1, 1000), (k, g, float(exact))
