"""Pull study of the MESSENGER variance estimator (issue 21, item 3).

    .venv/bin/python benchmarks/messenger_fit_pulls.py --realisations 20 --days 2 \\
        --compressive 0.03
    .venv/bin/python benchmarks/messenger_fit_pulls.py --realisations 20 --days 16 \\
        --processes 16          # on a many-core machine: one realisation per process

Each realisation simulates ``--days`` days of the independent realistic wind of
``tests/missions/messenger/_realistic_wind.py`` (18 nT, Alfvenic rotations, sectors;
``--compressive`` relative |B| fluctuation) through `flight_sim` at 1 Hz with seed
``--first-seed + k``, fits it with ``--estimator variance`` (guards off: the estimator's own
errors), and prints, per realisation and then over all, the pulls ``(fit - truth) /
stated error`` of tau, dt (when adopted), D0 (x, y, z), the breaks T_m, and the temperature law at
-50, -40, -30, -20, 0 and +30 C (per axis, where inside the fitted range), and the law's largest
error (nT) over the fitted range.  Pulls with mean ~0 and spread ~1, all within
[-3, 3], mean the errors say what they mean.  Each line also gives the passes run, the
predicted error of a recalibrated day (issue 34) and what the command line would have
done (the compressive share, convergence, `check_fit`, `fit_merit.check_merit`).
Issue 34's verification (20 realisations per world, 16 days; a 16-core machine)::

    .venv/bin/python benchmarks/messenger_fit_pulls.py --realisations 20 --days 16 \
        --unseen --passes 6 --processes 16 [--broadband --compressive 0.05] [--hold-d0 z]

``--markdown`` prints the table for docs/decisions/messenger_fit_verification.md.
``--draw-law`` draws the true temperature law (breaks and slopes) per realisation, so the
breaks' pulls test a spread of truths (``_hard_worlds.drawn_law``); ``--summarise FOLDER
--estimators`` compares spread estimators of the stated errors (standard deviation, half
the 15.9-84.1 percentile width, 1.4826 MAD, a mixture that states a rare break jump
apart) by the pulls each would give on the saved fits' own resamples (entry 39).  The
summary gives per parameter the pulls' spread, largest size and count beyond 3 (issue 34:
spread within 0.7-1.5, fewer than 1 % beyond 3), and which written tables miss a goal.
``--summarise FOLDER --bands`` gives the law's pulls under design-fixed bands that cannot
pinch (`BANDS`: the fixed-design bootstrap replayed, floored by or combined with the
stored pairs band; entry 46), at `LAW_T` and over the stated range's grid.
``--summarise FOLDER --wild`` gives the pulls under the wild cluster bootstrap
(`fit_variance.solve_variance(bootstrap="wild")`) beside the fit's own and combinations of
the two (`WILD_COLUMNS`; entry 50).
``--summarise FOLDER --profile`` gives T_m's pulls with its error from the residual's
profile against the break (`fit_break_profile.profile_break_errors`) beside the fit's own and
floored at fractions of it (`PROFILE_FLOORS`; entry 51).
``--save FOLDER`` keeps each realisation's fit, truth and row; ``--summarise FOLDER``
prints the summary of a saved run again (fits saved without a row: no unseen day).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import functools
import os
import pickle
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

# one BLAS/OpenMP thread per process (realisations run side by side with --processes)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402
from scipy.stats import chi2, norm  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.missions.messenger._hard_worlds import (  # noqa: E402
    MercuryOrbit,
    cruise_hard_wind,
    drawn_law,
)
from tests.missions.messenger._realistic_wind import realistic_wind  # noqa: E402
from tests.missions.messenger._unseen_day import (  # noqa: E402
    day_streams,
    inside_ranges,
    recalibrate_errors,
    rms,
)

from fluxcal.calibration.heater_signal import heater_signal, period_index  # noqa: E402
from fluxcal.calibration.offsets import two_segment_offset  # noqa: E402
from fluxcal.errors import FitRefusedError  # noqa: E402
from fluxcal.geometry.kernels import KernelPool  # noqa: E402
from fluxcal.geometry.time import SclkKernel  # noqa: E402
from fluxcal.missions.messenger import fit_breaks as fb  # noqa: E402
from fluxcal.missions.messenger import fit_merit, forward, levels  # noqa: E402
from fluxcal.missions.messenger import fit_variance as fv  # noqa: E402
from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.fit_break_profile import profile_break_errors  # noqa: E402
from fluxcal.missions.messenger.fit_guards import break_refusal, check_fit  # noqa: E402
from fluxcal.missions.messenger.fit_passes import (  # noqa: E402
    day_chunks,
    fit_days,
    judged_at,
    merit_inside_range,
)
from fluxcal.missions.messenger.fit_reduce import interpolation_weights  # noqa: E402
from fluxcal.missions.messenger.fit_write import write_calibration_folder  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402
from fluxcal.missions.messenger.identity import FRAME_KERNELS  # noqa: E402

#: Temperatures (C) of the law's pulls: the heater-regulated level, the heater-off warm
#: run up to the breaks (-18..-8 C in the true tables; the Mercury orbit's T_RANGE ends
#: at -45..-24 C), both sides of the breaks, the upper segment.
LAW_T = (-50.0, -40.0, -30.0, -20.0, 0.0, 30.0)
#: Counts to nT (fine range, eq. 8's diagonal, ~0.047 nT per count).
NT_PER_COUNT = 0.047


def law_difference(fitted: np.ndarray, truth: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Return the fitted minus the true Table 2 law (counts) at ``t``, shape (t, axis).

    Each as the table applies it (`two_segment_offset`, eq. 3a, 3b, 4): ``A0 + B0 T`` up
    to ``T_m``, ``A1 + B1 T`` above; not the larger of the two lines, which differs where
    a fitted upper segment no data determine comes out with ``B1 < B0`` (Mercury orbit,
    16 days, seed 3507: x's ``B1 = -239 +- 683`` counts/C, 10 000 counts off at -60 C;
    verification section 24).

    Parameters
    ----------
    fitted, truth : ndarray, shape (3, 4)
        ``A0, B0, A1, B1`` per axis.
    t : ndarray, shape (n,)
        Temperatures (C).
    """
    return two_segment_offset(t, fitted) - two_segment_offset(t, truth)


def defects(seed: int, days: int) -> dict:
    """Telemetry defects over ``days`` days (FlightConfig fields): per day 5 science gaps
    of 10 s to 20 min, one coarse-range span of 1-30 min, 3 heater-bit gaps of 5-90 s, 3
    temperature gaps of 20-500 s; rate setting 7 over the middle 30 % of the span."""
    rng = np.random.default_rng(seed)
    span = days * 86400.0

    def spans(per_day: int, lo: float, hi: float) -> list[tuple[float, float]]:
        return [(t, t + rng.uniform(lo, hi))
                for t in np.sort(rng.uniform(0, span, days * per_day))]

    return {"science_gaps": spans(5, 10.0, 1200.0), "coarse_intervals": spans(1, 60.0, 1800.0),
            "heater_gaps": spans(3, 5.0, 90.0), "temperature_gaps": spans(3, 20.0, 500.0),
            "rate_changes": [(0.3 * span, 7), (0.6 * span, 6)]}


def one(k: int, days: int, compressive: float, passes: int, save: Path | None = None,
        first_seed: int = 1000, unseen: bool = False, broadband: bool = False,
        with_defects: bool = False, hold_d0: tuple[str, ...] = (),
        world: str = "realistic", draw_law: bool = False) -> dict:
    """Simulate, fit and compare realisation ``k`` (``save``: pickle the fit and truth as
    ``fit_<seed>.pkl``; ``unseen``: one more day simulated, recalibrated with the fitted
    tables; ``broadband``: the compressive part down to 2 s; ``with_defects``: `defects`;
    ``world``: `WORLDS`; ``draw_law``: the true Table 2 drawn per seed, `drawn_law`)."""
    with tempfile.TemporaryDirectory() as tmp:
        wind, schedule = world_model(world, first_seed + k, compressive, broadband)
        extra = defects(first_seed + k, days) if with_defects else {}
        run = simulate_flight(Path(tmp) / "sim", FlightConfig(start="2010-03-01",
                                                              days=days + int(unseen),
                                                              seed=first_seed + k, **extra),
                              drawn_law(first_seed + k) if draw_law else None,
                              wind=wind, schedule=schedule, truth=unseen)
        true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
        base = load_calibration(np.datetime64("2010-03-01"))
        res = fit_days(day_chunks(run.input_dir, run.days[:days]), base, passes=passes,
                       estimator="variance", guard=False, hold_d0=hold_d0)
        verdict = command_line_verdict(res)
        nan3 = np.full(3, np.nan)
        unseen_rms = unseen_in = unseen_both = unseen_beyond = nan3
        beyond_share = np.nan
        wave_parts = {}
        day_pred = {}
        if unseen:
            folder = Path(tmp) / "fitted"
            write_calibration_folder(res, folder, None, {
                "inputs": {}, "intervals": "all data", "days": f"first {days}",
                "command": "messenger_fit_pulls"}, study=True)
            err, truth = recalibrate_errors(run.input_dir, run.days[-1], folder)
            unseen_rms = rms(err)
            in_t = inside_ranges(truth, res.stated_ranges)
            unseen_in = rms(err, in_t)
            # inside T_RANGE and D_RANGE: what the prediction now holds for (issue 34)
            both = inside_ranges(truth, res.stated_ranges, res.duty_range)
            unseen_both = rms(err, both)
            unseen_beyond = rms(err, in_t & ~both)  # heater-on, duty outside D_RANGE
            beyond_share = float(np.count_nonzero(in_t & ~both)) / max(in_t.sum(), 1)
            wave_parts = waveform_parts(run.input_dir, run.days[-1], folder, res, true,
                                        truth, in_t & ~both)
            day_pred = unseen_day_prediction(run.input_dir, run.days[-1], res)
    row = {**pulls(res, true), "k": k, "verdict": verdict, "unseen_nt": unseen_rms,
           "unseen_in_range_nt": unseen_in, "unseen_in_both_nt": unseen_both,
           "unseen_beyond_duty_nt": unseen_beyond, "unseen_beyond_duty_share": beyond_share,
           "waveform_parts": wave_parts,
           "day_prediction": day_pred}
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        # named by seed: runs of consecutive seeds (--first-seed) can share a folder
        (save / f"fit_{first_seed + k:03d}.pkl").write_bytes(pickle.dumps((res, true)))
        (save / f"row_{first_seed + k:03d}.pkl").write_bytes(pickle.dumps(row))
    return row


def command_line_verdict(res) -> str:
    """What the command line would do with the fit ``res`` (it writes nothing if refused):
    ``"accepted"`` or ``"refused: <cause>"``."""
    try:
        cause = fit_merit.compressive_refusal(res.variance.reason)
        if cause:
            raise FitRefusedError(cause)
        if not res.convergence["converged"]:
            cause = break_refusal(res, error=False)  # named first, as fit_days does
            raise FitRefusedError(f"{cause} ({res.convergence['stop']})" if cause
                                  else res.convergence["stop"])
        check_fit(res)
        fit_merit.check_merit(res, rejudge=judged_at)  # advice judged as fit_days does
    except FitRefusedError as exc:
        return f"refused: {exc}"
    return "accepted"


