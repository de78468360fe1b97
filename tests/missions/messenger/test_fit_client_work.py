"""Issue 34, item 7: less serial work in the fit's client, the same results bit for bit.

1. The waveform columns' fold errors are fitted once, after the passes.  No pass reads
   ``FitResult.waveform_error`` (only the figure of merit after the passes does,
   `fit_merit.predicted_error`), so `fit_passes.fit_days` skips the four folds' splines in
   every pass and states the errors once, from the last pass's statistics and starting
   table (docs/decisions/messenger_fit.md, entry 33).  The expected values are
   the fit's own, stated the way every pass stated them before: the same `fit_days`
   with the per-pass errors forced back on.  Everything must agree bit for bit (the
   same arithmetic on the same inputs), and the folds must be fitted once instead of
   once per pass.  The data are a forward model that shares no code with the fit
   (`flight_sim`, 2 days of the realistic wind).
2. The bootstrap's resamples, each with its own break choice, are solved in batches
   (`fit_breaks._fit_rows`) instead of one call per distinct choice: against the
   per-choice `fit_breaks.fit_columns` on random systems, bit for bit.
3. (entry 40) `fit_breaks.choose_breaks` solves, in a later sweep, only the rows
   whose other axes' choices moved since that axis was last chosen: against the rule
   written out here (every row, every sweep, every trial), bit for bit, and with fewer
   rows solved.  The three axes of a waveform column share one spline decomposition
   (`constrained_fits.fit_periodic_splines`): against `fit_periodic_spline` one value
   set at a time, bit for bit, with one decomposition per distinct set of points.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from fluxcal.calibration import constrained_fits as cf
from fluxcal.missions.messenger import fit_breaks as fb
from fluxcal.missions.messenger import fit_passes, fit_waveforms
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_reduce import WAVEFORM_FOLDS
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight

START = dt.date(2010, 3, 1)
PASSES = 3


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    return simulate_flight(tmp_path_factory.mktemp("flight"),
                           FlightConfig(start=str(START), days=2, seed=2121), truth=False)


def _fit(flight, monkeypatch, estimator: str, per_pass: bool):
    """`fit_days` as it runs (``per_pass`` False) or with every pass stating its errors."""
    stated: list[np.ndarray | None] = []
    fold_unmixes = []
    unmix = fit_waveforms.unmix_waveforms

    def counting_unmix(stats, waveform=None):
        if waveform is not None:  # one fold's statistics
            fold_unmixes.append(1)
        return unmix(stats, waveform)

    monkeypatch.setattr(fit_waveforms, "unmix_waveforms", counting_unmix)
    if per_pass:
        name = "fit_variance_calibration" if estimator == "variance" else "fit_calibration"
        original = getattr(fit_passes, name)

        def stating(*args, **kwargs):
            out = original(*args, **{**kwargs, "waveform_errors": True})
            stated.append(out.waveform_error)
            return out

        monkeypatch.setattr(fit_passes, name, stating)
    res = fit_passes.fit_days(fit_passes.day_chunks(flight.input_dir, flight.days),
                              load_calibration(str(START)), passes=PASSES,
                              estimator=estimator, guard=False)
    monkeypatch.undo()
    return res, stated, len(fold_unmixes)


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["variance", "zero-mean"])
def test_fold_errors_once_equal_the_last_pass_errors_and_change_nothing_else(
        flight, monkeypatch, estimator):
    now, _, folds_now = _fit(flight, monkeypatch, estimator, per_pass=False)
    before, stated, folds_before = _fit(flight, monkeypatch, estimator, per_pass=True)
    runs = len(before.passes)
    assert len(now.passes) == runs
    # the folds' spread fitted once (the four folds unmixed once), not once per pass
    assert folds_now == WAVEFORM_FOLDS
    assert folds_before >= WAVEFORM_FOLDS * runs
    # the stated column errors: those the last pass's own fit stated, bit for bit
    assert stated[-1] is not None and np.all(np.isfinite(stated[-1]))
    np.testing.assert_array_equal(now.waveform_error, stated[-1])
    np.testing.assert_array_equal(now.waveform_error, before.waveform_error)
    # and nothing else moved: the tables, every pass's history, the stated errors of
    # the other terms and the figure of merit built from all of them
    for name in ("temperature_coefficients", "breakpoint_temperature_c", "duty_cycle_c0",
                 "duty_cycle_d0", "heater_signal"):
        np.testing.assert_array_equal(getattr(now.calibration, name),
                                      getattr(before.calibration, name), err_msg=name)
    assert now.calibration.constants == before.calibration.constants
    assert now.passes == before.passes and now.convergence == before.convergence
    law = ("a0", "b0", "a1", "b1", "x_m", "a0_err", "b0_err", "a1_err", "b1_err", "x_m_err")
    assert [[getattr(f, k) for k in law] for f in now.temperature] == [
        [getattr(f, k) for k in law] for f in before.temperature]
    assert [f.slope_err for f in now.duty] == [f.slope_err for f in before.duty]
    assert now.merit == before.merit
    if estimator == "variance":
        assert now.merit["waveform_nt"] == before.merit["waveform_nt"]


def test_batched_resample_fits_equal_the_per_choice_fits_bit_for_bit():
    # random normal equations (A = X'X of a random design, so symmetric positive
    # definite on every free block), every break choice per axis (-1: kept, or one of
    # the shifts), dt free or held, held values on some columns: each row solved alone
    # by `fit_columns` with its own `break_layout` must give the batched rows exactly (the same
    # gathered numbers and the same LAPACK solve per matrix).  The layouts themselves
    # against the rule written out: a moved axis frees its shift's hinge column only,
    # fixes its slope change at -c and its break step at 0
    rng = np.random.default_rng(34)
    n, p = 300, fb.N_PARAMETERS
    x = rng.standard_normal((n, 2 * p, p))
    a = np.einsum("rki,rkj->rij", x, x)
    v = rng.standard_normal((n, p))
    choice = rng.integers(-1, fb.N_SHIFTS, size=(n, 3))
    slope = rng.normal(0.0, 0.1, 3)
    for fit_delay in (True, False):
        base_free = np.ones(p, dtype=bool)
        base_free[-1] = fit_delay
        base_free[4] = False  # D0 x held
        held = np.zeros((n, p))
        held[:, 4] = rng.normal(0.0, 0.01, n)
        free, fixed = fb._layout_rows(choice, base_free, slope)
        got = fb._fit_rows(a, v, free, fixed + held)
        for r in range(n):
            f1, x1 = fb.break_layout(tuple(int(c) for c in choice[r]), base_free, slope)
            np.testing.assert_array_equal(free[r], f1)
            moved = [j for j in range(3) if choice[r, j] >= 0]
            hinge = free[r, 3 * fb.PER_AXIS:3 * fb.PER_AXIS + 3 * fb.N_SHIFTS]
            assert sorted(np.flatnonzero(hinge)) == sorted(
                j * fb.N_SHIFTS + choice[r, j] for j in moved)
            for j in range(3):
                assert free[r, j * fb.PER_AXIS + 2] == (j not in moved)
                assert x1[j * fb.PER_AXIS + 2] == (-slope[j] if j in moved else 0.0)
            want = fb.fit_columns(a[r:r + 1], v[r:r + 1], f1, x1 + held[r:r + 1])[0]
            np.testing.assert_array_equal(got[r], want)
        # more than one batch: rows with one, two and three moved breaks differ in size
        assert np.unique(free.sum(axis=1)).size > 1


def _sweeps_written_out(a, v, yy, base_free, law, t_range, fixed, sweeps=2,
                        single=False):
    """`choose_breaks`'s rule with nothing skipped: every row, every sweep, every trial
    (axes in turn, the first least residual in the order kept, then the shifts)."""
    n = a.shape[0]
    choice = np.full((n, 3), -1, dtype=np.int64)
    for _ in range(sweeps):
        for j in range(3):
            best, best_r = choice[:, j].copy(), np.full(n, np.inf)
            for k in (-1, *range(fb.N_SHIFTS)):
                if k >= 0 and not (base_free[j * fb.PER_AXIS + 3] and t_range[0]
                                   <= law[j, 3] + fb.BREAK_SHIFTS_C[k] <= t_range[1]):
                    continue
                trial = choice.copy()
                trial[:, j] = k
                free, fx = fb._layout_rows(trial, base_free, law[:, 2])
                if k == -1:
                    free[:, j * fb.PER_AXIS + 3] = False
                if single:  # the solution's own system: least squares, as written
                    r = np.atleast_1d(fb.residual_sum(a[0], v[0], yy[0], fb.fit_columns(
                        a[0], v[0], free[0], fx[0] + fixed[0])))
                else:
                    r = fb.residual_sum(a, v, yy, fb._fit_rows(a, v, free, fx + fixed))
                better = r < best_r
                best[better], best_r[better] = k, r[better]
            choice[:, j] = best
    return choice


def _random_system(rng: np.random.Generator, n: int, p: int):
    """``n`` random positive-definite normal-equation systems of ``p`` parameters.

    Returns ``(a, v, yy, law)``: matrices (n, p, p), right-hand sides (n, p), sums of
    squares above each system's minimum (n,), and a law (3, 4) with breaks in -10..30 C.
    """
    x = rng.standard_normal((n, 2 * p, p)) * rng.uniform(0.1, 3.0, p)
    a = np.einsum("rki,rkj->rij", x, x)
    v = rng.standard_normal((n, p)) * 5.0
    yy = np.einsum("ri,rij,rj->r", v, np.linalg.inv(a), v) + rng.uniform(0.1, 10.0, n)
    law = np.column_stack([rng.normal(0, 1, 3), rng.normal(0, 1, 3),
                           rng.normal(0, 0.3, 3), rng.uniform(-10, 30, 3)])
    return a, v, yy, law


def test_later_sweeps_skip_unmoved_rows_and_choose_the_same_breaks(monkeypatch):
    # random normal equations whose residuals favour a shifted break on some axes of
    # some rows (so later sweeps have rows to redo and rows to skip); dt free and held,
    # a held D0 drawn per row, a held break on one axis, a range that excludes some
    # shifts; the written-out rule must choose exactly the same shifts, and the
    # skipping must solve fewer rows than it (the saving, item 7)
    rng = np.random.default_rng(3434)
    p = fb.N_PARAMETERS
    solved = []
    rows_of = fb._fit_rows

    def counting(a, v, free, fixed):
        solved.append(a.shape[0])
        return rows_of(a, v, free, fixed)

    for case in range(6):
        n = int(rng.integers(40, 160))
        a, v, yy, law = _random_system(rng, n, p)
        base_free = np.ones(p, dtype=bool)
        base_free[-1] = case % 2 == 0
        base_free[fb.PER_AXIS + 3] = case % 3 != 0  # y's break held in some cases
        fixed = np.zeros((n, p))
        base_free[4] = False
        fixed[:, 4] = rng.normal(0.0, 0.01, n)
        t_range = (float(rng.uniform(-20, 5)), float(rng.uniform(10, 40)))
        want = _sweeps_written_out(a, v, yy, base_free, law, t_range, fixed)
        monkeypatch.setattr(fb, "_fit_rows", counting)
        solved.clear()
        got = fb.choose_breaks(a, v, yy, base_free, law, t_range, fixed=fixed)
        monkeypatch.undo()
        np.testing.assert_array_equal(got, want)
        tried = sum(1 for j in range(3) for k in (-1, *range(fb.N_SHIFTS)) if k < 0 or (
            base_free[j * fb.PER_AXIS + 3]
            and t_range[0] <= law[j, 3] + fb.BREAK_SHIFTS_C[k] <= t_range[1]))
        assert (want >= 0).any()  # some rows moved a break
        assert sum(solved) < 2 * tried * n  # the second sweep redid only moved rows
        # the single system (the solution's own choice) by the same rule
        one = fb.choose_breaks(a[0], v[0], yy[0], base_free, law, t_range, fixed=fixed[0])
        assert one == tuple(int(c) for c in _sweeps_written_out(
            a[:1], v[:1], yy[:1], base_free, law, t_range, fixed[:1], single=True)[0])


def test_waveform_axes_share_one_spline_decomposition_bit_for_bit(monkeypatch):
    # three waveforms on the same phases and weights (a column's x, y, z), GCV and a
    # fixed smoothing, and one set with a missing point (its own points, so its own
    # decomposition): each fit must equal `fit_periodic_spline` of that set alone
    rng = np.random.default_rng(61)
    made = []
    smoother = cf._periodic_smoother

    def counting(*args, **kwargs):
        made.append(1)
        return smoother(*args, **kwargs)

    for smoothing in (None, 0.05):
        ph = np.sort(rng.uniform(0.0, 100.0, 90))
        w = rng.uniform(2.0, 30.0, ph.size)
        ys = [3.0 * np.sin(2 * np.pi * (k + 1) * ph / 100.0) + rng.normal(0, 1 / w)
              for k in range(3)]
        gap = ys[2].copy()
        gap[7] = np.nan
        monkeypatch.setattr(cf, "_periodic_smoother", counting)
        made.clear()
        many = cf.fit_periodic_splines(ph, [*ys, gap], w, 100.0, smoothing)
        monkeypatch.undo()
        assert len(made) == 2  # the three full sets share one; the gapped set its own
        for y, f in zip([*ys, gap], many, strict=True):
            g = cf.fit_periodic_spline(ph, y, w, 100.0, smoothing)
            assert (f.lam, f.n_knots, f.chi2, f.dof) == (g.lam, g.n_knots, g.chi2, g.dof)
            for name in ("coef_cov", "phase", "value_err"):
                np.testing.assert_array_equal(getattr(f, name), getattr(g, name))
            np.testing.assert_array_equal(f.spline.c, g.spline.c)
            np.testing.assert_array_equal(f.table(1.0)[1], g.table(1.0)[1])


def _step_written_out(cal, st, max_tau_shift, max_break_shift_c, shifts):
    """`apply_step`'s rule for one resample, written out axis by axis."""
    law = fv.law_parameters(cal).copy()
    d0 = np.asarray(cal.duty_cycle_d0, dtype=float).copy()
    for j in range(3):
        da, db, dc, dstep, dd0 = st[fb.PER_AXIS * j:fb.PER_AXIS * (j + 1)]
        c = law[j, 2]
        law[j, 0] += da
        law[j, 1] += db
        d0[j] += dd0
        if shifts[j] != 0.0:  # moved: the slope change fitted at the shifted break
            law[j, 2] = st[3 * fb.PER_AXIS + j * fb.N_SHIFTS
                           + fb.BREAK_SHIFTS_C.index(float(shifts[j]))]
            law[j, 3] += shifts[j]
        else:  # kept: the linearised break step -(step on [T > T_m]) / c, clipped
            law[j, 2] += dc
            law[j, 3] += float(np.clip(-dstep / c if c != 0 else 0.0,
                                       -max_break_shift_c, max_break_shift_c))
    rel = cal.constants["relaxation"]
    tau = float(rel["tau_s"])
    return (law, d0, tau + float(np.clip(st[-2], -max_tau_shift * tau, max_tau_shift * tau)),
            float(rel["delay_s"]) + float(st[-1]))


