"""IMAP MAG science vectors: the ``VECTORS`` field of every packet, compressed or not.

The field holds the primary sensor's vectors, then the secondary's (``PRI_SENS`` says
which sensor is primary); ``PRI_VECSEC``/``SEC_VECSEC`` give log2 of the vectors per
second and a packet holds ``PUS_SSUBTYPE + 1`` seconds.

Uncompressed (``COMPRESSION = 0``)
    Each vector is 50 bits, most significant bit first: x, y, z as 16-bit two's
    complement counts, then a 2-bit range; vectors are packed without padding.

Compressed (``COMPRESSION = 1``), in the order the bits come:

1. An 8-bit header: the width ``W`` (6 bits) of the uncompressed values, a flag (1 bit)
   saying a range section ends the field, one spare bit.
2. For each sensor, primary then secondary:

   a. its first vector, the *reference*: x, y, z as ``W``-bit two's complement
      counts and a 2-bit range;
   b. each following vector as three differences from the vector before it (x, y,
      z), each zig-zag mapped to a non-negative integer (0, -1, 1, -2, ... -> 0, 1,
      2, 3, ...), plus one, and written as a Fibonacci code: the Zeckendorf bits,
      least significant (weight 1, 2, 3, 5, 8, ...) first, closed by a ``1`` (so
      every code ends in ``11`` and holds no other ``11``);
   c. as soon as one such vector takes more than 60 bits, every later vector of
      that sensor in the packet is written uncompressed instead: x, y, z as
      ``W``-bit two's complement counts (absolute, not differences), no range.

3. When the header's flag is set: padding to a whole byte (counted from the start of
   the field), then 2 bits of range per vector of the primary after its reference,
   then per vector of the secondary after its reference.  Without the section every
   vector has its reference's range.

Compressed counts keep ``W`` bits of the sensor's output: L1B scales them by
``2**(16 - W)`` (`fluxcal.missions.imap.l1b`).

The decoding is one compiled loop (numba) over every packet and vector: the Fibonacci
codes make a vector's place depend on every code before it in the packet, so the
loop is sequential within a packet.

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing (MIT License),
   ``imap_processing/mag/l1a/mag_l1a_data.py`` (``process_compressed_vectors`` and
   its docstrings: the header, the reference vector, the Fibonacci/zig-zag
   differences, the 60-bit switch to uncompressed vectors, the range data section)
   and ``mag/constants.py`` (``MAX_COMPRESSED_VECTOR_BITS = 60``); read for the
   layout, this decoder is fluxcal's own.  Checked against the team's validation
   cases L1a T001-T008 and L1b T009-T012 (``tests/missions/imap/test_team_cases.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap.packets import MagPackets, vector_counts

#: Bits of one uncompressed (16-bit) vector: x, y, z and the range.
VECTOR_BITS = 50
#: A compressed vector longer than this switches the rest of its sensor's vectors in the
#: packet to uncompressed ``W``-bit values.
MAX_COMPRESSED_VECTOR_BITS = 60
#: Widths the header may give (the team's description: up to 20 bits).
MAX_WIDTH = 20
#: Longest Fibonacci code accepted (a difference of 2**21 counts needs 32 bits).
MAX_CODE_BITS = 64

_FIB = np.zeros(MAX_CODE_BITS, dtype=np.int64)
_FIB[:2] = 1, 2
for _k in range(2, MAX_CODE_BITS):
    _FIB[_k] = _FIB[_k - 1] + _FIB[_k - 2]

# status codes of the kernel, one per packet
_OK, _SHORT, _WIDTH, _LONG_CODE, _RANGE_SHORT = 0, 1, 2, 3, 4


@njit(cache=True, nogil=True, inline="always")
def _bit(data, pos):
    return (data[pos >> 3] >> (7 - (pos & 7))) & 1


@njit(cache=True, nogil=True, inline="always")
def _unsigned(data, pos, n):
    """Return the ``n`` bits (1..32) from bit ``pos`` on, most significant first."""
    first = pos >> 3
    last = (pos + n - 1) >> 3
    v = 0
    for i in range(first, last + 1):
        v = (v << 8) | np.int64(data[i])
    return (v >> ((last + 1) * 8 - pos - n)) & ((1 << n) - 1)


@njit(cache=True, nogil=True, inline="always")
def _signed(data, pos, n):
    v = _unsigned(data, pos, n)
    return v - (1 << n) if v >= 1 << (n - 1) else v


@njit(cache=True, nogil=True)
def _decode(data, start, stop, compressed, n_pri, n_sec, first, fib, counts, rng, width,
            status, detail):
    """Decode every packet's vectors into ``counts``/``rng`` from row ``first[p]``.

    ``start``/``stop``: bit span of each packet's field in ``data``; ``status[p]`` and
    ``detail[p]`` (the vector row or the width) say why a packet failed.
    """
    for p in range(start.size):
        pos = start[p]
        end = stop[p]
        row0 = first[p]
        n_total = n_pri[p] + n_sec[p]
        if compressed[p] == 0:
            if pos + n_total * 50 > end:
                status[p] = _SHORT
                detail[p] = (end - pos) // 50
                continue
            for v in range(n_total):
                for a in range(3):
                    counts[row0 + v, a] = _signed(data, pos, 16)
                    pos += 16
                rng[row0 + v] = _unsigned(data, pos, 2)
                pos += 2
            continue
        if pos + 8 > end:
            status[p] = _SHORT
            continue
        w = _unsigned(data, pos, 6)
        has_ranges = _bit(data, pos + 6)
        width[p] = w
        if w < 1 or w > 20:
            status[p] = _WIDTH
            detail[p] = w
            continue
        pos += 8
        row = row0
        for side in range(2):
            n = n_pri[p] if side == 0 else n_sec[p]
            if n == 0:
                continue
            ref = row
            if pos + 3 * w + 2 > end:
                status[p] = _SHORT
                detail[p] = row - row0
                break
            for a in range(3):
                counts[row, a] = _signed(data, pos, w)
                pos += w
            rng[row] = _unsigned(data, pos, 2)
            pos += 2
            row += 1
            packed = True
            for _ in range(1, n):
                if packed:
                    vector_start = pos
                    for a in range(3):
                        value = 0
                        previous = 0
                        k = 0
                        while True:
                            if pos >= end:
                                status[p] = _SHORT
                                break
                            b = _bit(data, pos)
                            pos += 1
                            if b == 1 and previous == 1:
                                break
                            if k >= fib.size:
                                status[p] = _LONG_CODE
                                break
                            if b == 1:
                                value += fib[k]
                            previous = b
                            k += 1
                        if status[p] != _OK:
                            break
                        value -= 1
                        counts[row, a] = counts[row - 1, a] + ((value >> 1) ^ -(value & 1))
                    if status[p] != _OK:
                        detail[p] = row - row0
                        break
                    packed = pos - vector_start <= 60
                else:
                    if pos + 3 * w > end:
                        status[p] = _SHORT
                        detail[p] = row - row0
                        break
                    for a in range(3):
                        counts[row, a] = _signed(data, pos, w)
                        pos += w
                rng[row] = rng[ref]
                row += 1
            if status[p] != _OK:
                break
        if status[p] != _OK or has_ranges == 0:
            continue
        pos = start[p] + (pos - start[p] + 7) // 8 * 8
        n_ranges = max(n_pri[p] - 1, 0) + max(n_sec[p] - 1, 0)
        if pos + 2 * n_ranges > end:
            status[p] = _RANGE_SHORT
            detail[p] = 2 * n_ranges - max(end - pos, 0)
            continue
        row = row0
        for side in range(2):
            n = n_pri[p] if side == 0 else n_sec[p]
            for v in range(1, n):
                rng[row + v] = _unsigned(data, pos, 2)
                pos += 2
            row += n


@dataclass(frozen=True)
class PacketVectors:
    """Every vector of a set of packets, in packet order (primary, then secondary).

    Attributes
    ----------
    counts : ndarray (n, 3) of int64
        x, y, z counts as sent (``W`` bits wide in compressed packets).
    range : ndarray (n,) of int64
        Range 0..3.
    packet : ndarray (n,) of int64
        Index of the vector's packet.
    secondary : ndarray (n,) of bool
        The vector is the secondary sensor's.
    index : ndarray (n,) of int64
        Position of the vector among its sensor's vectors in the packet.
    width : ndarray (packets,) of int64
        The compression width ``W`` of each packet (0 for an uncompressed packet).
    """

    counts: np.ndarray
    range: np.ndarray
    packet: np.ndarray
    secondary: np.ndarray
    index: np.ndarray
    width: np.ndarray


def decode_vectors(packets: MagPackets) -> PacketVectors:
    """Decode the ``VECTORS`` field of every packet (the layout in the module docstring).

    Raises
    ------
    InputFormatError
        Naming the file, the first packet that fails (index, sequence count, APID) and
        the field: a field that ends before its last vector or range, a compression
        width outside 1..20, a Fibonacci code longer than 64 bits.
    """
    n_pri, n_sec = vector_counts(packets)
    per_packet = n_pri + n_sec
    first = np.zeros(len(packets) + 1, dtype=np.int64)
    np.cumsum(per_packet, out=first[1:])
    lengths = np.fromiter((len(v) for v in packets.vectors), dtype=np.int64,
                          count=len(packets))
    start = np.zeros(len(packets), dtype=np.int64)
    np.cumsum(lengths[:-1] * 8, out=start[1:])
    data = np.frombuffer(b"".join(packets.vectors), dtype=np.uint8)
    total = int(first[-1])
    counts = np.zeros((total, 3), dtype=np.int64)
    rng = np.zeros(total, dtype=np.int64)
    width = np.zeros(len(packets), dtype=np.int64)
    status = np.zeros(len(packets), dtype=np.int64)
    detail = np.zeros(len(packets), dtype=np.int64)
    compressed = packets.fields["COMPRESSION"].astype(np.int64)
    if len(packets):
        _decode(data, start, start + lengths * 8, compressed, n_pri, n_sec, first[:-1], _FIB,
                counts, rng, width, status, detail)
    bad = np.flatnonzero(status)
    if bad.size:
        raise _failure(packets, int(bad[0]), int(status[bad[0]]), int(detail[bad[0]]),
                       int(n_pri[bad[0]]), int(lengths[bad[0]]) * 8)
    packet = np.repeat(np.arange(len(packets)), per_packet)
    position = np.arange(total) - first[packet]
    secondary = position >= n_pri[packet]
    index = np.where(secondary, position - n_pri[packet], position)
    return PacketVectors(counts, rng, packet, secondary, index, width)


def _failure(packets: MagPackets, i: int, status: int, detail: int, n_pri: int,
             bits: int) -> InputFormatError:
    """Return the error of packet ``i`` that the kernel stopped on."""
    kind = "compressed" if packets.fields["COMPRESSION"][i] else "uncompressed"
    side, k = ("secondary", detail - n_pri) if detail >= n_pri else ("primary", detail)
    if status == _WIDTH:
        what = f"compression width {detail} bits is not 1..{MAX_WIDTH}"
    elif status == _LONG_CODE:
        what = (f"{side} vector {k}: a difference code runs past {MAX_CODE_BITS} bits "
                "(damaged compressed vectors)")
    elif status == _RANGE_SHORT:
        what = f"the range section needs {detail} bits more than the field's {bits}"
    else:
        what = (f"{kind} VECTORS field of {bits} bits ends inside {side} vector {k}"
                if status == _SHORT else f"undecodable (status {status})")
    return InputFormatError(f"{packets.where(i)}: {what}", path=packets.source,
                            field="VECTORS")