def pulls(res, true) -> dict:
    """The pulls and errors of the fit ``res`` against the flight model's ``true`` tables
    (everything `one` reports but the unseen day and the verdict)."""
    cal = res.calibration
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    ranges = res.stated_ranges
    lo, hi = res.fitted_range
    t_all = np.arange(lo, hi + 0.01, 1.0)
    law_t = np.array(LAW_T)
    if ranges is not None:  # T_RANGE: one or more intervals (entry 24)
        t_all = t_all[ranges.contains(t_all)]
    inside = ranges.contains(law_t) if ranges is not None else (law_t >= lo) & (law_t <= hi)
    law_pull = (law_difference(cal.temperature_coefficients, tc, law_t)
                / res.law_error(law_t))
    true_tm = (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1])
    law_pull[~inside] = np.nan
    rel = true.constants["relaxation"]
    r = res.relaxation
    return {
        "tau_pull": (r.tau - rel["tau_s"]) / r.tau_err,
        "tau_rel": r.tau / rel["tau_s"] - 1.0,
        "dt_pull": (r.dt - rel["delay_s"]) / r.dt_err if res.delay_fitted else np.nan,
        "d0_pull": (cal.duty_cycle_d0 - true.d0) / np.array([f.slope_err for f in res.duty]),
        "d0_rel": cal.duty_cycle_d0 / true.d0 - 1.0,
        "d0_err_rel": np.array([f.slope_err for f in res.duty]) / np.abs(true.d0),
        "d0_balance": float(getattr(res, "d0_field", {}).get("balance", np.nan)),
        "law_pull": law_pull,  # (temperature, axis)
        "law_max_nt": NT_PER_COUNT * np.abs(law_difference(cal.temperature_coefficients, tc,
                                                           t_all)).max(axis=0),
        "range": (lo, hi),
        "t_range": str(ranges),
        "tm_pull": (np.asarray(cal.breakpoint_temperature_c) - true_tm)
        / np.array([f.x_m_err for f in res.temperature]),
        "tm_err": np.array([f.x_m_err for f in res.temperature]),
        "predicted_nt": np.asarray(res.merit.get("total_nt", [np.nan] * 3)),
        "stated_waveform_nt": np.asarray(res.merit.get("waveform_nt", [np.nan] * 3)),
        "fitted_mix_waveform_nt": np.asarray(res.merit.get("waveform_fitted_mix_nt",
                                                           [np.nan] * 3)),
        "passes": res.convergence["passes_run"],
        "duty_range": res.duty_range,
        "duty_outside_share": (res.merit.get("samples_outside_duty_range", 0)
                               / max(res.merit.get("heater_on_samples", 0), 1)),
        "predicted_without_duty_nt": _prediction_without_duty_range(res),
        "held_upper": sorted(res.held_upper),
        "law_band_max_nt": NT_PER_COUNT * res.law_error(t_all).max(axis=0),
        **dict(zip(("law_max_pull", "law_max_threshold"),
                   law_grid_pull(res, cal.temperature_coefficients, tc, t_all), strict=True)),
        "outside_share": (res.merit["outside"]["samples"] / max(res.merit["outside"]["of"], 1)
                          if "outside" in res.merit else 0.0),
        "compressive_share": fit_merit.compressive_share(res.variance.reason),
        "reasons": dict(zip(*np.unique(np.asarray(res.variance.reason), return_counts=True),
                            strict=True)),
    }


def waveform_parts(inp: Path, day, folder: Path, res, true, truth: dict,
                   outside: np.ndarray) -> dict:
    """The unseen day's heater-waveform error alone, inside and outside D_RANGE.

    The pipeline's heater signal (`heater_signal`, its periods from the day's heater
    bits) with the fitted columns less the same with the flight model's true columns,
    through eq. 8's fine matrix (nT rms per axis), over the heater-on samples whose
    duty cycle lies inside / outside D_RANGE (``outside``); and what the columns'
    stated errors give when propagated through the pipeline's interpolation weights
    (``sum_k w_k(d)^2 err_k^2``, the columns independent: the statistical part alone).
    """
    sci, htr, _ = day_streams(inp, day)
    cal = load_calibration(np.datetime64(str(day)), folder)
    with KernelPool(inp / "kernels.tm"):
        sclk = SclkKernel.from_pool(levels.SC_ID)
        et = levels.correct_time(sci, cal, sclk)["et"].values
        periods, _ = levels.find_heater_periods(htr, cal, sclk)
    bins = cal.heater_duty_bins_percent
    fitted, on = heater_signal(et, periods, cal.heater_signal, bins)
    truth_signal, _ = heater_signal(et, periods, np.asarray(true.heater), true.heater_bins)
    m = np.asarray(cal.matrices[0])
    diff = (fitted - truth_signal) @ m.T
    k = period_index(et, periods)
    duty = np.where(k >= 0, periods.duty_cycle[np.maximum(k, 0)] * 100.0, np.nan)
    w2 = interpolation_weights(duty, bins) ** 2                       # (n, bins)
    var = w2 @ (np.asarray(res.waveform_error) ** 2).T                 # (n, axes)
    out = {}
    for name, sel in (("inside", on & ~outside), ("outside", on & outside)):
        out[f"{name}_true_nt"] = rms(diff, sel)
        out[f"{name}_propagated_nt"] = (np.sqrt((m ** 2) @ var[sel].mean(axis=0))
                                        if sel.any() else np.full(3, np.nan))
    # where a shortfall inside D_RANGE comes from (entry 29): each column's true
    # error (rms over the phase, counts) weighted by the fitted days' shares (the merit's
    # weighting with the truth's errors), by the unseen day's shares, and through the
    # unseen day's interpolation weights (the columns' cross terms left out)
    table = np.asarray(true.heater, dtype=float)[:, :100, :]
    col_true = np.sqrt(np.mean((np.asarray(cal.heater_signal, dtype=float)[:, :100, :]
                                - (table - table.mean(axis=1, keepdims=True))) ** 2, axis=1))
    sel = on & ~outside
    if sel.any():
        count = np.array([w.count.sum() for w in res.stats.waveform], dtype=float)
        duty_range = res.duty_range or (-np.inf, np.inf)
        count[(bins < duty_range[0]) | (bins >= duty_range[1])] = 0.0
        fitted_share = count / count.sum()
        width = bins[1] - bins[0]
        b = np.clip(np.floor((duty[sel] - bins[0] + width / 2) / width).astype(int), 0,
                    bins.size - 1)
        unseen_share = np.bincount(b, minlength=bins.size) / b.size
        for name, share in (("fitted_share", fitted_share), ("unseen_share", unseen_share)):
            out[f"{name}_true_cols_nt"] = np.sqrt((m ** 2) @ (col_true ** 2 @ share))
        out["unseen_weights_true_cols_nt"] = np.sqrt(
            (m ** 2) @ (w2[sel] @ (col_true ** 2).T).mean(axis=0))
        for name, share in (("fitted_share", fitted_share), ("unseen_share", unseen_share)):
            out[f"{name}_stated_nt"] = np.sqrt(
                (m ** 2) @ (np.asarray(res.waveform_error) ** 2 @ share))
        out["col_true_over_stated"] = np.round(col_true / np.asarray(res.waveform_error), 2)
        out["fitted_share"] = np.round(fitted_share, 3)
        out["unseen_share"] = np.round(unseen_share, 3)
    return out


