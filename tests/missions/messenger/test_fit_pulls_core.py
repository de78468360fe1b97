"""The pull harness's ``--core`` and ``--estimators`` diagnostics (entries 39 and 41).

``benchmarks/messenger_fit_pulls.py --summarise DIR --core`` splits each stated error of
T_m and the law into factors (the widening, the design, the design-fixed cluster
sandwich and the units' shares of it); ``--estimators`` gives the pulls the stated
errors, the sandwich and the fixed-design bootstrap would give.  Both read the saved
fits' last normal equations through `fit_breaks.solve_step`.

The saved fits here are `fit.fit_variance_calibration` on the normal equations of raw
samples ``y = X 0 + noise`` (random regressors, the noise 5x larger in every seventh
2-h block, so that the cluster sandwich differs from the classical error); three with
every parameter but dt free, one with D0 z held with a width.  The
expected values come from those raw samples, sharing nothing with the normal-equation
algebra of `fit_variance` or of the harness:

* the solution and residuals by ``numpy.linalg.lstsq`` on the stacked samples of the
  free columns; the units' scores ``g_u = X_u^T e_u`` from the units' own residuals;
  the cluster sandwich ``A^-1 (sum_u g_u g_u^T) A^-1`` with ``A = X^T X``; a held
  column's width through the least-squares regression of its regressor on the free
  ones (``d theta / d h = -lstsq(X_f, X_h)``);
* the units as `solve_variance`'s docstring states them: runs of ``k`` consecutive
  blocks, ``k`` the largest that leaves ``2 p`` units (at most `MAX_GROUP`);
* the widening ``sqrt(n / (n - p))`` in closed form;
* T_m's error ``sd(-c dT_m) / |c|`` and the law's gradient ``(1, t, max(0, t - T_m),
  [t > T_m])`` from the linearised law of the module docstring, ``c`` and ``T_m`` from
  the fitted Table 2 by eq. 4;
* the pairs bootstrap's resamples by weighted ``lstsq`` on the raw samples (each unit's
  rows weighted by its count; the counts drawn as the harness documents: seed 0, 200
  resamples of ``n`` units with replacement), the fixed-design one as
  ``(counts - 1) @ g @ A^-1``;
* the pulls ``(fit - truth) / stated`` by hand, the truth set a known distance from the
  fit.

`solve_step` itself is checked against ``lstsq`` with the columns' layout written out
here (the breaks kept or moved, dt, held columns), and bit for bit against
`solve_variance`'s own solution at the break choice it made.

Tolerances: 1e-6 relative where the same quantity is computed two ways (the normal
equations against ``lstsq``: about 1e-12 apart); 25 % where the fixed-design bootstrap's
200 resamples estimate the sandwich (their standard deviation's sampling error is about
``1 / sqrt(2 x 200)`` = 5 %: five sigma).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import pickle
import types
from pathlib import Path

import numpy as np
import pytest

from fluxcal.errors import FluxcalError
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit import fit_variance_calibration
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    PER_AXIS,
    solve_step,
)
from fluxcal.missions.messenger.fit_reduce import DayStatistics, FitSettings
from fluxcal.missions.messenger.fit_variance import (
    MAX_GROUP,
    TEMPERATURE_EDGES_C,
    VarianceStatistics,
    law_parameters,
    solve_variance,
)

START = dt.date(2010, 3, 1)
#: 2-h blocks, samples per block, noise (counts): T_m's error about 0.02-0.1 C, no
#: upper segment undetermined, no break moved in any resample.
BLOCKS, PER_BLOCK, NOISE = 120, 60, 4.0
#: The columns of the shifted breaks' hinges (free only on an axis moved to a shift).
SHIFT_COLUMNS = np.arange(3 * PER_AXIS, 3 * PER_AXIS + 3 * len(BREAK_SHIFTS_C))
#: The harness's law temperatures and counts-to-nT factor (eq. 8's diagonal).
LAW_T = np.array([-50.0, -40.0, -30.0, -20.0, 0.0, 30.0])
NT_PER_COUNT = 0.047
#: Held D0 z's width (counts/ppt): with its regressor 0.8 x b's, it adds about 0.16
#: counts/C to b_z's error, so about 8 counts to the law z at -50 C (about 7 from the
#: data, widened).
HELD_WIDTH = 0.2
REL = 1e-6


@pytest.fixture(scope="module")
def bench(pulls_bench):
    return pulls_bench


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(str(START))


def _raw(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Raw samples ``(x (blocks, rows, p), y (blocks, rows))`` of ``y = X 0 + noise``;
    each axis's D0 regressor 0.8 x its ``b`` regressor plus its own."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(BLOCKS, PER_BLOCK, N_PARAMETERS))
    for j in range(3):
        x[..., j * PER_AXIS + 4] += 0.8 * x[..., j * PER_AXIS + 1]
    scale = np.where(np.arange(BLOCKS) % 7 == 0, 5.0, 1.0)[:, None]
    return x, NOISE * scale * rng.normal(size=(BLOCKS, PER_BLOCK))


def _stats(x: np.ndarray, y: np.ndarray) -> VarianceStatistics:
    """The samples' normal equations per 2-h block, every interval accepted, every 5-C
    bin from -60 to 40 C full (so every break is free and shifts are tried)."""
    centre = 0.5 * (TEMPERATURE_EDGES_C[:-1] + TEMPERATURE_EDGES_C[1:])
    return VarianceStatistics(
        normal=np.einsum("bni,bnj->bij", x, x), rhs=np.einsum("bni,bn->bi", x, y),
        yy=np.einsum("bn,bn->b", y, y), samples=np.full(BLOCKS, float(PER_BLOCK)),
        block_start=np.arange(BLOCKS) * 7200.0, interval_start=np.zeros(BLOCKS),
        reason=np.full(BLOCKS, ""),
        temperature_count=np.where((centre > -60.0) & (centre < 40.0), 3000.0, 0.0))


def _fit(x: np.ndarray, y: np.ndarray, base, hold_d0=()):
    """The pipeline's fit of the samples' normal equations (`_stats`; dt not fitted)."""
    return fit_variance_calibration(DayStatistics.empty(FitSettings()), _stats(x, y), base,
                                    fit_delay=False, hold_d0=hold_d0)


def _law_point(cal) -> tuple[np.ndarray, np.ndarray]:
    """``c`` and ``T_m`` per axis of a Table 2 ``(A0, B0, A1, B1)`` (eq. 4)."""
    a0, b0, a1, b1 = np.asarray(cal.offset_coefficients(), dtype=float).T
    return b1 - b0, (a0 - a1) / (b1 - b0)


def _independent(x: np.ndarray, y: np.ndarray, res, held: dict[int, float]) -> dict:
    """Everything the harness's core factors need, from the raw samples (see the module
    docstring): units, solution, scores, sandwich, widening and the gradients."""
    free = np.ones(N_PARAMETERS, dtype=bool)
    free[SHIFT_COLUMNS] = False
    free[-1] = False  # dt not fitted
    free[list(held)] = False
    f = np.flatnonzero(free)
    p = f.size
    k = min(MAX_GROUP, BLOCKS // (2 * p))
    unit = np.arange(BLOCKS) // k
    n = int(unit[-1]) + 1
    xs, ys = x.reshape(-1, N_PARAMETERS), y.ravel()
    theta = np.linalg.lstsq(xs[:, f], ys, rcond=None)[0]
    e = (y - x[..., f] @ theta)  # held steps are 0 at the fitted tables
    g_b = np.einsum("bri,br->bi", x[..., f], e)
    g = np.zeros((n, p))
    np.add.at(g, unit, g_b)
    a_inv = np.linalg.inv(xs[:, f].T @ xs[:, f])
    cov = np.zeros((N_PARAMETERS, N_PARAMETERS))
    cov[np.ix_(f, f)] = a_inv @ (g.T @ g) @ a_inv
    held_cov = np.zeros((N_PARAMETERS, N_PARAMETERS))
    for col, width in held.items():  # d theta_f / d h = -lstsq(X_f, X_h)
        jac = np.zeros(N_PARAMETERS)
        jac[f] = -np.linalg.lstsq(xs[:, f], xs[:, col], rcond=None)[0]
        jac[col] = 1.0
        held_cov += width ** 2 * np.outer(jac, jac)
    c, tm = _law_point(res.calibration)
    grads = {}
    for j, a in enumerate("xyz"):
        gm = np.zeros(N_PARAMETERS)
        gm[j * PER_AXIS + 3] = -1.0 / c[j]
        grads[f"T_m {a}"] = gm
        for t in LAW_T:
            gl = np.zeros(N_PARAMETERS)
            gl[j * PER_AXIS:j * PER_AXIS + 4] = (1.0, t, max(0.0, t - tm[j]), float(t > tm[j]))
            grads[f"law {a} {t:+g}"] = gl
    return {"f": f, "p": p, "n": n, "unit": unit, "theta": theta, "g": g, "a_inv": a_inv,
            "cov": cov, "held_cov": held_cov, "w": np.sqrt(n / (n - p)), "grads": grads,
            "c": c, "tm": tm, "xs": xs, "ys": ys, "k": k}


def _truth(res, seed: int):
    """A true table a known distance from the fit: each law ``(a, b, c, T_m)`` moved by
    (0.3 counts, 0, 0, d T_m), D0 by 0.1 counts/ppt and tau by 0.5 s; ``d T_m`` drawn
    in +-0.3 C (a few of its errors).  Returned as `forward.read_tables` gives it (the
    fields the harness reads)."""
    rng = np.random.default_rng(seed)
    c, tm = _law_point(res.calibration)
    a0, b0, _, _ = np.asarray(res.calibration.offset_coefficients(), dtype=float).T
    a, t_true = a0 + 0.3, tm + rng.uniform(-0.3, 0.3, 3)
    tau = float(res.relaxation.tau) + 0.5
    constants = {"relaxation": {"tau_s": tau, "delay_s": 10.0}}
    return types.SimpleNamespace(a0=a, b0=b0, a1=a - c * t_true, b1=b0 + c,
                                 d0=np.asarray(res.calibration.duty_cycle_d0) + 0.1,
                                 constants=constants, t_m=t_true)


@pytest.fixture(scope="module")
def saved(shipped):
    """Three free fits and one with D0 z held (width `HELD_WIDTH`), their raw samples
    and truths."""
    out = []
    for seed, hold in ((1, ()), (2, ()), (3, ()), (4, {"z": (None, HELD_WIDTH)})):
        x, y = _raw(seed)
        res = _fit(x, y, shipped, hold)
        out.append((x, y, res, _truth(res, 100 + seed), hold))
    return out


def _held(hold) -> dict[int, float]:
    """The held columns and widths of a fit of `saved` (D0 z or none)."""
    return {2 * PER_AXIS + 4: HELD_WIDTH} if hold else {}


# --- fit_breaks.solve_step --------------------------------------------------------


def _random_system(seed: int, stack: int | None = None):
    rng = np.random.default_rng(seed)
    shape = (stack, 300) if stack else (300,)
    x = rng.normal(size=(*shape, N_PARAMETERS))
    y = x @ rng.normal(size=N_PARAMETERS) + 0.1 * rng.normal(size=shape)
    return x, y, np.einsum("...ri,...rj->...ij", x, x), np.einsum("...ri,...r->...i", x, y)


@pytest.mark.parametrize("stack", [None, 4])
def test_solve_step_keeps_the_break_and_holds_columns_as_lstsq_does(stack):
    # breaks kept: the shifted hinges out; dt out when not fitted; held columns moved
    # to the right-hand side at their steps
    x, y, a, v = _random_system(5, stack)
    slope = np.array([1.3, 4.6, 1.6])
    held = {4: 0.25, 2 * PER_AXIS + 3: -0.5}
    for fit_delay in (True, False):
        step, free = solve_step(a, v, slope, fit_delay=fit_delay, held=held)
        want_free = np.ones(N_PARAMETERS, dtype=bool)
        want_free[SHIFT_COLUMNS] = False
        want_free[list(held)] = False
        want_free[-1] = fit_delay
        np.testing.assert_array_equal(free, want_free)
        xh = x[..., list(held)] @ np.array(list(held.values()))
        rows = [(x, y, xh)] if stack is None else list(zip(x, y, xh, strict=True))
        want = np.array([np.linalg.lstsq(xi[:, want_free], yi - hi, rcond=None)[0]
                         for xi, yi, hi in rows])
        got = step.reshape(-1, N_PARAMETERS)
        np.testing.assert_allclose(got[:, want_free], want, rtol=REL, atol=1e-12)
        np.testing.assert_array_equal(got[:, list(held)],
                                      np.broadcast_to(list(held.values()), (len(rows), 2)))
        assert np.all(got[:, ~want_free & ~np.isin(np.arange(N_PARAMETERS), list(held))]
                      == 0.0)


def test_solve_step_moves_a_break_to_a_shifted_hinge():
    # y's axis moved to BREAK_SHIFTS_C[7]: its current hinge cancelled (d(c) = -c), its
    # break step column out, the shifted hinge's slope fitted
    x, y, a, v = _random_system(6)
    slope = np.array([1.3, 4.6, 1.6])
    k = 7
    step, free = solve_step(a, v, slope, choice=(-1, k, -1))
    hinge = 3 * PER_AXIS + len(BREAK_SHIFTS_C) + k
    want_free = np.ones(N_PARAMETERS, dtype=bool)
    want_free[SHIFT_COLUMNS] = False
    want_free[[PER_AXIS + 2, PER_AXIS + 3]] = False
    want_free[hinge] = True
    np.testing.assert_array_equal(free, want_free)
    want = np.linalg.lstsq(x[:, want_free], y + slope[1] * x[:, PER_AXIS + 2], rcond=None)[0]
    np.testing.assert_allclose(step[want_free], want, rtol=REL, atol=1e-12)
    assert step[PER_AXIS + 2] == -slope[1] and step[PER_AXIS + 3] == 0.0


def test_solve_step_gives_solve_variances_solution_bit_for_bit(shipped):
    # normal equations whose solution moves x's break by +2 C (its hinge cancelled, the
    # hinge at +2 C carrying the shipped slope change), D0 z held: `solve_variance`
    # chooses that shift, and `solve_step` at its choice and held step is its solution
    law = law_parameters(shipped)
    step = np.zeros(N_PARAMETERS)
    step[2] = -law[0, 2]
    step[3 * PER_AXIS + BREAK_SHIFTS_C.index(2.0)] = law[0, 2]
    x, noise = _raw(9)
    stats = _stats(x, x @ step + 0.01 * noise)
    d0_z = 2 * PER_AXIS + 4
    sol = solve_variance(stats, fit_delay=False, n_bootstrap=3, law=law,
                         held={d0_z: (0.05, HELD_WIDTH)})
    np.testing.assert_array_equal(sol.break_shift, [2.0, 0.0, 0.0])
    # the break stays on its grid point (`refine` off, the fit's default; entry 42)
    np.testing.assert_array_equal(sol.break_offset, 0.0)
    got, free = solve_step(stats.normal.sum(axis=0), stats.rhs.sum(axis=0), law[:, 2],
                           choice=(BREAK_SHIFTS_C.index(2.0), -1, -1), fit_delay=False,
                           held={d0_z: 0.05})
    np.testing.assert_array_equal(got, sol.step)
    assert not free[d0_z] and not free[-1] and free[3 * PER_AXIS + BREAK_SHIFTS_C.index(2.0)]


@pytest.mark.parametrize(("choice", "held"), [((-2, -1, -1), {}),
                                              ((-1, len(BREAK_SHIFTS_C), -1), {}),
                                              ((-1, -1), {}),
                                              ((-1, -1, -1), {N_PARAMETERS: 0.0}),
                                              ((3, -1, -1), {3: 0.0})])
def test_solve_step_refuses_a_choice_or_column_it_cannot_lay_out(choice, held):
    _, _, a, v = _random_system(7)
    with pytest.raises(FluxcalError, match="solve_step"):
        solve_step(a, v, np.ones(3), choice=choice, held=held)


# --- the harness: --core ------------------------------------------------------------


def test_unit_scores_and_sandwich_errors_match_the_raw_samples(bench, saved):
    for x, y, res, _, hold in saved:
        held = _held(hold)
        ind = _independent(x, y, res, held)
        u = bench.unit_scores(res)
        # 120 blocks: p = 16 free (k = 3, 40 units); with D0 z held p = 15 (k = 4, 30)
        assert (ind["p"], ind["n"]) == ((15, 30) if hold else (16, 40))
        assert (u["p"], u["n"]) == (ind["p"], ind["n"])
        np.testing.assert_array_equal(u["f"], ind["f"])
        np.testing.assert_allclose(u["theta"][ind["f"]], ind["theta"], rtol=REL,
                                   atol=1e-9 * np.abs(ind["theta"]).max())
        np.testing.assert_allclose(u["score"], ind["g"], rtol=REL,
                                   atol=1e-9 * np.abs(ind["g"]).max())
        tm_err, law_err = bench.sandwich_errors(res)
        cov = ind["w"] ** 2 * ind["cov"] + ind["held_cov"]  # the data's part widened
        for j, a in enumerate("xyz"):
            gm = ind["grads"][f"T_m {a}"]
            assert tm_err[j] == pytest.approx(np.sqrt(gm @ cov @ gm), rel=REL)
            want = [np.sqrt(ind["grads"][f"law {a} {t:+g}"] @ cov
                            @ ind["grads"][f"law {a} {t:+g}"]) for t in LAW_T]
            np.testing.assert_allclose(law_err[:, j], want, rtol=REL)
        if hold:  # the held width is a sizeable part of b_z's (so of the law z's) error
            g = ind["grads"]["law z -50"]
            assert law_err[0, 2] > 1.3 * ind["w"] * np.sqrt(g @ ind["cov"] @ g)


def _pairs_and_fixed(ind: dict) -> tuple[np.ndarray, np.ndarray]:
    """The harness's 200 resample counts (seed 0), the pairs bootstrap's solutions by
    weighted lstsq on the raw samples, and the fixed-design steps ``(c - 1) g A^-1``
    (free columns)."""
    n = ind["n"]
    rng = np.random.default_rng(0)
    picks = np.stack([np.bincount(rng.integers(0, n, n), minlength=n)
                      for _ in range(200)]).astype(float)
    rows_unit = np.repeat(ind["unit"], PER_BLOCK)
    xf = ind["xs"][:, ind["f"]]
    pairs = np.empty((200, ind["p"]))
    for r in range(200):
        sw = np.sqrt(picks[r, rows_unit])
        pairs[r] = np.linalg.lstsq(xf * sw[:, None], ind["ys"] * sw, rcond=None)[0]
    return pairs, (picks - 1.0) @ ind["g"] @ ind["a_inv"]


def test_core_factors_match_the_raw_samples(bench, saved):
    x, y, res, true, _ = saved[0]
    ind = _independent(x, y, res, {})
    # two resamples marked as having moved x's break: `jumps` is the spread of all over
    # that of the rest (hand), 1 on the axes where none moved
    shifts = np.zeros((res.bootstrap["law"].shape[0], 3))
    dev = np.abs(res.bootstrap["law"][:, 0, 3] - res.bootstrap["law"][:, 0, 3].mean())
    moved = np.argsort(dev)[-2:]
    shifts[moved, 0] = 4.0
    res_moved = dataclasses.replace(res, bootstrap={**res.bootstrap, "break_shift": shifts})
    got = bench.core_factors(res_moved, true)
    pairs, fixed = _pairs_and_fixed(ind)
    f = ind["f"]
    law_true = (true.a0[None, :] + true.b0[None, :] * LAW_T[:, None]
                + (true.b1 - true.b0)[None, :] * np.maximum(0.0, LAW_T[:, None] - true.t_m))
    a0, b0, _, _ = np.asarray(res.calibration.offset_coefficients(), dtype=float).T
    law_fit = (a0[None, :] + b0[None, :] * LAW_T[:, None]
               + ind["c"][None, :] * np.maximum(0.0, LAW_T[:, None] - ind["tm"]))
    for j, a in enumerate("xyz"):
        tm_boot = res.bootstrap["law"][:, j, 3]
        for name in [f"T_m {a}", *(f"law {a} {t:+g}" for t in LAW_T)]:
            g = ind["grads"][name][f]
            e_u = ind["g"] @ ind["a_inv"] @ g
            cr0 = np.sqrt(np.sum(e_u ** 2))
            o = got[name]
            assert o["w"] == pytest.approx(ind["w"], rel=1e-12)
            assert o["cr0"] == pytest.approx(cr0, rel=REL)
            assert o["top3"] == pytest.approx(np.sort(e_u ** 2)[-3:].sum() / cr0 ** 2,
                                              rel=REL)
            assert o["lag1"] == pytest.approx(np.sum(e_u[1:] * e_u[:-1]) / cr0 ** 2,
                                              rel=REL, abs=1e-9)
            assert o["design"] == pytest.approx(np.std(pairs @ g) / np.std(fixed @ g),
                                                rel=REL)
        assert got[f"T_m {a}"]["err"] == pytest.approx(ind["tm"][j] - true.t_m[j], rel=REL)
        assert got[f"T_m {a}"]["stated"] == pytest.approx(np.std(tm_boot), rel=1e-12)
        keep = np.ones(tm_boot.size, dtype=bool)
        if j == 0:
            keep[moved] = False
        assert got[f"T_m {a}"]["jumps"] == pytest.approx(
            np.std(tm_boot) / np.std(tm_boot[keep]), rel=1e-12)
        for i, t in enumerate(LAW_T):
            assert got[f"law {a} {t:+g}"]["err"] == pytest.approx(
                law_fit[i, j] - law_true[i, j], rel=1e-9, abs=1e-9)
    assert got["T_m x"]["jumps"] > 1.0 and got["T_m y"]["jumps"] == 1.0


def _save(folder: Path, saved) -> None:
    folder.mkdir()
    for k, (_, _, res, true, _) in enumerate(saved):
        (folder / f"fit_{3500 + k}.pkl").write_bytes(pickle.dumps((res, true)))


def _cells(out: str, name: str) -> list[str]:
    """The cells after the first of the markdown row whose first cell starts ``name``."""
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0].startswith(name):
            return cells[1:]
    raise AssertionError(f"no row {name!r} in:\n{out}")


def test_core_summary_prints_the_factors_over_the_saved_fits(bench, saved, tmp_path,
                                                             capsys):
    free = saved[:3]
    _save(tmp_path / "run", free)
    bench.core_summary(tmp_path / "run")
    out = capsys.readouterr().out
    inds = [_independent(x, y, res, {}) for x, y, res, _, _ in free]
    for j, a in enumerate("xyz"):
        err = np.array([ind["tm"][j] - true.t_m[j] for ind, (_, _, _, true, _)
                        in zip(inds, free, strict=True)])
        rms = np.sqrt(np.mean(err ** 2))
        stated = np.median([np.std(res.bootstrap["law"][:, j, 3]) for _, _, res, _, _ in free])
        g = [ind["grads"][f"T_m {a}"][ind["f"]] for ind in inds]
        cr0 = np.median([np.sqrt(np.sum((ind["g"] @ ind["a_inv"] @ gi) ** 2))
                         for ind, gi in zip(inds, g, strict=True)])
        cells = _cells(out, f"T_m {a}")
        assert cells[0] == "3"
        assert float(cells[1]) == pytest.approx(rms, abs=5.1e-5)
        assert float(cells[2]) == pytest.approx(stated, abs=5.1e-5)
        assert float(cells[3]) == 1.0  # no break moved
        assert float(cells[4]) == pytest.approx(np.sqrt(40 / 24), abs=5.1e-4)
        assert float(cells[6]) == pytest.approx(cr0 / rms, abs=5.1e-3)
    # the law in nT: its rows are printed for every temperature inside T_RANGE
    # (at -50 C, below every break, the truth lies 0.3 counts above each fit)
    cells = _cells(out, "law z -50")
    assert cells[0] == "3"
    assert float(cells[1]) == pytest.approx(NT_PER_COUNT * 0.3, abs=5.1e-5)


# --- the harness: --estimators ------------------------------------------------------


def test_estimator_rows_and_summary_give_the_pulls_by_hand(bench, saved, tmp_path, capsys):
    free = saved[:3]
    pulls = {"sd": [], "sandwich": [], "fixed": []}
    for x, y, res, true, _ in free:
        ind = _independent(x, y, res, {})
        err_tm = ind["tm"] - true.t_m
        stated = np.std(res.bootstrap["law"][:, :, 3], axis=0)
        sandwich = np.array([ind["w"] * np.sqrt(ind["grads"][f"T_m {a}"] @ ind["cov"]
                                                @ ind["grads"][f"T_m {a}"]) for a in "xyz"])
        sd_row = bench.estimator_row(res, true, bench.spread_sd)
        np.testing.assert_allclose(sd_row["tm_pull"], err_tm / stated, rtol=REL)
        assert sd_row["tau_pull"] == pytest.approx(-0.5 / np.std(res.bootstrap["tau"]),
                                                   rel=REL)
        np.testing.assert_allclose(sd_row["d0_pull"], -0.1 / np.std(res.bootstrap["d0"],
                                                                    axis=0), rtol=REL)
        np.testing.assert_array_equal(sd_row["jump_share"], 0.0)
        # no break moved: the mixture states the standard deviation
        np.testing.assert_allclose(
            bench.estimator_row(res, true, bench.spread_mixture)["tm_pull"], sd_row["tm_pull"],
            rtol=1e-12)
        s_row = bench.sandwich_row(res, true, False)
        np.testing.assert_allclose(s_row["tm_pull"], err_tm / sandwich, rtol=REL)
        # the fixed design: the replayed sandwich, within its 200 resamples' noise
        fx_row = bench.fixed_design_row(res, true)
        np.testing.assert_allclose(fx_row["tm_pull"], err_tm / sandwich, rtol=0.25)
        pulls["sd"].append(err_tm / stated)
        pulls["sandwich"].append(err_tm / sandwich)
        pulls["fixed"].append(fx_row["tm_pull"])
    _save(tmp_path / "run", free)
    bench.estimator_summary(tmp_path / "run")
    out = capsys.readouterr().out
    header = _cells(out, "parameter")
    assert header == ["sd", "percentile", "mad", "mixture", "sandwich", "sandwich+jumps",
                      "fixed design"]
    for j, a in enumerate("xyz"):
        cells = _cells(out, f"T_m {a} (N 3)")
        for name, col in (("sd", 0), ("sd", 3), ("sandwich", 4), ("sandwich", 5),
                          ("fixed", 6)):
            p = np.array(pulls[name])[:, j]
            spread, largest, beyond = (float(s) for s in cells[col].split(","))
            assert spread == pytest.approx(p.std(ddof=1), abs=5.1e-3), (a, name)
            assert largest == pytest.approx(np.abs(p).max(), abs=5.1e-3), (a, name)
            assert beyond == np.count_nonzero(np.abs(p) > 3)


# --- the harness: --replay (entry 42) ---------------------------------------


def test_replay_states_the_raw_samples_sandwich(bench, saved):
    # the fixed-design bootstrap (800 resamples) replayed on the saved fits by the
    # harness: T_m's error is the raw samples' cluster sandwich (lstsq, `_independent`)
    # widened by w, within the resamples' noise (an sd from 800 resamples scatters by
    # about 1 / sqrt(1600) = 2.5 %; 10 % allowed).  (The replay is at the fitted tables,
    # these fits one step from the shipped ones: it is not the fit's own bootstrap to
    # the digit, as it is for converged fits.)
    for x, y, res, true, _ in saved[:3]:
        ind = _independent(x, y, res, {})
        err_tm = ind["tm"] - true.t_m
        sandwich = np.array([ind["w"] * np.sqrt(ind["grads"][f"T_m {a}"] @ ind["cov"]
                                                @ ind["grads"][f"T_m {a}"]) for a in "xyz"])
        row = bench.replay_row(res, true, True, 800)
        np.testing.assert_allclose(row["tm_pull"], err_tm / sandwich, rtol=0.1)
