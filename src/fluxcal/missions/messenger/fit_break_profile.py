"""T_m's error from the residual's profile against the break (opt-in; not the fit's).

For each axis with a free break, the exact residual of the variance estimator's normal
equations (`fluxcal.missions.messenger.fit_variance`) is profiled against the break placed
continuously over the shifts the fit tries (`fit_breaks.break_profile`, every other
parameter re-fitted); the break's interval is where the profile lies within one standard
error's rise of its least, at the resampling units' cluster-robust scale
(`fit_breaks.profile_threshold`, `fit_variance.resampling_units`), second minima inside
it kept (`fit_breaks.profile_interval`).  Measured on the saved fits it stated breaks
0.8-2.4 C off at 0.23-0.37 C, so the fit keeps the pairs bootstrap's errors and only
``benchmarks/messenger_fit_pulls.py --summarise DIR --profile`` calls
`profile_break_errors`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3-4 (the two-segment law and
   its break T_m).
.. [2] docs/decisions/messenger_fit.md entry 51; docs/decisions/messenger_fit_verification.md
   section 45.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    PER_AXIS,
    break_layout,
    break_profile,
    choice_shifts_c,
    fit_columns,
    profile_interval,
    profile_threshold,
)
from fluxcal.missions.messenger.fit_variance import (
    VarianceSettings,
    VarianceStatistics,
    resampling_units,
)

__all__ = ["PROFILE_POINTS", "PROFILE_REFINE", "PROFILE_STEP_C", "profile_break_errors"]


#: Step (C) of `profile_break_errors`' scan of the break; an interval narrower than
#: `PROFILE_POINTS` steps is scanned again about itself at a step of 1 / `PROFILE_POINTS`
#: of its width, at most `PROFILE_REFINE` times (a break known to +- 0.01 C).
PROFILE_STEP_C = 0.05
PROFILE_POINTS = 20
PROFILE_REFINE = 3


def profile_break_errors(stats: VarianceStatistics, law: np.ndarray,
                         held: Mapping[int, tuple[float, float]] | None = None,
                         fit_delay: bool = True, choice: tuple[int, int, int] = (-1, -1, -1),
                         fitted_c: np.ndarray | None = None,
                         step_c: float = PROFILE_STEP_C) -> dict[str, np.ndarray]:
    """Return the breaks' errors from the residual's profile against the break (opt-in).

    Per axis with a free break: the exact residual with the break placed continuously over
    the shifts `solve_variance` tries inside the data's range (`fit_breaks.break_profile`,
    every ``step_c``), the interval where it lies within one standard error's rise of its
    least (`fit_breaks.profile_threshold`: the cluster-robust scale of the resampling
    units, widened by ``sqrt(n / (n - p))`` as the bootstrap is), a second minimum inside
    it kept (`fit_breaks.profile_interval`), and the break's error the larger distance
    from the fitted break to the interval's ends (docs/decisions/messenger_fit.md entry
    51).

    Parameters
    ----------
    stats : VarianceStatistics
        Reduced at ``law``.
    law : ndarray, shape (3, 4)
        The linearisation point (`law_parameters` of the table ``stats`` was reduced with).
    held : mapping, optional
        `solve_variance`'s ``held`` (column -> (step, width); the widths not read).
    fit_delay : bool
    choice : tuple of int
        The solution's break choices (`choose_breaks`).
    fitted_c : ndarray, shape (3,), optional
        The fitted breaks' offsets from ``law[:, 3]`` (C); default the solution's at
        ``choice`` (a shift, or the linearised step).
    step_c : float

    Returns
    -------
    dict
        ``error`` (3,) C, ``lo``, ``hi`` (3,) the interval's ends (C from ``law[:, 3]``),
        ``closed`` (3, 2) whether each end lies inside the scan, ``threshold`` (3,),
        ``fitted`` (3,); NaN (False) on an axis whose break is held.
    """
    base_free = np.ones(N_PARAMETERS, dtype=bool)
    base_free[-1] = fit_delay
    fixed = np.zeros(N_PARAMETERS)
    for col, (value, _) in (held or {}).items():
        base_free[int(col)] = False
        fixed[int(col)] = value
    total_a, total_v = stats.normal.sum(axis=0), stats.rhs.sum(axis=0)
    yy = float(stats.yy.sum())
    free, fx = break_layout(tuple(choice), base_free, law[:, 2])
    p_free = int(free.sum())
    if fitted_c is None:
        step = fit_columns(total_a, total_v, free, fx + fixed)
        fitted_c = np.array([choice_shifts_c(np.asarray(choice[j])) if choice[j] >= 0
                             else -step[j * PER_AXIS + 3] / law[j, 2] for j in range(3)])
    a_u, v_u, _ = resampling_units(stats.normal, stats.rhs, stats.yy, p_free)
    n = a_u.shape[0]
    widening = float(np.sqrt(n / (n - p_free)))
    lo_d, hi_d = stats.fitted_range(VarianceSettings().min_samples)
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    out = {k: np.full(3, np.nan) for k in ("error", "lo", "hi", "threshold")}
    out["closed"] = np.zeros((3, 2), dtype=bool)
    out["fitted"] = np.asarray(fitted_c, dtype=float)
    for j in range(3):
        if not base_free[j * PER_AXIS + 3]:
            continue  # a held break keeps its held width
        ok = grid[(grid == 0.0) | ((lo_d <= law[j, 3] + grid) & (law[j, 3] + grid <= hi_d))]
        s = np.union1d(np.arange(ok[0], ok[-1] + 0.5 * step_c, step_c), ok)
        s = s[(s >= ok[0]) & (s <= ok[-1])]
        r = break_profile(total_a, total_v, yy, base_free, law, choice, j, s, fixed)
        thr = profile_threshold(a_u, v_u, base_free, law, choice, j, fixed, widening)
        lo, hi, c_lo, c_hi = profile_interval(s, r, thr)
        step = step_c
        for _ in range(PROFILE_REFINE):  # an interval a few steps wide: scanned finer
            if hi - lo >= PROFILE_POINTS * step:
                break
            step = max(hi - lo, step) / PROFILE_POINTS
            fine = np.arange(lo - step_c, hi + step_c, step)
            fine = fine[(fine > s[0]) & (fine < s[-1])]
            s, order = np.unique(np.r_[s, fine], return_index=True)
            r = np.r_[r, break_profile(total_a, total_v, yy, base_free, law, choice, j,
                                       fine, fixed)][order]
            lo, hi, c_lo, c_hi = profile_interval(s, r, thr)
        f = float(out["fitted"][j])
        out["error"][j] = max(hi - f, f - lo, 0.0)
        out["lo"][j], out["hi"][j], out["threshold"][j] = lo, hi, thr
        out["closed"][j] = c_lo, c_hi
    return out
