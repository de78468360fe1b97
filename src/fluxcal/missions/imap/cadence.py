"""IMAP MAG vector rates read from the time tags: the nominal rate of each interval.

The instrument samples at 1, 2, 4 ... 128 vectors per second; the L1B of the team's CSVs
and of fluxcal carries no declared rate, so L1C (`fluxcal.missions.imap.l1c`) and the
team's ``vectors_per_second`` attribute (`fluxcal.missions.imap.team_layout`) take it
from the spacing of the time tags, within the team's 7.5 % clock-drift tolerance.

References
----------
IMAP MAG L1C gap tolerance (7.5 %) and vector rates as in the IMAP Science Operations
Center's public ``imap_processing`` (``mag/constants.py``); docs/decisions/imap.md.
"""

from __future__ import annotations

import numpy as np

#: Vector rates the instrument can be commanded to (vectors per second).
NOMINAL_RATES = np.array([1, 2, 4, 8, 16, 32, 64, 128])
#: A spacing up to 7.5 % longer than ``1 / rate`` is clock drift, not a gap.
GAP_TOLERANCE = 0.075
#: A cadence must hold for this many consecutive intervals to count as a rate change.
MIN_RUN = 4
SEC = 1_000_000_000


def interval_rates(epoch: np.ndarray) -> np.ndarray:
    """Vector rate that holds over each interval ``epoch[i] .. epoch[i+1]`` (n-1 values).

    An interval matches a nominal rate when its length is within `GAP_TOLERANCE` of
    ``1 / rate``; a run of at least `MIN_RUN` intervals of one rate sets the rate; every
    other interval (a gap, or a short run such as one missed vector) takes the rate of the
    run before it (the first run for intervals before any run; 2 per second without any).
    """
    d = np.diff(np.asarray(epoch, dtype=np.int64)).astype(np.float64)
    if d.size == 0:
        return np.zeros(0, dtype=np.int64)
    cls = nominal_rate(d)
    start = np.r_[0, np.flatnonzero(np.diff(cls)) + 1]
    length = np.diff(np.r_[start, cls.size])
    good = (cls[start] > 0) & (length >= MIN_RUN)
    run_rate = np.where(good, cls[start], 0)
    if not good.any():
        return np.full(cls.size, 2, dtype=np.int64)
    # forward-fill the accepted run rates, back-fill before the first one
    idx = np.where(good, np.arange(start.size), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = np.flatnonzero(good)[0]
    return np.repeat(run_rate[idx], length).astype(np.int64)


def nominal_rate(d: np.ndarray) -> np.ndarray:
    """Nominal rate whose period ``d`` (ns, float) is within `GAP_TOLERANCE`, else 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.clip(np.rint(np.log2(SEC / np.maximum(d, 1.0))), 0, 7)
    rate = np.exp2(k).astype(np.int64)
    period = SEC / rate
    return np.where(np.abs(d - period) <= GAP_TOLERANCE * period, rate, 0)
