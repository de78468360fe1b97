"""Break choice and resampling of the MESSENGER variance fit (issue 34, estimator ``variance``).

The parameter columns of `fluxcal.missions.messenger.fit_variance`'s normal equations
(the Table 2 two-segment law of each axis, eq. 3-4, with its break T_m; D0, tau and dt,
eq. 5-6) and how they are solved for given break choices: the layout of the columns
(`PER_AXIS`, the hinge columns at the shifted breaks `BREAK_SHIFTS_C`, `N_PARAMETERS`)
and its least-squares solve (`solve_step`); the break of each axis at the shift of least
residual (`choose_breaks`, docs/decisions/messenger_fit.md entries 17 and 27); and the
bootstrap's resamples (`fit_variance.solve_variance` drives them):

* each resample chooses its own breaks and is solved with them (`resample_fits`, one
  batched solve per number of free columns; entries 39 and 40);
* a resample whose break moved to a grid shift is placed inside that shift's cell, on its
  own data (`refine_breaks`, entries 42 and 47), or drawn uniformly over the cell
  (`quantisation`, entry 27); the solution's own distance from its grid point is counted
  in every resample (`solution_distance`, entry 47);
* the units' scores resampled with the whole data's design kept, opt-in
  (`fixed_design_resamples`, entry 41);
* the wild cluster bootstrap: each unit's residual sign-flipped (or Webb-weighted) about
  the fit, the design kept, the breaks chosen again on that world, opt-in
  (`wild_weights`, `wild_resamples`, entry 50);
* the residual profiled against one axis's break placed anywhere on the shift grid's
  span, and the likelihood-ratio interval it gives at the units' cluster-robust scale,
  opt-in (`break_profile`, `profile_threshold`, `profile_interval`; entry 51).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 2-7 (the offset laws whose
   parameters are fitted: Table 2, eq. 3-4; D0, tau, dt, eq. 5-6).
.. [2] docs/decisions/messenger_fit.md entries 17, 27, 39, 40, 41, 42, 47, 50 and
   51.
.. [3] Cameron, A. C., Gelbach, J. B. and Miller, D. L., Rev. Econ. Stat. 90, 414-427
   (2008) (the wild cluster bootstrap); Webb, M. D., Can. J. Econ. 56, 1-23 (2023)
   (the six-point weights).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fluxcal.errors import FluxcalError

__all__ = ["BREAK_SHIFTS_C", "N_PARAMETERS", "WILD_WEIGHTS", "break_layout", "break_profile",
           "choice_shifts_c", "choose_breaks", "fit_columns", "fixed_design_resamples",
           "profile_interval", "profile_threshold", "quantisation",
           "refine_breaks", "resample_fits", "residual_sum", "shift_column",
           "solution_distance", "solve_step", "wild_resamples", "wild_weights"]

#: Per axis: d(a), d(b) (counts per C), d(c) (hinge slope), -c d(T_m), d(D0); then per
#: axis the hinge slopes at the shifted breaks (`BREAK_SHIFTS_C`); then the shared
#: d(tau) and d(dt).
PER_AXIS = 5
#: Shifts (C) of the break tried besides the linearised step (entry 17): the shipped
#: breaks can be several degrees off (the true y break of the flight model: +5 C).
BREAK_SHIFTS_C = (-8.0, -4.0, -2.0, -1.0, -0.5, 0.5, 1.0, 2.0, 4.0, 8.0)
N_SHIFTS = len(BREAK_SHIFTS_C)
N_PARAMETERS = 3 * PER_AXIS + 3 * N_SHIFTS + 2
#: The wild bootstrap's weight distributions (`wild_weights`): mean 0, variance 1.
#: Rademacher: +-1, half each; Webb's six points: +-sqrt(1/2), +-1, +-sqrt(3/2), a sixth
#: each (more distinct resamples where the units are few, Webb 2023).
WILD_WEIGHTS = {"rademacher": np.array([-1.0, 1.0]),
                "webb": np.array([-np.sqrt(1.5), -1.0, -np.sqrt(0.5),
                                  np.sqrt(0.5), 1.0, np.sqrt(1.5)])}


def shift_column(axis: int, k: int) -> int:
    """Index of axis ``axis``'s hinge column at the break shifted by BREAK_SHIFTS_C[k]."""
    return 3 * PER_AXIS + axis * N_SHIFTS + k


