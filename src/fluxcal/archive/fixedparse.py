"""Compiled parsing of fixed-width ASCII numbers (the fields of a PDS3 ASCII table).

`parse_reals` / `parse_ints` read every row of a ``(rows, width)`` byte field: optional
blanks, sign, digits, a decimal point, an exponent (``E``, ``e``, ``D``, ``d``), blanks.
A real is exact (correctly rounded) when its decimal mantissa is at most 2**53 and its
power of ten at most 22 in magnitude: then ``m * 10**e`` or ``m / 10**-e`` is one IEEE
operation on two exact doubles (Clinger's fast path, W. D. Clinger, "How to read
floating point numbers accurately", PLDI 1990).  Rows outside that fast path (more
digits, larger exponents, ``NaN``, or text that is not a number) are flagged, and the
caller converts those rows with numpy's exact parser, which also reports the bad ones.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["parse_ints", "parse_reals"]

_POW10 = np.array([10.0**k for k in range(23)])
_MAX_EXACT = 2**53


@njit(cache=True)
def _digits(row, j, n, value, significant):
    """Read digits from ``j`` onto ``value``: (value, digits read, significant, next index).

    ``significant`` counts the significant digits so far (the first 19 are kept).
    """
    count = 0
    while j < n and 48 <= row[j] <= 57:
        d = row[j] - 48
        if significant > 0 or d != 0:
            significant += 1
        if significant <= 19:
            value = value * np.uint64(10) + np.uint64(d)
        count += 1
        j += 1
    return value, count, significant, j


@njit(cache=True)
def _sign(row, n):  # pragma: no cover - compiled
    """Skip leading blanks and one sign: ``(negative, index of the first digit)``."""
    j = 0
    while j < n and row[j] == 32:
        j += 1
    negative = False
    if j < n and (row[j] == 45 or row[j] == 43):
        negative = row[j] == 45
        j += 1
    return negative, j


@njit(cache=True)
def parse_reals(field, pow10):  # pragma: no cover - compiled
    """Return ``(values, ok)``; ``ok[i]`` is False where row ``i`` needs the slow path."""
    rows, n = field.shape
    out = np.empty(rows, np.float64)
    ok = np.ones(rows, np.bool_)
    for i in range(rows):
        row = field[i]
        negative, j = _sign(row, n)
        mant, c1, sig, j = _digits(row, j, n, np.uint64(0), 0)
        c2 = 0
        if j < n and row[j] == 46:  # the fraction's digits continue the mantissa
            mant, c2, sig, j = _digits(row, j + 1, n, mant, sig)
        if c1 + c2 == 0 or sig > 19:
            ok[i] = False
            continue
        exp = np.int64(0)
        if j < n and (row[j] == 69 or row[j] == 101 or row[j] == 68 or row[j] == 100):
            j += 1
            eneg = False
            if j < n and (row[j] == 45 or row[j] == 43):
                eneg = row[j] == 45
                j += 1
            ev, ec, _, j = _digits(row, j, n, np.uint64(0), 0)
            if ec == 0 or ec > 4:
                ok[i] = False
                continue
            exp = -np.int64(ev) if eneg else np.int64(ev)
        while j < n and row[j] == 32:
            j += 1
        if j != n or mant > np.uint64(_MAX_EXACT):
            ok[i] = False
            continue
        e10 = np.int64(exp - np.int64(c2))
        if e10 > 22 or e10 < -22:
            ok[i] = False
            continue
        v = float(mant)
        v = v * pow10[e10] if e10 >= 0 else v / pow10[-e10]
        out[i] = -v if negative else v
    return out, ok


@njit(cache=True)
def parse_ints(field):  # pragma: no cover - compiled
    """Return ``(values, ok)`` for integer fields (at most 18 digits on the fast path)."""
    rows, n = field.shape
    out = np.empty(rows, np.int64)
    ok = np.ones(rows, np.bool_)
    for i in range(rows):
        row = field[i]
        negative, j = _sign(row, n)
        value, count, significant, j = _digits(row, j, n, np.uint64(0), 0)
        while j < n and row[j] == 32:
            j += 1
        if count == 0 or significant > 18 or j != n:
            ok[i] = False
            continue
        out[i] = -np.int64(value) if negative else np.int64(value)
    return out, ok


def pow10() -> np.ndarray:
    """Exact powers of ten 1e0 .. 1e22 (the fast path's table)."""
    return _POW10
