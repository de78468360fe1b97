"""Spacecraft clock, ephemeris time, TT2000 and UTC, vectorized over arrays.

Times inside fluxcal are either float64 ephemeris seconds (TDB seconds past J2000, the
SPICE ``et``) or int64 TT2000 nanoseconds (the CDF epoch: TT nanoseconds past J2000).
Float64 nanoseconds are never used.

The conversions follow the SPICE algorithms but run in numpy, from the constants of the
loaded kernels (SCLK type 1 coefficients, the leapseconds kernel's DELTET values); tests
compare them with ``spiceypy.scs2e``, ``sce2c``, ``unitim`` and ``timout``.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 9 "UTC Conversion".
.. [2] NAIF, "SCLK Required Reading" and "Time Required Reading" (type 1 SCLK,
       TDT-TDB relation, leap seconds).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import spiceypy
from numba import njit

from fluxcal.errors import InputFormatError, KernelError
from fluxcal.geometry.compiled import count_le
from fluxcal.geometry.kernels import spice_errors

#: Offset TT - TAI, exactly 32.184 s, in integer nanoseconds (never formed from a float:
#: ``int(32.184 * 1e9)`` is 32_183_999_999).
TT_MINUS_TAI_NS = 32_184_000_000
#: The CDF TT2000 fill value (ISTP ``FILLVAL``, -2**63); `tt2000_to_datetime64` maps it to NaT.
TT2000_FILL = np.iinfo(np.int64).min
#: The CDF TT2000 pad value (-2**63 + 1), also mapped to NaT (as ``cdflib`` does).
TT2000_PAD = TT2000_FILL + 1
_J2000_UTC_NAIVE = np.datetime64("2000-01-01T12:00:00", "ns")
_NS = 1_000_000_000
#: 2000-01-01T12:00:00 in ns past 1970-01-01T00:00:00 (naive UTC, 86400 s days).
_J2000_UNIX_NS = int(_J2000_UTC_NAIVE.astype(np.int64))
_DAY_NS = 86_400 * _NS


# ----------------------------------------------------------------------------------------
# TDB <-> TT (the LSK's DELTET model)
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LeapSecondTable:
    """Constants of the loaded leapseconds kernel (``DELTET/...``).

    Attributes
    ----------
    k, eb, m0, m1 : float
        Constants of TDB - TT = K sin(E), E = M + EB sin(M), M = M0 + M1 t.
    delta_at : ndarray of int
        TAI - UTC after each leap epoch.
    epochs_utc_naive : ndarray of float
        The leap epochs as naive (86400 s/day) UTC seconds past 2000-01-01T12:00:00.
    """

    k: float
    eb: float
    m0: float
    m1: float
    delta_at: np.ndarray
    epochs_utc_naive: np.ndarray

    @classmethod
    def from_pool(cls) -> LeapSecondTable:
        """Read the constants from the loaded leapseconds kernel."""
        with spice_errors("reading DELTET/* from the leapseconds kernel (is an LSK loaded?)"):
            k = spiceypy.gdpool("DELTET/K", 0, 1)[0]
            eb = spiceypy.gdpool("DELTET/EB", 0, 1)[0]
            m = spiceypy.gdpool("DELTET/M", 0, 2)
            n = spiceypy.dtpool("DELTET/DELTA_AT")[0]
            pairs = np.asarray(spiceypy.gdpool("DELTET/DELTA_AT", 0, n), dtype=float)
        if np.any(np.diff(pairs[0::2]) != 1):
            # the UTC conversions place one inserted second (23:59:60) before each epoch
            raise KernelError(
                "the leapseconds kernel's DELTET/DELTA_AT does not step by +1 s at every "
                f"epoch ({pairs[0::2].tolist()}); only inserted leap seconds are supported"
            )
        return cls(
            k=float(k),
            eb=float(eb),
            m0=float(m[0]),
            m1=float(m[1]),
            delta_at=pairs[0::2].astype(np.int64),
            epochs_utc_naive=pairs[1::2],
        )

    def tdb_minus_tt(self, t: np.ndarray) -> np.ndarray:
        """Return TDB - TT (s) for ``t`` in seconds past J2000 (either scale)."""
        m = self.m0 + self.m1 * t
        return self.k * np.sin(m + self.eb * np.sin(m))

    def tt_to_tdb(self, tt: np.ndarray) -> np.ndarray:
        """TT (TDT) seconds past J2000 -> TDB seconds past J2000 (as SPICE ``unitim``)."""
        tt = np.asarray(tt, dtype=float)
        return tt + self.tdb_minus_tt(tt)

    def tdb_to_tt(self, tdb: np.ndarray) -> np.ndarray:
        """TDB seconds past J2000 -> TT seconds past J2000 (fixed-point inverse)."""
        tdb = np.asarray(tdb, dtype=float)
        # one fixed-point step: d(TDB-TT)/dt < 4e-10, so the residual is < 1e-12 s
        return tdb - self.tdb_minus_tt(tdb - self.tdb_minus_tt(tdb))

    # leap seconds in TT2000 nanoseconds
    def leap_tt2000(self) -> np.ndarray:
        """Return the TT2000 (ns) instants at which each ``delta_at`` starts to apply."""
        return self.epochs_naive_ns() + self.delta_at * _NS + TT_MINUS_TAI_NS

    def epochs_naive_ns(self) -> np.ndarray:
        """Return the leap epochs as int64 naive UTC ns past 2000-01-01T12:00:00."""
        # the LSK's epochs are whole seconds, exact in float64
        return np.rint(self.epochs_utc_naive).astype(np.int64) * _NS


_LSK_CACHE: dict[tuple, LeapSecondTable] = {}


def leapseconds() -> LeapSecondTable:
    """Return the `LeapSecondTable` of the currently loaded LSK (cached per content)."""
    with spice_errors("reading the leapseconds kernel"):
        n = spiceypy.dtpool("DELTET/DELTA_AT")[0]
        key = tuple(spiceypy.gdpool("DELTET/DELTA_AT", 0, n)) + tuple(
            spiceypy.gdpool("DELTET/M", 0, 2)
        )
    if key not in _LSK_CACHE:
        _LSK_CACHE[key] = LeapSecondTable.from_pool()
    return _LSK_CACHE[key]


# ----------------------------------------------------------------------------------------
# ET <-> TT2000
# ----------------------------------------------------------------------------------------
def et_to_tt2000(et: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Convert ephemeris time (TDB s past J2000) to int64 TT2000 nanoseconds.

    Parameters
    ----------
    et : array_like of float
        Ephemeris times.
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    ndarray of int64
        TT nanoseconds past J2000 TT (the CDF ``TT2000`` epoch), rounded to the nearest ns.

    Notes
    -----
    The whole and fractional seconds are converted separately so that no float64
    nanosecond count is formed.
    """
    lsk = lsk or leapseconds()
    tt = lsk.tdb_to_tt(np.asarray(et, dtype=float))
    whole = np.floor(tt)
    frac_ns = np.rint((tt - whole) * 1e9).astype(np.int64)
    return whole.astype(np.int64) * _NS + frac_ns


