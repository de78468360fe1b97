"""Issue 34, item 2: the break temperatures' stated errors cover their truth (entry 27).

Closed forms first (no simulation): the quantisation of the shift grid is uniform over
the chosen shift's cell; the opt-in refinement places a break between grid shifts at its
truth (noise-free hinge worlds, entry 42); in a hinge world whose break is seen
only in a few warm blocks (above the stated 1800-sample range, inside the data's
300-sample range, as in issue 34's late-peak Mercury orbit) the stated T_m error covers
the truth, both where the linearised step has not brought the break home and after the
passes, where it is compared with the brute-force spread of the fitted breaks over noise
draws.  Then the late-peak Mercury orbit itself (`_hard_worlds.MercuryOrbit`, numpy only;
slow).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    quantisation,
    refine_breaks,
    resample_fits,
    solution_distance,
)
from fluxcal.missions.messenger.fit_holds import HOLD_BREAK_WIDTH_C
from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
from fluxcal.missions.messenger.fit_variance import (
    MIN_RANGE_SAMPLES,
    TEMPERATURE_EDGES_C,
    VarianceSettings,
    apply_step,
    law_parameters,
    law_to_table,
    law_values,
    solve_variance,
)
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
from tests.missions.messenger._hard_worlds import MercuryOrbit
from tests.missions.messenger.test_fit_variance import _hinge_statistics

START = "2010-03-01"
#: Samples per two-hour block of the hinge world, and every how many blocks one is warm.
PER_BLOCK = 600
WARM_EVERY = 3
#: Noise (counts, white) on every sample of the hinge world.
NOISE = 3.0


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(START)


def test_quantisation_is_uniform_over_the_chosen_shifts_cell():
    # the cell of a shift reaches half-way to its neighbours (the kept break, 0, counts
    # as one); the outermost cells as far outward as inward; a kept break draws 0
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    rng = np.random.default_rng(5)
    n = 20000
    for k, s in enumerate(BREAK_SHIFTS_C):
        i = int(np.searchsorted(grid, s))
        lo = 0.5 * (grid[i - 1] + s) if i > 0 else s - 0.5 * (grid[1] - s)
        hi = 0.5 * (grid[i + 1] + s) if i < grid.size - 1 else s + 0.5 * (s - grid[-2])
        d = quantisation(np.full((n, 3), k), rng)[:, 1]
        assert d.min() >= lo - s and d.max() <= hi - s
        # uniform: mean at the cell's centre, variance width^2 / 12 (20000 draws: 3 %)
        assert d.mean() == pytest.approx(0.5 * (lo + hi) - s, abs=0.02 * (hi - lo))
        assert d.var() == pytest.approx((hi - lo) ** 2 / 12.0, rel=0.03)
    np.testing.assert_array_equal(quantisation(np.full((4, 3), -1), rng), 0.0)


@pytest.mark.parametrize("off", [(0.3, -2.6, 6.0), (0.7, -1.3, -5.0)])
def test_a_break_between_grid_points_is_placed_at_its_truth(shipped, off):
    # noise-free hinge worlds whose true breaks lie inside grid cells (0.3 / 0.7 C: the
    # +0.5-C cell from either side; -2.6, -1.3: between -2 and -4, -1 and -2; 6.0, -5.0:
    # the outer cells): the data's least-squares break is the truth itself, the
    # expected value; the grid alone puts it at a grid point (up to 1 C off here), the
    # draw over the cell anywhere in it.  Tolerance 0.06 C: the rounded corner of two
    # hinges inside a cell, 3 % of the widest cell (2 C), 12 % of the narrowest (0.5)
    now = law_parameters(shipped)
    true = now.copy()
    true[:, 3] += off
    true[:, 2] *= 1.1  # a slope change 10 % larger too
    stats = _hinge_statistics(now, true, np.random.default_rng(31))
    sol = solve_variance(stats, n_bootstrap=20, law=now, refine=True)
    assert np.all(sol.break_shift != 0.0)  # every axis took a grid shift
    law = apply_step(shipped, sol.step, break_shift=sol.break_shift)[0]
    grid_only = law[:, 3].copy()
    law[:, 3] += sol.break_offset
    print("grid", (grid_only - true[:, 3]).round(3), "refined", (law[:, 3] - true[:, 3]).round(3))
    np.testing.assert_allclose(law[:, 3], true[:, 3], atol=0.06)
    # the slope change above both grid points: the sum of the two hinges' (1 %)
    np.testing.assert_allclose(law[:, 2], true[:, 2], rtol=0.01)
    # the law over the data (-60..+40 C) outside the cells: the rounded corner leans the
    # lines by a little (measured 0.2 counts at most, 0.01 nT); limit 0.5 counts
    # (0.024 nT, a sixth of the 0.15-nT goal); the grid point alone: 1.8-3.5 counts off
    t = np.arange(-60.0, 40.1, 0.5)
    far = np.abs(t[:, None] - true[None, :, 3]) > 2.0
    miss = np.abs(law_values(law, t) - law_values(true, t))[far]
    grid_law = law.copy()
    grid_law[:, 3] = grid_only
    print("law off outside the cells (counts)", miss.max().round(3), "grid point alone",
          np.abs(law_values(grid_law, t) - law_values(true, t))[far].max().round(2))
    assert miss.max() < 0.5


def test_kept_breaks_and_unmoved_resamples_are_left_as_they_are(shipped):
    # a world whose breaks are the current ones: resamples that keep their break are
    # returned unchanged with offset 0; a moved one stays inside the cells on either
    # side of its grid point (the neighbours' half-way is not a bound: the data decide)
    now = law_parameters(shipped)
    stats = _hinge_statistics(now, now, np.random.default_rng(8),
                              noise=40.0 * np.random.default_rng(9).normal(size=48 * 300))
    rng = np.random.default_rng(0)
    picks = np.stack([np.bincount(rng.integers(0, 48, 48), minlength=48)
                      for _ in range(100)]).astype(float)
    a_r, v_r = np.einsum("rb,bij->rij", picks, stats.normal), picks @ stats.rhs
    yy_r = picks @ stats.yy
    free = np.ones(N_PARAMETERS, dtype=bool)
    held = np.zeros((100, N_PARAMETERS))
    data_range = stats.fitted_range(VarianceSettings().min_samples)
    choice, steps, _ = resample_fits(a_r, v_r, yy_r, held, free, now, data_range)
    assert np.any(choice >= 0) and np.any(choice < 0)  # both kinds present
    out, offset = refine_breaks(a_r, v_r, yy_r, held, free, now, choice, steps, data_range)
    # refined inside `resample_fits` (on Dask: on the workers): the same, bit for bit
    _, inside, inside_offset = resample_fits(a_r, v_r, yy_r, held, free, now, data_range,
                                             refine=True)
    assert inside.tobytes() == out.tobytes() and inside_offset.tobytes() == offset.tobytes()
    kept = np.all(choice < 0, axis=1)
    np.testing.assert_array_equal(out[kept], steps[kept])
    np.testing.assert_array_equal(offset[choice < 0], 0.0)
    grid = np.array(sorted((0.0, *BREAK_SHIFTS_C)))
    s = np.array(BREAK_SHIFTS_C)[choice[choice >= 0]]
    i = np.searchsorted(grid, s)
    lo, hi = grid[np.maximum(i - 1, 0)], grid[np.minimum(i + 1, grid.size - 1)]
    moved = s + offset[choice >= 0]
    assert np.all((moved >= lo - 1e-9) & (moved <= hi + 1e-9))


@pytest.mark.parametrize("n", [200, 201])
def test_solution_distance_is_plus_or_minus_the_offset_half_each(n):
    # closed form: each draw is +d or -d; over an even count half each, so the mean is
    # exactly 0 and the variance exactly d^2 (np.var, ddof 0); an odd count: one more of
    # one sign
    d = np.array([0.2, -0.6, 0.0])
    out = solution_distance(d, n, np.random.default_rng(3))
    assert out.shape == (n, 3)
    np.testing.assert_array_equal(np.abs(out), np.broadcast_to(np.abs(d), (n, 3)))
    plus = np.count_nonzero(out[:, :2] > 0, axis=0)
    assert np.all(np.abs(2 * plus - n) == n % 2)
    if n % 2 == 0:
        np.testing.assert_allclose(out.mean(axis=0), 0.0, atol=1e-15)
        np.testing.assert_allclose(out.var(axis=0), d ** 2, rtol=1e-12)
    # the signs are independent of the axes' order of the resamples (not all alike)
    assert np.any(np.sign(out[:, 0]) != np.sign(out[:, 1]))


def test_refined_resamples_keep_the_solution_and_count_its_distance(shipped):
    # the noise-free hinge world of `test_a_break_between_grid_points_is_placed_at_its
    # _truth`: every axis's true break inside a grid cell.  With the refinement in the
    # resamples only, the solution is the default's bit for bit (the passes' path
    # unchanged) and stays on its grid point; every resample's data put its break at the
    # truth (noise-free), and the solution's own distance d = truth - grid point (the
    # world's definition) is added as +-d, so the resamples' breaks spread by |d| about
    # their mean (tolerance 0.06 C: the rounded corner, as in that test) and the grid
    # solution lies within 1 of that spread from the truth
    now = law_parameters(shipped)
    true = now.copy()
    true[:, 3] += (0.3, -2.6, 6.0)
    true[:, 2] *= 1.1
    stats = _hinge_statistics(now, true, np.random.default_rng(31))
    plain = solve_variance(stats, n_bootstrap=40, law=now, refine_resamples=False)
    sol = solve_variance(stats, n_bootstrap=40, law=now)  # refine_resamples, the default
    np.testing.assert_array_equal(sol.step, plain.step)
    np.testing.assert_array_equal(sol.break_shift, plain.break_shift)
    np.testing.assert_array_equal(sol.break_offset, 0.0)
    assert np.all(sol.break_shift != 0.0)
    grid = now[:, 3] + sol.break_shift  # the solution's break, on the grid
    distance = true[:, 3] - grid
    boots = np.stack([apply_step(shipped, b, max_tau_shift=np.inf, max_break_shift_c=np.inf,
                                 break_shift=s)[0][:, 3]
                      for b, s in zip(sol.boot, sol.boot_shift, strict=True)]) + sol.boot_dither
    print("distance", distance.round(3), "spread", boots.std(axis=0).round(3))
    np.testing.assert_allclose(boots.std(axis=0), np.abs(distance), atol=0.06)
    assert np.all(np.abs(distance) <= boots.std(axis=0) + 0.06)


def _sparse_peaks() -> np.ndarray:
    """Temperatures (C) of 48 blocks: regulated at -52..-48 C, every `WARM_EVERY`-th
    block a warm peak (Gaussian in time, -15..+40 C): 300-830 samples per 5-C bin from
    -45 to 0 C, so the breaks lie inside the data (300 per bin) and above the stated
    range (1800 per bin: -55..-45 C)."""
    s = np.linspace(0.0, 1.0, PER_BLOCK)
    warm = 48 // WARM_EVERY
    return np.concatenate([
        np.random.default_rng(b).uniform(-52.0, -48.0, PER_BLOCK) if b % WARM_EVERY else
        -50.0 + (35.0 + 55.0 * (b // WARM_EVERY) / (warm - 1))
        * np.exp(-((s - 0.5) / 0.18) ** 2) for b in range(48)])


def _fit(shipped, true, temp, seed, passes):
    """``passes`` Gauss-Newton steps as `fit_days` takes them (the statistics rebuilt
    about each new law, the same noise draw); the breaks and their stated errors as
    `fit.fit_variance_calibration` states them (the resamples' spread, each shifted
    break placed in its cell by its own data, widened)."""
    noise = NOISE * np.random.default_rng(900 + seed).normal(size=temp.size)
    cal = shipped
    for _ in range(passes):
        now = law_parameters(cal)
        stats = _hinge_statistics(now, true, np.random.default_rng(500 + seed), temp=temp,
                                  noise=noise)
        sol = solve_variance(stats, n_bootstrap=60, law=now)
        law = apply_step(cal, sol.step, break_shift=sol.break_shift)[0]
        boots = np.stack([apply_step(cal, b, max_tau_shift=np.inf, max_break_shift_c=np.inf,
                                     break_shift=s)[0][:, 3]
                          for b, s in zip(sol.boot, sol.boot_shift, strict=True)])
        boots += sol.boot_dither
        cal = dataclasses.replace(cal, temperature_coefficients=law_to_table(law),
                                  breakpoint_temperature_c=law[:, 3])
    err = sol.widening * np.std(boots, axis=0)
    return law[:, 3], err, stats


def _world(shipped):
    true = law_parameters(shipped).copy()
    true[0, 3] += 2.6  # x, y between the shifts (2 and 4 C)
    true[1, 3] -= 3.3
    return true, _sparse_peaks()


def test_sparse_world_puts_the_breaks_above_the_stated_range(shipped):
    true, temp = _world(shipped)
    count = np.histogram(temp, TEMPERATURE_EDGES_C)[0]
    near = (TEMPERATURE_EDGES_C[:-1] >= -45.0) & (TEMPERATURE_EDGES_C[:-1] < 0.0)
    assert np.all((count[near] >= VarianceSettings().min_samples)
                  & (count[near] < MIN_RANGE_SAMPLES)), count[near]
    stats = _hinge_statistics(law_parameters(shipped), true, np.random.default_rng(0),
                              temp=temp)
    assert stats.fitted_range() == (-55.0, -45.0)
    assert stats.fitted_range(VarianceSettings().min_samples)[1] >= 0.0
    assert np.all(true[:, 3] > -45.0)


def test_a_break_not_yet_brought_home_is_covered_by_its_stated_error(shipped):
    # one step from the shipped breaks, 2.6 and 3.3 C from the truth: the linearised
    # step takes part of the way, and before issue 34's fix (no shift outside the
    # stated range, no draw in the shift's cell) the x / y pulls were up to 3.1 / 7.1
    # (their rms 1.9 / 5.2, 8 draws): the stated error covered the noise, not the way
    # left.  Now within 3.
    true, temp = _world(shipped)
    pulls = np.array([(lambda tm, err, _: (tm - true[:, 3]) / err)(
        *_fit(shipped, true, temp, seed, passes=1)) for seed in range(8)])
    print("T_m pulls after one pass", pulls.round(2))
    assert np.all(np.abs(pulls) < 3.0), pulls


def test_converged_break_errors_match_the_brute_force_spread(shipped):
    # 4 passes (as far as `fit_days` goes in this world before it converges), 8 noise
    # draws: every pull within 3, and the stated error neither short nor far too wide:
    # its median within 0.5-2.5 of the brute-force rms of the fitted breaks about the
    # truth (8 draws: the rms itself is known to about 25 %)
    true, temp = _world(shipped)
    fits = [_fit(shipped, true, temp, seed, passes=4) for seed in range(8)]
    off = np.array([tm - true[:, 3] for tm, _, _ in fits])
    err = np.array([e for _, e, _ in fits])
    print("T_m off", off.round(2), "stated", err.round(2))
    assert np.all(np.abs(off / err) < 3.0), off / err
    ratio = np.median(err, axis=0) / np.sqrt(np.mean(off ** 2, axis=0))
    assert np.all((ratio > 0.5) & (ratio < 2.5)), ratio


# ---------------------------------------------------------------------------------------
# the late-peak Mercury orbit (forward model, slow)
# ---------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("seed", [3401])
def test_late_peak_breaks_are_covered_by_their_stated_errors(tmp_path, seed):
    # issue 34's late-peak Mercury orbit: the warm peaks 40-80 min after periapsis, the
    # break seen only in a few of them (4 days, seed 3401: stated +- 0.28 / 0.28 / 0.18 C
    # while 5.2 / 3.9 / 0.2 C off before the fix, pulls 18.6 / -13.9 / -0.9): every
    # break, free or held, lies within 3 of its stated error of the flight model's truth
    w = MercuryOrbit(seed, peak_lag_min=(40.0, 80.0))
    run = simulate_flight(tmp_path / "sim", FlightConfig(start=START, days=5, seed=seed),
                          wind=w.field, schedule=w.schedule, truth=True)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    res = fit_days(day_chunks(run.input_dir, run.days[:4]), load_calibration(START),
                   estimator="variance", guard=False, passes=12)
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    true_tm = (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1])
    fit_tm = np.asarray(res.calibration.breakpoint_temperature_c)
    err = np.array([f.x_m_err for f in res.temperature])
    pulls = (fit_tm - true_tm) / err
    print(f"held {sorted(res.held_upper)}, T_m {fit_tm.round(2)} +- {err.round(2)} C, "
          f"truth {true_tm.round(2)}, pulls {pulls.round(2)}; {res.convergence['stop']}")
    assert np.all(np.abs(pulls) < 3.0), pulls
    for j, a in enumerate("xyz"):  # a held break states the hold's width
        if a in res.held_upper:
            assert err[j] == pytest.approx(HOLD_BREAK_WIDTH_C, rel=0.2)
