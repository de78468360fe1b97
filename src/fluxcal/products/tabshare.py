"""Formatted table fields shared by tables printed from the same arrays.

The products of one day print the same time columns (UTC year, day, hour, minute,
second, MET of a time grid) in every frame: the same arrays, the same formats, the
same bytes.  `SharedFields` keeps the bytes of such a run of adjacent columns once it
has seen their arrays in an earlier table, and later tables copy them instead of
formatting them again.

An entry is used only while its arrays are alive (weak references: it goes with
them) and only when they still hold the bytes they held when it was made (a 128-bit
fingerprint of each array's bytes, taken then, is compared; no copy is kept), so a
table does not depend on what was written before it.  Only columns whose arrays were
already seen in an earlier table are kept, so a table of arrays printed once costs no
memory here.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

#: Entries kept at most (a day: the full-resolution grid and one per average); 0 turns
#: sharing off (a day's full-resolution time columns are ~40 bytes a row: 66 MB).
MAX_ENTRIES = 8


@dataclass
class Run:
    """Adjacent columns ``first:stop`` at bytes ``lo:hi`` of a row, kept or to keep."""

    first: int
    stop: int
    lo: int
    hi: int
    key: tuple
    text: np.ndarray  # (rows, hi - lo) uint8
    found: bool  # True: copy ``text`` in; False: fill ``text`` while formatting
    arrays: list[np.ndarray] = field(default_factory=list)


@njit(cache=True)
def _mix(words: np.ndarray, h1: np.uint64, h2: np.uint64) -> tuple[np.uint64, np.uint64]:
    """Two independent 64-bit multiply-xorshift hashes of a word sequence, continued."""
    for w in words:
        h1 = (h1 ^ w) * np.uint64(0xFF51AFD7ED558CCD)
        h1 ^= h1 >> np.uint64(33)
        h2 = (h2 + w) * np.uint64(0x100000001B3)
        h2 ^= h2 >> np.uint64(29)
    return h1, h2


def fingerprint(a: np.ndarray) -> tuple:
    """Dtype, shape and a 128-bit hash of the bytes of ``a`` (C order, no copy if C)."""
    raw = np.ascontiguousarray(a).reshape(-1).view(np.uint8)
    whole = raw.size - raw.size % 8
    tail = np.zeros(8, np.uint8)
    tail[:raw.size - whole] = raw[whole:]
    h = _mix(raw[:whole].view(np.uint64), np.uint64(0x9E3779B97F4A7C15),
             np.uint64(0xC2B2AE3D27D4EB4F))
    h = _mix(tail.view(np.uint64), np.uint64(h[0]), np.uint64(h[1]))
    return a.dtype.str, a.shape, int(h[0]), int(h[1])


class SharedFields:
    """Bytes of column runs by the identity of their arrays (see the module docstring)."""

    def __init__(self) -> None:
        self._seen: dict[int, weakref.ref] = {}
        self._entries: dict[tuple, tuple[list[weakref.ref], list[tuple], np.ndarray]] = {}

    def _known(self, a: np.ndarray) -> bool:
        ref = self._seen.get(id(a))
        return ref is not None and ref() is a

    def _note(self, a: np.ndarray) -> None:
        if self._known(a):
            return
        key = id(a)

        def gone(ref: weakref.ref, key: int = key) -> None:
            if self._seen.get(key) is ref:
                del self._seen[key]
            for k in [k for k, e in self._entries.items() if any(r is ref for r in e[0])]:
                del self._entries[k]

        self._seen[key] = weakref.ref(a, gone)

    def runs(self, arrays: Sequence[np.ndarray], components: Sequence[int],
             formats: Sequence[tuple], shareable: Sequence[bool], starts: Sequence[int],
             widths: Sequence[int], rows: int) -> list[Run]:
        """Return the runs of adjacent shareable columns whose arrays were seen before.

        Every array is noted as seen.  ``arrays[j]`` is column ``j``'s array as the
        dataset holds it, ``formats[j]`` everything else its text depends on.
        """
        out: list[Run] = []
        j, n = 0, len(arrays)
        while j < n:
            if not (shareable[j] and self._known(arrays[j])):
                j += 1
                continue
            k = j
            while k < n and shareable[k] and self._known(arrays[k]):
                k += 1
            key = (rows, tuple((id(arrays[i]), components[i], formats[i]) for i in range(j, k)))
            lo, hi = starts[j], starts[k - 1] + widths[k - 1]
            run_arrays = list({id(a): a for a in arrays[j:k]}.values())  # each once
            text = self._lookup(key, run_arrays)
            if text is None:
                out.append(Run(j, k, lo, hi, key, np.empty((rows, hi - lo), np.uint8), False,
                               run_arrays))
            else:
                out.append(Run(j, k, lo, hi, key, text, True))
            j = k
        for a in arrays:
            self._note(a)
        return out

    def _lookup(self, key: tuple, arrays: Sequence[np.ndarray]) -> np.ndarray | None:
        """Return the kept bytes of ``key``; ``arrays``: the run's arrays, each once."""
        entry = self._entries.get(key)
        if entry is None:
            return None
        refs, prints, text = entry
        same = len(refs) == len(arrays) and all(
            r() is a and fingerprint(a) == f
            for r, a, f in zip(refs, arrays, prints, strict=True))
        if not same:  # changed in place since: format again
            del self._entries[key]
            return None
        return text

    def keep(self, run: Run) -> None:
        """Keep a run's bytes, filled while its table was written completely."""
        if MAX_ENTRIES <= 0:  # sharing switched off
            return
        while len(self._entries) >= MAX_ENTRIES:
            self._entries.pop(next(iter(self._entries)))
        refs = [self._seen[id(a)] for a in run.arrays]
        self._entries[run.key] = (refs, [fingerprint(a) for a in run.arrays], run.text)


#: The process's shared fields (used by `fluxcal.products.tab.write_tab`).
SHARED = SharedFields()
