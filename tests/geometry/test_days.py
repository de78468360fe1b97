"""The days toolkit (`fluxcal.geometry.days`): day bounds and splits at UTC midnight.

Expected values come from the calendar (Python's `datetime`) and from the leap-second
history (IERS Bulletin C 52: a leap second at the end of 2016-12-31, so that day lasts
86,401 s), not from the functions under test.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
import xarray as xr

from fluxcal.geometry import days
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import utc_to_tt2000

NS = 1_000_000_000


@pytest.fixture(scope="module")
def lsk_pool():
    with KernelPool() as pool:
        yield pool


def test_day_bounds_length_and_leap_second(lsk_pool):
    start, end = days.day_bounds("2016-12-30")
    assert end - start == 86_400 * NS
    start, end = days.day_bounds("2016-12-31")  # 23:59:60 exists on that day
    assert end - start == 86_401 * NS
    assert start == int(utc_to_tt2000(np.array(["2016-12-31T00:00:00"]))[0])


def test_utc_days_assigns_each_time_to_its_date(lsk_pool):
    # 00:00:00 of 11-02, 1 ms before it, 12:00 of 11-04, 0.5 s after 11-03 began
    epoch = np.array([days.day_start("2014-11-02"), days.day_start("2014-11-02") - 1_000_000,
                      days.day_start("2014-11-04") + 12 * 3600 * NS,
                      days.day_start("2014-11-03") + NS // 2])
    index, dates, midnights = days.utc_days(epoch)
    assert [str(d) for d in dates] == ["2014-11-01", "2014-11-02", "2014-11-03", "2014-11-04"]
    assert index.tolist() == [1, 0, 3, 2]
    assert midnights[1] == days.day_start("2014-11-02")
    assert [str(d) for d in days.utc_day(epoch)] == ["2014-11-02", "2014-11-01",
                                                       "2014-11-04", "2014-11-03"]
    assert days.day_midnight(int(epoch[2])) == days.day_start("2014-11-04")
    empty = days.utc_days(np.zeros(0, dtype=np.int64))
    assert empty[0].size == 0 and empty[1] == []


def test_split_days_views_in_order_and_rows_otherwise(lsk_pool):
    t0 = days.day_start("2014-11-01") + 23 * 3600 * NS
    epoch = t0 + np.arange(0, 2 * 3600, 600) * NS  # 23:00 .. 00:50: 6 + 6 samples
    ds = xr.Dataset({"b": ("time", np.arange(epoch.size, dtype=float))},
                    coords={"epoch": ("time", epoch)})
    parts = days.split_days(ds)
    assert [str(d) for d, _ in parts] == ["2014-11-01", "2014-11-02"]
    assert [p.sizes["time"] for _, p in parts] == [6, 6]
    assert parts[1][1]["b"].values[0] == 6.0
    shuffled = ds.isel(time=[11, 0, 5, 6])
    parts = days.split_days(shuffled)
    assert [p["b"].values.tolist() for _, p in parts] == [[0.0, 5.0], [11.0, 6.0]]


@pytest.mark.parametrize("date", [dt.date(2012, 6, 1), dt.date(2012, 12, 31),
                                  dt.date(2013, 1, 1), dt.date(2015, 3, 1)])
def test_day_of_year_round_trip(date):
    doy = date.timetuple().tm_yday
    assert days.day_of_year(date.isoformat()) == (date.year, doy)
    assert str(days.from_day_of_year(date.year, doy)) == date.isoformat()