def unseen_day_prediction(inp: Path, day, res) -> dict:
    """The prediction for the unseen day itself (`fit_merit.DaySamples`: its own
    temperatures, relaxed duty cycles and duty-bin counts; entry 32), over its
    samples inside T_RANGE as `merit_inside_range` holds the fit's own: ``total_nt``,
    ``waveform_nt``."""
    sci, htr, tmp = day_streams(inp, day)
    # a pool of its own, unloaded on exit (not the fit workers' process-wide pool, which
    # would stay loaded after this realisation's folder is deleted)
    with KernelPool(inp / "kernels.tm", frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(levels.SC_ID)
        samples = fit_merit.day_samples(sci, htr, tmp, sclk, res.calibration)
    mom = samples.moments
    ranges = res.stated_ranges
    if ranges is not None and ranges.contains(-50.0):
        with np.errstate(invalid="ignore", divide="ignore"):
            inside = (mom[:, 0] > 0) & ranges.contains(mom[:, 1] / mom[:, 0])
        samples = dataclasses.replace(samples, moments=mom * inside[:, None])
    p = fit_merit.predicted_error(res, res.merit.get("goal_nt", 0.1), day=samples)
    return {"total_nt": np.round(p["total_nt"], 3), "waveform_nt": np.round(p["waveform_nt"], 3)}


def _parts(p: dict) -> str:
    return ", ".join(f"{k} {np.round(v, 3)}" for k, v in p.items()) or "-"


def _prediction_without_duty_range(res) -> np.ndarray:
    """The predicted error as before the duty range: every heater-on sample counted, the
    waveform share of the samples in no bin zero (a copy of ``res`` whose columns all
    read as kept states no D_RANGE; judged as `fit_days` judges, inside T_RANGE)."""
    if "total_nt" not in res.merit:
        return np.full(3, np.nan)
    copy = dataclasses.replace(res, waveform=[[None] * len(w) for w in res.waveform])
    fit_merit.assess(copy, res.merit["goal_nt"])
    merit_inside_range(copy, res.merit["goal_nt"])
    return np.asarray(copy.merit["total_nt"])


#: The worlds ``--world`` knows: the test wind of issue 21 and issue 34's two hard worlds
#: (tests/missions/messenger/_hard_worlds.py).
WORLDS = ("realistic", "cruise-hard", "mercury-orbit", "mercury-orbit-late")


def world_model(world: str, seed: int, compressive: float | None, broadband: bool):
    """``(wind, schedule)`` callables for `simulate_flight` (``None``: its default).

    ``compressive``: the relative rms of the compressive part (``None``: 0.03 in the
    realistic wind, drawn in 0.10-0.15 in the hard cruise wind).
    """
    if world == "realistic":
        return functools.partial(realistic_wind, broadband=broadband,
                                 compressive=0.03 if compressive is None else compressive), None
    if world == "cruise-hard":
        return functools.partial(cruise_hard_wind, compressive=compressive), None
    if world in ("mercury-orbit", "mercury-orbit-late"):
        orbit = (MercuryOrbit(seed) if world == "mercury-orbit"
                 else MercuryOrbit(seed, peak_lag_min=(40.0, 80.0)))
        return orbit.field, orbit.schedule
    raise ValueError(f"world {world!r}: choose one of {', '.join(WORLDS)}")


def _timed(k: int, **kwargs) -> tuple[int, float, dict]:
    """`one` with its wall time: ``(k, seconds, result)``."""
    t0 = time.perf_counter()
    r = one(k, **kwargs)
    return k, time.perf_counter() - t0, r


def table(rows: list[dict]) -> list[tuple[str, np.ndarray]]:
    """``(parameter, pulls over realisations)`` for every parameter."""
    out = [("tau", np.array([r["tau_pull"] for r in rows])),
           ("dt", np.array([r["dt_pull"] for r in rows]))]
    d0 = np.stack([r["d0_pull"] for r in rows])
    law = np.stack([r["law_pull"] for r in rows])
    out += [(f"D0 {a}", d0[:, j]) for j, a in enumerate("xyz")]
    # a held upper segment's break is the shipped one, its error the held width: with
    # the flight model's truth the same in every realisation its pull is one number
    tm = np.stack([r["tm_pull"] for r in rows])
    held = np.array([[a in r["held_upper"] for a in "xyz"] for r in rows])
    out += [(f"T_m {a}", np.where(held[:, j], np.nan, tm[:, j])) for j, a in enumerate("xyz")]
    out += [(f"T_m {a} held", np.where(held[:, j], tm[:, j], np.nan))
            for j, a in enumerate("xyz")]
    out += [(f"law {a} at {t:+.0f} C", law[:, i, j]) for j, a in enumerate("xyz")
            for i, t in enumerate(LAW_T)]
    return out


def realisation_table(rows: list[dict]) -> None:
    """Print one markdown row per realisation: verdict and issue 34's goal checks."""
    print("| k | passes | held | T_RANGE (C) | law in T_RANGE (nT) | tau | D0 x / y / z | "
          "unseen in T_RANGE, D_RANGE (nT) | predicted (nT) | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        def nt(v):
            return " / ".join(f"{x:.3f}" for x in v)
        print(f"| {r.get('k', '')} | {r['passes']} | {', '.join(r['held_upper']) or '-'} | "
              f"{r['t_range']} | {nt(r['law_max_nt'])} | {r['tau_rel']:+.1%} | "
              f"{' / '.join(f'{x:+.1%}' for x in r['d0_rel'])} | "
              f"{nt(r['unseen_in_both_nt'])} | {nt(r['predicted_nt'])} | "
              f"{r['verdict'][:90]} |")


def summarise(rows: list[dict], markdown: bool = False) -> None:
    """Print, per parameter, the pulls' mean, spread, largest size and count beyond 3
    (issue 34: spread within 0.7-1.5, fewer than 1 % beyond 3), then the goals met."""
    if markdown:
        realisation_table(rows)
        print()
        print("| parameter | N | mean pull | spread (std) | max abs pull | beyond 3 |")
        print("|---|---|---|---|---|---|")
    for name, p in table(rows):
        p = p[np.isfinite(p)]
        if p.size == 0:
            continue
        spread = p.std(ddof=1) if p.size > 1 else np.nan
        beyond = int(np.count_nonzero(np.abs(p) > 3.0))
        if markdown:
            print(f"| {name} | {p.size} | {p.mean():+.2f} | {spread:.2f} | "
                  f"{np.abs(p).max():.2f} | {beyond} |")
        else:
            flag = "" if 0.7 <= spread <= 1.5 and beyond < 0.01 * p.size else "  <- outside"
            print(f"{name}: N {p.size} mean {p.mean():+.2f} std {spread:.2f} "
                  f"max |pull| {np.abs(p).max():.2f} beyond 3: {beyond}{flag}")
    law_max = np.stack([r["law_max_nt"] for r in rows])
    print(f"law's largest error over the fitted range (nT): median "
          f"{np.round(np.median(law_max, axis=0), 3)}, max {np.round(law_max.max(axis=0), 3)}")
    if np.isfinite(rows[0]["unseen_nt"]).all():
        un = np.stack([r["unseen_nt"] for r in rows])
        print(f"unseen day rms (nT): median {np.round(np.median(un, axis=0), 3)}, max "
              f"{np.round(un.max(axis=0), 3)}; within 0.1 nT on every axis "
              f"{int(np.all(un <= 0.1, axis=1).sum())} of {len(rows)}")
        both = np.stack([r["unseen_in_both_nt"] for r in rows])
        print(f"unseen day inside T_RANGE and D_RANGE (nT): median "
              f"{np.round(np.nanmedian(both, axis=0), 3)}, max "
              f"{np.round(np.nanmax(both, axis=0), 3)}; within 0.1 nT on every axis "
              f"{int(np.all(both <= 0.1, axis=1).sum())} of {len(rows)}")
    accepted = [r for r in rows if r["verdict"] == "accepted"]
    print(f"guards: {len(accepted)} of {len(rows)} accepted; refused: "
          f"{sorted({r['verdict'] for r in rows} - {'accepted'})}")
    if accepted:
        worst = max(float(np.nanmax(np.abs(np.r_[r["tau_pull"], r["d0_pull"],
                                                  r["law_pull"].ravel()])))
                    for r in accepted)
        print(f"largest |pull| of tau, D0 and the law among the accepted fits: {worst:.2f}")
    tau = np.abs([r["tau_rel"] for r in rows])
    d0 = np.abs(np.stack([r["d0_rel"] for r in rows]))
    print(f"targets met (issue 21) in {len(rows)} realisations: law <= 0.15 nT on every axis "
          f"{int(np.all(law_max <= 0.15, axis=1).sum())}; tau within 5 % "
          f"{int((tau <= 0.05).sum())}; D0 within 5 % (x y z) "
          f"{(d0 <= 0.05).sum(axis=0).tolist()}")
    for k, r in enumerate(accepted):  # issue 34: every written table meets the goals
        missed = goals_missed(r)
        if missed:
            print(f"written table {k + 1} of {len(accepted)} misses: {'; '.join(missed)}")
        beyond = stated_errors_missed(r)  # ... and its own stated errors (T_m included)
        if beyond:
            print(f"written table {k + 1} of {len(accepted)} (seed {r.get('k', '?')}) lies "
                  f"beyond {MAX_STATED_PULL:g} of its stated errors: {'; '.join(beyond)}")
        if pointwise := law_pointwise_only(r):
            print(f"written table {k + 1} of {len(accepted)} (seed {r.get('k', '?')}): "
                  f"{pointwise}")
    print(f"written tables meeting every goal (unseen day inside T_RANGE and D_RANGE <= 0.1 "
          f"nT, law in T_RANGE <= 0.15 nT, tau and D0 within 5 %): "
          f"{sum(not goals_missed(r) for r in accepted)} of {len(accepted)}")


def goals_missed(r: dict) -> list[str]:
    """Issue 34's goals a written table misses (an unseen day not simulated: not judged)."""
    out = []
    if np.any(r["unseen_in_both_nt"] > 0.1):
        out.append(f"unseen {np.round(r['unseen_in_both_nt'], 3)} nT")
    if np.any(r["law_max_nt"] > 0.15):
        out.append(f"law {np.round(r['law_max_nt'], 3)} nT")
    if abs(r["tau_rel"]) > 0.05:
        out.append(f"tau {r['tau_rel']:+.1%}")
    if np.any(np.abs(r["d0_rel"]) > 0.05):
        out.append(f"D0 {np.round(100 * r['d0_rel'], 1)} %")
    return out


#: A written table whose truth lies beyond this many of its stated errors fails them
#: (issue 34: "beyond ~3 of its stated errors").
MAX_STATED_PULL = 3.0
#: How often an honest stated error puts one truth beyond `MAX_STATED_PULL` (two-sided
#: normal, 0.27 %): the rate `simultaneous_law_threshold` keeps for the law's largest
#: |error / band| over a grid (decision entry 61).
POINTWISE_FALSE_ALARM = float(2.0 * norm.sf(MAX_STATED_PULL))
#: Directions drawn behind `law_max_false_alarm` and `simultaneous_law_threshold`: with
#: the radius integrated exactly, 1e5 of them move the threshold by at most 0.01 from seed
#: to seed (0.0003 on a straight line; 0.005-0.01 where T_RANGE spans a break; section 63).
SIMULTANEOUS_DRAWS = 100_000
#: Seed of those draws: the same fit always gets the same threshold.
SIMULTANEOUS_SEED = 34
#: Values (draws x grid points) held at once by `_largest_cosines` (32 MB).
DRAW_BLOCK_VALUES = 4_000_000


def _largest_cosines(b_law: np.ndarray, t: np.ndarray, draws: int, seed: int
                     ) -> list[tuple[int, np.ndarray] | None]:
    """Per axis, for random directions ``v``, the largest ``|u_T . v|`` over the grid.

    The law's error over ``t`` drawn normal with the covariance of the fit's resampled
    laws (`fv.law_values`; the population covariance, as the band is their standard
    deviation at each temperature, `MessengerFitResult.law_error`) is ``w . u_T`` times
    the band, ``u_T`` unit vectors in the resamples' rank-``r`` span (their singular
    vectors) and ``w`` standard normal; ``w = R v``, ``R^2`` chi2_r and ``v`` uniform on
    the sphere, independent.  Per axis ``(r, cosines)``, ``cosines`` of shape
    ``(draws,)``; temperatures where the band is 0 are left out, and an axis with no
    band anywhere is None.
    """
    vals = fv.law_values(np.asarray(b_law, dtype=float), t)          # (n, m, 3)
    dev = (vals - vals.mean(axis=0)) / np.sqrt(vals.shape[0])
    band = np.sqrt(np.sum(dev ** 2, axis=0))                          # (m, 3)
    rng = np.random.default_rng(seed)
    out: list[tuple[int, np.ndarray] | None] = []
    for j in range(3):
        keep = band[:, j] > 0
        if not keep.any():
            out.append(None)
            continue
        _, sv, vt = np.linalg.svd(dev[:, keep, j], full_matrices=False)
        rank = sv > sv[0] * 1e-12
        units = sv[rank, None] * vt[rank] / band[keep, j]             # (r, m'): u_T
        cos = np.empty(draws)
        step = max(1, DRAW_BLOCK_VALUES // units.shape[1])  # bounded memory
        for lo in range(0, draws, step):
            g = rng.standard_normal((min(step, draws - lo), units.shape[0]))
            cos[lo:lo + g.shape[0]] = (np.abs(g @ units).max(axis=1)
                                       / np.linalg.norm(g, axis=1))
        out.append((int(rank.sum()), cos))
    return out


def _beyond(pair: tuple[int, np.ndarray], limit: float) -> float:
    """``P(max_T |w . u_T| > limit) = E_v[P(chi2_r > limit^2 / cos^2)]`` from one axis of
    `_largest_cosines` (the radius integrated exactly)."""
    rank, cos = pair
    return float(np.mean(chi2.sf(limit ** 2 / np.maximum(cos, 1e-300) ** 2, rank)))


def law_max_false_alarm(b_law: np.ndarray, t: np.ndarray, limit: float,
                        draws: int = SIMULTANEOUS_DRAWS,
                        seed: int = SIMULTANEOUS_SEED) -> np.ndarray:
    """Return per axis how often an honest band puts the law's largest |error / band|
    over ``t`` beyond ``limit``.

    The truth's error normal with the covariance of the fit's resamples (`_largest_cosines`;
    verification sections 58 and 63).  NaN on an axis with no band.

    Parameters
    ----------
    b_law : ndarray, shape (n, 3, 4)
        Resampled laws ``(a, b, c, T_m)`` per axis (``res.bootstrap["law"]``).
    t : ndarray, shape (m,)
        The grid (C).
    limit : float
    draws, seed : int
        The Monte Carlo's size and seed (`SIMULTANEOUS_DRAWS`, `SIMULTANEOUS_SEED`).

    Returns
    -------
    ndarray, shape (3,)
    """
    return np.array([np.nan if pair is None else _beyond(pair, limit)
                     for pair in _largest_cosines(b_law, t, draws, seed)])


def simultaneous_law_threshold(b_law: np.ndarray, t: np.ndarray,
                               false_alarm: float = POINTWISE_FALSE_ALARM,
                               draws: int = SIMULTANEOUS_DRAWS,
                               seed: int = SIMULTANEOUS_SEED) -> np.ndarray:
    """Return per axis the largest |error / band| over ``t`` that an honest band exceeds
    with probability ``false_alarm``.

    Where `law_max_false_alarm` equals ``false_alarm``: a maximum over a grid of
    correlated points exceeds `MAX_STATED_PULL` more often than one point does (1.1-1.6 %
    of axis-fits on the 16-day orbit; verification section 58), and this keeps the
    pointwise rate (0.27 %) for the maximum.  It lies between `MAX_STATED_PULL` (the
    maximum is at least each point's value, which an honest band puts beyond it at that
    rate) and ``sqrt`` of chi2_r's ``1 - false_alarm`` point (every direction of the
    rank-``r`` span on the grid; 3.44 for a straight line); `MAX_STATED_PULL` on an axis
    with no band.  Decision entry 61.

    Parameters
    ----------
    b_law, t, draws, seed
        As `law_max_false_alarm`.
    false_alarm : float

    Returns
    -------
    ndarray, shape (3,)
    """
    out = np.full(3, MAX_STATED_PULL)
    for j, pair in enumerate(_largest_cosines(b_law, t, draws, seed)):
        if pair is None or _beyond(pair, MAX_STATED_PULL) <= false_alarm:
            continue
        top = float(np.sqrt(chi2.isf(false_alarm, pair[0])))
        out[j] = top if _beyond(pair, top) >= false_alarm else brentq(
            lambda c, pair=pair: _beyond(pair, c) - false_alarm, MAX_STATED_PULL, top,
            xtol=1e-4)
    return out


def law_grid_pull(res, fitted: np.ndarray, truth: np.ndarray, t: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Return the law's largest |error / band| over the grid ``t`` per axis, and the
    simultaneous threshold it is judged against (`simultaneous_law_threshold` of the
    fit's resamples; `MAX_STATED_PULL` for a fit without them).

    ``fitted``, ``truth``: ``A0, B0, A1, B1`` per axis (`law_difference`); the band
    ``res.law_error(t)``.
    """
    big = np.abs(law_difference(fitted, truth, t) / res.law_error(t)).max(axis=0)
    if res.bootstrap is None:
        return big, np.full(3, MAX_STATED_PULL)
    return big, simultaneous_law_threshold(res.bootstrap["law"], t)


def stated_errors_missed(r: dict) -> list[str]:
    """The stated quantities of a table whose truth lies beyond `MAX_STATED_PULL` of its
    stated error: tau, each D0 (a held one: its width), each break T_m (a held one: its
    width); and the law over T_RANGE, whose largest |error / band| over the grid is
    judged against its simultaneous threshold (``law_max_threshold``,
    `simultaneous_law_threshold`: the same 0.27 % for an honest band; entry 61).
    The summary's largest accepted pull leaves T_m out; this does not (verification
    section 50)."""
    out = []
    if abs(r["tau_pull"]) > MAX_STATED_PULL:
        out.append(f"tau {r['tau_pull']:+.2f}")
    for name, key in (("D0", "d0_pull"), ("T_m", "tm_pull")):
        p = np.asarray(r[key], dtype=float)
        if np.any(np.abs(p) > MAX_STATED_PULL):
            out.append(f"{name} {np.round(p, 2)}")
    p, limit = (np.asarray(r[k], dtype=float) for k in ("law_max_pull", "law_max_threshold"))
    if np.any(p > limit):
        out.append(f"law in T_RANGE {np.round(p, 2)} (simultaneous {np.round(limit, 2)})")
    return out


def law_pointwise_only(r: dict) -> str:
    """``""``, or the law's largest |error / band| over T_RANGE where it is beyond
    `MAX_STATED_PULL` but within its simultaneous threshold (reported, not a failure)."""
    p, limit = (np.asarray(r[k], dtype=float) for k in ("law_max_pull", "law_max_threshold"))
    if np.any(p > MAX_STATED_PULL) and np.all(p <= limit):
        return (f"law in T_RANGE {np.round(p, 2)} beyond {MAX_STATED_PULL:g} pointwise, "
                f"within its simultaneous {np.round(limit, 2)}")
    return ""


def saved_rows(folder: Path) -> list[dict]:
    """The rows of a ``--save`` folder, the pulls recomputed from each saved fit and truth
    (`pulls` as it is now), the unseen day and the verdict from its ``row_*.pkl``; for a
    fit saved without one (before this option) the verdict recomputed and the unseen
    day not known."""
    rows = []
    nan3 = np.full(3, np.nan)
    for fit in sorted(folder.glob("fit_*.pkl")):
        res, true = pickle.loads(fit.read_bytes())
        row = folder / fit.name.replace("fit_", "row_")
        saved = (pickle.loads(row.read_bytes()) if row.exists()
                 else {"verdict": command_line_verdict(res), "unseen_nt": nan3,
                       "unseen_in_both_nt": nan3})
        rows.append({**saved, **pulls(res, true), "k": int(fit.stem[4:])})
    return rows


# --- spread estimators of the stated errors (docs/decisions/messenger_fit.md 39) ------

#: The normal distribution's tail beyond +1 sigma: a discrete break jump taken by fewer of
#: the resamples than this lies outside their central 68 % (`spread_mixture`).
ONE_SIGMA_TAIL = 0.15866


def spread_sd(x: np.ndarray, moved: np.ndarray | None = None) -> np.ndarray:
    """Standard deviation over the resamples (axis 0): what the fit states."""
    return np.std(np.asarray(x, dtype=float), axis=0)


def spread_percentile(x: np.ndarray, moved: np.ndarray | None = None) -> np.ndarray:
    """Half the width between the resamples' 15.87th and 84.13th percentiles (axis 0)."""
    lo, hi = np.percentile(np.asarray(x, dtype=float), [15.866, 84.134], axis=0)
    return 0.5 * (hi - lo)


def spread_mad(x: np.ndarray, moved: np.ndarray | None = None) -> np.ndarray:
    """1.4826 times the median absolute deviation from the median (axis 0)."""
    x = np.asarray(x, dtype=float)
    return 1.4826 * np.median(np.abs(x - np.median(x, axis=0)), axis=0)


def spread_mixture(x: np.ndarray, moved: np.ndarray | None = None) -> np.ndarray:
    """A discrete break jump stated apart: the standard deviation of the resamples that
    kept the solution's break, when those that moved it are fewer than `ONE_SIGMA_TAIL`
    of them (outside the central 68 %); else of all (the jump then is the error).

    ``x``: (n, ..., axis); ``moved``: (n, axis) bool, per resample and axis whether its
    break choice differs from the solution's (None: none moved, the standard deviation).
    """
    x = np.asarray(x, dtype=float)
    if moved is None:
        return spread_sd(x)
    moved = np.asarray(moved, dtype=bool)
    out = np.empty(x.shape[1:])
    for j in range(x.shape[-1]):
        keep = ~moved[:, j] if moved[:, j].mean() < ONE_SIGMA_TAIL else np.ones(len(x), bool)
        out[..., j] = np.std(x[keep][..., j], axis=0)
    return out


SPREADS = {"sd": spread_sd, "percentile": spread_percentile, "mad": spread_mad,
           "mixture": spread_mixture}


def moved_resamples(res) -> np.ndarray:
    """Per resample and axis whether its break choice differs from the solution's, (n, 3).

    From the fit's stored ``bootstrap["break_shift"]``; a fit saved before that was kept
    (entry 39): the last pass's bootstrap solved again on its normal equations at
    the fitted tables (the same resamples, seed 0; the linearisation point moved by the
    last step only, so a resample on the edge of two choices may choose otherwise).
    """
    shifts = res.bootstrap.get("break_shift")
    if shifts is None:
        sol = fv.solve_variance(res.variance, fit_delay=res.delay_fitted,
                                law=fv.law_parameters(res.calibration),
                                held=_held_columns(res))
        shifts = sol.boot_shift
    return np.asarray(shifts) != np.asarray(res.break_shift)[None, :]


def _held_columns(res) -> dict[int, tuple[float, float]]:
    """The held parameters of ``res`` as `fit_variance.solve_variance` takes them
    (column -> (step, width)) at the fitted tables, as `fit_variance_calibration` holds
    them: each held upper segment's slope change and break, each held D0 (steps 0)."""
    now = fv.law_parameters(res.calibration)
    held = {}
    for a, h in res.held_upper.items():
        j = "xyz".index(a)
        (tm, w_tm), (c, w_c) = h["Tm_c"], h["slope_change"]
        held[j * fb.PER_AXIS + 2] = (c - now[j, 2], w_c)
        held[j * fb.PER_AXIS + 3] = (-now[j, 2] * (tm - now[j, 3]), abs(now[j, 2]) * w_tm)
    d0 = np.asarray(res.calibration.duty_cycle_d0, dtype=float)
    for a, (value, width) in res.held.items():
        held["xyz".index(a) * fb.PER_AXIS + 4] = (value - d0["xyz".index(a)], width)
    return held


def estimator_row(res, true, spread) -> dict:
    """The pulls of `pulls` (tau, D0, T_m, the law at `LAW_T`) with the stated errors
    taken as ``spread`` of the fit's stored resamples, and the break-jump shares."""
    boot = res.bootstrap
    moved = moved_resamples(res)
    cal = res.calibration
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    law_t = np.array(LAW_T)
    law_pull = (law_difference(cal.temperature_coefficients, tc, law_t)
                / spread(fv.law_values(boot["law"], law_t), moved))
    law_pull[~res.stated_ranges.contains(law_t)] = np.nan
    true_tm = (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1])
    return {"tau_pull": float((res.relaxation.tau - true.constants["relaxation"]["tau_s"])
                              / spread(boot["tau"])),
            "dt_pull": np.nan,
            "d0_pull": (cal.duty_cycle_d0 - true.d0) / spread(boot["d0"]),
            "tm_pull": (np.asarray(cal.breakpoint_temperature_c) - true_tm)
            / spread(boot["law"][:, :, 3], moved),
            "law_pull": law_pull, "held_upper": sorted(res.held_upper),
            "jump_share": moved.mean(axis=0)}


def unit_scores(res) -> dict:
    """The last pass's normal equations at the fitted tables, grouped into the bootstrap's
    units (`fit_variance.solve_variance`), the breaks kept, the held columns at their
    held steps: per unit ``a_u``, ``v_u``; ``total``; the solution ``theta``; the free
    columns ``free`` / ``f``; ``layout`` (`fit_breaks.solve_step`'s ``fit_delay`` and
    ``held`` steps); each unit's score ``v_u - a_u theta`` on them (``score``); ``inv``
    (the free block of ``total``, inverted); ``n`` units, ``p`` free; ``held`` (column ->
    width)."""
    now = fv.law_parameters(res.calibration)
    held_cols = _held_columns(res)
    layout = {"fit_delay": res.delay_fitted,
              "held": {col: step for col, (step, _) in held_cols.items()}}
    a, v = res.variance.normal, res.variance.rhs
    # the free columns (breaks kept) set the units' length, as in solve_variance
    free = fb.solve_step(a.sum(axis=0), v.sum(axis=0), now[:, 2], **layout)[1]
    p = int(free.sum())
    group = np.arange(a.shape[0]) // int(min(fv.MAX_GROUP, max(1, a.shape[0] // (2 * p))))
    n = int(group[-1]) + 1
    a_u, v_u = np.zeros((n, *a.shape[1:])), np.zeros((n, v.shape[1]))
    np.add.at(a_u, group, a)
    np.add.at(v_u, group, v)
    total = a_u.sum(axis=0)
    theta = fb.solve_step(total, v_u.sum(axis=0), now[:, 2], **layout)[0]
    f = np.flatnonzero(free)
    return {"a_u": a_u, "v_u": v_u, "total": total, "theta": theta, "free": free,
            "layout": layout, "f": f, "n": n, "p": p,
            "score": (v_u - np.einsum("uij,j->ui", a_u, theta))[:, f],
            "inv": np.linalg.inv(total[np.ix_(f, f)]),
            "held": {col: width for col, (_, width) in held_cols.items()}}


def core_factors(res, true) -> dict:
    """Per quantity (T_m and the law at `LAW_T`, per axis), the stated error split into
    factors (entry 41): ``jumps`` (the resamples' standard deviation over that of
    those that kept the solution's break), ``w`` (``sqrt(n / (n - p))``), ``design`` (the
    pairs bootstrap of the linear solve, breaks kept, over the same counts applied to the
    units' scores with the whole normal matrix kept), ``cr0`` (the design-fixed cluster
    sandwich, no widening), ``top3`` (the three largest units' share of it), ``lag1``
    (adjacent units' correlation of it), and the fit's error ``err`` about the truth."""
    u = unit_scores(res)
    now = fv.law_parameters(res.calibration)
    f, score, inv = u["f"], u["score"], u["inv"]
    rng = np.random.default_rng(0)
    picks = np.stack([np.bincount(rng.integers(0, u["n"], u["n"]), minlength=u["n"])
                      for _ in range(200)]).astype(float)
    pairs = fb.solve_step(np.einsum("rb,bij->rij", picks, u["a_u"]), picks @ u["v_u"],
                          now[:, 2], **u["layout"])[0][:, f]
    fixed = (picks - 1.0) @ score @ inv.T
    moved = moved_resamples(res)
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    law_t = np.array(LAW_T)
    err_tm = (np.asarray(res.calibration.breakpoint_temperature_c)
              - (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1]))
    err_law = law_difference(res.calibration.temperature_coefficients, tc, law_t)
    b_law = res.bootstrap["law"]
    out = {}
    for j, a in enumerate("xyz"):
        rows = [(f"T_m {a}", np.eye(4)[3] * -1.0 / now[j, 2], err_tm[j], b_law[:, j, 3])]
        vals = fv.law_values(b_law, law_t)[:, :, j]
        rows += [(f"law {a} {t:+g}", np.array([1.0, t, max(0.0, t - now[j, 3]),
                                                float(t > now[j, 3])]), err_law[i, j],
                  vals[:, i]) for i, t in enumerate(law_t)]
        for name, g4, err, boot in rows:
            g = np.zeros(fb.N_PARAMETERS)
            g[j * fb.PER_AXIS:j * fb.PER_AXIS + 4] = g4
            gf = g[f]
            e_u = score @ inv @ gf
            cr0 = float(np.sqrt(np.sum(e_u ** 2)))
            s_fixed = float(np.std(fixed @ gf))  # 0 for a held break: no factor
            keep = ~moved[:, j]
            out[name] = {"err": float(err), "stated": float(np.std(boot)),
                         "jumps": float(np.std(boot) / np.std(boot[keep]))
                         if keep.sum() > 2 else np.nan,
                         "w": float(np.sqrt(u["n"] / (u["n"] - u["p"]))),
                         "design": float(np.std(pairs @ gf)) / s_fixed if s_fixed > 0
                         else np.nan,
                         "cr0": cr0,
                         "top3": float(np.sort(e_u ** 2)[-3:].sum() / max(cr0 ** 2, 1e-300)),
                         "lag1": float(np.sum(e_u[1:] * e_u[:-1]) / max(cr0 ** 2, 1e-300))}
    return out


def core_summary(folder: Path) -> None:
    """Print `core_factors` per quantity over the fits of ``folder`` (medians; the rms
    error about the truth; in C for T_m, nT for the law; entry 41)."""
    fits = [pickle.loads(f.read_bytes()) for f in sorted(folder.glob("fit_*.pkl"))]
    per = [(res, core_factors(res, true)) for res, true in fits]
    print("| quantity | N | rms error | stated (median) | jumps | w | design | CR0 / rms |"
          " top-3 share | lag-1 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in per[0][1]:
        unit = 1.0 if name.startswith("T_m") else NT_PER_COUNT
        if name.startswith("T_m"):
            sel = [o[name] for res, o in per if name[-1] not in res.held_upper]
        else:
            t = float(name.split()[-1])
            sel = [o[name] for res, o in per if res.stated_ranges.contains(np.array([t]))[0]]
        if len(sel) < 3:
            continue
        g = {k: np.array([d[k] for d in sel], dtype=float) for k in sel[0]}
        rms = float(np.sqrt(np.mean(g["err"] ** 2)))
        print(f"| {name} | {len(sel)} | {rms * unit:.4f} | {np.median(g['stated']) * unit:.4f} |"
              f" {np.nanmedian(g['jumps']):.2f} | {np.median(g['w']):.3f} |"
              f" {np.median(g['design']):.2f} | {np.median(g['cr0']) / rms:.2f} |"
              f" {np.median(g['top3']):.2f} | {np.median(g['lag1']):+.2f} |")


def sandwich_errors(res) -> tuple[np.ndarray, np.ndarray]:
    """Design-fixed, linearised errors of T_m (C) and of the law at `LAW_T` (counts).

    The last pass's normal equations at the fitted tables, grouped into the bootstrap's
    units (`fit_variance.solve_variance`): ``A^-1 (sum_u g_u g_u^T) A^-1 n / (n - p)``,
    ``g_u`` each unit's score at the solution, the breaks kept; a held column's width
    propagated through ``-A_ff^-1 A_fh``.  The fifth candidate of entry 39: the
    pairs bootstrap without its resampling of the design and its break re-choices.
    Returns ``(tm_err (3,), law_err (len(LAW_T), 3))``.
    """
    now = fv.law_parameters(res.calibration)
    u = unit_scores(res)
    held, f, inv, score, total = u["held"], u["f"], u["inv"], u["score"], u["total"]
    n, p = u["n"], u["p"]
    cov = np.zeros((fb.N_PARAMETERS, fb.N_PARAMETERS))
    cov[np.ix_(f, f)] = inv @ (score.T @ score) @ inv * n / (n - p)
    if held:
        h = np.array(sorted(held))
        jac = np.zeros((fb.N_PARAMETERS, h.size))
        jac[f] = -inv @ total[np.ix_(f, h)]
        jac[h, np.arange(h.size)] = 1.0
        cov += jac @ np.diag([held[c] ** 2 for c in h]) @ jac.T
    law_t = np.array(LAW_T)
    tm_err, law_err = np.empty(3), np.empty((law_t.size, 3))
    for j in range(3):
        cols = [j * fb.PER_AXIS + i for i in range(4)]  # a, b, c, -c T_m
        c = cov[np.ix_(cols, cols)]
        tm_err[j] = np.sqrt(c[3, 3]) / abs(now[j, 2])
        grad = np.column_stack([np.ones_like(law_t), law_t, np.maximum(0.0, law_t - now[j, 3]),
                                (law_t > now[j, 3]).astype(float)])
        law_err[:, j] = np.sqrt(np.einsum("ti,ij,tj->t", grad, c, grad))
    return tm_err, law_err


def sandwich_row(res, true, with_jumps: bool) -> dict:
    """`estimator_row` with T_m and the law stated by `sandwich_errors` (``with_jumps``:
    the bootstrap's standard deviation on an axis whose break jumps in at least
    `ONE_SIGMA_TAIL` of the resamples); tau and D0 as stated."""
    row = estimator_row(res, true, spread_sd)
    tm_s, law_s = sandwich_errors(res)
    boot = res.bootstrap
    if with_jumps:
        common = row["jump_share"] >= ONE_SIGMA_TAIL
        tm_s = np.where(common, spread_sd(boot["law"][:, :, 3]), tm_s)
        law_s = np.where(common[None, :], spread_sd(fv.law_values(boot["law"], LAW_T)), law_s)
    row["tm_pull"] = row["tm_pull"] * spread_sd(boot["law"][:, :, 3]) / tm_s
    row["law_pull"] = row["law_pull"] * spread_sd(fv.law_values(boot["law"], LAW_T)) / law_s
    return row


def replayed_errors(res, fixed_design: bool, n_bootstrap: int = 200,
                    refine: bool | str = False, bootstrap: str = "pairs") -> dict:
    """The stated errors of ``res`` replayed from its last pass's normal equations at the
    fitted tables (as `moved_resamples`), with the pairs bootstrap or the fixed-design
    one (`fit_breaks.fixed_design_resamples`) of ``n_bootstrap`` resamples, treated as
    `fit.fit_variance_calibration` treats them (dither, widening, held draws, D0 along
    the field; ``refine``: moved breaks placed inside their cells instead,
    `fit_breaks.refine_breaks`; ``"resamples"``: in the resamples only, the solution's
    distance counted, ``refine_resamples``; ``bootstrap``: `fit_variance.solve_variance`'s,
    ``"wild"`` the wild cluster bootstrap, entry 50): tau, D0 (3,), T_m (3,), the law
    at `LAW_T` (len(LAW_T), 3)."""
    b = replayed_resamples(res, fixed_design, n_bootstrap, refine, bootstrap)
    return {"tau": np.std(b["tau"]), "d0": np.std(b["d0"], axis=0),
            "tm": np.std(b["law"][:, :, 3], axis=0),
            "law": np.std(fv.law_values(b["law"], np.array(LAW_T)), axis=0)}


def replayed_resamples(res, fixed_design: bool, n_bootstrap: int = 200,
                       refine: bool | str = False, bootstrap: str = "pairs") -> dict:
    """The resamples behind `replayed_errors`, widened as the fit widens them: the law
    (n, 3, 4), D0 (n, 3) and tau (n,) (tau about its mean, the others about the
    solution), and ``moved`` (n, 3): whether each resample's break choice differs from
    the solution's."""
    held = _held_columns(res)
    sol = fv.solve_variance(res.variance, fit_delay=res.delay_fitted,
                            law=fv.law_parameters(res.calibration), held=held,
                            fixed_design=fixed_design, n_bootstrap=n_bootstrap,
                            refine=refine is True, refine_resamples=refine == "resamples",
                            bootstrap=bootstrap)
    law, d0, tau, _ = fv.apply_step(res.calibration, sol.step, break_shift=sol.break_shift)
    law[:, 3] += sol.break_offset
    b_law, b_d0, b_tau, _ = fv.apply_steps(res.calibration, sol.boot, max_tau_shift=np.inf,
                                           max_break_shift_c=np.inf,
                                           break_shifts=sol.boot_shift)
    b_law[:, :, 3] += sol.boot_dither
    w = sol.widening
    w_law = np.full((3, 4), w)
    for a in res.held_upper:  # a held slope change and break keep their draws
        w_law["xyz".index(a), 2:] = 1.0
    w_d0 = np.array([1.0 if a in res.held else w for a in "xyz"])
    b_law = law + w_law * (b_law - b_law.mean(axis=0))
    b_d0 = d0 + w_d0 * (b_d0 - b_d0.mean(axis=0))
    direction, balance = fv.d0_field_balance(res.variance)
    b_d0 = fv.widen_d0_along_field(b_d0, d0, np.asarray(res.calibration.matrices[0], float),
                                   direction, balance,
                                   np.array([a not in res.held for a in "xyz"]))[0]
    return {"law": b_law, "d0": b_d0, "tau": w * (b_tau - b_tau.mean()),
            "moved": np.asarray(sol.boot_shift) != np.asarray(sol.break_shift)[None, :]}


def fixed_design_row(res, true) -> dict:
    """`estimator_row` with every stated error scaled by the replayed fixed-design
    bootstrap's over the replayed pairs bootstrap's (entry 41): the same resample
    counts, so the ratio is the design's part alone."""
    row = estimator_row(res, true, spread_sd)
    pairs, fixed = replayed_errors(res, False), replayed_errors(res, True)
    row["tau_pull"] *= pairs["tau"] / fixed["tau"]
    row["d0_pull"] = row["d0_pull"] * pairs["d0"] / fixed["d0"]
    row["tm_pull"] = row["tm_pull"] * pairs["tm"] / fixed["tm"]
    row["law_pull"] = row["law_pull"] * pairs["law"] / fixed["law"]
    return row


#: The bootstraps `replay_summary` replays: (column, fixed design, resamples, refine,
#: bootstrap; refine False: the uniform draw over the cell, the fit's default before
#: entry 47; ``"resamples"``: refined in the resamples only, the fit's default since;
#: bootstrap ``"wild"``: the wild cluster bootstrap, breaks chosen again, entry 50).
REPLAYS = (("pairs 200", False, 200, False, "pairs"), ("refined", False, 200, True, "pairs"),
           ("refined resamples", False, 200, "resamples", "pairs"),
           ("fixed 800", True, 800, False, "pairs"),
           ("refined, fixed 800", True, 800, True, "pairs"),
           ("wild", False, 200, "resamples", "wild"))


def replay_row(res, true, fixed_design: bool, n_bootstrap: int,
               refine: bool | str = False, bootstrap: str = "pairs") -> dict:
    """`estimator_row` with every stated error replaced by a bootstrap replayed on the
    fit's stored normal equations (`replayed_errors`): the pulls the fit would state
    with that bootstrap, the fitted tables kept (entry 42)."""
    row = estimator_row(res, true, spread_sd)
    boot = res.bootstrap
    now = replayed_errors(res, fixed_design, n_bootstrap, refine, bootstrap)
    row["tau_pull"] *= spread_sd(boot["tau"]) / now["tau"]
    row["d0_pull"] = row["d0_pull"] * spread_sd(boot["d0"]) / now["d0"]
    row["tm_pull"] = row["tm_pull"] * spread_sd(boot["law"][:, :, 3]) / now["tm"]
    row["law_pull"] = (row["law_pull"] * spread_sd(fv.law_values(boot["law"], LAW_T))
                       / now["law"])
    return row


def _print_pull_rows(per: dict, only: str = "") -> None:
    """Print one markdown row per parameter of the first column's rows: in each column of
    ``per`` (name -> `estimator_row`-like rows) the pulls' spread, largest size and count
    beyond 3 (`replay_summary`, `estimator_summary`); ``only``: the parameters whose name
    starts with it."""
    tables = {name: dict(table(rows)) for name, rows in per.items()}
    first = next(iter(tables))
    for name in (n for n in tables[first] if n.startswith(only)):
        cells = []
        for est in per:
            p = tables[est][name]
            p = p[np.isfinite(p)]
            cells.append(f"{p.std(ddof=1):.2f}, {np.abs(p).max():.2f}, "
                         f"{int(np.count_nonzero(np.abs(p) > 3))}" if p.size > 1 else "")
        if any(cells):
            n = int(np.isfinite(tables[first][name]).sum())
            print(f"| {name} (N {n}) | " + " | ".join(cells) + " |")


def replay_summary(folder: Path) -> None:
    """Print, per parameter, the pulls' spread, largest size and count beyond 3 as stored
    in the saved fits of ``folder`` and under each bootstrap of `REPLAYS` replayed on
    them (docs/decisions/messenger_fit.md entry 42)."""
    fits = [pickle.loads(f.read_bytes()) for f in sorted(folder.glob("fit_*.pkl"))]
    per = {"stored": [estimator_row(res, true, spread_sd) for res, true in fits]}
    per.update({name: [replay_row(res, true, fixed, n, refine, kind) for res, true in fits]
                for name, fixed, n, refine, kind in REPLAYS})
    print(f"{len(fits)} fits; (spread, max |pull|, beyond 3)")
    print("| parameter | " + " | ".join(per) + " |")
    print("|---|" + "---|" * len(per))
    _print_pull_rows(per)


# --- the wild cluster bootstrap (docs/decisions/messenger_fit.md 50) -----------

#: The columns `wild_summary` prints beside the stored errors: the fit's own bootstrap
#: replayed (pairs, refined in the resamples), the wild one (Rademacher, Webb's six
#: points), and two combinations: T_m alone from the wild bootstrap; T_m from it and the
#: law's band per temperature the larger of the wild and the pairs bands (a fixed design
#: pinches at the law's pivot, entry 42 (4)); the wild errors of an axis (T_m and the
#: law) only where fewer than `ONE_SIGMA_TAIL` of the pairs resamples moved its break
#: (entry 39's rule for a jump that is the error), else the pairs'; and that with the
#: law's wild band floored as `band_floor_regulated` floors the fixed design's (entry 46
#: rule 3: at the pairs band at -50 C and its least over the data's range).
WILD_COLUMNS = ("pairs (fit)", "wild", "wild webb", "wild T_m only",
                "wild T_m, law max(wild, pairs)", "wild where pairs rarely jump",
                "... law floored at -50 C")


def _resample_errors(b: dict, t: np.ndarray) -> dict:
    """Errors of replayed resamples ``b`` (`replayed_resamples`): tau, D0, T_m and the law
    at ``t`` (len(t), 3) counts."""
    return {"tau": np.std(b["tau"]), "d0": np.std(b["d0"], axis=0),
            "tm": np.std(b["law"][:, :, 3], axis=0), "law": _band(b["law"], t)}


def _pull_row(res, true, err: dict, law_t: np.ndarray) -> dict:
    """The pulls of ``res`` against ``true`` with the errors ``err`` (`_resample_errors`
    at ``law_t``): tau, D0, T_m, the law at ``law_t`` (NaN outside the stated range)."""
    cal = res.calibration
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    law_pull = law_difference(cal.temperature_coefficients, tc, law_t) / err["law"]
    law_pull[~res.stated_ranges.contains(law_t)] = np.nan
    return {"tau_pull": float((res.relaxation.tau - true.constants["relaxation"]["tau_s"])
                              / err["tau"]),
            "dt_pull": np.nan,
            "d0_pull": (cal.duty_cycle_d0 - true.d0) / err["d0"],
            "tm_pull": (np.asarray(cal.breakpoint_temperature_c)
                        - (tc[:, 0] - tc[:, 2]) / (tc[:, 3] - tc[:, 1])) / err["tm"],
            "law_pull": law_pull, "held_upper": sorted(res.held_upper)}


def wild_rows(res, true, n_bootstrap: int = 200) -> dict:
    """Per column of `WILD_COLUMNS`, the pulls of ``res`` (`_pull_row` at `LAW_T`) with
    its errors replayed on the stored normal equations (`replayed_resamples`, refined in
    the resamples as the fit does), and ``grid_max`` (3,): the law's largest |pull| per
    axis over a `BAND_GRID_STEP_C` grid of the stated range (where a band pinches)."""
    lo, hi = res.fitted_range
    grid = np.arange(np.floor(lo), np.ceil(hi) + 0.01, BAND_GRID_STEP_C)
    grid = grid[res.stated_ranges.contains(grid)]
    t = np.concatenate([np.array(LAW_T), grid])
    boots = {name: replayed_resamples(res, False, n_bootstrap, "resamples", kind)
             for name, kind in (("pairs (fit)", "pairs"), ("wild", "wild"),
                                ("wild webb", "wild-webb"))}
    err = {name: _resample_errors(b, t) for name, b in boots.items()}
    err["wild T_m only"] = {**err["pairs (fit)"], "tm": err["wild"]["tm"]}
    err["wild T_m, law max(wild, pairs)"] = {
        **err["wild T_m only"], "law": np.maximum(err["wild"]["law"],
                                                  err["pairs (fit)"]["law"])}
    rare = boots["pairs (fit)"]["moved"].mean(axis=0) < ONE_SIGMA_TAIL  # per axis
    pairs, wild = err["pairs (fit)"], err["wild"]
    err["wild where pairs rarely jump"] = {
        **pairs, "tm": np.where(rare, wild["tm"], pairs["tm"]),
        "law": np.where(rare[None, :], wild["law"], pairs["law"])}
    lo_d, hi_d = res.fitted_range
    data_t = np.arange(np.ceil(lo_d), np.floor(hi_d) + 0.01, BAND_GRID_STEP_C)
    floored = band_floor_regulated(boots["pairs (fit)"]["law"], boots["wild"]["law"], t,
                                   data_t)
    err["... law floored at -50 C"] = {
        **err["wild where pairs rarely jump"],
        "law": np.where(rare[None, :], floored, pairs["law"])}
    out = {}
    n_law = len(LAW_T)
    for name in WILD_COLUMNS:
        row = _pull_row(res, true, err[name], t)
        row["grid_max"] = (np.abs(row["law_pull"][n_law:]).max(axis=0) if grid.size
                           else np.zeros(3))
        row["law_pull"] = row["law_pull"][:n_law]
        out[name] = row
    return out


def wild_summary(folder: Path) -> None:
    """Print, per parameter, the pulls' spread, largest size and count beyond 3 as stored
    and under each column of `WILD_COLUMNS` (`wild_rows`), then the law's largest |pull|
    over the stated range's grid and the fits with one beyond 3 (entry 50)."""
    fits = [pickle.loads(f.read_bytes()) for f in sorted(folder.glob("fit_*.pkl"))]
    rows = [wild_rows(res, true) for res, true in fits]
    per = {"stored": [estimator_row(res, true, spread_sd) for res, true in fits]}
    per.update({name: [r[name] for r in rows] for name in WILD_COLUMNS})
    print(f"{len(fits)} fits; (spread, max |pull|, beyond 3)")
    print("| parameter | " + " | ".join(per) + " |")
    print("|---|" + "---|" * len(per))
    _print_pull_rows(per)
    cells = [""]
    for name in WILD_COLUMNS:
        g = np.stack([r[name]["grid_max"] for r in rows])
        cells.append(f"{g.max():.2f}, {int(np.count_nonzero(np.any(g > 3, axis=1)))} fits")
    print(f"| grid of T_RANGE, every {BAND_GRID_STEP_C:g} C: max |pull|, fits beyond 3 | "
          + " | ".join(cells) + " |")


# --- T_m from the residual's profile against the break (messenger_fit.md 51) --

#: The columns `profile_summary` prints: T_m's error as the fit states it (the pairs
#: bootstrap replayed, refined in the resamples: the fit's default since entry 47), from
#: the profile of the residual against the break (`fit_break_profile.profile_break_errors`),
#: and the larger of the profile's and these fractions of the pairs' (a floor where the
#: profile alone is too narrow).
PROFILE_FLOORS = (0.5, 0.65)


def linearisation_point(res) -> tuple[np.ndarray, tuple[int, int, int], dict]:
    """The law ``(a, b, c, T_m)`` per axis that the saved fit's last normal equations were
    reduced at (the pass's starting table), its break choices and its held columns.

    The last step solved again on the stored normal equations (`fit_breaks.solve_step`
    at the fit's break choices, the held columns at `_held_columns`' steps) and taken
    back from the fitted table: ``a``, ``b``, ``c`` by their steps, ``T_m`` by its
    linearised step ``-q / c`` (or the shift where the last pass took one)."""
    now = fv.law_parameters(res.calibration)
    held = _held_columns(res)
    shifts = np.asarray(res.break_shift, dtype=float)
    choice = tuple(fb.BREAK_SHIFTS_C.index(float(x)) if x != 0.0 else -1 for x in shifts)
    step = fb.solve_step(res.variance.normal.sum(axis=0), res.variance.rhs.sum(axis=0),
                         now[:, 2], choice, fit_delay=res.delay_fitted,
                         held={col: st for col, (st, _) in held.items()})[0]
    base = now.copy()
    for j in range(3):
        base[j, 0] -= step[j * fb.PER_AXIS]
        base[j, 1] -= step[j * fb.PER_AXIS + 1]
        if choice[j] < 0:
            base[j, 2] -= step[j * fb.PER_AXIS + 2]
            base[j, 3] += step[j * fb.PER_AXIS + 3] / base[j, 2]
        else:
            base[j, 2] = -step[j * fb.PER_AXIS + 2]
            base[j, 3] -= shifts[j]
    return base, choice, held


def profile_tm(res) -> dict:
    """`fit_break_profile.profile_break_errors` of the saved fit ``res`` at its linearisation
    point (`linearisation_point`), the fitted breaks' offsets taken from its table."""
    base, choice, held = linearisation_point(res)
    fitted = np.asarray(res.calibration.breakpoint_temperature_c, dtype=float) - base[:, 3]
    return profile_break_errors(res.variance, base, held, res.delay_fitted, choice,
                                fitted_c=fitted)


def profile_rows(res, true) -> dict:
    """Per column (pairs replayed, profile, the floors of `PROFILE_FLOORS`), `estimator_row`
    with T_m's error replaced (a held break keeps its replayed held width), and
    ``detail``: the fit's T_m error, the pairs' and the profile's errors and interval."""
    row = estimator_row(res, true, spread_sd)
    row["tm_pull"] = row["tm_pull"] * spread_sd(res.bootstrap["law"][:, :, 3])  # the error
    pairs = replayed_errors(res, False, 200, "resamples")["tm"]
    prof = profile_tm(res)
    err = {"pairs (fit)": pairs, "profile": np.where(np.isfinite(prof["error"]),
                                                     prof["error"], pairs)}
    for f in PROFILE_FLOORS:
        err[f"max(profile, {f:g} pairs)"] = np.maximum(err["profile"], f * pairs)
    out = {name: {**row, "tm_pull": row["tm_pull"] / e} for name, e in err.items()}
    out["detail"] = {"err": row["tm_pull"], "pairs": pairs, **prof}
    return out


def profile_summary(folder: Path) -> None:
    """Print, per parameter, the T_m pulls' spread, largest size and count beyond 3 under
    each column of `profile_rows`, then per free axis with a pull beyond 2 under any column
    or an error beyond 0.5 C: the error, the errors and the profile's interval
    (entry 51)."""
    fits = sorted(folder.glob("fit_*.pkl"))
    rows = []
    for f in fits:
        res, true = pickle.loads(f.read_bytes())
        rows.append((f.stem, res.held_upper, profile_rows(res, true)))
    names = [n for n in rows[0][2] if n != "detail"]
    per = {name: [r[name] for _, _, r in rows] for name in names}
    print(f"{len(fits)} fits; (spread, max |pull|, beyond 3)")
    print("| parameter | " + " | ".join(per) + " |")
    print("|---|" + "---|" * len(per))
    _print_pull_rows(per, only="T_m")
    print("| fit | axis | err (C) | pairs (C) | profile (C) | interval about the fit (C) |"
          " pulls: " + " / ".join(names) + " |")
    print("|---|---|---|---|---|---|---|")
    for stem, held, r in rows:
        d = r["detail"]
        for j, a in enumerate("xyz"):
            if a in held:
                continue
            pulls = [r[n]["tm_pull"][j] for n in names]
            if max(abs(x) for x in pulls) > 2.0 or abs(d["err"][j]) > 0.5:
                lo, hi = d["lo"][j] - d["fitted"][j], d["hi"][j] - d["fitted"][j]
                print(f"| {stem} | {a} | {d['err'][j]:+.3f} | {d['pairs'][j]:.3f} | "
                      f"{d['error'][j]:.3f} | {lo:+.2f}..{hi:+.2f}"
                      f"{'' if d['closed'][j].all() else ' (open)'} | "
                      + " / ".join(f"{x:+.2f}" for x in pulls) + " |")


# --- design-fixed law bands that cannot pinch (docs/decisions/messenger_fit.md 46) --

#: The regulated sensor temperature (C; sec. 7, eq. 2): `band_floor_regulated`'s floor.
REGULATED_C = -50.0
#: Step (C) of the grids over the data's range (the floors) and over the stated range (the
#: largest pull of a band, `band_pulls`).
BAND_GRID_STEP_C = 0.5


def _band(law: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The spread of resampled laws ``law`` (n, 3, 4) at ``t``: (len(t), 3) counts."""
    return np.std(fv.law_values(law, t), axis=0)


def band_fixed(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
               data_t: np.ndarray, lever=None) -> np.ndarray:
    """The fixed-design band alone (entry 41): it pinches at its pivot (entry 42)."""
    return _band(fixed, t)


def band_max(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
             data_t: np.ndarray, lever=None) -> np.ndarray:
    """Per temperature and axis the larger of the pairs and the fixed-design bands."""
    return np.maximum(_band(pairs, t), _band(fixed, t))


def band_floor_least(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
                     data_t: np.ndarray, lever=None) -> np.ndarray:
    """The fixed-design band, floored per axis by the pairs band's least value over the
    data's range ``data_t`` (its pivot)."""
    return np.maximum(_band(fixed, t), _band(pairs, data_t).min(axis=0)[None, :])


def band_floor_regulated(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
                         data_t: np.ndarray, lever=None) -> np.ndarray:
    """The fixed-design band, floored per axis by the pairs band at `REGULATED_C` where
    the data's range ``data_t`` holds it (there the law is tied to D0 R, an error the
    units' scores do not see and the widening covers, entry 42), else by its least."""
    floor = _band(pairs, data_t).min(axis=0)
    if data_t.size and data_t.min() <= REGULATED_C <= data_t.max():
        floor = np.maximum(floor, _band(pairs, np.array([REGULATED_C]))[0])
    return np.maximum(_band(fixed, t), floor[None, :])


def band_correlation(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
                     data_t: np.ndarray, lever=None) -> np.ndarray:
    """The pairs resamples rescaled per law parameter (a, b, c, T_m per axis) about their
    mean to the fixed design's standard deviations: the fixed design's widths with the
    pairs' correlations."""
    sd_p, sd_f = np.std(pairs, axis=0), np.std(fixed, axis=0)
    mean = pairs.mean(axis=0)
    scale = np.divide(sd_f, sd_p, out=np.ones_like(sd_p), where=sd_p > 0)
    return _band(mean + (pairs - mean) * scale, t)


def band_leverage_floored(pairs: np.ndarray, fixed: np.ndarray, t: np.ndarray,
                          data_t: np.ndarray, lever=None) -> np.ndarray:
    """The fixed-design band widened per temperature by the units' leverage (``lever(t)``,
    `leverage_ratio`: CR2 over CR0; never narrowed by it, where the ratio is below 1),
    floored as `band_floor_regulated`."""
    return np.maximum(_band(fixed, t) * lever(t),
                      band_floor_regulated(pairs, fixed, t, data_t))


def leverage_ratio(res):
    """Return ``ratio(t)`` -> (len(t), 3): per temperature and axis, the law's cluster
    sandwich with each unit's score adjusted for its leverage over the unadjusted one.

    The units, scores and normal matrix of `unit_scores` (the breaks kept, the free
    columns): CR0 is ``A^-1 (sum_u g_u g_u^T) A^-1``; CR2 (Bell and McCaffrey 2002) takes
    ``X_u^T (I - H_uu)^(-1/2) e_u`` instead of ``g_u = X_u^T e_u``, ``H_uu = X_u A^-1
    X_u^T`` the unit's block of the hat matrix.  From the normal equations alone:
    ``X_u^T f(X_u A^-1 X_u^T) = f(A_u A^-1) X_u^T``, so the adjusted score is
    ``A^(1/2) (I - A^(-1/2) A_u A^(-1/2))^(-1/2) A^(-1/2) g_u``.  A unit that alone fixes
    a direction (a few warm peaks: the lever arm the pairs bootstrap resamples and the
    fixed design keeps, entry 41) has an eigenvalue of ``A^(-1/2) A_u A^(-1/2)`` near 1
    and its score is inflated; the law is linearised, ``(1, t, max(0, t - T_m), [t >
    T_m])`` as in `sandwich_errors`.
    """
    u = unit_scores(res)
    f, inv, score = u["f"], u["inv"], u["score"]
    a = u["total"][np.ix_(f, f)]
    lam, vec = np.linalg.eigh(a)
    lam = np.clip(lam, lam.max() * 1e-15, None)
    root, inv_root = (vec * np.sqrt(lam)) @ vec.T, (vec / np.sqrt(lam)) @ vec.T
    adjusted = np.empty_like(score)
    for k, a_k in enumerate(u["a_u"][:, f][:, :, f]):  # one small eigenproblem per unit
        mu, w = np.linalg.eigh(inv_root @ a_k @ inv_root)
        mu = np.clip(mu, 0.0, 1.0 - 1e-9)
        adjusted[k] = root @ (w / np.sqrt(1.0 - mu)) @ w.T @ inv_root @ score[k]
    cr0 = inv @ (score.T @ score) @ inv
    cr2 = inv @ (adjusted.T @ adjusted) @ inv
    now = fv.law_parameters(res.calibration)

    def ratio(t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.ones((t.size, 3))
        for j in range(3):
            g = np.zeros((t.size, fb.N_PARAMETERS))
            g[:, j * fb.PER_AXIS:j * fb.PER_AXIS + 4] = np.column_stack(
                [np.ones_like(t), t, np.maximum(0.0, t - now[j, 3]), (t > now[j, 3])])
            g = g[:, f]
            v0 = np.einsum("ti,ij,tj->t", g, cr0, g)
            v2 = np.einsum("ti,ij,tj->t", g, cr2, g)
            out[:, j] = np.sqrt(np.divide(v2, v0, out=np.ones_like(v0), where=v0 > 0))
        return out

    return ratio


#: The band candidates `band_summary` compares (column -> rule).
BANDS = {"fixed 800": band_fixed, "max": band_max, "floor: pairs' least": band_floor_least,
         "floor: pairs at -50 C": band_floor_regulated, "pairs' correlation": band_correlation,
         "leverage, floor at -50 C": band_leverage_floored}


def band_pulls(res, true, fixed: np.ndarray, rule, lever=None) -> dict:
    """The law's pulls with its band from ``rule`` (`BANDS`; the pairs resamples are the
    fit's stored ones, ``fixed`` the replayed fixed-design ones, ``lever`` the fit's
    `leverage_ratio`): ``law_pull`` at `LAW_T` ((len(LAW_T), 3), NaN outside the stated
    range) and ``grid_max`` (3,), the largest |pull| per axis over a `BAND_GRID_STEP_C`
    grid of the stated range."""
    lo, hi = res.fitted_range
    data_t = np.arange(np.ceil(lo), np.floor(hi) + 0.01, BAND_GRID_STEP_C)
    grid = np.arange(np.floor(lo), np.ceil(hi) + 0.01, BAND_GRID_STEP_C)
    grid = grid[res.stated_ranges.contains(grid)]
    law_t = np.array(LAW_T)
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    fit = res.calibration.temperature_coefficients
    pairs = res.bootstrap["law"]
    pull = law_difference(fit, tc, law_t) / rule(pairs, fixed, law_t, data_t, lever)
    pull[~res.stated_ranges.contains(law_t)] = np.nan
    on_grid = law_difference(fit, tc, grid) / rule(pairs, fixed, grid, data_t, lever)
    return {"law_pull": pull, "grid_max": np.abs(on_grid).max(axis=0)}


def band_summary(folder: Path, n_bootstrap: int = 800) -> None:
    """Print, per law row at `LAW_T` (inside the stated range), the pulls' spread, largest
    size and count beyond 3 with the stored (pairs) band and each candidate of `BANDS`
    (the fixed-design resamples replayed, ``n_bootstrap``, `replayed_resamples`), then the
    largest |pull| over the stated range's grid and the fits with one beyond 3."""
    fits = [pickle.loads(f.read_bytes()) for f in sorted(folder.glob("fit_*.pkl"))]
    fixed = [replayed_resamples(res, True, n_bootstrap)["law"] for res, _ in fits]
    lever = [leverage_ratio(res) for res, _ in fits]
    per = {"stored": [band_pulls(res, true, None, lambda p, f, t, d, lv: _band(p, t))
                      for res, true in fits]}
    per.update({name: [band_pulls(res, true, fx, rule, lv)
                       for (res, true), fx, lv in zip(fits, fixed, lever, strict=True)]
                for name, rule in BANDS.items()})
    print(f"{len(fits)} fits; (spread, max |pull|, beyond 3)")
    print("| law row | " + " | ".join(per) + " |")
    print("|---|" + "---|" * len(per))
    for i, t in enumerate(LAW_T):
        for j, a in enumerate("xyz"):
            cells = []
            for rows in per.values():
                p = np.array([r["law_pull"][i, j] for r in rows])
                p = p[np.isfinite(p)]
                cells.append(f"{p.std(ddof=1):.2f}, {np.abs(p).max():.2f}, "
                             f"{int(np.count_nonzero(np.abs(p) > 3))}" if p.size > 1 else "")
            if any(cells):
                print(f"| law {a} at {t:+.0f} C (N {p.size}) | " + " | ".join(cells) + " |")
    cells = []
    for rows in per.values():
        g = np.stack([r["grid_max"] for r in rows])
        cells.append(f"{g.max():.2f}, {int(np.count_nonzero(np.any(g > 3, axis=1)))} fits")
    print(f"| grid of T_RANGE, every {BAND_GRID_STEP_C:g} C: max |pull|, fits beyond 3 | "
          + " | ".join(cells) + " |")


def estimator_summary(folder: Path) -> None:
    """Print, per parameter, the pulls' spread, largest size and count beyond 3 under each
    of `SPREADS` on the saved fits of ``folder`` (entry 39)."""
    fits = [pickle.loads(f.read_bytes()) for f in sorted(folder.glob("fit_*.pkl"))]
    per = {name: [estimator_row(res, true, f) for res, true in fits]
           for name, f in SPREADS.items()}
    per["sandwich"] = [sandwich_row(res, true, False) for res, true in fits]
    per["sandwich+jumps"] = [sandwich_row(res, true, True) for res, true in fits]
    per["fixed design"] = [fixed_design_row(res, true) for res, true in fits]
    jump = np.stack([r["jump_share"] for r in per["sd"]])
    print(f"{len(fits)} fits; resamples whose break moved from the solution's, per axis: "
          f"median {np.round(np.median(jump, axis=0), 3)}, max {np.round(jump.max(axis=0), 3)}")
    print("| parameter | " + " | ".join(per) + " |")
    print("|---|" + "---|" * len(per) + "   (spread, max |pull|, beyond 3)")
    _print_pull_rows(per)


def main() -> None:
    """Run the study and print the pulls."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=20)
    ap.add_argument("--days", type=int, default=2)
    ap.add_argument("--compressive", type=float, default=None,
                    help="Relative rms of the compressive part (default 0.03; the hard "
                         "cruise wind draws 0.10-0.15 per realisation).")
    ap.add_argument("--world", choices=WORLDS, default="realistic",
                    help="realistic: the test wind of issue 21; cruise-hard, mercury-orbit: "
                         "issue 34's hard worlds (tests/missions/messenger/_hard_worlds.py); "
                         "mercury-orbit-late: the warm peaks 40-80 min after periapsis.")
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--first-seed", type=int, default=1000,
                    help="Seed of the first realisation (then +1 each).")
    ap.add_argument("--processes", type=int, default=1,
                    help="Realisations run side by side in this many processes.")
    ap.add_argument("--unseen", action="store_true",
                    help="Simulate one more day and recalibrate it with the fitted tables "
                         "(rms against the truth per sensor axis, the issue's figure of merit).")
    ap.add_argument("--broadband", action="store_true",
                    help="Compressive part with an f^-5/3 spectrum from 1 h to 2 s (the "
                         "estimator's assumption failing) instead of f^-2 from 1 h to 5 min.")
    ap.add_argument("--defects", action="store_true",
                    help="Telemetry defects: science, heater and temperature gaps, coarse "
                         "range, a rate change (`defects`).")
    ap.add_argument("--hold-d0", default="",
                    help="Comma list of axes whose D0 is held (shipped value, default width).")
    ap.add_argument("--draw-law", action="store_true",
                    help="Draw the true temperature law (Table 2, breaks included) per "
                         "realisation (tests/missions/messenger/_hard_worlds.drawn_law), "
                         "so that the breaks' pulls test a spread of truths.")
    ap.add_argument("--save", type=Path, default=None,
                    help="Folder to pickle each realisation's fit and true tables into.")
    ap.add_argument("--summarise", type=Path, default=None,
                    help="Print the summary of a --save folder's realisations; run nothing.")
    ap.add_argument("--estimators", action="store_true",
                    help="With --summarise: the pulls under each spread estimator of the "
                         "stated errors (SPREADS) instead of the summary.")
    ap.add_argument("--replay", action="store_true",
                    help="With --summarise: the pulls as stored and under the pairs, "
                         "refined and fixed-design bootstraps replayed on the stored normal "
                         "equations (REPLAYS; entry 42).")
    ap.add_argument("--bands", action="store_true",
                    help="With --summarise: the law's pulls under the design-fixed band "
                         "candidates (BANDS: the fixed-design bootstrap replayed, floored "
                         "or combined with the pairs band so that it cannot pinch; entry "
                         "46), at LAW_T and over the stated range.")
    ap.add_argument("--wild", action="store_true",
                    help="With --summarise: the pulls under the wild cluster bootstrap "
                         "replayed on the stored normal equations, beside the fit's own "
                         "(pairs) and two combinations (WILD_COLUMNS; entry 50), and "
                         "the law's largest pull over the stated range.")
    ap.add_argument("--profile", action="store_true",
                    help="With --summarise: T_m's pulls with its error from the residual's "
                         "profile against the break (fit_break_profile.profile_break_errors), "
                         "beside the fit's own (pairs) and floored at a fraction of it "
                         "(PROFILE_FLOORS; entry 51), and the fits far off.")
    ap.add_argument("--core", action="store_true",
                    help="With --summarise: the stated errors of T_m and the law split into "
                         "factors (jumps, widening, design, sandwich; entry 41).")
    args = ap.parse_args()
    if args.summarise is not None:
        if not any(args.summarise.glob("fit_*.pkl")):
            ap.error(f"--summarise {args.summarise}: no fit_*.pkl there (a --save folder)")
        for flag, summary in (("estimators", estimator_summary), ("core", core_summary),
                              ("replay", replay_summary), ("bands", band_summary),
                              ("wild", wild_summary), ("profile", profile_summary)):
            if getattr(args, flag):  # the first option given, in this order
                summary(args.summarise)
                return
        summarise(saved_rows(args.summarise), args.markdown)
        return
    rows = []
    t_start = time.perf_counter()
    run = functools.partial(_timed, days=args.days, compressive=args.compressive,
                            passes=args.passes, save=args.save, first_seed=args.first_seed,
                            unseen=args.unseen, broadband=args.broadband,
                            with_defects=args.defects,
                            hold_d0=tuple(a for a in args.hold_d0.split(",") if a),
                            world=args.world, draw_law=args.draw_law)
    if args.processes > 1:
        pool = ProcessPoolExecutor(max_workers=args.processes)
        done = (f.result() for f in as_completed([pool.submit(run, k)
                                                  for k in range(args.realisations)]))
    else:
        pool, done = None, map(run, range(args.realisations))
    for k, seconds, r in done:
        rows.append(r)
        print(f"{k:3d} {seconds:6.1f} s  tau pull {r['tau_pull']:+.2f} "
              f"({r['tau_rel']:+.3f})  dt pull {r['dt_pull']:+.2f}  D0 pulls "
              f"{np.round(r['d0_pull'], 2)} ({np.round(r['d0_rel'], 3)} +- "
              f"{np.round(r['d0_err_rel'], 3)}; field one-sided {r['d0_balance']:.2f})  "
              "law pulls max "
              f"{np.round(np.nanmax(np.abs(r['law_pull']), axis=0), 2)}  law max "
              f"{np.round(r['law_max_nt'], 3)} nT over T_RANGE {r['t_range']} C  "
              f"T_m pulls {np.round(r['tm_pull'], 2)} (+- "
              f"{np.round(r['tm_err'], 2)} C)  predicted {np.round(r['predicted_nt'], 3)} nT  "
              f"unseen day {np.round(r['unseen_nt'], 3)} nT (inside the stated range "
              f"{np.round(r['unseen_in_range_nt'], 3)} nT; samples outside "
              f"{r['outside_share']:.1%}); D_RANGE {r['duty_range']} % (fitted heater-on "
              f"samples outside {r['duty_outside_share']:.1%}): unseen inside T_RANGE and "
              f"D_RANGE {np.round(r['unseen_in_both_nt'], 3)} nT against predicted "
              f"{np.round(r['predicted_nt'], 3)} nT (before the duty range "
              f"{np.round(r['predicted_without_duty_nt'], 3)} nT); unseen heater-on outside "
              f"D_RANGE {np.round(r['unseen_beyond_duty_nt'], 3)} nT "
              f"({r['unseen_beyond_duty_share']:.1%} of the samples in T_RANGE); waveform "
              f"part alone {_parts(r['waveform_parts'])}; the unseen day's own prediction "
              f"{_parts(r['day_prediction'])} (stated waveform part "
              f"{np.round(r['stated_waveform_nt'], 3)} nT, fitted mix "
              f"{np.round(r['fitted_mix_waveform_nt'], 3)} nT); held upper "
              f"segments {r['held_upper']}; law band "
              f"max {np.round(r['law_band_max_nt'], 3)} nT, law max |error / band| "
              f"{np.round(r['law_max_pull'], 2)} (simultaneous threshold "
              f"{np.round(r['law_max_threshold'], 2)}); passes {r['passes']}; guards: "
              f"{r['verdict']}; compressive {r['compressive_share'][0]} of "
              f"{r['compressive_share'][1]} judged; intervals {r['reasons']}", flush=True)
    print(f"{dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M} UTC, {len(rows)} realisations (seeds "
          f"{args.first_seed}..{args.first_seed + len(rows) - 1}), "
          f"{args.days} days at 1 Hz, world {args.world}, compressive {args.compressive}"
          f"{' (broadband)' if args.broadband else ''}{', defects' if args.defects else ''}"
          f"{', law drawn per realisation' if args.draw_law else ''}, "
          f"{args.passes} passes, "
          f"{time.perf_counter() - t_start:.0f} s")
    summarise(rows, args.markdown)
    if pool is not None:
        pool.shutdown()


if __name__ == "__main__":
    main()