def break_layout(shift: tuple[int, ...], base_free: np.ndarray,
            slope: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Free columns and fixed values for break choices ``shift`` (-1: linearised step).

    An axis moved to shift ``k`` cancels its current hinge (its d(c) fixed at ``-c``)
    and fits the slope of the hinge at the shifted break; the linearised break step of
    that axis is not used.
    """
    free, fixed = _layout_rows(np.asarray([shift], dtype=np.int64), base_free, slope)
    return free[0], fixed[0]


def _layout_rows(choice: np.ndarray, base_free: np.ndarray,
                 slope: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`break_layout` of every row of ``choice`` (n, 3): free (n, p) and fixed (n, p)."""
    choice = np.asarray(choice, dtype=np.int64)
    n = choice.shape[0]
    rows = np.arange(n)
    free = np.broadcast_to(base_free, (n, N_PARAMETERS)).copy()
    fixed = np.zeros((n, N_PARAMETERS))
    free[:, 3 * PER_AXIS:3 * PER_AXIS + 3 * N_SHIFTS] = False
    for j in range(3):
        moved = choice[:, j] >= 0
        free[moved, j * PER_AXIS + 2] = free[moved, j * PER_AXIS + 3] = False
        fixed[moved, j * PER_AXIS + 2] = -slope[j]
        free[rows[moved], shift_column(j, choice[moved, j])] = True
    return free, fixed


def _fit_rows(a: np.ndarray, v: np.ndarray, free: np.ndarray,
              fixed: np.ndarray) -> np.ndarray:
    """`fit_columns` of a stack whose rows each have their own free columns (``free`` (n, p)).

    The rows are solved together, in one batch per number of free columns, each row's
    free block gathered as `fit_columns` takes it for that row alone (the same numbers, the
    same solver), instead of one call per distinct layout (issue 34, item 7).
    """
    theta = np.where(free, 0.0, fixed)
    out = theta.copy()
    n_free = free.sum(axis=1)
    for m in np.unique(n_free):
        rows = np.flatnonzero(n_free == m)
        idx = np.nonzero(free[rows])[1].reshape(rows.size, int(m))  # ascending per row
        a_rows = a[rows[:, None], idx]  # (rows, m, p): the free rows of each system
        rhs = (np.take_along_axis(v[rows], idx, axis=1)
               - np.einsum("...ij,...j->...i", a_rows, theta[rows]))
        aa = np.take_along_axis(a_rows, idx[:, None, :], axis=2)
        out[rows[:, None], idx] = _solve(aa, rhs)
    return out


def _solve(aa: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """Solve (stacks of) normal equations, scaled to unit diagonal."""
    d = np.sqrt(np.abs(np.diagonal(aa, axis1=-2, axis2=-1)))
    d = np.where(d > 0, d, 1.0)
    scaled = aa / (d[..., :, None] * d[..., None, :])
    sol = np.linalg.lstsq(scaled, vv / d, rcond=1e-12)[0] if aa.ndim == 2 else (
        np.linalg.solve(scaled + 1e-12 * np.eye(aa.shape[-1]), (vv / d)[..., None])[..., 0])
    return sol / d


def fit_columns(a: np.ndarray, v: np.ndarray, free: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Parameters (fixed ones at ``fixed``) minimising the residual of ``a``, ``v``.

    ``a``, ``v`` may be stacks (resamples); ``fixed`` broadcasts against ``v``.
    """
    theta = np.broadcast_to(fixed, (*v.shape[:-1], N_PARAMETERS)).copy()
    theta[..., free] = 0.0
    rhs = v[..., free] - np.einsum("...ij,...j->...i", a[..., free, :], theta)
    theta[..., free] = _solve(a[..., free][..., free, :], rhs)
    return theta


def residual_sum(a: np.ndarray, v: np.ndarray, yy: np.ndarray | float,
              theta: np.ndarray) -> np.ndarray:
    """Residual sum of squares of ``theta`` from the normal equations (stacks too)."""
    return (yy - 2.0 * np.einsum("...i,...i->...", theta, v)
            + np.einsum("...i,...ij,...j->...", theta, a, theta))


def solve_step(a: np.ndarray, v: np.ndarray, slope: np.ndarray,
               choice: tuple[int, int, int] = (-1, -1, -1), fit_delay: bool = True,
               held: Mapping[int, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Solve (a stack of) the normal equations for given break choices and held steps.

    The solve `solve_variance` makes for one layout of the columns, without its break
    search and bootstrap: for diagnostics of its errors on saved statistics (the pull
    harness's sandwich and design factors, ``benchmarks/messenger_fit_pulls.py``;
    docs/decisions/messenger_fit.md entries 39 and 41).  The shifted breaks' hinge
    columns are free only on an axis moved to one (`choose_breaks`); such an axis
    cancels its current hinge (its d(c) fixed at ``-slope``) and takes no linearised
    break step.

    Parameters
    ----------
    a : ndarray, shape (N_PARAMETERS, N_PARAMETERS) or (n, N_PARAMETERS, N_PARAMETERS)
        Normal matrix (e.g. `VarianceStatistics.normal` summed over blocks), or a stack
        of them (resamples).
    v : ndarray, shape (N_PARAMETERS,) or (n, N_PARAMETERS)
        Right-hand side(s).
    slope : ndarray, shape (3,)
        Each axis's slope change ``c`` at the linearisation point (`law_parameters`'
        third column).
    choice : tuple of int
        Per axis, the index of the break shift in `BREAK_SHIFTS_C`, or -1: the break
        kept, with its linearised step (`choose_breaks`' convention).
    fit_delay : bool
        Solve for dt too (else its step is 0).
    held : mapping, optional
        Held parameters: column (`PER_AXIS` layout) -> step (not fitted; the value
        `solve_variance`'s ``held`` gives without its width).

    Returns
    -------
    step : ndarray, shape (N_PARAMETERS,) or (n, N_PARAMETERS)
        The solution(s), the held columns at their steps.
    free : ndarray of bool, shape (N_PARAMETERS,)
        The columns solved for.

    Raises
    ------
    FluxcalError
        A choice outside ``-1 .. len(BREAK_SHIFTS_C) - 1``, a held column outside the
        parameters, or a break moved on an axis whose break column is held.

    Notes
    -----
    A single system is solved by least squares on the matrix scaled to unit diagonal
    (rank-safe), a stack by one batched solve: `solve_variance`'s own solver, so its
    solution at the same choices and held steps comes out bit for bit (with ``refine``,
    only where `refine_breaks` leaves a moved break on its grid point:
    ``VarianceSolution.break_offset`` 0).
    """
    held = dict(held or {})
    choice = tuple(int(c) for c in choice)
    if len(choice) != 3 or not all(-1 <= c < N_SHIFTS for c in choice):
        raise FluxcalError(f"solve_step: choice {choice}: give one of -1..{N_SHIFTS - 1} "
                           "per axis (the index in BREAK_SHIFTS_C, -1 for the break kept)")
    if not all(0 <= int(col) < N_PARAMETERS for col in held):
        raise FluxcalError(f"solve_step: held columns {sorted(held)}: give columns "
                           f"0..{N_PARAMETERS - 1}")
    moved_held = [j for j in range(3) if choice[j] >= 0 and j * PER_AXIS + 3 in held]
    if moved_held:
        raise FluxcalError(f"solve_step: axes {moved_held} hold their break column; their "
                           "break cannot move (choice -1)")
    base_free = np.ones(N_PARAMETERS, dtype=bool)
    base_free[-1] = fit_delay
    fixed_h = np.zeros(N_PARAMETERS)
    for col, value in held.items():
        base_free[int(col)] = False
        fixed_h[int(col)] = value
    free, fixed = break_layout(choice, base_free, np.asarray(slope, dtype=float))
    return fit_columns(np.asarray(a, dtype=float), np.asarray(v, dtype=float), free,
                fixed + fixed_h), free


def choose_breaks(a: np.ndarray, v: np.ndarray, yy: np.ndarray | float,
                  base_free: np.ndarray, law: np.ndarray, t_range: tuple[float, float],
                  sweeps: int = 2, fixed: np.ndarray | None = None):
    """Per axis, the break shift of least residual (-1: keep the break, linearised step).

    The exact two-segment law at each shifted break is compared with the law whose break
    stays (its slope change free, no linearised step); axes in turn, ``sweeps`` times.
    Shifts whose break falls outside ``t_range`` (`solve_variance`: the data's range,
    5-C bins with an interval's worth of accepted samples) are not tried, nor any on an
    axis whose break column is not free in ``base_free`` (a held break).

    ``a``, ``v``, ``yy`` may be stacks of resampled normal equations (leading axis
    ``n``): each resample then chooses its own breaks (the bootstrap repeats every
    discrete choice, issue 34), and an ``(n, 3)`` array is returned; else a tuple.
    ``fixed`` (broadcasting to ``(n, N_PARAMETERS)``): values of the held parameters.
    """
    stacked = a.ndim == 3
    a_s, v_s = (a, v) if stacked else (a[None], v[None])
    yy_s = np.atleast_1d(np.asarray(yy, dtype=float))
    n = a_s.shape[0]
    held = np.broadcast_to(np.zeros(N_PARAMETERS) if fixed is None else fixed,
                           (n, N_PARAMETERS))
    choice = np.full((n, 3), -1, dtype=np.int64)
    # the other axes' choices when each axis was last chosen: an axis whose others have
    # not moved since would try the same layouts again and choose the same shift, so
    # those rows are not solved again (a later sweep then costs only the rows that
    # moved; the same numbers: every row is solved on its own, entry 40)
    seen = [np.full((n, 3), -2, dtype=np.int64) for _ in range(3)]
    lo, hi = t_range
    for _ in range(sweeps):
        for j in range(3):
            others = np.arange(3) != j
            rows = np.flatnonzero(np.any(choice[:, others] != seen[j][:, others], axis=1))
            seen[j] = choice.copy()
            if rows.size == 0:
                continue
            best = choice[rows, j].copy()
            best_r = np.full(rows.size, np.inf)
            for k in (-1, *range(N_SHIFTS)):
                if k >= 0 and not (base_free[j * PER_AXIS + 3]
                                   and lo <= law[j, 3] + BREAK_SHIFTS_C[k] <= hi):
                    continue  # outside the fitted range, or the break held
                trial = choice[rows].copy()
                trial[:, j] = k
                if stacked:  # every resample's own layout, one batched solve (item 7)
                    free, fx = _layout_rows(trial, base_free, law[:, 2])
                    if k == -1:  # the break kept: exact, without the linearised step
                        free[:, j * PER_AXIS + 3] = False
                    every = rows.size == n  # all rows: no copy of the stack
                    a_k, v_k = (a_s, v_s) if every else (a_s[rows], v_s[rows])
                    r = residual_sum(a_k, v_k, yy_s if every else yy_s[rows],
                                  _fit_rows(a_k, v_k, free, fx + held[rows]))
                else:  # the single system: least squares as before (rank-safe)
                    free, fx = break_layout(tuple(int(c) for c in trial[0]), base_free,
                                       law[:, 2])
                    if k == -1:
                        free[j * PER_AXIS + 3] = False
                    r = np.atleast_1d(residual_sum(a, v, yy_s[0],
                                                fit_columns(a, v, free, fx + held[0])))
                better = r < best_r
                best[better] = k
                best_r[better] = r[better]
            choice[rows, j] = best
    return choice if stacked else tuple(int(c) for c in choice[0])


def resample_fits(a_r: np.ndarray, v_r: np.ndarray, yy_r: np.ndarray, held_r: np.ndarray,
                  base_free: np.ndarray, law: np.ndarray | None,
                  data_range: tuple[float, float], refine: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the break choices (n, 3), the fitted steps (n, p) and the break offsets (n, 3).

    Each row of the stacked normal equations chooses its own breaks (`choose_breaks`;
    none tried without ``law``) and is solved with them (`_fit_rows`), on its own: a
    block of rows gives the numbers those rows get in the whole stack (`solve_variance`).
    With ``refine`` (and a ``law``) every moved break is then placed inside its cell on
    its row's own data (`refine_breaks`, which also treats each row on its own), so that
    on Dask the refinement runs on the workers with the resamples (docs/decisions/
    messenger_fit.md entry 54); else the offsets are 0.
    """
    n = a_r.shape[0]
    slope = law[:, 2] if law is not None else np.zeros(3)
    if law is not None:
        choice = choose_breaks(a_r, v_r, yy_r, base_free, law, data_range, fixed=held_r)
    else:
        choice = np.full((n, 3), -1, dtype=np.int64)
    free_r, fixed_r = _layout_rows(choice, base_free, slope)
    steps = _fit_rows(a_r, v_r, free_r, fixed_r + held_r)
    if refine and law is not None:
        steps, offset = refine_breaks(a_r, v_r, yy_r, held_r, base_free, law, choice, steps,
                                      data_range)
        return choice, steps, offset
    return choice, steps, np.zeros((n, 3))


def choice_shifts_c(choice: np.ndarray) -> np.ndarray:
    """Break shifts (C) of break choices (``-1``: 0)."""
    table = np.array([*BREAK_SHIFTS_C, 0.0])
    return table[np.where(np.asarray(choice) >= 0, choice, N_SHIFTS)]


def quantisation(choice: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw, per chosen shift, where in its cell the break lies (C; 0 for a kept break).

    A break moved to a shift of `BREAK_SHIFTS_C` is known only to the cell about it: from
    half-way to the next lower shift (or the kept break, 0) to half-way to the next
    higher one, the outermost cells as wide outward as inward.  Uniform over the cell
    (variance ``width^2 / 12``): the quantisation of the shift grid, which a resample
    that took a shift would otherwise leave out (one step from breaks 3.3 C away, every
    resample took the same -4-C shift: spread 0; tests/missions/messenger/
    test_fit_breaks.py, docs/decisions/messenger_fit.md entry 27).  The fit places a
    resample's break in the cell by its own data instead (`refine_breaks`,
    `solve_variance`'s ``refine_resamples``, entry 47); this draw stays for
    ``refine_resamples=False``.
    """
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    mid = 0.5 * (grid[1:] + grid[:-1])
    lo = np.r_[2.0 * grid[0] - mid[0], mid]
    hi = np.r_[mid, 2.0 * grid[-1] - mid[-1]]
    s = choice_shifts_c(choice)
    i = np.searchsorted(grid, s)
    return np.where(np.asarray(choice) >= 0, rng.uniform(lo[i], hi[i]) - s, 0.0)


def _neighbour(axis: int, shift_c: np.ndarray) -> np.ndarray:
    """Return the column of axis ``axis``'s hinge at each grid point ``shift_c`` (C).

    A shifted break's own column; for 0 (the kept break) the column d(c) of its hinge.
    """
    k = np.searchsorted(np.asarray(BREAK_SHIFTS_C), shift_c).clip(0, N_SHIFTS - 1)
    return np.where(shift_c == 0.0, axis * PER_AXIS + 2, shift_column(axis, k))


def refine_breaks(a_r: np.ndarray, v_r: np.ndarray, yy_r: np.ndarray, held_r: np.ndarray,
                  base_free: np.ndarray, law: np.ndarray, choice: np.ndarray,
                  steps: np.ndarray, data_range: tuple[float, float]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Place every break moved to a grid shift inside its cell, on its own data.

    A break moved to ``s_k`` (one of `BREAK_SHIFTS_C`) lies between ``s_k`` and a
    neighbouring grid point ``s_n`` (the kept break counts as 0).  Its hinge is split
    between the two, the slope changes ``c_k`` and ``c_n`` fitted by least squares with
    every other parameter (on the side, below or above ``s_k``, of the lower residual
    among those whose two hinges make one, ``0 <= lambda <= 1`` below; a neighbour
    outside ``data_range`` is not tried, as in `choose_breaks`).  Below both
    grid points the two hinges are 0, and above both ``c_k (T - T_m - s_k) + c_n (T - T_m
    - s_n)`` is exactly one hinge of slope change ``c = c_k + c_n`` at ``s = s_k + lambda
    (s_n - s_k)``, ``lambda = c_n / c``: only inside the cell is the corner rounded.  The
    break is taken at ``s`` with the slope change ``c`` where ``0 <= lambda <= 1``; where
    not (slopes of opposite sign: no single hinge between the grid points), at ``s_k``
    as chosen (the pair dropped, the row solved again).

    The alternative to a uniform draw over the cell (`quantisation`, entry 27), where a
    resample whose data put its break 0.3 C from the solution, just past half-way to the
    +0.5-C grid point, is drawn anywhere in 0.25..0.75 C.  In the resamples only by
    default (`solve_variance`'s ``refine_resamples``, entry 47); in the solution too
    opt-in (``refine``, entry 42: it changes the passes' path).

    Parameters
    ----------
    a_r, v_r, yy_r, held_r
        The resamples' normal equations and held values (`resample_fits`).
    base_free : ndarray of bool
    law : ndarray, shape (3, 4)
        The linearisation point (`law_parameters`).
    choice : ndarray of int, shape (n, 3)
        The break choices (`choose_breaks`; -1: kept).
    steps : ndarray, shape (n, N_PARAMETERS)
        The resamples' steps at those choices (`resample_fits`).
    data_range : tuple of float

    Returns
    -------
    steps : ndarray, shape (n, N_PARAMETERS)
        ``steps`` with each refined row solved again; a refined axis's shifted column
        holds ``c`` (`apply_steps` reads the slope change there).
    offset : ndarray, shape (n, 3)
        ``s - s_k`` (C) per resample and axis; 0 where the break was kept or not refined.
    """
    choice = np.asarray(choice, dtype=np.int64)
    n = choice.shape[0]
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    lo, hi = data_range
    free, fixed = _layout_rows(choice, base_free, law[:, 2])
    fixed = fixed + held_r
    shift_c = np.array([*BREAK_SHIFTS_C, 0.0])[np.where(choice >= 0, choice, N_SHIFTS)]
    pair = np.full((n, 3), np.nan)  # the neighbour grid point of each refined break
    for j in range(3):
        rows = np.flatnonzero(choice[:, j] >= 0)
        best = np.full(rows.size, np.inf)
        for side in (-1, 1):
            g = np.searchsorted(grid, shift_c[rows, j]) + side
            s_n = grid[g.clip(0, grid.size - 1)]
            ok = ((g >= 0) & (g < grid.size)
                  & ((s_n == 0.0) | ((lo <= law[j, 3] + s_n) & (law[j, 3] + s_n <= hi))))
            r_ok = rows[ok]
            if r_ok.size == 0:
                continue
            f = free[r_ok].copy()
            col = _neighbour(j, s_n[ok])
            f[np.arange(r_ok.size), col] = True
            theta = _fit_rows(a_r[r_ok], v_r[r_ok], f, fixed[r_ok])
            r = residual_sum(a_r[r_ok], v_r[r_ok], yy_r[r_ok], theta)
            # a side counts only where its two hinges make one between the grid points
            c_n = theta[np.arange(r_ok.size), col] + np.where(s_n[ok] == 0.0, law[j, 2], 0.0)
            c = theta[np.arange(r_ok.size), shift_column(j, choice[r_ok, j])] + c_n
            single = (c != 0.0) & (c_n * c >= 0.0) & (np.abs(c_n) <= np.abs(c))
            r = np.where(single, r, np.inf)
            better = np.zeros(rows.size, dtype=bool)
            better[ok] = r < best[ok]
            best[better] = r[better[ok]]
            pair[rows[better], j] = s_n[better]
    out, offset = np.array(steps, dtype=float, copy=True), np.zeros((n, 3))
    while True:  # drop the pairs with no single hinge between them, solve again (each
        # round drops at least one pair, so this ends)
        rows = np.flatnonzero(np.isfinite(pair).any(axis=1))
        if rows.size == 0:
            break
        f = free[rows].copy()
        for j in range(3):
            m = np.isfinite(pair[rows, j])
            f[np.flatnonzero(m), _neighbour(j, pair[rows[m], j])] = True
        theta = _fit_rows(a_r[rows], v_r[rows], f, fixed[rows])
        dropped = False
        for j in range(3):
            m = np.flatnonzero(np.isfinite(pair[rows, j]))
            s_k, s_n = shift_c[rows[m], j], pair[rows[m], j]
            c_k = theta[m, shift_column(j, choice[rows[m], j])]
            c_n = theta[m, _neighbour(j, s_n)] + np.where(s_n == 0.0, law[j, 2], 0.0)
            c = c_k + c_n
            lam = np.divide(c_n, c, out=np.full(m.size, -1.0), where=c != 0.0)
            bad = (lam < 0.0) | (lam > 1.0)
            if np.any(bad):
                pair[rows[m[bad]], j] = np.nan
                dropped = True
            theta[m, shift_column(j, choice[rows[m], j])] = c
            offset[rows[m], j] = np.where(bad, 0.0, lam * (s_n - s_k))
        if not dropped:
            out[rows] = theta
            break
        offset[rows] = 0.0
    return out, offset


def solution_distance(offset: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Per resample and axis, ``+offset`` or ``-offset``, half each in a random order.

    The solution's break left at its grid point while its own data put it ``offset``
    (C, `refine_breaks`) from there (`solve_variance`'s ``refine_resamples``): added to
    every resample's break, so that the stated error counts that distance too.  Over an
    even ``n`` the draws' mean is exactly 0 and their variance exactly ``offset^2`` (an
    odd ``n``: one more of one sign), independent of the resamples' own order.

    Parameters
    ----------
    offset : ndarray, shape (3,)
    n : int
        Resamples.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, 3)
    """
    offset = np.asarray(offset, dtype=float)
    signs = np.stack([rng.permutation(np.resize([1.0, -1.0], n)) for _ in offset], axis=1)
    return signs * offset[None, :]


def fixed_design_resamples(picks: np.ndarray, a: np.ndarray, v: np.ndarray,
                           total_a: np.ndarray, total_v: np.ndarray, yy: float,
                           step: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resampled normal equations with the design of the whole data kept.

    Each unit's score at the solution, ``g_u = v_u - A_u step`` (all columns), is
    resampled with the counts ``picks`` (n_bootstrap, n_units); the normal matrix stays
    the whole data's ``A`` in every resample: ``A_r = A``, ``v_r = v + sum_u (picks_ru -
    1) g_u``, ``yy_r = yy`` (a constant of every residual a resample compares).  On the
    free columns ``sum_u g_u = 0``, so a resample's step is ``step + A^-1 sum_u (picks_ru
    - 1) g_u``: a multiplier (wild) bootstrap of the units, whose covariance is the
    cluster sandwich ``A^-1 (sum_u g_u g_u^T) A^-1`` exactly (the counts' variance
    ``(n - 1) / n`` and covariance ``-1 / n`` cancel against ``sum_u g_u = 0``).  On the
    other columns (the shifted breaks not chosen) ``v_r`` keeps the data's own evidence,
    so each resample still chooses its break again (`choose_breaks`).

    Unlike the pairs bootstrap (``A_r = sum_u picks_ru A_u``), no resample drops or
    doubles the few warm units that fix a law's lever arm: the error for the fitted
    days' temperatures as given.  On the saved 16-day late-peak fits the pairs
    bootstrap's resampled design states the law at 0 C 1.24-1.47x and T_m 1.07-1.11x
    wider than this (docs/decisions/messenger_fit.md entry 41).  Not the default
    (`solve_variance`'s ``fixed_design``): on one of 80 saved fits it narrows the law at
    -50 C by 4 % and moves a pull from 2.89 to 3.00 (entry 41).

    Returns
    -------
    a_r : ndarray, shape (n_bootstrap, p, p)
        ``A`` for every resample (a read-only broadcast view).
    v_r : ndarray, shape (n_bootstrap, p)
    yy_r : ndarray, shape (n_bootstrap,)
    """
    picks = np.asarray(picks, dtype=float)
    score = v - np.einsum("uij,j->ui", a, step)
    a_r = np.broadcast_to(total_a, (picks.shape[0], *total_a.shape))
    return a_r, total_v + (picks - 1.0) @ score, np.full(picks.shape[0], float(yy))


def wild_weights(n_bootstrap: int, n_units: int, rng: np.random.Generator,
                 kind: str = "rademacher") -> np.ndarray:
    """Draw the wild bootstrap's weights, one per resample and unit.

    Parameters
    ----------
    n_bootstrap, n_units : int
    rng : numpy.random.Generator
    kind : {"rademacher", "webb"}
        The distribution (`WILD_WEIGHTS`), each point equally likely: mean 0, variance
        1 (Rademacher: ``eta^2 = 1`` always).

    Returns
    -------
    ndarray, shape (n_bootstrap, n_units)

    Raises
    ------
    FluxcalError
        An unknown ``kind``.
    """
    if kind not in WILD_WEIGHTS:
        raise FluxcalError(f"wild_weights: kind {kind!r}: give one of {sorted(WILD_WEIGHTS)}")
    points = WILD_WEIGHTS[kind]
    return points[rng.integers(0, points.size, (n_bootstrap, n_units))]


def wild_resamples(weights: np.ndarray, a: np.ndarray, v: np.ndarray, yy: np.ndarray,
                   total_a: np.ndarray, step: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the wild cluster bootstrap's resampled normal equations, exactly from sums.

    Each resample is the fitted model plus every unit's own residual times that unit's
    weight: ``y*_u = X_u b + eta_ru e_u`` (``b = step``, every column of the layout, the
    held and fixed ones at their values; ``e_u = y_u - X_u b``), on the data's own design
    (every column, the shifted breaks' hinges too, so that each resample can choose its
    breaks again, `choose_breaks`).  With ``g_u = v_u - A_u b`` (the unit's score) and
    ``e_u'e_u = yy_u - 2 b'v_u + b'A_u b``::

        A*_r  = sum_u A_u                                   (the design kept)
        v*_r  = A b + sum_u eta_ru g_u
        yy*_r = b'A b + 2 sum_u eta_ru b'g_u + sum_u eta_ru^2 e_u'e_u

    Unlike the pairs bootstrap (``A_r = sum_u picks_ru A_u``: a resample's residual is the
    data's own, its roughness over the break's grid, plus a resampled part again) and the
    fixed-design one (`fixed_design_resamples`: ``v_r = A b + sum_u picks_ru g_u``, the
    data's own residual kept in every resample), a wild resample's residual is only its
    units' residuals, each with a random sign: the world the resample chooses its break
    in is one whose truth is the fit (its break at the solution) with noise like the
    data's (Cameron, Gelbach and Miller 2008; the cure for a bootstrap of an argmin over
    a rough criterion re-adding that roughness, docs/decisions/messenger_fit.md entry
    42 (2)).  On the solution's free columns the linear step's covariance is the cluster
    sandwich ``A^-1 (sum_u g_u g_u') A^-1`` (``E eta = 0``, ``E eta^2 = 1``), as the
    fixed design's.

    Parameters
    ----------
    weights : ndarray, shape (n_bootstrap, n_units)
        ``eta`` (`wild_weights`).
    a : ndarray, shape (n_units, N_PARAMETERS, N_PARAMETERS)
    v : ndarray, shape (n_units, N_PARAMETERS)
    yy : ndarray, shape (n_units,)
        The units' normal equations (`fit_variance.VarianceStatistics`, grouped into the
        bootstrap's units).
    total_a : ndarray, shape (N_PARAMETERS, N_PARAMETERS)
        ``sum_u A_u``.
    step : ndarray, shape (N_PARAMETERS,)
        The fitted parameters ``b`` in the full layout (`solve_step`, `fit_columns`: the held
        columns and an axis's cancelled hinge at their fixed values).

    Returns
    -------
    a_r, v_r, yy_r : ndarray
        ``A*`` (a read-only broadcast view of ``total_a``), ``v*`` and ``yy*`` per
        resample: shapes ``(n_bootstrap, N_PARAMETERS, N_PARAMETERS)``, ``(n_bootstrap,
        N_PARAMETERS)``, ``(n_bootstrap,)``, as `fixed_design_resamples` returns them.

    References
    ----------
    .. [1] Cameron, A. C., Gelbach, J. B. and Miller, D. L., Bootstrap-based improvements
       for inference with clustered errors, Rev. Econ. Stat. 90, 414-427 (2008).
    """
    weights = np.asarray(weights, dtype=float)
    b = np.asarray(step, dtype=float)
    a, v, yy = np.asarray(a, dtype=float), np.asarray(v, dtype=float), np.asarray(yy, float)
    a_b = np.einsum("uij,j->ui", a, b)  # A_u b
    score = v - a_b  # g_u
    bab = a_b @ b  # b'A_u b
    ee = yy - 2.0 * (v @ b) + bab  # e_u'e_u
    fitted = total_a @ b
    a_r = np.broadcast_to(total_a, (weights.shape[0], *total_a.shape))
    v_r = fitted[None, :] + weights @ score
    yy_r = float(fitted @ b) + 2.0 * (weights @ (score @ b)) + (weights ** 2) @ ee
    return a_r, v_r, yy_r


def break_profile(a: np.ndarray, v: np.ndarray, yy: float, base_free: np.ndarray,
                  law: np.ndarray, choice: tuple[int, int, int], axis: int,
                  offsets_c: np.ndarray, fixed: np.ndarray | None = None,
                  parameters: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Residual sum with axis ``axis``'s break placed at each of ``offsets_c``, profiled.

    The profile of the exact residual against the break (docs/decisions/messenger_fit.md
    entry 51): at each offset ``s`` (C from ``law[axis, 3]``) the break is a hinge
    of free slope change at ``s``, every other parameter re-fitted (the other axes at
    their ``choice``, `choose_breaks`' convention; the held ones at ``fixed``).  At a grid
    point (0, the kept break, or one of `BREAK_SHIFTS_C`) the hinge is that point's
    column; between two grid points ``s_k < s < s_n`` it is ``(1 - lambda) h(s_k) +
    lambda h(s_n)``, ``lambda = (s - s_k) / (s_n - s_k)``: `refine_breaks`' two-hinge
    split with ``lambda`` given instead of fitted, the same line as one hinge at ``s``
    below ``s_k`` and above ``s_n``, its corner rounded inside the cell.  The break's
    linearised step (``-c dT_m``) is not used, so each value is the residual of a law
    whose break lies at ``s``, not a step from it.

    Parameters
    ----------
    a, v, yy
        The summed normal equations (`solve_variance`'s ``total_a``, ``total_v``, ``yy``).
    base_free : ndarray of bool, shape (N_PARAMETERS,)
        The columns free in the fit (dt, the held columns not).
    law : ndarray, shape (3, 4)
        The linearisation point's ``(a, b, c, T_m)`` per axis (`law_parameters`).
    choice : tuple of int
        The other axes' break choices (axis ``axis``'s entry is not read).
    axis : int
    offsets_c : ndarray, shape (m,)
        Break positions (C from ``law[axis, 3]``), each between ``BREAK_SHIFTS_C[0]`` and
        ``BREAK_SHIFTS_C[-1]``.
    fixed : ndarray, shape (N_PARAMETERS,), optional
        Values of the held columns (default 0).
    parameters : bool
        Also return each offset's parameters.

    Returns
    -------
    ndarray, shape (m,)
        The least residual sum at each offset (`residual_sum`).
    theta : ndarray, shape (m, N_PARAMETERS)
        With ``parameters``: the parameters in the full layout (the moved hinge's slope
        change split between its two grid columns as ``1 - lambda`` and ``lambda``).

    Raises
    ------
    FluxcalError
        An offset outside the grid, or an axis whose break column is held.
    """
    s = np.atleast_1d(np.asarray(offsets_c, dtype=float))
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    if np.any((s < grid[0]) | (s > grid[-1])) or not base_free[axis * PER_AXIS + 3]:
        raise FluxcalError(f"break_profile: axis {axis}: give offsets within "
                           f"{grid[0]:g}..{grid[-1]:g} C of a free break")
    ch = np.array(choice, dtype=np.int64)
    ch[axis] = -1
    free, fx = break_layout(tuple(int(c) for c in ch), base_free, law[:, 2])
    fx = fx + (np.zeros(N_PARAMETERS) if fixed is None else np.asarray(fixed, float))
    # the axis's own hinge moves: its d(c) cancels the current one, no linearised step
    free[axis * PER_AXIS + 2] = free[axis * PER_AXIS + 3] = False
    fx[axis * PER_AXIS + 2] = -law[axis, 2]
    fx[axis * PER_AXIS + 3] = 0.0
    k = np.clip(np.searchsorted(grid, s, side="right") - 1, 0, grid.size - 2)
    lam = (s - grid[k]) / (grid[k + 1] - grid[k])
    cols = np.flatnonzero(free)
    q = cols.size + 1
    m = np.zeros((s.size, N_PARAMETERS, q))  # theta = fx + m phi
    m[:, cols, np.arange(cols.size)] = 1.0
    rows = np.arange(s.size)
    m[rows, _neighbour(axis, grid[k]), -1] += 1.0 - lam
    m[rows, _neighbour(axis, grid[k + 1]), -1] += lam
    a = np.asarray(a, dtype=float)
    v0 = np.asarray(v, dtype=float) - a @ fx
    a_q = np.swapaxes(m, 1, 2) @ (a @ m)  # m' A m per offset (batched matmuls)
    v_q = np.einsum("sia,i->sa", m, v0)
    phi = _solve(a_q, v_q)
    theta = fx[None, :] + np.einsum("sia,sa->si", m, phi)
    r = residual_sum(a[None], np.asarray(v, float)[None], float(yy), theta)
    return (r, theta) if parameters else r


def profile_interval(offsets_c: np.ndarray, residual: np.ndarray,
                     threshold: float) -> tuple[float, float, bool, bool]:
    """Return the outermost offsets whose residual lies within ``threshold`` of its least.

    Every offset whose residual exceeds the least by at most ``threshold`` belongs to the
    interval, a second minimum too: the interval runs from the lowest to the highest of
    them (a hull, not the connected piece about the least), each end interpolated
    linearly to where the residual crosses the threshold between two offsets.

    Parameters
    ----------
    offsets_c : ndarray, shape (m,)
        Ascending.
    residual : ndarray, shape (m,)
        `break_profile` at ``offsets_c``.
    threshold : float
        ``Delta`` of the residual sum (`profile_threshold`).

    Returns
    -------
    lo, hi : float
        The interval's ends (C).
    closed_lo, closed_hi : bool
        Whether each end was crossed inside ``offsets_c`` (False: the interval reaches the
        first or last offset, so it is a lower bound of the break's uncertainty there).
    """
    s = np.asarray(offsets_c, dtype=float)
    d = np.asarray(residual, dtype=float) - float(np.min(residual)) - float(threshold)
    inside = np.flatnonzero(d <= 0.0)
    i, j = int(inside[0]), int(inside[-1])
    lo = s[i] if i == 0 else s[i - 1] + (s[i] - s[i - 1]) * d[i - 1] / (d[i - 1] - d[i])
    hi = (s[j] if j == s.size - 1
          else s[j] + (s[j + 1] - s[j]) * (-d[j]) / (d[j + 1] - d[j]))
    return float(lo), float(hi), i > 0, j < s.size - 1


def profile_threshold(a_u: np.ndarray, v_u: np.ndarray, base_free: np.ndarray,
                      law: np.ndarray, choice: tuple[int, int, int], axis: int,
                      fixed: np.ndarray | None = None, widening: float = 1.0) -> float:
    """Return the rise of the residual sum that one standard error of the break makes.

    At the break kept (axis ``axis`` at choice -1, the other axes at ``choice``), the
    linearised break column ``q = -c dT_m`` has the naive variance ``s^2 (A^-1)_qq`` and
    the cluster-robust one ``(A^-1 (sum_u g_u g_u') A^-1)_qq`` (``g_u = v_u - A_u theta``
    each unit's score at the solution, free columns); their ratio is the ``Delta chi^2``
    of one standard error, so that correlated units do not shrink the interval.  In
    residual units (``Delta chi^2 s^2``) the naive scale ``s^2`` cancels::

        Delta = w^2 (A^-1 S A^-1)_qq / (A^-1)_qq

    (``w``: ``widening``, the fit's ``sqrt(n / (n - p))``).  Where the residual is
    quadratic in the break (the linearised model), `profile_interval` at this threshold
    is the break +- its widened sandwich error exactly.

    Parameters
    ----------
    a_u, v_u : ndarray, shapes (n, N_PARAMETERS, N_PARAMETERS), (n, N_PARAMETERS)
        The resampling units' normal equations (`fit_variance.resampling_units`).
    base_free, law, choice, axis, fixed
        As `break_profile`.
    widening : float

    Returns
    -------
    float
    """
    ch = np.array(choice, dtype=np.int64)
    ch[axis] = -1
    free, fx = break_layout(tuple(int(c) for c in ch), base_free, law[:, 2])
    fx = fx + (np.zeros(N_PARAMETERS) if fixed is None else np.asarray(fixed, float))
    total_a, total_v = a_u.sum(axis=0), v_u.sum(axis=0)
    theta = fit_columns(total_a, total_v, free, fx)
    f = np.flatnonzero(free)
    score = (v_u - np.einsum("uij,j->ui", a_u, theta))[:, f]
    inv = np.linalg.pinv(total_a[np.ix_(f, f)])
    q = int(np.flatnonzero(f == axis * PER_AXIS + 3)[0])
    e = score @ inv[:, q]
    return float(widening ** 2 * np.sum(e ** 2) / inv[q, q])