def tt2000_to_et(tt2000: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Convert int64 TT2000 nanoseconds to ephemeris time (TDB s past J2000)."""
    lsk = lsk or leapseconds()
    tt2000 = np.asarray(tt2000, dtype=np.int64)
    whole, rem = np.divmod(tt2000, _NS)
    tt = whole.astype(float) + rem.astype(float) * 1e-9
    return lsk.tt_to_tdb(tt)


# ----------------------------------------------------------------------------------------
# TT2000 <-> UTC
# ----------------------------------------------------------------------------------------
#: Range of TT2000 values (other than fill and pad) the UTC conversions accept, so that
#: no int64 sum overflows: about 1707-09-22 .. 2292-03-31.
_TT2000_MIN = TT2000_FILL + 1000 * _NS
_TT2000_MAX = np.iinfo(np.int64).max - 10**15


def _check_tt2000(tt2000: np.ndarray, special: np.ndarray) -> None:
    bad = ((tt2000 < _TT2000_MIN) | (tt2000 > _TT2000_MAX)) & ~special
    if bad.any():
        raise InputFormatError(
            f"TT2000 value {int(tt2000[np.flatnonzero(bad)[0]])} is outside the supported "
            f"range {_TT2000_MIN} .. {_TT2000_MAX} (or the CDF fill/pad values)",
            field="tt2000",
        )


def _tt2000_to_utc_midnight(
    tt2000: np.ndarray, lsk: LeapSecondTable
) -> tuple[np.ndarray, np.ndarray | bool]:
    """TT2000 -> naive UTC ns past 2000-01-01T00:00, and whether each is in a leap second.

    Int64 arithmetic only.  Inside a leap second (``23:59:60.x``) the naive time is that
    of ``23:59:59.x`` (the new TAI - UTC already applies) and the mask tells the caller
    to show seconds ``60``.  Before the first LSK epoch (1972) its TAI - UTC applies.
    When all times lie between the same two leap seconds (a day of data, usually) the
    offset is one scalar and no per-sample table search is made.
    """
    leaps = lsk.leap_tt2000()  # the leap second before leaps[i] is [leaps[i] - 1 s, leaps[i])
    starts = leaps - _NS
    shift = TT_MINUS_TAI_NS - _DAY_NS // 2  # naive counts from 12:00; this from 00:00
    if tt2000.size:
        lo, hi = int(tt2000.min()), int(tt2000.max())
        j = np.searchsorted(starts, [lo, hi], side="right") - 1
        if j[0] == j[1] and (j[0] < 0 or lo >= leaps[j[0]]):
            return tt2000 - (shift + int(lsk.delta_at[max(j[0], 0)]) * _NS), False
    j = np.searchsorted(starts, tt2000, side="right") - 1
    jc = np.clip(j, 0, None)
    in_leap = (j >= 0) & (tt2000 < leaps[jc])
    return tt2000 - (shift + lsk.delta_at[jc] * _NS), in_leap


def _utc_naive_to_tt2000(
    naive: np.ndarray, leap: np.ndarray | bool, lsk: LeapSecondTable
) -> np.ndarray:
    """Naive UTC ns past 2000-01-01T12 (``leap``: a ``23:59:60.x`` read as ``59.x``) -> TT2000."""
    epochs = lsk.epochs_naive_ns()
    if naive.size:
        j = np.searchsorted(epochs, [naive.min(), naive.max()], side="right") - 1
        if j[0] == j[1]:
            delta_at = int(lsk.delta_at[max(j[0], 0)])
            return naive + (delta_at * _NS + TT_MINUS_TAI_NS) + np.where(leap, _NS, 0)
    idx = np.searchsorted(epochs, naive, side="right") - 1
    delta_at = lsk.delta_at[np.clip(idx, 0, None)]
    # 23:59:60.x is 23:59:59.x of the old TAI - UTC count plus one second
    return naive + delta_at * _NS + TT_MINUS_TAI_NS + np.where(leap, _NS, 0)


def tt2000_to_datetime64(tt2000: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Convert int64 TT2000 nanoseconds to UTC ``datetime64[ns]`` (e.g. an xarray time index).

    Parameters
    ----------
    tt2000 : array_like of int64
        TT2000 nanoseconds (the CDF epoch).
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    ndarray of datetime64[ns]
        UTC, same shape as ``tt2000``.  The CDF fill (-2**63) and pad (-2**63 + 1)
        values give NaT.

    Raises
    ------
    InputFormatError
        For a value that UTC datetime64[ns] cannot hold (before ~1708 or after 2262-04-11).

    Notes
    -----
    ``datetime64`` has no leap seconds.  A time inside a leap second
    (``23:59:60.000000000`` to ``23:59:60.999999999``) is clamped to
    ``23:59:59.999999999``, so the index stays sorted (non-decreasing) and no time is
    moved into the next day.  ``cdflib.cdfepoch.to_datetime`` (1.3) instead adds the
    broken-down fields, which carries ``23:59:60.5`` into ``00:00:00.5`` of the next
    day, one second late and out of order with the samples that follow; outside leap
    seconds the two agree exactly (``tests/geometry/test_utc_exact.py``).  Use
    `tt2000_to_utc` (seconds ``60``) or the TT2000 epoch itself where the leap second
    must be seen.  See docs/decisions.md, geometry.
    """
    lsk = lsk or leapseconds()
    tt = np.asarray(tt2000, dtype=np.int64)
    shape = tt.shape
    flat = tt.ravel()
    special = flat <= TT2000_PAD
    _check_tt2000(flat, special)
    midnight, in_leap = _tt2000_to_utc_midnight(
        np.where(special, 0, flat) if special.any() else flat, lsk)
    if np.any(in_leap):
        midnight = np.where(in_leap, midnight - midnight % _NS + (_NS - 1), midnight)
    to_unix = _J2000_UNIX_NS - _DAY_NS // 2
    too_late = midnight > np.iinfo(np.int64).max - to_unix
    if too_late.any():
        raise InputFormatError(
            f"TT2000 value {int(flat[np.flatnonzero(too_late)[0]])} is after the last "
            "datetime64[ns] (2262-04-11)",
            field="tt2000",
        )
    unix = midnight + to_unix
    if special.any():
        unix = np.where(special, np.iinfo(np.int64).min, unix)
    return unix.view("M8[ns]").reshape(shape)


def datetime64_to_tt2000(dt64: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Convert UTC ``datetime64`` values to int64 TT2000 nanoseconds.

    Parameters
    ----------
    dt64 : array_like of datetime64
        UTC times, any unit (converted exactly to ns).  NaT gives the CDF fill value
        `TT2000_FILL`.
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    ndarray of int64
        TT2000 nanoseconds, same shape.

    Raises
    ------
    InputFormatError
        When the input is not datetime64, or does not fit datetime64[ns].

    Notes
    -----
    The inverse of `tt2000_to_datetime64` except inside a leap second, which
    ``datetime64`` cannot express: there the clamped ``23:59:59.999999999`` maps back to
    itself, not to the leap second.
    """
    lsk = lsk or leapseconds()
    d = np.asarray(dt64)
    if d.dtype.kind != "M":
        raise InputFormatError(f"expected datetime64 values, got dtype {d.dtype}", field="time")
    nat = np.isnat(d)
    ns = d.astype("M8[ns]")
    if d.dtype != ns.dtype:
        lost = (ns.astype(d.dtype) != d) & ~nat
        if lost.any():
            i = int(np.flatnonzero(lost.ravel())[0])
            raise InputFormatError(
                f"time {d.ravel()[i]} does not fit datetime64[ns] (1677-09-22 .. 2262-04-11)",
                field="time",
            )
    naive = ns.view(np.int64) - _J2000_UNIX_NS
    if not nat.any():
        return _utc_naive_to_tt2000(naive, False, lsk)
    out = _utc_naive_to_tt2000(np.where(nat, 0, naive), False, lsk)
    return np.where(nat, TT2000_FILL, out)


def _utc_parts(
    tt2000: np.ndarray, lsk: LeapSecondTable | None
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray | bool]:
    """Return the UTC fields of 1-d TT2000 values, the date part as a table of days.

    Returns
    -------
    dates : dict of str to ndarray of int64
        ``year, month, day, doy`` of each row of the day table.
    row : ndarray of int
        The day-table row of each time.
    sec_of_day, nanosecond : ndarray of int64
        Whole seconds of the naive day (0-86399) and nanoseconds of the second.
    in_leap : ndarray of bool or False
        Inside a leap second (show seconds 60 = ``sec_of_day`` 86399 plus one).

    Notes
    -----
    The calendar is computed once per day of the range covered (the data of a day
    touch one or two days), not once per time.  The CDF fill and pad values get two
    extra rows (9999-12-31 and 0000-01-01) and times 23:59:59.999999999 and 0.
    """
    lsk = lsk or leapseconds()
    lo, hi = (int(tt2000.min()), int(tt2000.max())) if tt2000.size else (0, 0)
    any_special = lo <= TT2000_PAD
    if any_special:
        fill = tt2000 == TT2000_FILL
        pad = tt2000 == TT2000_PAD
        special = fill | pad
        _check_tt2000(tt2000, special)
        regular = tt2000[~special]
        tt2000 = np.where(special, regular[0] if regular.size else 0, tt2000)
    elif lo < _TT2000_MIN or hi > _TT2000_MAX:
        _check_tt2000(tt2000, np.zeros(tt2000.shape, dtype=bool))
    midnight, in_leap = _tt2000_to_utc_midnight(tt2000, lsk)
    # floor division and a product: faster than np.divmod for int64
    days = midnight // _DAY_NS  # days past 2000-01-01
    ns_of_day = midnight - days * _DAY_NS
    sec_of_day = ns_of_day // _NS
    nanosecond = ns_of_day - sec_of_day * _NS
    first, last = (int(days.min()), int(days.max())) if days.size else (0, 0)
    if last - first < max(days.size, 1024):
        table_days = np.arange(first, last + 1, dtype=np.int64)
        row = days - first
    else:  # few times spread over many days: one calendar row per time
        table_days, row = days, np.arange(days.size)
    year, month, day, doy = _civil_from_days(table_days + 10_957)  # days past 1970-01-01
    dates = {"year": year, "month": month, "day": day, "doy": doy}
    if any_special:
        extra = {"year": (9999, 0), "month": (12, 1), "day": (31, 1), "doy": (365, 1)}
        dates = {k: np.concatenate([v, extra[k]]) for k, v in dates.items()}
        n = table_days.size
        row = np.where(fill, n, np.where(pad, n + 1, row))
        sec_of_day = np.where(fill, 86_399, np.where(pad, 0, sec_of_day))
        nanosecond = np.where(fill, _NS - 1, np.where(pad, 0, nanosecond))
        if np.any(in_leap):
            in_leap = in_leap & ~special
    return dates, row, sec_of_day, nanosecond, in_leap


def tt2000_to_utc_fields(
    tt2000: np.ndarray, lsk: LeapSecondTable | None = None
) -> dict[str, np.ndarray]:
    """Break int64 TT2000 nanoseconds down into UTC calendar fields, exactly.

    Parameters
    ----------
    tt2000 : array_like of int64
        TT2000 nanoseconds (the CDF epoch).
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    dict of str to ndarray of int64
        ``year, month, day, doy, hour, minute, second, nanosecond``, each of the shape of
        ``tt2000``; ``doy`` is the day of the year (1-366), ``second`` is 60 inside a leap
        second and ``nanosecond`` is 0-999,999,999.  The CDF fill value gives
        9999-12-31 23:59:59.999999999 and the pad value 0000-01-01 00:00:00.000000000,
        as ``cdflib.cdfepoch.breakdown_tt2000`` does.

    Raises
    ------
    InputFormatError
        For a value outside ~1708-2292 (other than fill and pad), where int64 sums
        would overflow.

    Notes
    -----
    Int64 arithmetic only: TAI - UTC from the LSK table, TT - TAI = `TT_MINUS_TAI_NS`,
    the date from the day count by the proleptic Gregorian "civil from days" algorithm
    of [1]_.  No float is formed, so the result is exact to the nanosecond.

    References
    ----------
    .. [1] H. Hinnant, "chrono-Compatible Low-Level Date Algorithms" (``civil_from_days``).
    .. [2] NAIF, "Time Required Reading" (UTC, TAI, leap seconds).
    """
    tt = np.asarray(tt2000, dtype=np.int64)
    dates, row, sec_of_day, nanosecond, in_leap = _utc_parts(tt.ravel(), lsk)
    fields = {name: value[row] for name, value in dates.items()}
    fields["hour"] = sec_of_day // 3600
    fields["minute"] = sec_of_day // 60 % 60
    fields["second"] = sec_of_day % 60 + in_leap
    fields["nanosecond"] = nanosecond
    return {name: np.asarray(value, dtype=np.int64).reshape(tt.shape)
            for name, value in fields.items()}


def utc_fields_to_tt2000(
    year: np.ndarray,
    doy: np.ndarray,
    hour: np.ndarray,
    minute: np.ndarray,
    second: np.ndarray,
    lsk: LeapSecondTable | None = None,
) -> np.ndarray:
    """TT2000 (int64 ns) from UTC fields: year, day of year, hour, minute, float second.

    The inverse of `tt2000_to_utc_fields` for tables that print the time as fields
    (the seed 000 CDR/RDR ``YEAR DAY_OF_YEAR HOUR MINUTE SECOND``).  ``second`` is rounded
    to the nearest nanosecond, which removes the float's representation error of any
    value printed with up to 6 decimals (``|error|`` < 1e-14 s for seconds below 61).  A
    second of 60 or more is a leap second: it is counted from ``23:59:59`` of the old
    TAI - UTC plus one second, so ``23:59:60.5`` is 1.5 s after ``23:59:59.0``.

    Parameters
    ----------
    year, doy, hour, minute : array_like of int
        UTC calendar fields (day of year 1-366).
    second : array_like of float
        Seconds of the minute, 0 to < 61.
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    ndarray of int64
        TT2000 nanoseconds, shape of the broadcast fields.

    Notes
    -----
    Whole minutes are built as ``datetime64`` (integer), the nanoseconds of the second
    added as integers, then `datetime64_to_tt2000` applies TAI - UTC: no float holds an
    epoch, so the result is exact to the nanosecond of the rounded second.
    """
    ns = np.rint(np.asarray(second, dtype=np.float64) * 1e9).astype(np.int64)
    leap = ns >= 60 * _NS
    minutes = (((np.asarray(doy, np.int64) - 1) * 24 + np.asarray(hour, np.int64)) * 60
               + np.asarray(minute, np.int64))
    start = (np.asarray(year, np.int64) - 1970).astype("M8[Y]").astype("M8[m]")
    stamp = (start + minutes.astype("m8[m]")).astype("M8[ns]") \
        + (ns - np.where(leap, _NS, 0)).astype("m8[ns]")
    tt2000 = datetime64_to_tt2000(stamp, lsk) + np.where(leap, _NS, 0)
    return np.asarray(tt2000, dtype=np.int64)


def utc_day_start_tt2000(day: np.datetime64 | str, lsk: LeapSecondTable | None = None) -> int:
    """TT2000 (int64 ns) of 00:00:00 UTC of the date ``day`` (leap seconds included).

    The one day edge of the products: a seed 000 day's averaging origin and a seed 003
    day folder's bounds (``utc_day_start_tt2000(d)`` to ``utc_day_start_tt2000(d + 1)``,
    86,401 s across a leap second).

    Parameters
    ----------
    day : numpy.datetime64 or str
        The date (any datetime64 unit; the time of day is dropped).
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.
    """
    midnight = np.datetime64(day, "D").astype("M8[ns]")
    return int(datetime64_to_tt2000(np.array([midnight]), lsk)[0])


def _civil_from_days(days: np.ndarray) -> tuple[np.ndarray, ...]:
    """Days past 1970-01-01 -> (year, month, day, day of year), proleptic Gregorian.

    Hinnant's ``civil_from_days`` in int64 numpy (years start on 1 March inside it).
    """
    z = days + 719_468
    era = z // 146_097
    doe = z - era * 146_097  # day of the 400-year era, 0..146096
    yoe = (doe - doe // 1460 + doe // 36_524 - doe // 146_096) // 365  # 0..399
    doy_march = doe - (365 * yoe + yoe // 4 - yoe // 100)  # 0..365, 0 = 1 March
    mp = (5 * doy_march + 2) // 153  # 0..11, 0 = March
    day = doy_march - (153 * mp + 2) // 5 + 1
    jan_feb = mp >= 10
    month = np.where(jan_feb, mp - 9, mp + 3)
    year = yoe + era * 400 + jan_feb
    leap = (year % 4 == 0) & ((year % 100 != 0) | (year % 400 == 0))
    # 1 March is day 60 (61 in a leap year); 1 January is 306 days after 1 March
    doy = np.where(jan_feb, doy_march - 305, doy_march + 60 + leap)
    return year, month, day, doy


#: ASCII digits of 0..999, three per row (the formatting tables of `tt2000_to_utc`).
_DIGITS = np.array([[48 + i // 100, 48 + i // 10 % 10, 48 + i % 10] for i in range(1000)],
                   dtype=np.uint8)


def _put(buf: np.ndarray, col: int, values: np.ndarray, first: int, count: int) -> None:
    """Write digits ``first:first + count`` of the 3-digit form of ``values`` at ``col``."""
    buf[:, col:col + count] = np.take(_DIGITS[:, first:first + count], values, axis=0)


def _date_rows(dates: dict[str, np.ndarray], style: str) -> np.ndarray:
    """ASCII ``YYYY-MM-DDT`` (iso) or ``YYYY DOY `` (doy) of each day, (n, 11 or 9) uint8."""
    year = dates["year"]
    rows = np.empty((year.size, 11 if style == "iso" else 9), dtype=np.uint8)
    _put(rows, 0, year // 100, 1, 2)
    _put(rows, 2, year % 100, 1, 2)
    if style == "iso":
        rows[:, 4] = rows[:, 7] = ord("-")
        _put(rows, 5, dates["month"], 1, 2)
        _put(rows, 8, dates["day"], 1, 2)
        rows[:, 10] = ord("T")
    else:
        rows[:, 4] = rows[:, 8] = ord(" ")
        _put(rows, 5, dates["doy"], 0, 3)
    return rows


_CLOCK_ROWS: dict[str, np.ndarray] = {}


def _clock_rows(sep: str) -> np.ndarray:
    """ASCII ``HH:MM:SS`` (``sep`` between) of seconds 0-86399 of a day, and ``23:59:60``."""
    if sep not in _CLOCK_ROWS:
        sec = np.arange(86_401)
        rows = np.empty((sec.size, 8), dtype=np.uint8)
        whole = np.minimum(sec, 86_399)  # the leap second is 23:59 and 60 s
        _put(rows, 0, whole // 3600, 1, 2)
        rows[:, 2] = rows[:, 5] = ord(sep)
        _put(rows, 3, whole // 60 % 60, 1, 2)
        _put(rows, 6, np.where(sec == 86_400, 60, sec % 60), 1, 2)
        _CLOCK_ROWS[sep] = rows
    return _CLOCK_ROWS[sep]


def tt2000_to_utc(
    tt2000: np.ndarray,
    style: str = "iso",
    digits: int = 3,
    lsk: LeapSecondTable | None = None,
    *,
    as_bytes: bool = False,
) -> np.ndarray:
    """Format TT2000 nanoseconds as UTC strings, exactly.

    Parameters
    ----------
    tt2000 : array_like of int64
        TT2000 nanoseconds.
    style : {"iso", "doy"}
        ``"iso"``: ``YYYY-MM-DDTHH:MM:SS.fff``; ``"doy"``: the archive form
        ``YYYY DOY HH MM SS.fff`` of seed 000 sec. 9 (``timout`` picture
        ``YYYY DOY HR MN SC.###``).
    digits : int
        Decimal places of the seconds, 0-9.  Seconds are truncated, as SPICE ``timout``
        does without the ``::RND`` token.
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.
    as_bytes : bool
        Return ASCII bytes (``S`` dtype, e.g. for CSV/CDF writers) instead of ``str``.

    Returns
    -------
    ndarray of str (``U``) or bytes (``S``)
        Fixed-width strings, one per time, of the shape of ``tt2000`` (at least 1-d);
        a time inside a leap second shows seconds ``60``.  The CDF fill value prints
        as ``9999-12-31T23:59:59.999...`` (``9999 365 23 59 59.999...``).

    Raises
    ------
    InputFormatError
        For a TT2000 value outside ~1708-2292 other than the CDF fill/pad values.

    Notes
    -----
    The fields come from the int64 arithmetic of `tt2000_to_utc_fields`, so a time
    exactly on a millisecond prints that millisecond; formatting from a float64 ET that
    may sit a few ns early would print the one before.  The characters are written
    into an ``(n, width)`` uint8 array from tables (the date of each day covered, the
    ``HH:MM:SS`` of each second of a day, the digits of 0-999) and viewed as
    fixed-width strings: no per-sample Python and no per-field string operations.
    A 20 Hz day (1.73 M times) formats in 0.1-0.2 s of CPU (issue 10; 5-6.5 s with
    per-field ``np.char``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 9 "UTC Conversion".
    .. [2] NAIF, ``timout`` (truncation unless ``::RND``).
    """
    if style not in ("iso", "doy"):
        raise ValueError(f"style must be 'iso' or 'doy', not {style!r}")
    if not 0 <= digits <= 9:
        raise ValueError(f"digits must be within 0..9, not {digits}")
    tt = np.atleast_1d(np.asarray(tt2000, dtype=np.int64))
    dates, row, sec_of_day, nanosecond, in_leap = _utc_parts(tt.ravel(), lsk)
    date_rows = _date_rows(dates, style)
    head = date_rows.shape[1] + 8
    width = head + (digits + 1 if digits else 0)
    buf = np.empty((tt.size, width), dtype=np.uint8)
    buf[:, :head - 8] = np.take(date_rows, row, axis=0)
    buf[:, head - 8:head] = np.take(_clock_rows(":" if style == "iso" else " "),
                                    sec_of_day + in_leap, axis=0)
    if digits:
        buf[:, head] = ord(".")
        for g in range((digits + 2) // 3):  # milli-, micro-, nanoseconds
            group = nanosecond // 10 ** (6 - 3 * g) % 1000 if g else nanosecond // 1_000_000
            _put(buf, head + 1 + 3 * g, group, 0, min(3, digits - 3 * g))
    if as_bytes:
        out = buf.view(f"S{width}")
    else:
        out = buf.astype(np.uint32).view(f"U{width}")
    return out.reshape(tt.shape)


def et_to_utc(
    et: np.ndarray, style: str = "iso", digits: int = 3, lsk: LeapSecondTable | None = None
) -> np.ndarray:
    """Format ephemeris times as UTC strings (see `tt2000_to_utc`).

    The float64 ET is rounded to the nearest TT2000 nanosecond first; ET itself resolves
    only ~60 ns at these epochs, so a time meant to lie on a millisecond may print the
    millisecond before.  Products hold the integer TT2000 epoch and should format it with
    `tt2000_to_utc`.
    """
    lsk = lsk or leapseconds()
    return tt2000_to_utc(et_to_tt2000(et, lsk), style=style, digits=digits, lsk=lsk)


def utc_to_tt2000(utc: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Parse ISO 8601 UTC strings (``YYYY-MM-DDTHH:MM:SS[.f]``, optional ``Z``) to TT2000.

    Parameters
    ----------
    utc : array_like of str or bytes
        UTC times.  A seconds field of ``60`` is accepted in the last second of a day
        that ends with a leap second in the LSK.
    lsk : LeapSecondTable, optional
        Leapseconds constants; default the loaded LSK.

    Returns
    -------
    ndarray of int64
        TT2000 nanoseconds.

    Raises
    ------
    InputFormatError
        Naming the first string that cannot be parsed, or a seconds field ``60`` that is
        not a leap second.

    Notes
    -----
    Exact: numpy reads the date, time and up to nine decimals of the seconds as
    integers (further decimals are cut off, i.e. truncated to the nanosecond), and TAI -
    UTC and TT - TAI are added in int64 nanoseconds.  No float is formed.
    """
    lsk = lsk or leapseconds()
    text = np.atleast_1d(np.asarray(utc, dtype=str))
    text = np.char.rstrip(np.char.strip(text), "Z")
    leap = np.char.find(text, ":60") == 16
    if leap.any():
        text = text.astype(object)
        text[leap] = [s[:17] + "59" + s[19:] for s in text[leap]]
        text = text.astype(str)
    try:
        stamp = text.astype("M8[ns]")
    except ValueError:
        bad = _first_unparsable(text)
        raise InputFormatError(
            f"cannot parse UTC time {bad!r}; expected ISO 8601 YYYY-MM-DDTHH:MM:SS.fff",
            field="time_utc",
        ) from None
    naive = (stamp - _J2000_UTC_NAIVE).astype(np.int64)
    if leap.any():  # 23:59:60.x only where the next whole second starts a new TAI - UTC
        ends = naive[leap] - naive[leap] % _NS + _NS
        false_leap = ~np.isin(ends, lsk.epochs_naive_ns())
        if false_leap.any():
            raise InputFormatError(
                f"UTC time {str(np.asarray(utc).ravel()[leap][false_leap][0])!r} has seconds 60 "
                "but is not in a leap second of the leapseconds kernel",
                field="time_utc",
            )
    return _utc_naive_to_tt2000(naive, leap, lsk)


def _first_unparsable(text: np.ndarray) -> str:
    for item in text:
        try:
            np.datetime64(item, "ns")
        except ValueError:
            return str(item)
    return str(text[0])  # pragma: no cover


def utc_to_et(utc: np.ndarray, lsk: LeapSecondTable | None = None) -> np.ndarray:
    """Parse ISO 8601 UTC strings to ephemeris time (see `utc_to_tt2000`)."""
    lsk = lsk or leapseconds()
    return tt2000_to_et(utc_to_tt2000(utc, lsk), lsk)


# ----------------------------------------------------------------------------------------
# Spacecraft clock (SCLK type 1)
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SclkKernel:
    """A type 1 spacecraft clock, converted in numpy from the kernel's own coefficients.

    Attributes
    ----------
    sc_id : int
        NAIF spacecraft id (the clock's id, negative).
    moduli : ndarray
        Field moduli (``SCLK01_MODULI``).
    partition_start, partition_end : ndarray
        Partition limits in ticks (``SCLK_PARTITION_START/END``).
    ticks, parallel, rate : ndarray
        The coefficient triplets: encoded SCLK, parallel time (s past J2000), rate
        (parallel seconds per most-significant count).
    time_system : int
        1 = TDB, 2 = TDT (TT) parallel time.

    Notes
    -----
    A clock reading is given as a partition number and the reading in units of the first
    (most significant) field, fraction included: for a clock with fields seconds and
    microseconds (seed 000) ``seconds = 16458912.103412`` is ``1/16458912:103412``.  Offsets of the
    fields (``SCLK01_OFFSETS``) must be zero.

    A reading within the float64 resolution of a whole tick (`SNAP_RELATIVE`) is taken
    as that tick, and the TT2000 of a TT (TDT) clock is computed in int64 from the
    integer ticks and the kernel's parallel times held as integer nanoseconds
    (`ExactClock`): the rate product is the only floating-point step, and it is
    confined to a term far below 1 ns of rounding (docs/decisions/geometry.md).
    """

    sc_id: int
    moduli: np.ndarray
    partition_start: np.ndarray
    partition_end: np.ndarray
    ticks: np.ndarray
    parallel: np.ndarray
    rate: np.ndarray
    time_system: int
    lsk: LeapSecondTable

    @classmethod
    def from_pool(cls, sc_id: int) -> SclkKernel:
        """Read the SCLK of spacecraft ``sc_id`` from the loaded kernel pool.

        Raises
        ------
        KernelError
            When no type 1 SCLK for ``sc_id`` is loaded, or its coefficients or
            partitions are not well formed (an edited kernel), in one line naming them.
        """
        cid = abs(int(sc_id))

        def get(name: str) -> np.ndarray:
            key = f"{name}_{cid}"
            try:
                n = spiceypy.dtpool(key)[0]
                return np.asarray(spiceypy.gdpool(key, 0, n), dtype=float)
            except spiceypy.utils.exceptions.SpiceyError:
                raise KernelError(
                    f"no SCLK kernel for spacecraft {sc_id} is loaded (missing {key})"
                ) from None

        try:
            spiceypy.dtpool(f"SCLK01_COEFFICIENTS_{cid}")
        except spiceypy.utils.exceptions.SpiceyError:
            raise KernelError(
                f"no SCLK kernel for spacecraft {sc_id} is loaded "
                f"(missing SCLK01_COEFFICIENTS_{cid})"
            ) from None
        dtype = get("SCLK_DATA_TYPE")
        if int(dtype[0]) != 1:
            raise KernelError(f"SCLK of spacecraft {sc_id} is type {int(dtype[0])}, not 1")
        offsets = get("SCLK01_OFFSETS")
        if np.any(offsets != 0):
            raise KernelError(f"SCLK of spacecraft {sc_id} has non-zero field offsets {offsets}")
        try:
            system = int(get("SCLK01_TIME_SYSTEM")[0])
        except KernelError:
            system = 1
        moduli = get("SCLK01_MODULI")
        if moduli.size == 0 or np.any(moduli < 1):
            raise KernelError(f"SCLK of spacecraft {sc_id}: SCLK01_MODULI_{cid} {moduli} must "
                              "be counts >= 1: a damaged or edited kernel")
        raw = get("SCLK01_COEFFICIENTS")
        if raw.size == 0 or raw.size % 3:
            raise KernelError(f"SCLK of spacecraft {sc_id}: SCLK01_COEFFICIENTS_{cid} holds "
                              f"{raw.size} numbers, not triples (encoded SCLK, parallel "
                              "time, rate): a damaged or edited kernel")
        coeff = raw.reshape(-1, 3)
        starts, ends = get("SCLK_PARTITION_START"), get("SCLK_PARTITION_END")
        if starts.size == 0 or starts.size != ends.size or np.any(ends < starts):
            raise KernelError(f"SCLK of spacecraft {sc_id}: SCLK_PARTITION_START_{cid}/END "
                              f"({starts.size}/{ends.size} values) are not matching "
                              "intervals: a damaged or edited kernel")
        if np.any(np.diff(coeff[:, 0]) < 0) or not np.all(np.isfinite(coeff)):
            raise KernelError(f"SCLK of spacecraft {sc_id}: SCLK01_COEFFICIENTS_{cid} encoded "
                              "clock values decrease or are not finite: a damaged or edited "
                              "kernel")
        return cls(
            sc_id=int(sc_id),
            moduli=moduli,
            partition_start=_snap_whole(starts),
            partition_end=_snap_whole(ends),
            ticks=_snap_whole(coeff[:, 0]),
            parallel=coeff[:, 1].copy(),
            rate=coeff[:, 2].copy(),
            time_system=system,
            lsk=leapseconds(),
        )

    @property
    def ticks_per_count(self) -> float:
        """Ticks per most-significant count (product of the lower field moduli)."""
        return float(np.prod(self.moduli[1:]))

    @property
    def partition_offsets(self) -> np.ndarray:
        """Encoded ticks at the start of each partition."""
        lengths = self.partition_end - self.partition_start
        return np.concatenate([[0.0], np.cumsum(lengths)[:-1]])

    @functools.cached_property
    def exact(self) -> ExactClock:
        """The kernel's ticks as int64 and parallel times as int64 ns (`ExactClock`).

        Raises
        ------
        KernelError
            Naming the field and record of a tick count (partition limit, coefficient
            tick, modulus) that is not a whole number.
        """
        where = f"SCLK of spacecraft {self.sc_id}"
        return ExactClock(
            ticks_per_count=int(_whole_ticks(np.array([self.ticks_per_count]), where,
                                             "SCLK01_MODULI")[0]),
            partition_start=_whole_ticks(self.partition_start, where, "SCLK_PARTITION_START"),
            partition_offsets=_whole_ticks(self.partition_offsets, where,
                                           "SCLK_PARTITION_START/END"),
            ticks=_whole_ticks(self.ticks, where, "SCLK01_COEFFICIENTS (encoded SCLK)"),
            parallel_ns=seconds_to_exact_ns(self.parallel),
            rate_minus_one=_rate_minus_one(self.rate),
        )

    def _reading(
        self, partition: np.ndarray, seconds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Validate readings; return (partition index, whole ticks, reading, tick rest).

        The reading ``seconds * ticks_per_count`` is split into the nearest whole tick
        and the rest; a rest within float64 resolution (`SNAP_RELATIVE`) is zero.

        Raises
        ------
        InputFormatError
            Naming the first reading outside its partition (or an unknown partition).
        """
        partition = np.asarray(partition)
        seconds = np.asarray(seconds, dtype=float)
        partition, seconds = np.broadcast_arrays(partition, seconds)
        n_part = len(self.partition_start)
        bad_p = (partition < 1) | (partition > n_part)
        if bad_p.any():
            i = int(np.flatnonzero(bad_p)[0])
            raise InputFormatError(
                f"SCLK reading {int(partition[i])}/{seconds[i]:.6f} of spacecraft {self.sc_id}: "
                f"partition {int(partition[i])} does not exist (kernel has 1..{n_part})",
                line=None,
                field="partition",
            )
        p = partition.astype(np.int64) - 1
        raw = seconds * self.ticks_per_count
        whole = np.rint(raw)
        rest = raw - whole
        rest = np.where(np.abs(rest) <= np.abs(raw) * SNAP_RELATIVE, 0.0, rest)
        reading = whole + rest
        start = self.partition_start[p]
        end = self.partition_end[p]
        outside = (reading < start) | (reading > end)
        if outside.any():
            i = int(np.flatnonzero(outside)[0])
            raise InputFormatError(
                f"SCLK reading {int(partition[i])}/{seconds[i]:.6f} of spacecraft {self.sc_id} "
                f"is outside partition {int(partition[i])} "
                f"({start[i] / self.ticks_per_count:.6f} .. {end[i] / self.ticks_per_count:.6f})",
                field="met",
            )
        return p, whole, reading, rest

    def encode(self, partition: np.ndarray, seconds: np.ndarray) -> np.ndarray:
        """Return encoded SCLK ticks (continuous across partitions) of clock readings.

        A reading within float64 resolution of a whole tick is that tick (`_reading`).

        Raises
        ------
        InputFormatError
            Naming the first reading outside its partition (or an unknown partition).
        """
        p, _, reading, _ = self._reading(partition, seconds)
        return self.partition_offsets[p] + (reading - self.partition_start[p])

    def decode(self, encoded: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (partition, seconds) of encoded SCLK ticks."""
        encoded = np.asarray(encoded, dtype=float)
        offsets = self.partition_offsets
        p = np.clip(np.searchsorted(offsets, encoded, side="right") - 1, 0, len(offsets) - 1)
        reading = self.partition_start[p] + (encoded - offsets[p])
        return p + 1, reading / self.ticks_per_count

    def encoded_to_et(self, encoded: np.ndarray) -> np.ndarray:
        """Convert encoded ticks to ephemeris time (SPICE ``sct2e``)."""
        par = self._parallel(np.asarray(encoded, dtype=float))
        return self.lsk.tt_to_tdb(par) if self.time_system == 2 else par

    def et_to_encoded(self, et: np.ndarray) -> np.ndarray:
        """Ephemeris time -> encoded ticks (SPICE ``sce2c``, continuous ticks)."""
        et = np.asarray(et, dtype=float)
        par = self.lsk.tdb_to_tt(et) if self.time_system == 2 else et
        last = len(self.parallel) - 1
        i = np.clip(np.searchsorted(self.parallel, par, side="right") - 1, 0, last)
        return self.ticks[i] + (par - self.parallel[i]) * (self.ticks_per_count / self.rate[i])

    def to_et(self, partition: np.ndarray, seconds: np.ndarray) -> np.ndarray:
        """Clock readings (partition, seconds) -> ephemeris time, as ``spiceypy.scs2e``.

        One compiled pass (`_sclk_kernel`); `to_et_reference` is the numpy version
        (`encode`, `encoded_to_et`) the tests compare with.

        Raises
        ------
        InputFormatError
            Naming the first reading outside its partition (or an unknown partition).
        """
        out = self._compiled(partition, seconds, None, want_tt2000=False)
        return self.to_et_reference(partition, seconds) if out is None else out[0]

    def to_et_reference(self, partition: np.ndarray, seconds: np.ndarray) -> np.ndarray:
        """Numpy reference of `to_et`: `encode`, then `encoded_to_et` (whole arrays)."""
        return self.encoded_to_et(self.encode(partition, seconds))

    def _compiled(
        self, partition: np.ndarray, seconds: np.ndarray | None, ticks: np.ndarray | None,
        *, want_tt2000: bool,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(ET, TT2000) from `_sclk_kernel`; None when the reference must decide.

        Readings are ``seconds`` (float, most significant field) or, when ``seconds``
        is None, whole ``ticks`` (int64).  The kernel stops at a reading the reference
        would reject (unknown partition, reading outside its partition) or treat
        specially (NaN); the caller then runs the numpy reference, which raises its
        error or returns its values.
        """
        values = np.asarray(ticks, dtype=np.int64) if seconds is None else np.asarray(
            seconds, dtype=float)
        partition, values = np.broadcast_arrays(np.asarray(partition), values)
        if partition.dtype.kind not in "iuf" or self.ticks.size == 0:
            return None
        shape = values.shape
        part = partition.ravel()
        flat = values.ravel()
        exact = self.exact if self.time_system == 2 and want_tt2000 else _NO_EXACT
        et = np.empty(flat.size)
        tt2000 = np.empty(flat.size if want_tt2000 else 0, dtype=np.int64)
        lsk = self.lsk
        no_ticks = np.empty(0, dtype=np.int64)
        bad = _sclk_kernel(
            part, flat if seconds is not None else np.empty(0),
            flat if seconds is None else no_ticks, seconds is None,
            float(len(self.partition_start)), self.ticks_per_count,
            self.partition_start, self.partition_end, self.partition_offsets,
            self.ticks, self.parallel, self.rate, self.time_system == 2,
            *_ns_per_tick_ratio(exact.ticks_per_count), exact.partition_start,
            exact.partition_offsets,
            exact.ticks, exact.parallel_ns, exact.rate_minus_one,
            lsk.k, lsk.eb, lsk.m0, lsk.m1, et, tt2000, want_tt2000,
        )
        if bad >= 0:
            return None
        if not want_tt2000:
            return et.reshape(shape)[()], tt2000
        return et.reshape(shape)[()], tt2000.reshape(shape)[()]

    def _parallel(self, encoded: np.ndarray) -> np.ndarray:
        """Convert encoded ticks to parallel time (TDB or TT seconds past J2000)."""
        i = self._record(encoded)
        return self.parallel[i] + (encoded - self.ticks[i]) * (self.rate[i] / self.ticks_per_count)

    def _record(self, encoded: np.ndarray) -> np.ndarray:
        """Index of the coefficient record of each encoded tick (the first for earlier ones)."""
        last = len(self.ticks) - 1
        return np.clip(np.searchsorted(self.ticks, encoded, side="right") - 1, 0, last)

    def to_et_and_tt2000(
        self, partition: np.ndarray, seconds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Clock readings -> (ephemeris time, int64 TT2000 ns), sharing the work.

        With a TT (TDT) parallel time the TT2000 epoch comes straight from the clock
        correlation in integer nanoseconds (`exact_tt2000`), without a TDB round trip:
        a reading on the clock's tick grid gives the TT2000 of the kernel's values
        exactly (the ``1/0`` of the seed 000 clock is 2004-08-03T05:59:16.000000000 UTC).  One
        compiled pass (`_sclk_kernel`); `to_et_and_tt2000_reference` is the numpy
        version the tests compare with.

        Raises
        ------
        InputFormatError
            Naming the first reading outside its partition (or an unknown partition).
        """
        out = self._compiled(partition, seconds, None, want_tt2000=True)
        return self.to_et_and_tt2000_reference(partition, seconds) if out is None else out

    def to_et_and_tt2000_reference(
        self, partition: np.ndarray, seconds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Numpy reference of `to_et_and_tt2000` (`_reading`, `_parallel`, `exact_tt2000`)."""
        p, whole, reading, rest = self._reading(partition, seconds)
        encoded = self.partition_offsets[p] + (reading - self.partition_start[p])
        parallel = self._parallel(encoded)
        if self.time_system != 2:
            return parallel, et_to_tt2000(parallel, self.lsk)
        exact = self.exact
        with np.errstate(invalid="ignore"):  # NaN readings: NaN ET, meaningless TT2000
            ticks = whole.astype(np.int64)
        enc = exact.partition_offsets[p] + (ticks - exact.partition_start[p])
        return self.lsk.tt_to_tdb(parallel), self.exact_tt2000(enc, rest, self._record(encoded))

    def exact_tt2000(self, encoded: np.ndarray, rest: np.ndarray, record: np.ndarray
                     ) -> np.ndarray:
        """TT2000 ns of whole encoded ticks (int64) plus ``rest`` ticks, TT clock only.

        ``TT = parallel_ns[j] + (encoded - ticks[j]) * 1e9 / tpc * rate[j]`` with the
        nominal part ``(encoded - ticks[j]) * 1e9 / tpc`` split into an int64 count and
        a fraction (floor division); only ``fraction + nominal * (rate - 1)`` and the
        ``rest`` term are float (rate - 1 from `_rate_minus_one`), then rounded once to
        the ns (numpy version of the
        arithmetic in `_sclk_kernel`).
        """
        exact = self.exact
        tpc = exact.ticks_per_count
        dt = encoded - exact.ticks[record]
        q, r = np.divmod(dt, tpc)
        nominal, left = np.divmod(r * _NS, tpc)
        nominal += q * _NS
        frac = left / tpc
        rate = self.rate[record]
        small = (frac + (nominal + frac) * exact.rate_minus_one[record]
                 + rest * (_NS / tpc) * rate)
        with np.errstate(invalid="ignore"):
            return exact.parallel_ns[record] + nominal + np.rint(small).astype(np.int64)

    def to_tt2000(self, partition: np.ndarray, seconds: np.ndarray) -> np.ndarray:
        """Clock readings -> int64 TT2000 nanoseconds."""
        return self.to_et_and_tt2000(partition, seconds)[1]

    def to_et_and_tt2000_ticks(
        self, partition: np.ndarray, ticks: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Whole-tick clock readings -> (ET, int64 TT2000 ns), the TT2000 exact.

        Parameters
        ----------
        partition : array_like of int
        ticks : array_like of int
            The reading in ticks of the least significant field (seed 000: microseconds,
            ``1/16458912:103412`` is 16458912103412; seed 003: 1/65536 s).

        Raises
        ------
        InputFormatError
            Naming the first reading outside its partition (or an unknown partition).
        KernelError
            If the parallel time is TDB (the TT2000 would not be exact).
        """
        if self.time_system != 2:
            raise KernelError(
                f"SCLK of spacecraft {self.sc_id}: exact TT2000 from ticks needs a TDT "
                f"(TT) parallel time, the kernel's is TDB (SCLK01_TIME_SYSTEM = 1)"
            )
        ticks = np.asarray(ticks)
        if ticks.dtype.kind not in "iu":
            raise InputFormatError(
                f"SCLK ticks of spacecraft {self.sc_id} must be integers, got {ticks.dtype}",
                field="ticks",
            )
        out = self._compiled(partition, None, ticks, want_tt2000=True)
        if out is not None:
            return out
        # rejected reading: the reference names it (ticks -> seconds only for the message)
        return self.to_et_and_tt2000_reference(partition, ticks / self.ticks_per_count)

    def to_tt2000_ticks(self, partition: np.ndarray, ticks: np.ndarray) -> np.ndarray:
        """Whole-tick clock readings -> exact int64 TT2000 ns (`to_et_and_tt2000_ticks`)."""
        return self.to_et_and_tt2000_ticks(partition, ticks)[1]

    def from_et(self, et: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ephemeris time -> clock readings (partition, seconds)."""
        return self.decode(self.et_to_encoded(et))


#: A clock reading ``r = seconds * ticks_per_count`` within ``|r| * SNAP_RELATIVE`` of a
#: whole tick is that tick: twice the largest error of ``r`` when ``seconds`` is the
#: float64 nearest to a whole-tick reading (half an ulp of ``seconds``, scaled, plus half
#: an ulp of the product), e.g. 0.12 tick (120 ns) for the seed 000 clock at 2.7e8 s.
SNAP_RELATIVE = 2.0**-51


class ExactClock(NamedTuple):
    """Integer form of a type 1 SCLK (`SclkKernel.exact`).

    Attributes
    ----------
    ticks_per_count : int
    partition_start, partition_offsets : ndarray of int64
    ticks : ndarray of int64
        Encoded SCLK of each coefficient record.
    parallel_ns : ndarray of int64
        Parallel time of each record in ns past J2000 (`seconds_to_exact_ns`).
    rate_minus_one : ndarray of float
        Each record's rate - 1 (`_rate_minus_one`).
    """

    ticks_per_count: int
    partition_start: np.ndarray
    partition_offsets: np.ndarray
    ticks: np.ndarray
    parallel_ns: np.ndarray
    rate_minus_one: np.ndarray


_NO_EXACT = ExactClock(1, *(np.zeros(1, dtype=np.int64) for _ in range(4)), np.zeros(1))


def _ns_per_tick_ratio(ticks_per_count: int) -> tuple[int, int, int]:
    """Return ``1e9 / ticks_per_count`` in lowest terms, ``num, den``, and ``log2(den)``.

    The last is -1 when ``den`` is not a power of two (`_sclk_kernel`).
    """
    g = math.gcd(_NS, ticks_per_count)
    den = ticks_per_count // g
    return _NS // g, den, den.bit_length() - 1 if den & (den - 1) == 0 else -1


#: Decimal places of the SCLK rates that `_rate_minus_one` recovers.
RATE_DECIMALS = 14


def _rate_minus_one(rate: np.ndarray) -> np.ndarray:
    """Return rate - 1 of each record, from the kernel's decimal rate when it has one.

    The kernels state the rates with at most 14 decimals (seed 000 ``1.00001013271``,
    seed 003 ``9.9849419388587E-01``); the pool's float64 is up to ~2 ulp (4.4e-16) off the
    decimal, i.e. up to 0.3 ns over the 7e5 s of a seed 003 record.  When every rate lies
    within 0.1 of the 1e-14 grid (an accident for other kernels: each would have a 20 %
    chance), rate - 1 is taken from the nearest grid value, an integer count of 1e-14
    computed exactly; otherwise it is the float64 ``rate - 1`` (itself exact).
    """
    scaled = np.asarray(rate, dtype=float) * 10.0**RATE_DECIMALS
    grid = np.rint(scaled)
    if np.all(np.abs(scaled - grid) <= 0.1):
        return (grid - 10.0**RATE_DECIMALS) / 10.0**RATE_DECIMALS
    return np.asarray(rate, dtype=float) - 1.0


def _snap_whole(values: np.ndarray) -> np.ndarray:
    """Return ``values`` with each one within float64 resolution of a whole number made whole.

    The kernel pool's parser is not always correctly rounded: seed 000's
    ``2.68435455999999e+14`` is read as 268435455999998.97 and seed 003's encoded ticks
    are up to 0.004 tick off; left so, a reading exactly at a coefficient record would
    fall in the record before it.  Tolerance `SNAP_RELATIVE` (about 2 ulp).
    """
    values = np.asarray(values, dtype=float)
    whole = np.rint(values)
    return np.where(np.abs(values - whole) <= np.abs(values) * SNAP_RELATIVE, whole, values)


def _whole_ticks(values: np.ndarray, where: str, field: str) -> np.ndarray:
    """Return whole tick counts (float64, `_snap_whole`) as int64; KernelError for others."""
    values = _snap_whole(values)
    bad = ~(np.isfinite(values) & (values == np.rint(values)) & (np.abs(values) < 2.0**53))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise KernelError(
            f"{where}: {field} value {i + 1} ({float(values[i])!r}) is not a whole number of ticks"
        )
    return values.astype(np.int64)


def seconds_to_exact_ns(seconds: np.ndarray) -> np.ndarray:
    """Float64 seconds stated to the microsecond (or not) -> int64 nanoseconds.

    A value within float64 resolution (2 ulp) of a whole microsecond is that microsecond
    (the SCLK kernels state their parallel times to the microsecond: seed 000
    ``@03-AUG-2004-06:00:20.184000``, seed 003 ``1.3146108418400E+08``); any other value
    is rounded to the nearest nanosecond of its float64 value.
    """
    seconds = np.asarray(seconds, dtype=float)
    whole = np.floor(seconds)
    micro = (seconds - whole) * 1e6
    micro_whole = np.rint(micro)
    tol = 2.0 * np.spacing(np.abs(seconds)) * 1e6
    on_grid = np.abs(micro - micro_whole) <= tol
    frac_ns = np.where(on_grid, micro_whole * 1000.0, np.rint((seconds - whole) * 1e9))
    return whole.astype(np.int64) * _NS + frac_ns.astype(np.int64)


# ----------------------------------------------------------------------------------------
# Compiled clock conversion (one pass per reading)
# ----------------------------------------------------------------------------------------
#: Spacing (s) of the nodes of the compiled TDB - TT expansion (`_tdb_minus_tt_taylor`).
TDB_TT_NODE_SPACING = 128.0


@njit(cache=True, nogil=True)
def _tdb_minus_tt_coefficients(node, k, eb, m0, m1):
    """Taylor coefficients ``g, g', g''/2, g'''/6`` of TDB - TT at ``node``.

    ``g = K sin E``, ``E = M + EB sin M``, ``M = M0 + M1 t``; ``g`` itself is evaluated
    with the expression of `LeapSecondTable.tdb_minus_tt`.
    """
    m = m0 + m1 * node
    sm = math.sin(m)
    cm = math.cos(m)
    e = m + eb * sm
    se = math.sin(e)
    ce = math.cos(e)
    e1 = m1 * (1.0 + eb * cm)  # E'
    e2 = -m1 * m1 * eb * sm  # E''
    e3 = -m1 * m1 * m1 * eb * cm  # E'''
    g1 = k * ce * e1
    g2 = k * (ce * e2 - se * e1 * e1)
    g3 = k * (ce * e3 - ce * e1 * e1 * e1 - 3.0 * se * e1 * e2)
    return k * se, g1, g2 / 2.0, g3 / 6.0


@njit(cache=True, nogil=True, inline="always")
def _tdb_minus_tt_taylor(t, k, eb, m0, m1, cache):
    """TDB - TT at ``t`` from a cubic Taylor expansion about the nearest node.

    Nodes lie every `TDB_TT_NODE_SPACING` s (``|t - node| <= 64 s``); ``cache`` (float64,
    5: node index, coefficients) is refreshed when ``t`` moves to another node, so
    sorted times cost four multiply-adds each instead of two sines.  The result
    depends on ``t`` alone, not on the order of the calls.

    Accuracy: the truncation error is the fourth-order term, ``|g''''| h**4 / 24`` with
    ``|g''''| <= K (M1 (1 + EB))**4 (1 + 6 EB)`` ~ 3e-30 s/s**4: < 1e-23 s at
    ``h = 64 s``, far below the float64 resolution of TDB - TT itself (ulp(1.7e-3 s)
    = 2.2e-19 s).  What both this and the numpy reference do carry is the rounding of
    the argument ``M = M0 + M1 t`` (ulp 1.4e-14 rad for the 2004-2015 epochs, ~1e-17 s
    of TDB - TT); against an 80-bit evaluation both err by < 3.3e-17 s for
    ``1e8 < t < 5e8`` and < 2.2e-16 s for ``|t| < 3e9``, and they differ from each
    other by as much.  ET = parallel time + (TDB - TT) (ulp 6e-8 s) thus equals the
    reference's value except, by one ulp, in about one reading in 10**9.  Non-finite
    ``t`` gives NaN, as the reference does.
    """
    cell = np.floor(t * (1.0 / TDB_TT_NODE_SPACING) + 0.5)
    if cell != cache[0]:
        a0, a1, a2, a3 = _tdb_minus_tt_coefficients(cell * TDB_TT_NODE_SPACING, k, eb, m0, m1)
        cache[0] = cell
        cache[1] = a0
        cache[2] = a1
        cache[3] = a2
        cache[4] = a3
    dt = t - cell * TDB_TT_NODE_SPACING
    return cache[1] + dt * (cache[2] + dt * (cache[3] + dt * cache[4]))


@njit(cache=True, nogil=True)
def _sclk_kernel(
    partition, seconds, ticks_in, from_ticks, n_part, ticks_per_count, part_start, part_end,
    part_offsets, ticks, parallel, rate, tt_clock, num, den, shift, part_start_i, part_offsets_i,
    ticks_i, parallel_ns, rate_m1, k, eb, m0, m1, et, tt2000, want_tt2000,
):
    """Type 1 SCLK readings -> ET (and TT2000 ns), one pass (seed 000 sec. 9, ``scs2e``).

    Per reading, the arithmetic of `SclkKernel._reading`, `SclkKernel.encode`,
    `SclkKernel._parallel`, `LeapSecondTable.tt_to_tdb` (TT clock) or
    `LeapSecondTable.tdb_to_tt` (TDB clock) and, for the TT2000 of a TT clock,
    `SclkKernel.exact_tt2000` (int64), in the same order.

    Parameters
    ----------
    partition : ndarray, shape (n,)
        Partition numbers.
    seconds : ndarray, shape (n,) or (0,)
        Readings in units of the most significant field (unless ``from_ticks``).
    ticks_in : ndarray of int64, shape (n,) or (0,)
        Readings in whole ticks (when ``from_ticks``).
    from_ticks : bool
    n_part : float
        Number of partitions.
    ticks_per_count : float
    part_start, part_end, part_offsets : ndarray
        Partition limits (ticks) and encoded ticks at each partition start.
    ticks, parallel, rate : ndarray
        SCLK01 coefficient triplets.
    tt_clock : bool
        Parallel time is TT (TDT); else TDB.
    num, den, shift : int
        ``1e9 / ticks_per_count`` in lowest terms, ``num / den``; ``log2(den)`` when
        ``den`` is a power of two, else -1.
    part_start_i, part_offsets_i, ticks_i, parallel_ns, rate_m1 : ndarray
        `ExactClock` fields (used for the TT2000 of a TT clock).
    k, eb, m0, m1 : float
        DELTET constants of the leapseconds kernel.
    et : ndarray, shape (n,)
        Written.
    tt2000 : ndarray of int64, shape (n,) or (0,)
        Written when ``want_tt2000``.
    want_tt2000 : bool

    Returns
    -------
    int
        -1, or the index of the first reading with an unknown partition or outside its
        partition, NaN included (the loop stops there).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 9.
    .. [2] NAIF, "SCLK Required Reading" (type 1), "Time Required Reading" (TDT-TDB).
    """
    last = ticks.size - 1
    hint = 0
    cache = np.full(5, np.nan)  # node index and Taylor coefficients of TDB - TT
    den_f = float(den)
    ns_per_tick = num / den_f
    n = ticks_in.size if from_ticks else seconds.size
    for i in range(n):
        pv = partition[i]
        if not (pv >= 1 and pv <= n_part):
            return i
        p = int(pv) - 1
        if from_ticks:
            whole_i = ticks_in[i]
            rest = 0.0
            reading = float(whole_i)
        else:
            raw = seconds[i] * ticks_per_count
            whole = np.rint(raw)
            rest = raw - whole
            if abs(rest) <= abs(raw) * SNAP_RELATIVE:
                rest = 0.0
            reading = whole + rest
            whole_i = np.int64(0)
        start = part_start[p]
        if not (reading >= start and reading <= part_end[p]):
            return i
        encoded = part_offsets[p] + (reading - start)
        c = count_le(ticks, encoded, hint)
        hint = c
        j = min(max(c - 1, 0), last)
        par = parallel[j] + (encoded - ticks[j]) * (rate[j] / ticks_per_count)
        if tt_clock:
            et[i] = par + _tdb_minus_tt_taylor(par, k, eb, m0, m1, cache)
            if not want_tt2000:
                continue
            if not from_ticks:
                whole_i = np.int64(whole)
            # nominal ns = floor(dt * a / b) + left / b  (a / b = 1e9 / tpc in lowest terms)
            dt = part_offsets_i[p] + (whole_i - part_start_i[p]) - ticks_i[j]
            if shift >= 0:  # b a power of two: shifts, not integer divisions (~40 cycles)
                ra = (dt & (den - 1)) * num
                nominal = (dt >> shift) * num + (ra >> shift)
                left = ra & (den - 1)
            else:
                q = dt // den
                ra = (dt - q * den) * num
                nominal = q * num + ra // den
                left = ra - (ra // den) * den
            frac = left / den_f
            small = (frac + (float(nominal) + frac) * rate_m1[j]
                     + rest * ns_per_tick * rate[j])
            tt2000[i] = parallel_ns[j] + nominal + np.int64(np.rint(small))
        else:
            et[i] = par
            if not want_tt2000:
                continue
            inner = par - _tdb_minus_tt_taylor(par, k, eb, m0, m1, cache)
            tt = par - _tdb_minus_tt_taylor(inner, k, eb, m0, m1, cache)
            whole_s = np.floor(tt)
            tt2000[i] = np.int64(whole_s) * _NS + np.int64(np.rint((tt - whole_s) * 1e9))
    return -1
