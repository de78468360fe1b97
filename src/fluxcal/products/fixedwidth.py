"""Vectorized fixed-width text formatting of numbers (FORTRAN ``Iw.m``, ``Fw.d``, ``Ew.d``).

The kernels write the decimal digits of each value straight into a preallocated
``(rows, row_bytes)`` ``uint8`` buffer, no Python string per value.  `format_rows`
writes whole rows (blanks, every ``Iw.m`` and ``Fw.d`` field, CR LF) in one pass, a
block of rows at a time so that the block stays in the L1 cache while every column
writes into it; `format_exp` (``Ew.d``) and `copy_text` (``Aw``) fill one column's
fields afterwards.  The printed text is exactly Python's own printf output:

- ``Fw.d`` == ``"%w.df" % x`` (``"%0w.df"`` with ``zero_pad``),
- ``Ew.d`` == ``"%w.dE" % x`` (at least two exponent digits),
- ``Iw.m`` == ``"%w.md" % i`` (``"%0wd"`` when ``m == w`` and ``i >= 0``),

i.e. the value is rounded to the printed digits from its *exact* binary value, ties
(possible only when ``x * 10**d`` is exactly a half-integer, e.g. ``0.0625`` at
``d = 3``) to even; a negative value that rounds to zero keeps its sign (``-0.000``),
as Python does.  ``x * 10**d`` is formed with an error-free product (Dekker), so the
rounding decision is exact for ``d <= 22``; ``Ew.d`` is exact while the decimal scale
``10**(d - exponent)`` is within ``1e+-22`` and uses a double-double power of ten
(106 bits) beyond (tiny or huge values), where an exact decimal tie cannot occur.

A value that does not fit its width, or is infinite, is reported (first bad row),
never written as ``*****``; NaN is written as ``NaN`` right-justified (or the column's
fill value, when it has one).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from numba import njit

# Result codes of the kernels (0 = all rows written).
OK, TOO_WIDE, NOT_FINITE, TOO_LARGE = 0, 1, 2, 3  # TOO_LARGE: beyond int64 once scaled

_SPLIT = 134217729.0  # 2**27 + 1, Dekker's splitter for float64
_TWO52 = 4503599627370496.0
_TWO63 = 9223372036854775808.0


def _pow10_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``10**n = (hi + lo) * 2**b`` for n in -350..350, ``1 <= hi < 2`` (exact rationals).

    The double-double mantissa ``hi + lo`` carries 106 bits; the binary exponent is kept
    apart so that neither part over- or underflows at any ``n``.
    """
    ns = range(-350, 351)
    hi, lo, b2 = np.zeros(len(ns)), np.zeros(len(ns)), np.zeros(len(ns), np.int64)
    for i, n in enumerate(ns):
        exact = Fraction(10) ** n
        b = exact.numerator.bit_length() - exact.denominator.bit_length()
        mant = exact / Fraction(2) ** b
        if mant < 1:
            b -= 1
            mant *= 2
        h = float(mant)
        hi[i], lo[i], b2[i] = h, float(mant - Fraction(h)), b
    return hi, lo, b2


_P10_HI, _P10_LO, _P10_EXP = _pow10_table()
_P10_EXACT = np.array([float(10**i) for i in range(23)])  # exact in float64 up to 1e22


@njit(cache=True)
def _two_prod_err(a: float, b: float, p: float) -> float:
    """Exact ``a * b - p`` for ``p = fl(a * b)`` (Dekker's TwoProduct, no FMA needed)."""
    t = _SPLIT * a
    ahi = t - (t - a)
    alo = a - ahi
    t = _SPLIT * b
    bhi = t - (t - b)
    blo = b - bhi
    return ((ahi * bhi - p) + ahi * blo + alo * bhi) + alo * blo


@njit(cache=True)
def _round_sum(p: float, e: float) -> tuple[int, bool]:
    """Round the exact sum ``p + e`` (``|e| <= ulp(p) / 2``) to an integer, ties to even.

    Returns ``(k, ok)``; ``ok`` is False when the result does not fit an int64.
    """
    if p >= _TWO63:
        return 0, False
    if p < _TWO52:  # p may have a fraction; only p == k + 1/2 needs e to decide
        fl = math.floor(p)
        f = p - fl
        k = np.int64(fl)
        if f > 0.5:
            k += 1
        elif f == 0.5:
            if e > 0.0 or (e == 0.0 and k % 2 == 1):
                k += 1
        return k, True
    # p is an integer (ulp >= 1): the fraction is e's
    k = np.int64(p)
    fe = math.floor(e)
    fr = e - fe
    k += np.int64(fe)
    if fr > 0.5 or (fr == 0.5 and k % 2 == 1):
        k += 1
    return k, True


