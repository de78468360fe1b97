"""Where the samples are: the spans an interpolation grid covers, split at long gaps.

The interpolated positions (`fluxcal.geometry.positions.StateInterpolator`), rotations
(`fluxcal.geometry.frames.Rotator`) and sec. 10.2 angles (`fluxcal.geometry.axes`) look
SPICE up on a grid of nodes.  A grid from the first to the last sample asks the kernels
about every instant between them: two files of one run months apart (a clock reset, an
instrument off) ask about the months in between, which the kernels the user gave need not
cover, and place millions of nodes there.  The grid is therefore laid over each *span* of
samples (`sample_spans`: consecutive samples no more than `BRIDGED_GAP_S` apart) and never
over a gap between spans; no node lies in such a gap, and no interval across one is
checked (no sample falls in it, so its interpolant is never used).
"""

from __future__ import annotations

import numpy as np

#: Longest gap (s) between consecutive samples that one interpolation grid bridges.  Ten
#: minutes: above the first grid steps of the positions (300 s) and the rotations
#: (600 s), so a run without longer gaps is covered by one grid exactly as before.
BRIDGED_GAP_S = 600.0


def sample_spans(et: np.ndarray, max_gap: float = BRIDGED_GAP_S) -> np.ndarray:
    """Return the spans of the samples, shape (k, 2): ``[first, last]`` ET of each.

    Consecutive samples (in time order) more than ``max_gap`` seconds apart start a new
    span.  A lone sample is a span of zero length.

    Examples
    --------
    >>> sample_spans(np.array([5.0, 0.0, 10.0, 2000.0, 2001.0]))
    array([[   0.,   10.],
           [2000., 2001.]])
    """
    t = np.asarray(et, dtype=float).ravel()
    if t.size == 0:
        return np.empty((0, 2))
    if not (t[1:] >= t[:-1]).all():  # a run is nearly always in time order: no sort then
        t = np.sort(t)
    cut = np.flatnonzero(np.diff(t) > max_gap)
    return np.column_stack([t[np.r_[0, cut + 1]], t[np.r_[cut, t.size - 1]]])


def span_grid(spans: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Return grid nodes over every span (at most ``step`` apart) and the inner intervals.

    Each span ``[a, b]`` gets ``ceil((b - a) / step) + 1`` equally spaced nodes (one node
    for a span of zero length); the nodes of all spans are concatenated in time order.

    Returns
    -------
    nodes : ndarray, shape (m,)
        Increasing node times.
    inner : ndarray of bool, shape (m - 1,)
        Whether interval ``i`` (``nodes[i]`` to ``nodes[i + 1]``) lies inside a span;
        False for an interval across a gap between spans.
    """
    pieces = [np.linspace(a, b, max(int(np.ceil((b - a) / step)), 1) + 1) if b > a
              else np.array([a]) for a, b in np.asarray(spans, dtype=float)]
    nodes = np.concatenate(pieces) if pieces else np.empty(0)
    owner = np.repeat(np.arange(len(pieces)), [p.size for p in pieces])
    return nodes, owner[:-1] == owner[1:]


def intervals_with_samples(nodes: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """Return, per interval of ``nodes``, whether samples lie inside it.

    True where the open interval overlaps a span of samples.  Any other interval holds
    at most a sample at one of its ends, where the interpolant takes the node's exact
    value: it needs no check (nor any SPICE call at its mid-point, which may lie in a
    gap the kernels do not cover).
    """
    spans = np.asarray(spans, dtype=float)
    lo, hi = nodes[:-1], nodes[1:]
    # the first span ending after the interval's start must begin before its end
    k = np.searchsorted(spans[:, 1], lo, side="right")
    inside = k < spans.shape[0]
    inside[inside] = spans[k[inside], 0] < hi[inside]
    return inside