def test_resample_steps_applied_at_once_equal_one_at_a_time():
    # every resample's step applied in one call (`apply_steps`, entry 40) against the
    # rule one resample at a time: steps of three sizes (the clips bind for the large
    # ones), every break shift and none, the clipped and the unclipped ranges
    rng = np.random.default_rng(77)
    cal = load_calibration(str(START))
    n = 300
    steps = rng.normal(0, 1, (n, fb.N_PARAMETERS)) * rng.choice([0.01, 1.0, 300.0],
                                                                (n, fb.N_PARAMETERS))
    shifts = rng.choice([0.0, *fb.BREAK_SHIFTS_C], (n, 3))
    for limits in ((0.3, 10.0), (np.inf, np.inf)):
        law, d0, tau, dt = fv.apply_steps(cal, steps, *limits, break_shifts=shifts)
        assert law.shape == (n, 3, 4) and d0.shape == (n, 3) and tau.shape == dt.shape == (n,)
        for r in range(n):
            want = _step_written_out(cal, steps[r], *limits, shifts[r])
            np.testing.assert_array_equal(law[r], want[0])
            np.testing.assert_array_equal(d0[r], want[1])
            assert (tau[r], dt[r]) == want[2:]
            one = fv.apply_step(cal, steps[r], *limits, break_shift=shifts[r])
            assert all(np.array_equal(x, y) for x, y in zip(one, want, strict=True))


