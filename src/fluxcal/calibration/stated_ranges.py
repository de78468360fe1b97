"""The ranges over which a fitted calibration states its law: one or more closed intervals.

A fitted law is determined only where its data determine it; the table states where
(e.g. a ``T_RANGE`` header line) and calibrating a sample outside warns.  The
determined part of an axis need not be one span: a sensor held at one temperature by a
heater and warmed in excursions gives a well-determined regulated point and a
well-determined warm stretch with a poorly determined gap between them.
`StatedRanges` is that set, with the one test of "inside" every user applies
(`StatedRanges.contains`), its header text (``lo hi`` pairs separated by commas: a
single interval reads as the two numbers of the older one-interval form) and its
parser.

References
----------
.. [1] docs/decisions/messenger_fit.md, entry 24 (T_RANGE as a set of intervals).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

__all__ = ["StatedRanges"]


@dataclass(frozen=True)
class StatedRanges:
    """Disjoint closed intervals ``[lo, hi]``, in increasing order.

    Parameters
    ----------
    intervals : tuple of (float, float)
        Finite, ``lo < hi``, each starting above the previous one's end (touching
        intervals are merged by `from_bins`, refused here).

    Raises
    ------
    ValueError
        Intervals that are not finite, empty, unordered or overlapping.
    """

    intervals: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        pairs = tuple((float(lo), float(hi)) for lo, hi in self.intervals)
        if not pairs:
            raise ValueError("no interval")
        for k, (lo, hi) in enumerate(pairs):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"interval {lo:g} {hi:g}: needs two finite numbers, low "
                                 "below high")
            if k and not pairs[k - 1][1] < lo:
                raise ValueError(f"interval {lo:g} {hi:g} does not start above the end of "
                                 f"the one before ({pairs[k - 1][1]:g}): give the intervals "
                                 "in increasing order, not overlapping")
        object.__setattr__(self, "intervals", pairs)

    @classmethod
    def of(cls, value: StatedRanges | Iterable[float] | Iterable[Iterable[float]]
           ) -> StatedRanges:
        """Return ``value`` as `StatedRanges`: itself, one ``(lo, hi)`` or several pairs."""
        if isinstance(value, cls):
            return value
        items = list(value)
        if len(items) == 2 and all(np.ndim(v) == 0 for v in items):
            return cls(((items[0], items[1]),))
        return cls(tuple(tuple(v) for v in items))

    @classmethod
    def from_bins(cls, edges: np.ndarray, inside: np.ndarray) -> StatedRanges | None:
        """Return the union of the bins ``[edges[i], edges[i + 1]]`` where ``inside[i]``.

        None where no bin is inside.

        Adjacent bins merge into one interval.
        """
        edges = np.asarray(edges, dtype=float)
        ok = np.asarray(inside, dtype=bool)
        if not ok.any():
            return None
        d = np.diff(np.concatenate(([0], ok.astype(np.int8), [0])))
        starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
        return cls(tuple((edges[a], edges[b]) for a, b in zip(starts, ends, strict=True)))

    @classmethod
    def parse(cls, text: str) -> StatedRanges:
        """Read the header text: ``lo hi`` pairs separated by commas (``-50 -49, 2 40``).

        Two numbers separated by a comma (``lo, hi``) are one interval, as the older
        one-interval form read them.

        Raises
        ------
        ValueError
            Not pairs of numbers, or intervals `StatedRanges` refuses; the message says
            what is wrong.
        """
        parts = str(text).split(",")
        if len(parts) == 2 and all(len(p.split()) == 1 for p in parts):
            parts = [" ".join(parts)]
        pairs = []
        for part in parts:
            words = part.split()
            try:
                numbers = [float(w) for w in words]
            except ValueError:
                numbers = []
            if len(numbers) != 2:
                raise ValueError(f"{part.strip()!r} is not two numbers LOW HIGH")
            pairs.append((numbers[0], numbers[1]))
        return cls(tuple(pairs))

    @property
    def span(self) -> tuple[float, float]:
        """``(lo, hi)`` from the first interval's start to the last one's end."""
        return self.intervals[0][0], self.intervals[-1][1]

    def contains(self, x: np.ndarray | float) -> np.ndarray:
        """Boolean array: ``x`` lies in one of the intervals (ends included); NaN does not."""
        x = np.asarray(x, dtype=float)
        out = np.zeros(x.shape, dtype=bool)
        for lo, hi in self.intervals:
            out |= (x >= lo) & (x <= hi)
        return out

    def distance(self, x: np.ndarray | float) -> np.ndarray:
        """How far ``x`` lies outside (0 inside): to the nearest interval's end."""
        x = np.asarray(x, dtype=float)
        d = np.full(x.shape, np.inf)
        for lo, hi in self.intervals:
            d = np.minimum(d, np.maximum(lo - x, 0.0) + np.maximum(x - hi, 0.0))
        return d

    def header_text(self) -> str:
        """``lo hi`` pairs joined by ``", "`` (`parse` reads it back exactly)."""
        return ", ".join(f"{lo!r} {hi!r}" if not float(lo).is_integer()
                         or not float(hi).is_integer() else f"{lo:g} {hi:g}"
                         for lo, hi in self.intervals)

    def __format__(self, spec: str) -> str:
        """``lo..hi`` per interval joined by ``", "``, each number in ``spec`` (``.1f``)."""
        spec = spec or "g"
        return ", ".join(f"{lo:{spec}}..{hi:{spec}}" for lo, hi in self.intervals)

    def __str__(self) -> str:
        """``lo..hi`` per interval, joined by ``", "`` (for messages)."""
        return format(self, "g")
