"""Issue 34, item 2: a refusal never advises an option that then writes a table failing it.

The ``--error-goal`` a MESSENGER fit refusal advises (`fit_merit.advised_goal`, entry
26) is the least goal at which the same tables, judged as ``fit_days`` judges that
goal (`fit_passes.judged_at`), are written with the regulated temperature inside the range they
state.  Expected values here come from brute force over the constructed resamples, never
from the code under test.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger import fit_merit
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_breaks import N_PARAMETERS
from fluxcal.missions.messenger.fit_merit import (
    advised_goal,
    assess,
    check_merit,
    regulated_sum_untrusted,
)
from fluxcal.missions.messenger.fit_passes import (
    CONVERGENCE_SIGMA,
    LAW_TOLERANCE_COUNTS,
    convergence_record,
    judged_at,
    pass_changes,
)
from fluxcal.missions.messenger.fit_variance import (
    MOMENT_EDGES_C,
    law_parameters,
    law_values,
    offset_moments,
)
from tests.missions.messenger._fit_tables import (
    applied_law,
    scattered_laws,
    table_bootstrap,
    with_law_resamples,
)
from tests.missions.messenger.test_fit_variance import START, _variance_result

#: The regulated sensor temperature (C; sec. 7, eq. 2).
REGULATED_C = -50.0


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(str(START))


def _goal_for(band_nt: float) -> float:
    """The least goal (0.01 nT steps) whose law band limit, half the goal, admits ``band_nt``
    (entry 23: the limit is 0.05 nT at the goal 0.1 nT)."""
    return float(np.ceil(round(band_nt * 2.0 * 100, 6)) / 100)


def test_the_band_refusal_advises_the_goal_that_states_the_regulated_temperature(shipped):
    # resampled laws pivoting about 0 C: intercepts scatter by 1.25 counts, slopes by
    # 0.0223 counts/C, so the band is least near 0 C (about 0.06 nT on z) and 0.08 nT
    # at -50 C.  The least goal admitting any bin (about 0.12 nT) would state the law
    # near 0 C only, without the regulated -50 C where the heater holds the sensor; the
    # advice is the goal whose half admits the -50..-49 C bin, and at it the table is
    # written with -50 C inside its range
    base = _variance_result(shipped, np.zeros(N_PARAMETERS))
    law = law_parameters(base.calibration)
    rng = np.random.default_rng(34)
    k = 4000
    b_law = scattered_laws(law, rng, k, (1.25, 0.0223, 0.0, 0.0))
    temp = rng.uniform(-60.0, 40.0, 6000)
    res = with_law_resamples(base, b_law, temp)
    assess(res)
    # brute force: each 1-C bin's band (nT) at its samples' mean temperature, the
    # resamples' rms through Table 4's fine diagonal, the worst axis
    m_diag = np.abs(np.diag(np.asarray(res.calibration.matrices[0])))
    idx = np.searchsorted(MOMENT_EDGES_C, temp, side="right") - 1
    bins = np.unique(idx)
    t_mean = np.array([temp[idx == b].mean() for b in bins])
    spread = law_values(b_law, t_mean) - law_values(law, t_mean)[None]
    band = np.sqrt((spread ** 2).mean(axis=0)) * m_diag  # (bins, axes)
    guess = _goal_for(band.max(axis=1).min())
    regulated = _goal_for(band[MOMENT_EDGES_C[bins] == REGULATED_C].max())
    assert regulated > guess + 0.02  # the case this test is about
    assert not res.merit["law_determined"]
    # the least goal alone: the law stated near 0 C, without -50 C
    assert not judged_at(res, guess).stated_ranges.contains(REGULATED_C)
    with pytest.raises(FitRefusedError) as info:
        check_merit(res, rejudge=judged_at)
    msg = str(info.value)
    assert re.search(rf"--error-goal {regulated:g} \(the law's limit is 0\.5 of the goal; "
                     r"written into every table header; judged at", msg), msg
    goal, judged = advised_goal(res, guess, judged_at)
    assert goal == pytest.approx(regulated)
    assert judged.stated_ranges.contains(REGULATED_C)
    check_merit(judged)  # written at the advised goal
    # followed as the command line would (a fresh judgement at that goal): the same
    again = judged_at(res, regulated)
    assert again.stated_ranges == judged.stated_ranges
    np.testing.assert_allclose(again.merit["total_nt"], judged.merit["total_nt"])
    assert res.merit["goal_nt"] == pytest.approx(0.1)  # ``res`` itself is left as it was
    # without a re-judgement the refusal names its own numbers' goal (the old advice)
    with pytest.raises(FitRefusedError, match=rf"--error-goal {guess:g} \("):
        check_merit(res)


def test_a_goal_is_judged_with_the_law_s_convergence_over_its_own_t_range(shipped):
    # issue 34, item 1: the passes judge the law's change over the span of the T_RANGE
    # the table states, so a goal whose wider T_RANGE takes in a law the last pass still
    # moved would not write the table `judged_at` describes: it says so, and no such
    # goal is advised.  The first test's resampled laws with a smaller scatter (0.8
    # counts): the law is stated near 0 C at the default goal, wider at larger goals.
    # The last pass started from x's lower line rotated about its break (B0 + d,
    # A0 - d T_m: the lines still meet at T_m, eq. 4), so the law changed by
    # d (T_m - T) below T_m (closed form), inside the allowance over the default T_RANGE
    # and beyond it over a wider one.
    base = _variance_result(shipped, np.zeros(N_PARAMETERS))
    law = law_parameters(base.calibration)
    rng = np.random.default_rng(34)
    b_law = scattered_laws(law, rng, 4000, (0.8, 0.0223, 0.0, 0.0))
    res = with_law_resamples(base, b_law, rng.uniform(-60.0, 40.0, 6000))
    assess(res)
    tm, d = float(law[0, 3]), 0.008  # C, counts/C
    start = np.asarray(res.calibration.temperature_coefficients, dtype=float).copy()
    start[0, 0] -= d * tm
    start[0, 1] += d
    res.pass_start = dataclasses.replace(res.calibration, temperature_coefficients=start)

    def ratio_at(result, t):
        allow = max(LAW_TOLERANCE_COUNTS, CONVERGENCE_SIGMA * float(result.law_error(t)[0, 0]))
        return d * (tm - t) / allow

    lo = res.stated_ranges.span[0]
    assert lo < tm and ratio_at(res, lo) < 1.0  # the case this test is about
    res.convergence = convergence_record(
        pass_changes(res.pass_start, res, 2e-3, res.stated_ranges), 5, 12, 2e-3,
        res.stated_ranges)
    assert res.convergence["converged"]
    assert res.convergence["stop"].endswith(
        f"(the law judged over T_RANGE's span {res.stated_ranges.span[0]:g}.."
        f"{res.stated_ranges.span[1]:g} C)")
    wider = judged_at(res, 0.14)
    w_lo = wider.stated_ranges.span[0]
    assert w_lo < lo and ratio_at(wider, w_lo) > 1.0
    assert not wider.convergence["converged"]
    assert wider.convergence["stop"].startswith(
        f"not converged after 5 passes: the last changed law x at {w_lo:+.0f} C "
        f"{d * (tm - w_lo):+.4g} counts")
    assert res.convergence["converged"]  # ``res`` itself is left as it was
    # no goal is advised once a candidate's T_RANGE takes in the moving law (a larger
    # goal only widens it)
    assert advised_goal(res, 0.14, judged_at) == (None, None)
    # and the refusal says why, advising more days, not more passes: the fit converged at
    # its own goal, so more --passes would run the same passes (verification section 55)
    said = fit_merit._goal_advice(res, 0.14, judged_at, "the table")
    assert "so no --error-goal is advised: give more days" in said
    assert "give more passes" not in said
    # the same tables, the last pass not moving the law: the candidate converges
    res.pass_start = res.calibration
    assert judged_at(res, 0.14).convergence["converged"]


def _regulated_sum_result(shipped, compressive: int, judged: int = 48):
    """A fit whose law no bin determines on its own, while the regulated -50 C bin's
    offset ``cT(-50 C) + D0 R`` is determined: its D0 resamples cancel the law's error
    there up to 1.5 counts at ``R = 300`` ppt; ``compressive`` of ``judged`` intervals
    rejected as compressive.  Returns the result and the brute-force bands (nT) of the
    regulated bin: the law alone and the sum, per axis."""
    base = _variance_result(shipped, np.zeros(N_PARAMETERS))
    law = law_parameters(base.calibration)
    rng = np.random.default_rng(35)
    k = 4000
    b_law = scattered_laws(law, rng, k, (4.0, 0.03, 0.0, 0.0))
    off = rng.uniform(-60.0, 40.0, 6000)
    off = off[(off < -51.0) | (off >= -48.0)]  # heater off (R = 0), away from -50 C
    t_reg, r_reg = -49.6, 300.0  # heater-on at the regulated temperature
    n_reg = 3000
    temp = np.concatenate([off, np.full(n_reg, t_reg)])
    r = np.concatenate([np.zeros(off.size), np.full(n_reg, r_reg)])
    d_law = law_values(b_law, np.array([t_reg]))[:, 0, :] - law_values(law, np.array([t_reg]))[0]
    e = 1.5 * rng.standard_normal((k, 3))  # the sum's own scatter (counts)
    d0 = np.asarray(base.calibration.duty_cycle_d0, dtype=float)
    b_d0 = d0 + (e - d_law) / r_reg
    zero = np.zeros(temp.size)
    base.variance.offset_moments = offset_moments(temp, r, zero, zero)
    base.variance.reason = np.array(["compressive"] * compressive + [""] * (judged - compressive)
                                    + ["too_few_samples"] * (48 - judged))
    res = dataclasses.replace(base, bootstrap=table_bootstrap(base, b_law, b_d0),
                              waveform_error=None)
    assess(res)
    m_diag = np.abs(np.diag(np.asarray(res.calibration.matrices[0])))
    return (res, np.sqrt((d_law ** 2).mean(axis=0)) * m_diag,
            np.sqrt((e ** 2).mean(axis=0)) * m_diag)


@pytest.mark.parametrize("compressive, advised", [(12, True), (13, False), (0, True)])
def test_no_goal_is_advised_for_a_regulated_sum_alone_in_a_compressive_wind(
        shipped, compressive, advised):
    # entry 44: a table that would state the regulated -50 C only through the sum
    # cT(-50 C) + D0 R (the law's own band there above the limit) is advised only while at
    # most 25 % of the judged intervals were compressive (12 of 48 = 25 %: advised; 13:
    # not).  Expected goal: brute force, the least 0.01-nT goal whose half admits the
    # sum's band (the worst axis) in the regulated bin, the one bin any goal admits.
    # This fit states no field direction (`FitResult.d0_field`), so the sum is not
    # widened along it (entry 48: test_fit_sum_field.py, where it is): the refusal stands
    res, law_band, sum_band = _regulated_sum_result(shipped, compressive)
    goal = _goal_for(sum_band.max())
    assert law_band.min() > goal  # the law alone: beyond the limit at that goal, every axis
    assert sum_band.max() > 0.05  # refused at the default goal: the band
    assert not res.merit["law_determined"]
    with pytest.raises(FitRefusedError) as info:
        check_merit(res, rejudge=judged_at)
    msg = str(info.value)
    got, judged = advised_goal(res, goal, judged_at)
    if advised:
        assert re.search(rf"--error-goal {goal:g} \(", msg), msg
        assert got == pytest.approx(goal)
        assert str(judged.stated_ranges) == "-50..-49"
        check_merit(judged)  # written there
    else:
        assert got is None and judged is None
        assert "--error-goal" not in msg.split("not written.")[1].replace(
            "no --error-goal is advised", ""), msg
        assert re.search(rf"{compressive} of 48 intervals compressive \(above 25%\)", msg), msg
        assert "only through the sum of the law and D0 R" in msg
        # the law's own band there, as the brute force gives it (3 digits)
        assert f"{law_band[0]:.3g} / {law_band[1]:.3g} / {law_band[2]:.3g} nT" in msg, msg
        # entry 45: the goal the 25-% share would have advised, given by the
        # user anyway: that table's prediction is short, so it is refused, not written
        with pytest.raises(FitRefusedError, match=rf"regulated temperature \(sec. 7, eq. "
                           rf"2\): judged at {goal:g} nT.*{compressive} of 48 intervals"):
            check_merit(judged_at(res, goal))
        # a table that does not state -50 C at all predicts none of its samples there:
        # the sum's short error does not enter its prediction, so it is not judged
        elsewhere = dataclasses.replace(judged_at(res, goal),
                                        temperature_ranges=StatedRanges(((-40.0, -30.0),)))
        assert regulated_sum_untrusted(elsewhere) == ""


def test_a_compressive_wind_alone_keeps_the_advice_where_the_law_states_the_regulated_bin(
        shipped):
    # entry 44: the share alone withholds nothing.  The band test's world (the
    # laws pivot about 0 C, D0 not resampled: the regulated bin's band is the law's own),
    # 20 of 48 intervals compressive (42 %, below the 50 % guard): the advice is the goal
    # whose half admits the -50 C bin's band, brute force as in that test
    base = _variance_result(shipped, np.zeros(N_PARAMETERS))
    law = law_parameters(base.calibration)
    rng = np.random.default_rng(34)
    b_law = scattered_laws(law, rng, 4000, (1.25, 0.0223, 0.0, 0.0))
    temp = rng.uniform(-60.0, 40.0, 6000)
    res = with_law_resamples(base, b_law, temp)
    res.variance.reason = np.array(["compressive"] * 20 + [""] * 28)
    assess(res)
    m_diag = np.abs(np.diag(np.asarray(res.calibration.matrices[0])))
    t_reg = temp[(temp >= REGULATED_C) & (temp < REGULATED_C + 1.0)].mean()
    spread = law_values(b_law, np.array([t_reg]))[:, 0] - law_values(law, np.array([t_reg]))[0]
    regulated = _goal_for((np.sqrt((spread ** 2).mean(axis=0)) * m_diag).max())
    with pytest.raises(FitRefusedError, match=rf"--error-goal {regulated:g} \("):
        check_merit(res, rejudge=judged_at)


#: One unseen day is one draw of a predicted rms (test_fit_honest.py).
UNSEEN_OVER_PREDICTED = 1.5
#: D0, tau and the law against their stated errors: within 3 (D0's error along the
#: field's mean direction stated since messenger_fit.md entry 28; before it, D0 y's pull
#: here was 3.05).
D0_PULL_LIMIT = 3.0


@pytest.mark.slow
@pytest.mark.parametrize("days, hold", [(2, ""), (4, "z")])
def test_mercury_orbit_advice_writes_a_table_that_meets_its_stated_errors(tmp_path, days, hold):
    # issue 34: "4-day fits meet their stated errors or refuse, with and without holds",
    # and a refusal's advice followed exactly (`fluxcal messenger fit --error-goal G`:
    # `fit_days(..., error_goal=G)`) writes a table that meets them.  The truth: the
    # flight model's tables and its unseen next day (seed 3400: refused on the predicted
    # error, the heater waveforms the largest part; about 2-3 min)
    from fluxcal.missions.messenger import forward
    from fluxcal.missions.messenger.fit_cli import parse_hold_d0
    from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
    from fluxcal.missions.messenger.fit_write import write_calibration_folder
    from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
    from tests.missions.messenger._hard_worlds import MercuryOrbit
    from tests.missions.messenger._unseen_day import inside_ranges, recalibrate_errors, rms

    world = MercuryOrbit(3400)
    run = simulate_flight(tmp_path / "sim", FlightConfig(start="2010-03-01", days=days + 1,
                                                         seed=3400),
                          wind=world.field, schedule=world.schedule, truth=True)
    chunks = day_chunks(run.input_dir, run.days[:days])
    base = load_calibration(str(START))
    # follow each refusal's advice exactly, as a user would: a D0 the data do not
    # determine (--hold-d0 AXIS), then the predicted error (--error-goal G)
    hold_text, goal, followed = hold, None, []
    for _ in range(3):
        try:
            res = fit_days(chunks, base, estimator="variance", hold_d0=parse_hold_d0(hold_text),
                           **({} if goal is None else {"error_goal": goal}))
            break
        except FitRefusedError as exc:
            msg = str(exc)
            if m := re.search(r"--error-goal ([0-9.]+[0-9])", msg):
                goal = float(m.group(1))
            elif m := re.search(r"--hold-d0 ([xyz])\b", msg):
                hold_text = ",".join(filter(None, (hold_text, m.group(1))))
            else:  # a refusal that advises no option: it says why (entry 26)
                assert "none is advised" in msg or "more days" in msg, msg
                print(f"{days} days: followed {followed}, then refused: {msg}")
                return
            followed.append(m.group(0))
    else:
        pytest.fail(f"still refused after following {followed}")
    assert followed  # this world needs advice (seed 3400)
    assert res.merit["goal_nt"] == goal and res.stated_ranges.contains(REGULATED_C)
    out = tmp_path / "fitted"
    write_calibration_folder(res, out, None, {"inputs": {}, "intervals": "all data",
                                              "days": str(days), "command": "test"})
    assert f"--error-goal {goal:g}" in (out / "offsets_temperature_v2.csv").read_text()
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    # the unseen day inside T_RANGE and D_RANGE (the truth's temperature and duty cycle)
    # within 1.5x the prediction the header states
    err, truth = recalibrate_errors(run.input_dir, run.days[days], out)
    unseen = rms(err, inside_ranges(truth, res.stated_ranges, res.duty_range))
    predicted = np.asarray(res.merit["total_nt"])
    assert np.all(unseen <= UNSEEN_OVER_PREDICTED * predicted), (unseen, predicted)
    # the law inside T_RANGE within 3 of its stated band (0.5-C grid)
    lo, hi = res.merit["data_range_c"]
    grid = np.arange(np.floor(lo), np.ceil(hi) + 0.01, 0.5)
    grid = grid[res.stated_ranges.contains(grid)]
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    law_pull = ((applied_law(res.calibration.temperature_coefficients, grid)
                 - applied_law(tc, grid)) / res.law_error(grid))
    assert np.all(np.abs(law_pull) <= 3.0), np.abs(law_pull).max(axis=0)
    # tau and D0 (a held one: its width) against their stated errors
    tau = true.constants["relaxation"]["tau_s"]
    assert abs(res.relaxation.tau - tau) <= 3.0 * res.relaxation.tau_err
    d0_pull = ((res.calibration.duty_cycle_d0 - true.d0)
               / np.array([f.slope_err for f in res.duty]))
    assert np.all(np.abs(d0_pull) <= D0_PULL_LIMIT), d0_pull
    print(f"{days} days, held {hold_text or 'none'}: followed {followed}; T_RANGE "
          f"{res.stated_ranges} C, D_RANGE {res.duty_range}; predicted {predicted.round(3)} "
          f"nT, unseen inside both {unseen.round(3)} nT; law pulls within "
          f"{np.abs(law_pull).max():.2f}; D0 pulls {d0_pull.round(2)}")


@pytest.mark.slow
def test_the_demo_follows_each_advice_to_a_table_that_meets_its_stated_errors(tmp_path):
    # the fit demo's world (`fit_demo`: its true tables, 2 days of its realistic wind):
    # refused on D0 z, whose advice (--hold-d0 z) is refused on the law's band, whose
    # advice (--error-goal G) writes a table stating the regulated -50 C; checked against
    # the true tables and the unseen 2-h orbit (heater on at -50 C, fine range).  Before
    # entry 26 the band refusal advised 0.13 nT, which states T_RANGE 21..23 C
    # only.  Three fits, about 4 min
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel, utc_to_et
    from fluxcal.missions.messenger import fit_demo
    from fluxcal.missions.messenger.chain import calibrate
    from fluxcal.missions.messenger.fit_cli import parse_hold_d0
    from fluxcal.missions.messenger.fit_passes import Chunk, fit_days
    from fluxcal.missions.messenger.fit_write import write_calibration_folder
    from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
    from fluxcal.missions.messenger.simulate import SimulationConfig
    from tests.missions.messenger._unseen_day import inside_ranges, rms

    start = "2012-06-01T00:00:00"
    truth = fit_demo.perturbed_folder(tmp_path / "truth_tables")
    train = fit_demo.simulate_training(tmp_path / "training", truth, start, 2.0)
    chunks = [Chunk("training", (train["science"],), (train["heater"],),
                    (train["temperature"],), (train["kernels"],))]
    base = load_calibration(start)
    with pytest.raises(FitRefusedError, match=r"D0 z = .* a relative error above the 5% "
                                              r"goal.*--hold-d0 z: the start table") as info:
        fit_days(chunks, base, estimator="variance")
    axis = re.search(r"--hold-d0 ([xyz]): the start table", str(info.value)).group(1)
    held = parse_hold_d0(axis)
    with pytest.raises(FitRefusedError, match=r"its stated error exceeds 0\.05 nT at every "
                                              r"temperature") as info:
        fit_days(chunks, base, estimator="variance", hold_d0=held)
    goal = float(re.search(r"--error-goal ([0-9.]+[0-9])", str(info.value)).group(1))
    assert goal > 0.13  # the old advice stated the law at 21..23 C only
    res = fit_days(chunks, base, estimator="variance", hold_d0=held, error_goal=goal)
    ranges = res.stated_ranges
    assert ranges.contains(REGULATED_C), ranges
    out = tmp_path / "fitted"
    write_calibration_folder(res, out, None, {"inputs": {}, "intervals": "all data",
                                              "days": "2", "command": "test"})
    tc = load_calibration(fit_demo.UNSEEN_START, truth)
    # the law inside T_RANGE within 3 of its band (0.5-C grid), tau and D0 (held z: its
    # width) within 3 of their stated errors, against the true tables
    lo, hi = res.merit["data_range_c"]
    grid = np.arange(np.floor(lo), np.ceil(hi) + 0.01, 0.5)
    grid = grid[ranges.contains(grid)]
    law_pull = ((applied_law(res.calibration.offset_coefficients(), grid)
                 - applied_law(tc.offset_coefficients(), grid)) / res.law_error(grid))
    assert np.all(np.abs(law_pull) <= 3.0), np.abs(law_pull).max(axis=0)
    tau = tc.constants["relaxation"]["tau_s"]
    assert abs(res.relaxation.tau - tau) <= 3.0 * res.relaxation.tau_err
    d0_pull = ((res.calibration.duty_cycle_d0 - np.asarray(tc.duty_cycle_d0))
               / np.array([f.slope_err for f in res.duty]))
    assert np.all(np.abs(d0_pull) <= 3.0), d0_pull
    # the unseen orbit: its fine-range samples inside T_RANGE and, heater on, inside
    # D_RANGE (the commanded duty cycle of each 1000-s block of the forward model's
    # schedule), within 1.5x the prediction the header states
    config = SimulationConfig()
    mk = fit_demo.unseen_kernels(tmp_path)
    with KernelPool(mk, frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        sim = fit_demo.simulate_unseen(tc, sclk)
        ds = calibrate(sim["science"], sim["heater"], sim["temperature"],
                       load_calibration(fit_demo.UNSEEN_START, out), frames=("sc",),
                       max_offset_step=None)
        et0 = float(utc_to_et(np.array([fit_demo.UNSEEN_START]))[0])
    tr = sim["truth"]
    block = np.floor((tr["et"].values - et0 + config.lead_s) / config.block_s).astype(int)
    duty = np.asarray(config.duty_cycles_percent)[np.mod(np.maximum(block, 0),
                                                         len(config.duty_cycles_percent))]
    sample = {"met": tr["et"].values, "temperature_c": tr["temperature"].values,
              "duty_percent": np.where(block >= 0, duty, 0)}
    inside = inside_ranges(sample, ranges, res.duty_range) & (tr["range"].values == 0)
    assert inside.mean() > 0.3
    unseen = rms(ds["b_sensor"].values - tr["b_sensor"].values, inside)
    predicted = np.asarray(res.merit["total_nt"])
    print(f"advised --hold-d0 {axis}, then --error-goal {goal:g}: T_RANGE {ranges} C; "
          f"predicted {predicted.round(3)} nT, unseen orbit inside T_RANGE and D_RANGE "
          f"{unseen.round(3)} nT; law pulls within {np.abs(law_pull).max():.2f}; D0 pulls "
          f"{d0_pull.round(2)}")
    assert np.all(unseen <= UNSEEN_OVER_PREDICTED * predicted), (unseen, predicted)