def test_resamples_in_blocks_equal_the_whole_stack():
    # the bootstrap's resamples solved in blocks of rows (`fit_days` on Dask maps them
    # onto the workers, `solve_variance(map_rows=...)`) against the whole stack at once:
    # every row chooses, solves and (``refine``) places its breaks in their cells on its
    # own, so the blocks must give the same choices, steps and offsets, bit for bit, for
    # any split (one row per block included), and the refinement inside `resample_fits`
    # must be `refine_breaks` after it (entry 54)
    rng = np.random.default_rng(4711)
    p = fb.N_PARAMETERS
    n = 90
    a, v, yy, law = _random_system(rng, n, p)
    held = np.zeros((n, p))
    held[:, 4] = rng.normal(0.0, 0.01, n)
    for fit_delay, with_law, refine in ((True, True, False), (False, True, False),
                                        (True, False, False), (True, True, True),
                                        (False, True, True), (True, False, True)):
        base_free = np.ones(p, dtype=bool)
        base_free[-1] = fit_delay
        base_free[4] = False
        args = (base_free, law if with_law else None, (-15.0, 35.0), refine)
        whole = fb.resample_fits(a, v, yy, held, *args)
        assert (whole[0] >= 0).any() == with_law
        if refine and with_law:
            plain = fb.resample_fits(a, v, yy, held, *args[:3])
            want = fb.refine_breaks(a, v, yy, held, base_free, law, plain[0], plain[1],
                                    (-15.0, 35.0))
            assert whole[1].tobytes() == want[0].tobytes()
            assert whole[2].tobytes() == want[1].tobytes()
            assert (whole[2] != 0.0).any()  # some breaks were placed inside their cells
        else:
            np.testing.assert_array_equal(whole[2], 0.0)
        for blocks in (2, 7, n):
            parts = [fb.resample_fits(a[c], v[c], yy[c], held[c], *args)
                     for c in np.array_split(np.arange(n), blocks)]
            for k in range(3):
                got = np.concatenate([x[k] for x in parts])
                assert got.tobytes() == whole[k].tobytes()
