"""Which level is heater-off: evidence pooled over the stretches of one heater configuration.

`fluxcal.cleaning.steps.remove_heater_steps` cleans one gap-free stretch and reads the
heater sign (which of the two levels of a square wave is "off") from that stretch alone
(`fluxcal.cleaning.steps.heater_off_segments`).  A stretch whose heater current is
constant cannot tell: its two levels are symmetric.  Over several stretches the data
can: the background field is continuous from one stretch to the next, so at the border
of two stretches of *different* currents the off level is the one common to both, and
only the right sign leaves the cleaned field continuous across the border.  Stretches
whose heater fields point the same way (one configuration) share the sign: a sign read
by a rule in one of them serves the others; otherwise the borders decide.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12, 4.12.1 (heaters of different currents,
   "flatten all the infected levels"); the pooling is a fluxcal decision
   (docs/decisions/cleaning.md, issue 31).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from fluxcal.cleaning.steps import StepRemovalResult

#: Stretches whose disturbance axes are closer than this (|cos|) share a configuration.
SAME_CONFIGURATION_COS = 0.95
#: The border evidence decides when one sign's squared border steps sum to less than this
#: fraction of the other's (the rule-2 ratio of `heater_off_segments`).
BORDER_RATIO = 0.35
#: A rule of `heater_off_segments` that did not decide.
UNDECIDED_RULE = "first segment"

#: ``rerun(k, direction, sign)``: stretch ``k`` cleaned with that direction and sign.
Rerun = Callable[[int, NDArray[np.float64], int], StepRemovalResult]


def border_step(t_a: NDArray[np.float64], u_a: NDArray[np.float64], t_b: NDArray[np.float64],
                u_b: NDArray[np.float64], samples: int) -> float:
    """Step of a series from one stretch to the next: ``u_b - u_a`` at the border.

    Where ``b`` begins inside ``a`` (a mode whose filter delay differs: its first vectors
    overlap the previous mode's last ones) and at least ``samples`` of its vectors lie in
    the overlap, the median difference of ``b`` and ``a`` interpolated to ``b``'s times
    there; otherwise the last ``samples`` vectors of ``a`` and the first of ``b`` are
    fitted with a common level and slope in time plus a step for ``b`` (few samples: a
    red background wanders with the distance from the border, as for the jump heights
    of `fluxcal.cleaning.steps.remove_heater_steps`).
    """
    inside = (t_b >= t_a[0]) & (t_b <= t_a[-1])
    if np.count_nonzero(inside) >= samples:
        return float(np.median(u_b[inside] - np.interp(t_b[inside], t_a, u_a)))
    t = np.concatenate([t_a[-samples:], t_b[:samples]])
    u = np.concatenate([u_a[-samples:], u_b[:samples]])
    step = np.concatenate([np.zeros(min(samples, t_a.size)), np.ones(min(samples, t_b.size))])
    design = np.column_stack([np.ones_like(t), t - t_a[-1], step])
    return float(np.linalg.lstsq(design, u, rcond=None)[0][2])


def _configurations(directions: Sequence[NDArray[np.float64]]) -> list[list[int]]:
    """Group stretch indices whose disturbance axes agree (`SAME_CONFIGURATION_COS`)."""
    groups: list[list[int]] = []
    for k, e in enumerate(directions):
        for g in groups:
            if abs(float(directions[g[0]] @ e)) >= SAME_CONFIGURATION_COS:
                g.append(k)
                break
        else:
            groups.append([k])
    return groups


def pool_heater_signs(
    times_s: Sequence[NDArray[np.float64]],
    values: Sequence[NDArray[np.float64]],
    results: Sequence[StepRemovalResult],
    rerun: Rerun,
    *,
    max_gap_s: float = 1.0,
    samples: int = 5,
) -> list[StepRemovalResult]:
    """Decide the heater sign of undecided stretches from the other stretches.

    Parameters
    ----------
    times_s : sequence of ndarray
        Sample times (s, any origin common to all) of each stretch, increasing.
    values : sequence of ndarray (n_k, 3)
        The stretches' uncleaned vectors.
    results : sequence of StepRemovalResult
        Each stretch cleaned on its own (`remove_heater_steps`).
    rerun : callable
        ``rerun(k, direction, sign)`` cleans stretch ``k`` with a given disturbance
        direction and heater sign.
    max_gap_s : float
        Borders between stretches further apart than this are not compared: the
        background moves over a gap (a red f^-2 background of 1e-3 nT^2/Hz at 1 Hz
        by 0.2 nT in 2 s).
    samples : int
        Vectors on each side of a border in its step fit (`border_step`).

    Returns
    -------
    list of StepRemovalResult
        The results; an undecided stretch (rule ``"first segment"``) of a configuration
        in which other stretches decided by a rule takes their sign (rule ``"pooled:
        <rule> of k stretch(es)"``); else, when the borders between the stretches of
        the configuration decide, the sign that leaves the cleaned field continuous
        (rule ``"pooled: continuity over k border(s)"``); else it is left as it was.
    """
    out = list(results)
    memo: dict[tuple[int, int], StepRemovalResult] = {}

    def cleaned_with(k: int, direction: NDArray[np.float64], sign: int) -> StepRemovalResult:
        if (k, sign) not in memo:  # one direction per configuration
            memo[k, sign] = rerun(k, direction, sign)
        return memo[k, sign]

    jumped = [k for k, r in enumerate(results) if r.jump_indices.size]
    for group in _configurations([results[k].direction for k in jumped]):
        members = [jumped[i] for i in group]
        ref = results[members[0]].direction
        # sign along the configuration's reference axis
        along = {k: results[k].heater_sign * (1 if float(results[k].direction @ ref) >= 0
                                              else -1) for k in members}
        undecided = [k for k in members if results[k].off_rule.startswith(UNDECIDED_RULE)]
        decided = [k for k in members if k not in undecided]
        if not undecided:
            continue
        sign, rule = 0, ""
        if decided:
            vote = int(np.sign(sum(along[k] for k in decided)))
            if vote:
                sign = vote
                rules = sorted({results[k].off_rule.split(" (")[0] for k in decided})
                rule = f"pooled: {', '.join(rules)} of {len(decided)} stretch(es)"
        if not sign:
            sign, n_borders = _border_sign(times_s, results, members, undecided, ref,
                                           cleaned_with, max_gap_s, samples)
            rule = f"pooled: continuity over {n_borders} border(s)"
        if not sign:
            continue
        for k in undecided:
            out[k] = replace(cleaned_with(k, ref, sign), off_rule=rule)
    return out


def _border_sign(times_s, results, members, undecided, ref, rerun, max_gap_s,
                 samples) -> tuple[int, int]:
    """Return the undecided stretches' sign that keeps the borders continuous (0: none)."""
    order = sorted(members, key=lambda k: float(times_s[k][0]))
    pairs = [(a, b) for a, b in zip(order[:-1], order[1:], strict=True)
             if float(times_s[b][0]) - float(times_s[a][-1]) <= max_gap_s
             and (a in undecided or b in undecided)]
    if not pairs:
        return 0, 0
    cleaned: dict[tuple[int, int], NDArray[np.float64]] = {}
    for k in {k for pair in pairs for k in pair}:
        for sign in (1, -1):
            if k in undecided:
                cleaned[k, sign] = rerun(k, ref, sign).values @ ref
            else:
                cleaned[k, sign] = results[k].values @ ref
    cost = {}
    for sign in (1, -1):
        cost[sign] = sum(border_step(times_s[a], cleaned[a, sign], times_s[b],
                                     cleaned[b, sign], samples) ** 2 for a, b in pairs)
    lo, hi = sorted(cost, key=cost.get)
    if cost[lo] < BORDER_RATIO * cost[hi]:
        return lo, len(pairs)
    return 0, len(pairs)