@njit(cache=True)
def _scaled_round(ax: float, n: int) -> tuple[int, bool]:
    """``round_half_even(ax * 10**n)`` for finite ``ax >= 0``; ``(k, fits_int64)``."""
    if 0 <= n <= 22:
        s = _P10_EXACT[n]
        p = ax * s
        if p < _TWO52:  # fast path: the product's error matters only at an exact .5
            fl = math.floor(p)
            f = p - fl
            k = np.int64(fl)
            if f > 0.5:
                k += 1
            elif f == 0.5:
                e = _two_prod_err(ax, s, p)
                if e > 0.0 or (e == 0.0 and k % 2 == 1):
                    k += 1
            return k, True
        if not p < _TWO63:
            return 0, False
        return _round_sum(p, _two_prod_err(ax, s, p))
    if -22 <= n < 0:  # divide by an exact 10**-n, exact remainder decides ties
        s = _P10_EXACT[-n]
        q = ax / s
        if not q < _TWO63:
            return 0, False
        pp = q * s
        r = (ax - pp) - _two_prod_err(q, s, pp)  # ax - q*s, exact
        if q < _TWO52:
            return _round_sum(q, r)
        # q integer: the exact quotient is q + r/s with |r/s| <= ulp(q)/2
        return _round_sum(q, r / s)
    # |n| > 22: mantissas near 1 (no over/underflow in the products), exponents apart
    pre = 0
    if ax < 1e-300:  # subnormal: scale into the normal range exactly first
        ax *= 3.402823669209385e38  # 2**128
        pre = 128
    m, e2 = math.frexp(ax)
    e2 -= pre
    hi = _P10_HI[n + 350]
    p = m * hi
    err = _two_prod_err(m, hi, p) + m * _P10_LO[n + 350]
    scale = e2 + _P10_EXP[n + 350]
    if scale > 64:
        return 0, False
    big = math.ldexp(p, scale)
    small = math.ldexp(err, scale)
    s2 = big + small  # renormalise the double-double
    return _round_sum(s2, small - (s2 - big))


@njit(cache=True)
def _write_uint(buf: np.ndarray, row: int, end: int, k: int, min_digits: int) -> int:
    """Write ``k >= 0`` right-aligned so that its last digit is at ``end - 1``; return start."""
    pos = end
    nd = 0
    while k > 0 or nd < min_digits:
        pos -= 1
        buf[row, pos] = 48 + k % 10
        k //= 10
        nd += 1
    return pos


@njit(cache=True)
def _ndigits(k: int) -> int:
    nd = 1
    while k >= 10:
        k //= 10
        nd += 1
    return nd


@njit(cache=True)
def _write_nan(buf: np.ndarray, row: int, start: int, width: int) -> bool:
    if width < 3:
        return False
    end = start + width
    buf[row, end - 3] = 78  # N
    buf[row, end - 2] = 97  # a
    buf[row, end - 1] = 78  # N
    return True


@njit(cache=True)
def format_exp(values: np.ndarray, buf: np.ndarray, start: int, width: int,
               decimals: int) -> tuple[int, int]:
    """Write ``"%{w}.{d}E"`` of every value into ``buf[:, start:start + width]``."""
    top = np.int64(1)
    for _ in range(decimals + 1):
        top *= 10  # 10**(d+1): the mantissa digits must stay below
    for i in range(values.shape[0]):
        x = values[i]
        if math.isnan(x):
            if not _write_nan(buf, i, start, width):
                return TOO_WIDE, i
            continue
        if math.isinf(x):
            return NOT_FINITE, i
        neg = math.copysign(1.0, x) < 0.0
        ax = abs(x)
        expo = 0
        k = np.int64(0)
        if ax > 0.0:
            expo = int(math.floor(math.log10(ax)))
            for _ in range(3):  # log10 may be one off near powers of ten; carries too
                k, ok = _scaled_round(ax, decimals - expo)
                if not ok:
                    return TOO_LARGE, i
                if k >= top:
                    expo += 1
                elif k < top // 10:
                    expo -= 1
                else:
                    break
            if k == top // 10:  # 10**expo may exceed ax, reached only by rounding up
                k2, ok = _scaled_round(ax, decimals - expo + 1)
                if ok and k2 < top:
                    k = k2
                    expo -= 1
        ae = abs(expo)
        ne = max(2, _ndigits(ae))
        length = (1 if neg else 0) + 1 + (decimals + 1 if decimals > 0 else 0) + 2 + ne
        if length > width:
            return TOO_WIDE, i
        end = start + width
        pos = _write_uint(buf, i, end, ae, 2)
        pos -= 1
        buf[i, pos] = 45 if expo < 0 else 43  # - or +
        pos -= 1
        buf[i, pos] = 69  # E
        for _ in range(decimals):
            pos -= 1
            buf[i, pos] = 48 + k % 10
            k //= 10
        if decimals > 0:
            pos -= 1
            buf[i, pos] = 46
        pos -= 1
        buf[i, pos] = 48 + k
        if neg:
            buf[i, pos - 1] = 45
    return OK, -1


