"""Stage 1 of the assisted heater removal: heater states and disturbed intervals.

Method 2 of seed 003 (sec. 4.12.2) is a two-stage procedure: first all
disturbed times are identified in the data of a sensor next to the heaters (the lander
magnetometer ROMAP, disturbed by 1000-2000 nT) and assigned to the activated heaters;
then the RPC-MAG offsets are removed in those intervals
(`fluxcal.cleaning.steps.remove_labelled_offsets`, the second stage).

* `states_from_steps` identifies the heater states from such a strongly disturbed
  series, given each heater's field change at that sensor (its signature): every jump
  is decomposed into the heaters switched on and off, and the states follow from the
  jumps alone, whatever the signs of the signatures.
* `intervals_from_states` turns a heater-state series (from `states_from_steps`, or
  heater housekeeping) into the labelled intervals of the second stage.

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1),
   sec. 4.12.2 (heater disturbance elimination, method 2).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fluxcal.errors import InputFormatError

__all__ = ["HeaterStates", "intervals_from_states", "states_from_steps"]

#: Most heaters decomposed jointly (3**k switch patterns are tried per jump).
MAX_HEATERS = 8


def intervals_from_states(
    times: ArrayLike,
    states: ArrayLike,
    names: Sequence[str] | None = None,
    *,
    stop: float | int | None = None,
) -> list[tuple[float | int, float | int, str]]:
    """Labelled disturbed intervals from a heater-state series.

    Parameters
    ----------
    times : array_like, shape (n,)
        Strictly increasing sample times (any numeric scale, e.g. TT2000 ns).
    states : array_like, shape (n,) or (n, k)
        On/off state of each heater at each sample (non-zero = on).
    names : sequence of str, optional
        Heater names (default ``H1 .. Hk``).
    stop : number, optional
        End of the last sample's state (default: last time plus the last spacing).

    Returns
    -------
    list of (start, stop, label)
        One interval per maximal run of samples with the same non-empty set of active
        heaters: ``start`` = time of the run's first sample, ``stop`` = time of the
        next run's first sample (the state holds until it is next seen to change);
        ``label`` = the active heaters' names joined by ``+``.

    Raises
    ------
    InputFormatError
        Shape mismatch, non-increasing times or wrong number of names.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12.2 (first stage).

    Examples
    --------
    >>> intervals_from_states([0, 1, 2, 3, 4], [[0, 0], [1, 0], [1, 1], [1, 1], [0, 0]])
    [(1, 2, 'H1'), (2, 4, 'H1+H2')]
    """
    t = np.asarray(times)
    s = np.asarray(states)
    if s.ndim == 1:
        s = s[:, None]
    if t.ndim != 1 or s.ndim != 2 or s.shape[0] != t.size:
        raise InputFormatError(
            f"times {t.shape} and states {np.shape(states)} do not match", field="states"
        )
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise InputFormatError("times must be strictly increasing", field="times")
    k = s.shape[1]
    labels = [f"H{j + 1}" for j in range(k)] if names is None else [str(x) for x in names]
    if len(labels) != k:
        raise InputFormatError(f"{len(labels)} names for {k} heaters", field="names")
    if t.size == 0:
        return []
    on = s != 0
    code = on.astype(np.int64) @ (1 << np.arange(k, dtype=np.int64))  # active set
    first = np.flatnonzero(np.concatenate([[True], code[1:] != code[:-1]]))
    if stop is None:
        if t.size < 2:
            raise InputFormatError("a single sample needs the end of its state", field="stop")
        stop = t[-1] + (t[-1] - t[-2])
    ends = np.concatenate([t[first[1:]], [stop]])
    out = []
    for i, end in zip(first, ends, strict=True):  # one entry per run, not per sample
        if code[i]:
            name = "+".join(lab for j, lab in enumerate(labels) if on[i, j])
            out.append((t[i].item(), np.asarray(end).item(), name))
    return out


@dataclass(frozen=True)
class HeaterStates:
    """Output of `states_from_steps`.

    Attributes
    ----------
    states : ndarray (n, k) of bool
        State of each heater at each sample.
    names : list of str
        Heater names (order of ``states`` columns).
    jump_indices : ndarray (m,)
        First sample after each detected jump.
    switches : ndarray (m, k) of int
        +1 heater switched on, -1 off, 0 unchanged, per jump.
    misfit : ndarray (m,)
        Norm (nT) of the jump minus its decomposition, per jump.
    undetermined : list of str
        Heaters never switched in the series: their state is unknown from the jumps
        and taken as off throughout.
    """

    states: NDArray[np.bool_]
    names: list[str]
    jump_indices: NDArray[np.int64]
    switches: NDArray[np.int64]
    misfit: NDArray[np.float64]
    undetermined: list[str]


def states_from_steps(
    values: ArrayLike,
    signatures: Mapping[str, ArrayLike],
    *,
    threshold: float | None = None,
    max_misfit: float | None = None,
) -> HeaterStates:
    """Heater states from a series the heaters disturb strongly (e.g. ROMAP).

    Parameters
    ----------
    values : array_like, shape (n, 3)
        Field at the strongly disturbed sensor (nT), uniformly sampled, no gaps.
    signatures : mapping name -> (3,)
        Field change (nT, same frame) at that sensor when each heater switches on.
    threshold : float, optional
        A sample-to-sample change larger than this (nT, vector norm) is a jump.
        Consecutive ones are separate switches, unless one of them is no switch
        pattern (a transition sample of a filtered sensor): that run is then one
        jump from its first to its last sample.  Default: half the smallest
        signature norm.
    max_misfit : float, optional
        Largest allowed norm of (jump - best decomposition) (default: the threshold).

    Returns
    -------
    HeaterStates

    Raises
    ------
    InputFormatError
        On malformed input, more than `MAX_HEATERS` heaters, or a jump no switch
        pattern explains within ``max_misfit`` (names the sample).

    Notes
    -----
    Each jump ``d`` (field after minus before the run of large changes) is
    decomposed as ``S tau`` with ``tau`` in ``{-1, 0, 1}^k`` minimising
    ``|d - S tau|`` (all ``3^k`` patterns).  The state of heater ``j`` after jump
    ``m`` is ``s0_j + sum(tau_j[:m])``; since states are 0 or 1 the initial state is
    ``s0_j = -min(0, min(cumsum tau_j))``: no sign convention and no assumption on
    the state at the start are needed for a heater that switched at least once (a
    heater first seen switching off was on before).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12.2 (first stage: disturbed times from
       ROMAP, assigned to the activated heaters).
    """
    b = np.asarray(values, dtype=float)
    if b.ndim != 2 or b.shape[1] != 3 or not np.all(np.isfinite(b)):
        raise InputFormatError(f"expected finite (n, 3) values, got {b.shape}", field="values")
    names = [str(x) for x in signatures]
    if not 1 <= len(names) <= MAX_HEATERS:
        raise InputFormatError(
            f"{len(names)} heater signatures; 1 to {MAX_HEATERS} supported", field="signatures"
        )
    sig = np.stack([np.asarray(signatures[x], dtype=float).reshape(3) for x in signatures])
    norms = np.linalg.norm(sig, axis=1)
    if not np.all(norms > 0):
        raise InputFormatError("every heater signature must be non-zero", field="signatures")
    thr = 0.5 * float(norms.min()) if threshold is None else float(threshold)
    lim = thr if max_misfit is None else float(max_misfit)
    n, k = b.shape[0], len(names)
    step = np.linalg.norm(np.diff(b, axis=0), axis=1) > thr  # step[i]: between i and i+1
    patterns = np.array(list(itertools.product((-1, 0, 1), repeat=k)), dtype=np.int64)
    model = patterns @ sig  # (3^k, 3)

    def decompose(lo: NDArray[np.int64], hi: NDArray[np.int64]):
        d = b[hi] - b[lo]  # jump from sample lo (last before) to hi (first after)
        dist = np.linalg.norm(d[:, None, :] - model[None, :, :], axis=2)  # (m, 3^k)
        best = np.argmin(dist, axis=1) if d.shape[0] else np.zeros(0, np.int64)
        return d, best, dist[np.arange(d.shape[0]), best] if d.shape[0] else np.zeros(0)

    # every large step on its own (heaters switching on consecutive samples) ...
    run_lo = np.flatnonzero(step)
    run_hi = run_lo + 1
    d, best, misfit = decompose(run_lo, run_hi)
    # ... except runs of steps of which one is no switch pattern: transition samples
    # (a filtered sensor), the run is then one jump from its first to its last sample
    edges = np.diff(np.concatenate([[0], step.astype(np.int8), [0]]))
    r_lo, r_hi = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    run_of = np.searchsorted(r_lo, run_lo, side="right") - 1
    merge = np.zeros(r_lo.size, dtype=bool)
    np.logical_or.at(merge, run_of, misfit > lim)
    merge &= (r_hi - r_lo) > 1
    if merge.any():
        keep = ~merge[run_of]
        m_d, m_best, m_misfit = decompose(r_lo[merge], r_hi[merge])
        run_lo = np.concatenate([run_lo[keep], r_lo[merge]])
        run_hi = np.concatenate([run_hi[keep], r_hi[merge]])
        d = np.concatenate([d[keep], m_d])
        best = np.concatenate([best[keep], m_best])
        misfit = np.concatenate([misfit[keep], m_misfit])
        order = np.argsort(run_lo, kind="stable")
        run_lo, run_hi, d, best, misfit = (a[order] for a in (run_lo, run_hi, d, best, misfit))
    bad = np.flatnonzero(misfit > lim)
    if bad.size:
        i = int(run_hi[bad[0]])
        raise InputFormatError(
            f"jump before sample {i} ({np.round(d[bad[0]], 1).tolist()} nT) is no "
            f"combination of the heater signatures (misfit {misfit[bad[0]]:.1f} nT > "
            f"{lim:.1f} nT)",
            field="values",
        )
    tau = patterns[best]  # (m, k)
    level = np.concatenate([np.zeros((1, k), np.int64), np.cumsum(tau, axis=0)])  # (m+1, k)
    s0 = -np.minimum(level.min(axis=0), 0)
    state = level + s0
    if np.any(state > 1):
        j = int(np.flatnonzero((state > 1).any(axis=0))[0])
        raise InputFormatError(
            f"heater {names[j]} switched on twice without switching off: the signatures "
            "do not explain the jumps",
            field="signatures",
        )
    switched = (tau != 0).any(axis=0)
    undetermined = [x for j, x in enumerate(names) if not switched[j]]
    segment = np.searchsorted(run_hi, np.arange(n), side="right")
    return HeaterStates(
        states=state[segment].astype(bool),
        names=names,
        jump_indices=run_hi.astype(np.int64),
        switches=tau,
        misfit=misfit,
        undetermined=undetermined,
    )
