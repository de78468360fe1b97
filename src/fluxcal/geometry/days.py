"""UTC days of TT2000 times: the one toolkit for day bounds and day splits.

Every daily product is cut at UTC midnights, and every averaging interval counts from
one.  The functions here compute them once, for every mission, on TT2000 (int64 ns)
times, correct across leap seconds (a day holding one has 86,401 s):

- `day_start`, `day_bounds`: TT2000 of a date's 00:00 UTC, and of the next date's;
- `utc_days`, `utc_day`, `day_midnight`: the UTC day of each time;
- `split_days`: a dataset's samples per UTC day;
- `from_day_of_year`, `day_of_year`: dates as (year, day of year), the archives' ``yyddd``.

References
----------
.. [1] CDF TT2000: nanoseconds since 2000-01-01T12:00:00 TT (CDF User's Guide, sec. 2.4).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.geometry.time import (
    LeapSecondTable,
    tt2000_to_utc,
    utc_day_start_tt2000,
    utc_to_tt2000,
)


def day_start(day: np.datetime64 | str, lsk: LeapSecondTable | None = None) -> int:
    """Return the TT2000 (int64 ns) of 00:00:00 UTC of the date ``day``.

    Examples
    --------
    >>> from fluxcal.geometry.kernels import KernelPool
    >>> with KernelPool():  # 12 h before the TT2000 epoch, less TT - UTC (64.184 s)
    ...     day_start("2000-01-01")
    -43135816000000
    """
    return utc_day_start_tt2000(day, lsk)


def day_bounds(day: np.datetime64 | str, lsk: LeapSecondTable | None = None) -> tuple[int, int]:
    """Return the TT2000 of 00:00 UTC of ``day`` and of the next day (``[start, end)``)."""
    d = np.datetime64(day, "D")
    return day_start(d, lsk), day_start(d + 1, lsk)


def utc_days(epoch: np.ndarray,
             lsk: LeapSecondTable | None = None) -> tuple[np.ndarray, list[np.datetime64],
                                                          np.ndarray]:
    """Return the UTC day of each time: ``(day_index, days, midnight_tt2000)``.

    ``days`` are the dates from the earliest time's to the latest's (every date between,
    with data or not); ``midnight_tt2000[k]`` is the TT2000 of 00:00 UTC of ``days[k]``;
    ``day_index[i]`` is the position in ``days`` of the date of ``epoch[i]``, found by
    comparison with these boundaries (correct across leap seconds).  ``epoch`` need not
    be sorted.
    """
    epoch = np.asarray(epoch, dtype=np.int64)
    if epoch.size == 0:
        return np.zeros(0, dtype=np.int64), [], np.zeros(0, dtype=np.int64)
    ends = tt2000_to_utc(np.array([epoch.min(), epoch.max()]), digits=0, lsk=lsk)
    first, last = (np.datetime64(str(s)[:10], "D") for s in ends)
    days = list(np.arange(first, last + np.timedelta64(1, "D"), dtype="M8[D]"))
    midnight = utc_to_tt2000(np.array([f"{d}T00:00:00" for d in days]), lsk=lsk)
    day_index = np.searchsorted(midnight, epoch, side="right") - 1
    return day_index, days, midnight


def utc_day(epoch: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Return the UTC date (``datetime64[D]``) of each TT2000 time (`utc_days`)."""
    day_index, days, _ = utc_days(epoch, lsk)
    return np.asarray(days, dtype="M8[D]")[day_index] if days else np.zeros(0, "M8[D]")


def day_midnight(epoch: int, lsk: LeapSecondTable | None = None) -> int:
    """Return the TT2000 of 00:00 UTC of the day holding the TT2000 time ``epoch``."""
    return int(utc_days(np.array([epoch], dtype=np.int64), lsk)[2][0])


def split_days(ds: xr.Dataset, epoch: str = "epoch", dim: str = "time",
               lsk: LeapSecondTable | None = None) -> list[tuple[np.datetime64, xr.Dataset]]:
    """Return ``[(date, samples of ds in that UTC day), ...]`` for the days with samples.

    Samples are selected by the TT2000 variable ``epoch`` along ``dim``; in time order,
    each day is a slice (a view of ``ds``); otherwise each keeps the samples' order.
    """
    day_index, days, _ = utc_days(ds[epoch].values, lsk)
    out = []
    for k, day in enumerate(days):
        rows = np.flatnonzero(day_index == k)
        if rows.size == 0:
            continue
        contiguous = rows[-1] - rows[0] + 1 == rows.size
        out.append((day, ds.isel({dim: slice(int(rows[0]), int(rows[-1]) + 1)})
                    if contiguous else ds.isel({dim: rows})))
    return out


def from_day_of_year(year: int, doy: int) -> np.datetime64:
    """Return the date of day ``doy`` (1 = January 1st) of ``year``.

    Examples
    --------
    >>> str(from_day_of_year(2012, 153))
    '2012-06-01'
    """
    return np.datetime64(f"{int(year):04d}-01-01") + np.timedelta64(int(doy) - 1, "D")


def day_of_year(day: np.datetime64 | str) -> tuple[int, int]:
    """Return ``(year, day of year)`` of a date.

    Examples
    --------
    >>> day_of_year("2012-06-01")
    (2012, 153)
    """
    d = np.datetime64(day, "D")
    year = d.astype("M8[Y]")
    return int(str(year)), int((d - year.astype("M8[D]")).astype(int)) + 1