# Result codes of `copy_text` beyond the numeric ones.
EMPTY, BLANK_INSIDE = 4, 5


@njit(cache=True)
def copy_text(src: np.ndarray, buf: np.ndarray, start: int, width: int) -> tuple[int, int]:
    """Copy NUL-padded ASCII strings ``src`` (rows, itemsize) left-justified, blank-padded.

    A string longer than ``width`` (``TOO_WIDE``), empty (``EMPTY``) or containing ASCII
    whitespace (``BLANK_INSIDE``) is reported with its row.
    """
    k = src.shape[1]
    for i in range(src.shape[0]):
        if k == 0 or src[i, 0] == 0:
            return EMPTY, i
        for j in range(k):
            c = src[i, j]
            if c == 0:
                break
            if c == 32 or (9 <= c <= 13):
                return BLANK_INSIDE, i
            if j >= width:
                return TOO_WIDE, i
            buf[i, start + j] = c
    return OK, -1


# --- whole rows in one pass ------------------------------------------------------------

#: Column kinds of `format_rows`: ``Iw.m``, ``Fw.d``.
INT, FIXED = 1, 2
#: Spec fields of `format_rows` (one row of ``spec`` per column).
S_KIND, S_SLOT, S_COMP, S_START, S_WIDTH, S_DEC, S_ZPAD, S_FILL = range(8)
#: Rows per block: a block of rows (a few KiB) stays in the L1 cache while every column
#: writes its digits into it.
BLOCK_ROWS = 64
#: Source arrays of each kind per `format_rows` call (unused slots: empty arrays), so that
#: one compiled signature serves every table.
SLOTS = 8
_PAIRS = np.frombuffer("".join(f"{i:02d}" for i in range(100)).encode(), np.uint8).copy()


def integer_limit(digits: int) -> int:
    """``10**digits`` as the bound of an integer part of ``digits`` places (0: none fit).

    ``2**64 - 1`` stands for "any int64 fits" (``digits >= 19``).
    """
    if digits <= 0:
        return 0
    return 10**digits if digits < 19 else 2**64 - 1


@njit(cache=True, inline="always")
def _put_digits(buf: np.ndarray, i: int, end: int, q: np.uint64, pairs: np.ndarray) -> int:
    """Write ``q`` (at least one digit) into row ``i`` ending before ``end``; return start."""
    pos = end
    hundred = np.uint64(100)
    while q >= hundred:
        r = np.intp(q % hundred) * 2
        q //= hundred
        pos -= 2
        buf[i, pos] = pairs[r]
        buf[i, pos + 1] = pairs[r + 1]
    if q >= np.uint64(10):
        r = np.intp(q) * 2
        pos -= 2
        buf[i, pos] = pairs[r]
        buf[i, pos + 1] = pairs[r + 1]
    else:
        pos -= 1
        buf[i, pos] = np.uint8(48 + np.intp(q))
    return pos


@njit(cache=True, inline="always")
def _round_scaled(ax: float, dec: int, scale: float) -> tuple[int, bool]:
    """`_scaled_round` with the common case (``ax * 10**dec < 2**52``) branch-free."""
    p = ax * scale
    if dec > 22 or not p < _TWO52:
        return _scaled_round(ax, dec)
    fl = math.floor(p)
    f = p - fl
    k = np.int64(fl) + np.int64(f > 0.5)
    if f == 0.5:  # an exact product decides the tie (rare)
        e = _two_prod_err(ax, scale, p)
        if e > 0.0 or (e == 0.0 and k % 2 == 1):
            k += 1
    return k, True


@njit(cache=True)
def format_rows(buf: np.ndarray, reals: tuple, ints: tuple, spec: np.ndarray,
                fills: np.ndarray, limits: np.ndarray, blank: bool) -> tuple[int, int, int]:
    """Write whole rows: blanks, ``Iw.m`` and ``Fw.d`` fields, CR LF at the end.

    ``reals``/``ints`` are tuples of 2-D float64/int64 arrays (``(rows, components)``,
    rows aligned with ``buf``); column ``c`` prints component ``spec[c, S_COMP]`` of
    array ``spec[c, S_SLOT]`` of its kind.  ``limits[c]`` bounds the integer part
    (non-negative, negative value: `integer_limit` of the places left).  Fields of
    other columns stay blank.  With ``blank`` False the rows are not blanked first (a
    further group of columns of rows already written).

    ``Fw.d`` is ``"%w.df"`` (``"%0w.df"`` with ``S_ZPAD``), NaN printed as ``NaN`` unless
    ``S_FILL`` (then ``fills[c]`` is printed instead); ``Iw.m`` is ``"%w.md"``.  Returns
    ``(code, row, column)`` of the first failure found, or ``(OK, -1, -1)``.
    """
    n, width_row = buf.shape
    ncol = spec.shape[0]
    pairs = _PAIRS
    ten = np.uint64(10)
    hundred = np.uint64(100)
    for b0 in range(0, n, BLOCK_ROWS):
        b1 = min(n, b0 + BLOCK_ROWS)
        if blank:
            for i in range(b0, b1):
                for j in range(width_row - 2):
                    buf[i, j] = 32
                buf[i, width_row - 2] = 13
                buf[i, width_row - 1] = 10
        for c in range(ncol):
            kind = spec[c, S_KIND]
            comp = spec[c, S_COMP]
            start = spec[c, S_START]
            width = spec[c, S_WIDTH]
            end = start + width
            dec = spec[c, S_DEC]
            lim_pos = limits[c, 0]
            lim_neg = limits[c, 1]
            if kind == INT:
                arr_i = ints[spec[c, S_SLOT]]
                for i in range(b0, b1):
                    v = arr_i[i, comp]
                    neg = v < 0
                    if v == -9223372036854775807 - 1:
                        return TOO_LARGE, i, c
                    q = np.uint64(-v if neg else v)
                    if q >= (lim_neg if neg else lim_pos):
                        return TOO_WIDE, i, c
                    pos = _put_digits(buf, i, end, q, pairs)
                    while end - pos < dec:  # at least `dec` digits (``Iw.m``)
                        pos -= 1
                        buf[i, pos] = 48
                    if neg:
                        buf[i, pos - 1] = 45
                continue
            places = width - (dec + 1 if dec > 0 else 0)
            if places < 1:  # no room for the point and the decimals (any value)
                return TOO_WIDE, b0, c
            arr_f = reals[spec[c, S_SLOT]]
            has_fill = spec[c, S_FILL] != 0
            zpad = spec[c, S_ZPAD] != 0
            fill = fills[c]
            scale = _P10_EXACT[dec] if dec <= 22 else 1.0
            point = end - dec - 1
            for i in range(b0, b1):
                x = arr_f[i, comp]
                if has_fill and math.isnan(x):
                    x = fill
                if math.isnan(x):
                    if not _write_nan(buf, i, start, width):
                        return TOO_WIDE, i, c
                    continue
                if math.isinf(x):
                    return NOT_FINITE, i, c
                neg = math.copysign(1.0, x) < 0.0
                k, ok = _round_scaled(abs(x), dec, scale)
                if not ok:
                    return TOO_LARGE, i, c
                q = np.uint64(k)
                pos = end
                for _ in range(dec // 2):
                    r = np.intp(q % hundred) * 2
                    q //= hundred
                    pos -= 2
                    buf[i, pos] = pairs[r]
                    buf[i, pos + 1] = pairs[r + 1]
                if dec % 2 == 1:
                    buf[i, pos - 1] = np.uint8(48 + np.intp(q % ten))
                    q //= ten
                if dec > 0:
                    buf[i, point] = 46
                if q >= (lim_neg if neg else lim_pos):
                    return TOO_WIDE, i, c
                pos = _put_digits(buf, i, start + places, q, pairs)
                if zpad:
                    lim = start + 1 if neg else start
                    while pos > lim:
                        pos -= 1
                        buf[i, pos] = 48
                if neg:
                    buf[i, pos - 1] = 45
    return OK, -1, -1
