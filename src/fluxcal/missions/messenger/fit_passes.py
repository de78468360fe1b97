"""The MESSENGER fit's passes over the days: map (days) -> reduce (merge) -> fit, repeated.

The long-term averages of sec. 7 (and the variance estimator's normal equations) are
sums over many days, so the fit runs as a map-reduce:

* `day_chunks` lists one `Chunk` (a day's input files) per day of the batch layout, and
  `reduce_chunk` reads and reduces one (`fit_reduce.reduce_day`, with the variance
  estimator also `fit_variance.reduce_variance`), serially or on a Dask worker;
* the days' statistics are merged in groups of `MERGE_FAN_IN`, level by level, the same
  sums in the same order serially and on the workers (the merge tree);
* `fit_days` fits the merged statistics (`fit.fit_calibration` or
  `fit.fit_variance_calibration`), reduces the days again with the new estimates, and
  repeats until a pass changes every parameter by less than its allowance
  (`pass_changes`, `convergence_criterion`; the law over the span of the T_RANGE that
  pass's table would state, `judged_law_range`) or ``passes`` have run (with the variance
  estimator a pass that reverses the previous one, `REVERSAL_COSINE`, is followed from
  half way); then it states the waveform columns' errors, judges the last pass at the
  error goal (`fit_merit.assess`, `merit_inside_range`; `judged_at` at another goal) and
  refuses what the guards refuse (`fit_guards.check_fit`, `fit_merit.check_merit`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 and sec. 7 (long-term averages
   of solar-wind data binned by temperature and duty cycle; eq. 6a-6f look back over the
   duty-cycle changes before a sample, so a day reads the heater files of the day before).
.. [2] docs/decisions/messenger_fit.md entries 1, 16, 18, 19, 21, 26, 27, 33, 40, 53,
   54 and 57 (the law's convergence over T_RANGE, issue 34 item 1).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import reduce
from pathlib import Path
from typing import Any

import numpy as np

from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import FitRefusedError, FluxcalError, InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import fit_merit
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.batch_task import default_kernels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.fit import (
    AXES,
    ESTIMATORS,
    TEMPERATURE_LAWS,
    FitResult,
    fit_calibration,
    fit_variance_calibration,
    with_tables,
)
from fluxcal.missions.messenger.fit_guards import break_refusal, check_fit
from fluxcal.missions.messenger.fit_holds import HoldD0, held_d0_values
from fluxcal.missions.messenger.fit_reduce import (
    DayStatistics,
    FitSettings,
    intervals_to_et,
    reduce_day,
)
from fluxcal.missions.messenger.fit_variance import VarianceStatistics, reduce_variance
from fluxcal.missions.messenger.fit_waveforms import waveform_column_errors
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.routes import EDR_MAPPING, day_file_groups
from fluxcal.products.provenance import sha256_file
from fluxcal.runs.batch import release_worker_kernel_pool, worker_kernel_pool

__all__ = ["fit_days"]


@dataclass(frozen=True)
class Chunk:
    """The input files of one reduction (a day of the batch layout, or all given files)."""

    label: str
    science: tuple[Path, ...]
    heater: tuple[Path, ...]
    temperature: tuple[Path, ...]
    kernels: tuple[Path, ...]

    def files(self) -> list[Path]:
        """All stream files of the chunk."""
        return [*self.science, *self.heater, *self.temperature]


def refuse_edr_folder(input_dir: Path) -> None:
    """Refuse a batch folder of archived EDRs: the fit reads the CSV batch layout only.

    Raises
    ------
    InputFormatError
        When ``input_dir`` holds ``edr_mapping.toml`` (`routes.EDR_MAPPING`).
    """
    if (Path(input_dir) / EDR_MAPPING).is_file():
        raise InputFormatError(
            f"holds {EDR_MAPPING}: 'fluxcal messenger fit' reads the CSV batch layout "
            "(MAGSCI/MAGHTR/MAGTMP_YYYYDDD.csv), not archived EDRs; convert them first or "
            "give the CSV streams with --input/--heater/--temperature",
            path=str(input_dir), field="--input-dir")


def day_chunks(input_dir: Path, days: Sequence, kernels: Path | None = None) -> list[Chunk]:
    """One `Chunk` per day of the ``fluxcal batch messenger`` input layout.

    A day's science file only (each sample counted once); the heater files of the day
    before and the day (look-back, sec. 7); the temperatures of the days around it —
    the files a ``fluxcal batch messenger`` day reads (`routes.day_file_groups`).  Days
    without a science file are skipped.
    """
    refuse_edr_folder(Path(input_dir))
    k = (default_kernels(Path(input_dir), kernels),)
    out = []
    for day in days:
        files = day_file_groups(Path(input_dir), day)
        if not files["science"][0].exists():
            continue
        out.append(Chunk(f"{day:%Y-%m-%d}", tuple(files["science"]), tuple(files["heater"]),
                         tuple(files["temperature"]), k))
    return out


def reduce_chunk(
    chunk: Chunk,
    cal: MessengerCalibration,
    intervals: np.ndarray | None,
    settings: FitSettings,
    hash_inputs: bool = False,
    estimator: str = "zero-mean",
) -> DayStatistics | tuple[DayStatistics, Any]:
    """Read one chunk's streams and reduce them (`reduce_day`); runs on a worker.

    With ``estimator="variance"`` also `fit_variance.reduce_variance`: returns both.
    """
    worker_kernel_pool(list(chunk.kernels), FRAME_KERNELS)
    sclk = SclkKernel.from_pool(SPACECRAFT_ID)
    inputs = {p.name: sha256_file(p) for p in chunk.files()} if hash_inputs else None
    sci, htr = read_science(list(chunk.science)), read_heater(list(chunk.heater))
    tmp = read_temperature(list(chunk.temperature))
    iv = intervals_to_et(intervals)
    stats = reduce_day(sci, htr, tmp, sclk, cal, iv, settings, label=chunk.label,
                       inputs=inputs)
    if estimator != "variance":
        return stats
    return stats, reduce_variance(sci, htr, tmp, sclk, cal, iv)


Progress = Callable[[str, int, int], None]


#: A pass converges when, besides tau and D0 (``tolerance``), the Table 2 law moved by less
#: than this many fine counts (0.2 x 0.047 = 0.009 nT) anywhere the table states it (the
#: span of its T_RANGE, `law_change_temperatures`): the law and its break can still move
#: after tau and D0 have settled (docs/decisions/messenger_fit.md, entry 16: 0.19 nT left
#: on y in a 32-day fit that stopped on tau and D0 alone).
LAW_TOLERANCE_COUNTS = 0.2
#: Temperatures (C) over which the law's change between passes is taken where the table
#: states no T_RANGE (the zero-mean estimator), on this 1-C grid inside a T_RANGE.
LAW_CHANGE_GRID_C = np.arange(-65.0, 55.5, 1.0)


#: A pass has converged when every parameter changed by less than the larger of its
#: absolute tolerance and this fraction of its stated error (entry 18): what is left
#: to move (at most about the last change for a contracting iteration) is then a tenth
#: of the stated error, which it widens by half a percent.
CONVERGENCE_SIGMA = 0.1
#: Absolute tolerance of dt's change (s) between passes.
DELAY_TOLERANCE_S = 0.05
#: Most passes (``--passes``); a convergence refusal advises it, not a doubling: a fit
#: stops as soon as it converges, and 6 -> 12 passes was refused again at 12 where 13
#: converged (entry 26).
MAX_PASSES = 20


def law_change_temperatures(ranges: StatedRanges | None) -> np.ndarray:
    """Return the temperatures (C) at which a pass's law change is judged.

    The 1-C grid over the span of ``ranges`` (the table's T_RANGE, gaps between its
    intervals included) with the span's ends; `LAW_CHANGE_GRID_C` where None.  The law
    outside the span is not stated (calibrating there warns), and a break beyond it is
    said in the header as not checked (`fit_write.break_outside_lines`, entry 56); a
    break inside the span is judged through the law around it.
    """
    if ranges is None:
        return LAW_CHANGE_GRID_C
    lo, hi = ranges.span
    return np.union1d(np.arange(np.ceil(lo), hi, 1.0), [lo, hi])


def judged_law_range(result: FitResult, goal: float = fit_merit.ERROR_GOAL_NT
                     ) -> StatedRanges | None:
    """Return the T_RANGE ``result``'s table would state at ``goal``: where its law is judged.

    The variance estimator: `fit_merit.stated_range` over the data's range at the goal's
    band limit, as `fit_merit.assess` states it after the last pass; where the law is
    determined nowhere, the data's range (the table then states that, and
    `fit_merit.check_merit` refuses it).  None for the zero-mean estimator, whose table
    states no T_RANGE (`LAW_CHANGE_GRID_C` then).
    """
    if result.estimator != "variance":
        return None
    ranges = fit_merit.stated_range(result, fit_merit.band_limit_for(goal))
    return ranges if ranges is not None else result.stated_ranges


def pass_changes(old: MessengerCalibration, new: FitResult, tolerance: float = 2e-3,
                 ranges: StatedRanges | None = None) -> dict[str, Any]:
    """Change of every parameter from ``old`` to ``new`` and its allowance (entry 18).

    Each change is compared with the larger of an absolute tolerance (``tolerance``
    of tau and of each D0; `DELAY_TOLERANCE_S`; `LAW_TOLERANCE_COUNTS` of the law at
    every temperature of `law_change_temperatures` ``ranges``: the span of the T_RANGE
    the table states, `judged_law_range`; None: `LAW_CHANGE_GRID_C`) and
    `CONVERGENCE_SIGMA` times its stated error (the law's at each temperature,
    `FitResult.law_error`).  ``ratio`` is the largest change over its allowance: the
    pass has converged when it is at most 1.  ``law_range_c``: the temperatures judged.
    """
    cal = new.calibration
    r = new.relaxation
    rel_old, rel_new = old.constants["relaxation"], cal.constants["relaxation"]
    d_tau = float(rel_new["tau_s"]) - float(rel_old["tau_s"])
    d_dt = float(rel_new["delay_s"]) - float(rel_old["delay_s"])
    d0_new = np.asarray(cal.duty_cycle_d0, dtype=float)
    d_d0 = d0_new - np.asarray(old.duty_cycle_d0, dtype=float)
    grid = law_change_temperatures(ranges)
    law_new = two_segment_offset(grid, cal.offset_coefficients())
    d_law = law_new - two_segment_offset(grid, old.offset_coefficients())
    allow_law = np.maximum(LAW_TOLERANCE_COUNTS,
                           CONVERGENCE_SIGMA * np.nan_to_num(new.law_error(grid)))
    law_ratio = np.abs(d_law) / allow_law
    at = np.argmax(law_ratio, axis=0)
    items = [("tau", d_tau, max(tolerance * abs(float(rel_new["tau_s"])),
                                CONVERGENCE_SIGMA * np.nan_to_num(r.tau_err)), "s"),
             ("dt", d_dt, max(DELAY_TOLERANCE_S, CONVERGENCE_SIGMA * np.nan_to_num(r.dt_err)),
              "s")]
    items += [(f"D0 {a}", float(d_d0[j]),
               max(tolerance * abs(float(d0_new[j])),
                   CONVERGENCE_SIGMA * np.nan_to_num(new.duty[j].slope_err)), "counts/ppt")
              for j, a in enumerate(AXES)]
    items += [(f"law {a} at {grid[at[j]]:+.0f} C", float(d_law[at[j], j]),
               float(allow_law[at[j], j]), "counts") for j, a in enumerate(AXES)]
    ratios = [abs(c) / allow if allow > 0 else (0.0 if c == 0 else np.inf)
              for _, c, allow, _ in items]
    return {
        "tau_s": d_tau, "delay_s": d_dt, "D0": d_d0.tolist(),
        "law_counts": np.abs(d_law).max(axis=0).tolist(),
        "law_range_c": [float(grid[0]), float(grid[-1])],
        "Tm_c": (np.asarray(cal.breakpoint_temperature_c, dtype=float)
                 - np.asarray(old.breakpoint_temperature_c, dtype=float)).tolist(),
        "ratio": float(max(ratios)),
        "over": [f"{name} {c:+.4g} {unit} (allowed {allow:.2g})"
                 for (name, c, allow, unit), q in zip(items, ratios, strict=True) if q > 1.0],
    }


#: A pass reverses the previous one when the cosine of their steps (in units of the
#: stated errors) is below this: the two-state cycle of entry 18.
REVERSAL_COSINE = -0.5


def _table_step(old: MessengerCalibration, new: FitResult) -> np.ndarray:
    """Return the change of the law ``(a, b, c, T_m)``, D0 and tau in units of their errors."""
    law_old, law_new = fv.law_parameters(old), fv.law_parameters(new.calibration)
    err_law = np.array([[f.a0_err, f.b0_err, max(f.b0_err, f.b1_err), f.x_m_err]
                        for f in new.temperature])
    err_d0 = np.array([f.slope_err for f in new.duty])
    tau = [float(c.constants["relaxation"]["tau_s"]) for c in (old, new.calibration)]

    def scaled(d, e):
        e = np.asarray(e, dtype=float)
        return np.where(e > 0, np.asarray(d, dtype=float) / np.where(e > 0, e, 1.0), 0.0)

    return np.concatenate([
        scaled(law_new - law_old, err_law).ravel(),
        scaled(np.asarray(new.calibration.duty_cycle_d0) - np.asarray(old.duty_cycle_d0),
               err_d0),
        scaled([tau[1] - tau[0]], [new.relaxation.tau_err])])


def _reverses(before: np.ndarray, step: np.ndarray) -> bool:
    """Whether ``step`` goes back along ``before`` (`REVERSAL_COSINE`)."""
    norm = float(np.linalg.norm(before) * np.linalg.norm(step))
    return norm > 0 and float(before @ step) / norm < REVERSAL_COSINE


def _midpoint(old: MessengerCalibration, new: FitResult) -> MessengerCalibration:
    """Return the calibration half way between two passes (the new waveforms kept)."""
    rel_old, rel_new = old.constants["relaxation"], new.calibration.constants["relaxation"]
    return with_tables(
        new.calibration,
        0.5 * (fv.law_parameters(old) + fv.law_parameters(new.calibration)),
        0.5 * (np.asarray(old.duty_cycle_d0) + np.asarray(new.calibration.duty_cycle_d0)),
        0.5 * (float(rel_old["tau_s"]) + float(rel_new["tau_s"])),
        0.5 * (float(rel_old["delay_s"]) + float(rel_new["delay_s"])),
        new.calibration.heater_signal)


def also_refused(result: FitResult) -> str:
    """Return what `check_fit` refuses a fit's last pass for, without its advice ('' if none).

    A fit refused as not converged names that cause first; this says whether its last pass
    would be refused for another one as well (in a 5-%-compressive cruise wind all ten fits
    refused as not converged were, on the D0 z goal: verification section 49), so
    that more passes are not advised as if they alone would write the table.
    """
    try:
        check_fit(result)
    except FitRefusedError as err:
        return str(err).split("; not written", 1)[0]
    return ""


def convergence_criterion(tolerance: float, ranges: StatedRanges | None = None) -> str:
    """Return the stated convergence criterion (report and refusal).

    ``ranges``: the T_RANGE over whose span the law was judged (`judged_law_range`);
    None: `LAW_CHANGE_GRID_C`.
    """
    grid = law_change_temperatures(ranges)
    where = (f"every 1 C of {grid[0]:.0f}..{grid[-1]:.0f} C" if ranges is None else
             f"every 1 C of {grid[0]:g}..{grid[-1]:g} C, the span of the T_RANGE the table "
             "states: beyond it the table states no law, and its header says a break "
             "there is not checked")
    return (f"every parameter changed by less than the larger of an absolute tolerance "
            f"(tau and each D0 {tolerance:g} of their value, dt {DELAY_TOLERANCE_S:g} s, the "
            f"law {LAW_TOLERANCE_COUNTS:g} counts at {where}) and "
            f"{CONVERGENCE_SIGMA:g} of its stated error")


def convergence_record(changes: dict[str, Any], passes_run: int, max_passes: int,
                       tolerance: float, ranges: StatedRanges | None) -> dict[str, Any]:
    """Return ``FitResult.convergence`` for a last pass's `pass_changes` ``changes``.

    ``ranges``: the T_RANGE over whose span the law was judged (`judged_law_range`),
    named in the stop reason (every header) and the criterion (report and refusal).
    """
    converged = changes["ratio"] <= 1.0
    lo, hi = changes["law_range_c"]
    where = "" if ranges is None else f" (the law judged over T_RANGE's span {lo:g}..{hi:g} C)"
    return {
        "passes_run": passes_run, "max_passes": max_passes, "converged": converged,
        "tolerance": tolerance, "criterion": convergence_criterion(tolerance, ranges),
        "stop": (f"converged after {passes_run} passes: the last changed every parameter "
                 f"by at most {changes['ratio']:.2g} of its allowance{where}" if converged
                 else f"not converged after {passes_run} passes: the last changed "
                 + ", ".join(changes["over"]) + where),
    }


def merit_inside_range(result: FitResult, goal: float = fit_merit.ERROR_GOAL_NT) -> None:
    """Hold the predicted error to the samples inside the stated range (entry 21).

    ``result.merit`` (`fit_merit.assess`) predicts the error over every used sample;
    the table states its law only over ``result.temperature_ranges`` (``T_RANGE``, one
    or more intervals), and calibrating a sample outside it warns with how far
    (`calibration_data`, `chain.warn_outside_temperature_range`).  The figure of
    merit ``total_nt`` (and its parts) becomes `fit_merit.predicted_error` over the
    samples whose 1-C bin's mean temperature T_RANGE contains
    (`StatedRanges.contains`); ``outside`` keeps the share of the samples outside and
    the prediction over all samples, both stated in every header and the report.  Only
    when T_RANGE holds the regulated temperature (eq. 2, -50 C): the heater runs only
    there, and the prediction's waveform part counts every heater-on sample as inside;
    a range without it keeps the prediction over all samples.
    """
    m = result.merit
    ranges = result.temperature_ranges
    if not m or "total_nt" not in m or ranges is None:
        return
    if not ranges.contains(result.calibration.reference_temperature_c):
        return
    v = result.variance
    mom = v.offset_moments
    with np.errstate(invalid="ignore", divide="ignore"):
        t_b = mom[:, 1] / mom[:, 0]
    inside = (mom[:, 0] > 0) & ranges.contains(t_b)
    view = dataclasses.replace(result, variance=dataclasses.replace(
        v, offset_moments=mom * inside[:, None]))
    within = fit_merit.predicted_error(view, goal)
    n_all = int(m["samples"])
    result.merit = {
        **m, **{k: within[k] for k in ("total_nt", "law_nt", "d0_nt", "relaxation_nt",
                                        "waveform_nt", "waveform_fitted_mix_nt", "samples")
                if k in within},
        "range_c": [list(pair) for pair in ranges.intervals],
        "outside": {"samples": n_all - int(within["samples"]), "of": n_all,
                    "all_samples_total_nt": list(m["total_nt"]),
                    "all_samples_law_nt": list(m["law_nt"])},
    }


def judged_at(result: FitResult, goal: float) -> FitResult:
    """Return a copy of ``result`` judged at the error goal ``goal`` (nT).

    As `fit_days` judges a fit at ``--error-goal goal``: `fit_merit.assess` over the
    data's range (``merit["data_range_c"]``), then `merit_inside_range`.  The passes do
    not depend on the goal, so this is the table that option writes, or refuses
    (`fit_merit.advised_goal`: a refusal's advice; the fit demo's goal).  ``result`` is
    left as it is.
    """
    out = dataclasses.replace(result, fitted_range=tuple(result.merit["data_range_c"]))
    fit_merit.assess(out, goal, max_compressive_share=result.merit["max_compressive_share"])
    merit_inside_range(out, goal)
    c = result.convergence
    if c and result.pass_start is not None:
        # the last pass judged again over this goal's T_RANGE, as a fit at this goal
        # judges it: a wider range may take in a law still moving (issue 34, item 1)
        out.convergence = convergence_record(
            pass_changes(result.pass_start, out, c["tolerance"], out.stated_ranges),
            c["passes_run"], c["max_passes"], c["tolerance"], out.stated_ranges)
    return out


def fit_days(
    chunks: Sequence[Chunk],
    base: MessengerCalibration,
    *,
    intervals: np.ndarray | None = None,
    passes: int = 12,
    tolerance: float = 2e-3,
    scheduler: str | None = "serial",
    n_workers: int = 2,
    settings: FitSettings | None = None,
    fit_delay: bool = True,
    progress: Progress | None = None,
    temperature_law: str = "distribution",
    estimator: str = "zero-mean",
    guard: bool = True,
    hold_d0: HoldD0 = (),
    error_goal: float = fit_merit.ERROR_GOAL_NT,
    max_compressive_share: float = fit_merit.MAX_COMPRESSIVE_SHARE,
) -> FitResult:
    """Fit the calibration to many days: reduce each (map), merge, fit; ``passes`` times.

    Parameters
    ----------
    chunks : sequence of Chunk
        `day_chunks` of a batch input folder, or one `Chunk` of given files.
    base : MessengerCalibration
        Starting estimate (the shipped tables) and the unfitted terms.
    intervals : ndarray, shape (k, 2), optional
        Solar-wind intervals, UTC ``datetime64`` (`read_intervals`) or ET; None: all data.
    passes : int
        Most reduce-and-fit iterations (each pass removes the others' terms with the
        previous estimates; docs/decisions/messenger_fit.md, entry 1).
    tolerance : float
        Stop after a pass that changed every parameter by less than its allowance
        (`pass_changes`: the larger of this fraction of tau and of each D0, dt by
        `DELAY_TOLERANCE_S`, the law by `LAW_TOLERANCE_COUNTS` over the span of the
        T_RANGE the pass's table would state at ``error_goal`` (`judged_law_range`), and
        `CONVERGENCE_SIGMA` of its stated error).
    scheduler : str or None
        ``"serial"``: in this process; None: a local Dask cluster of ``n_workers``
        single-threaded processes (`fluxcal.runs.batch.make_local_cluster`); else
        the address of a running Dask scheduler.
    n_workers : int
        Workers of the local cluster.
    settings : FitSettings, optional
    fit_delay : bool
        Also fit dt (`fit_calibration`).
    progress : callable, optional
        ``progress(description, done, total)`` after every reduced chunk.
    temperature_law : {"distribution", "binned-mean"}
        Estimator of the temperature law (`fit_calibration`).
    estimator : {"zero-mean", "variance"}
        ``zero-mean``: the seed's long-term averages (`fit_calibration`), which assume
        the field averages to zero over each bin's samples; ``variance``: ``|B|`` least
        variable within 15-min intervals (`fit_variance_calibration`), which assumes
        rotations at nearly constant ``|B|`` (docs/decisions/messenger_fit.md, entry 11).
    guard : bool
        Refuse a fit that has not converged after ``passes``, a pass outside the
        physical ranges (`check_fit`) and, with the variance estimator, a fit whose
        predicted error exceeds ``error_goal`` or that the data cannot support
        (`fit_merit.check_merit`); False only for studies of the estimators themselves
        (the result must then not be written).
    hold_d0 : tuple of str or mapping
        Axes whose D0 is held (variance estimator only; `held_d0_values`): the user's
        choice for an axis whose D0 the data do not determine (``--hold-d0``;
        docs/decisions/messenger_fit.md, entries 15 and 18), with a width that enters
        every other error.
    error_goal : float
        Largest predicted rms error (nT) of a recalibrated day (`fit_merit`).
    max_compressive_share : float
        Largest share of the judged intervals rejected as compressive
        (`fit_merit.compressive_refusal`; above the default it is written into every
        header).

    Returns
    -------
    FitResult
        Of the last pass, with ``passes`` holding every pass's summary.

    Raises
    ------
    FluxcalError
        No chunk, or the fit's own errors (`fit_calibration`).
    FitRefusedError
        Not converged after ``passes``; a parameter outside its physical range or
        undetermined (`check_fit`); the predicted error above ``error_goal`` or a
        named guard (`fit_merit.check_merit`).
    """
    if not chunks:
        raise FluxcalError("no day with a science file to fit")
    if passes < 1:
        raise FluxcalError(f"passes must be at least 1, got {passes}")
    if temperature_law not in TEMPERATURE_LAWS:
        raise FluxcalError(f"temperature_law must be one of {', '.join(TEMPERATURE_LAWS)}, "
                           f"got {temperature_law!r}")
    if estimator not in ESTIMATORS:
        raise FluxcalError(f"estimator must be one of {', '.join(ESTIMATORS)}, "
                           f"got {estimator!r}")
    if hold_d0 and estimator != "variance":
        raise FluxcalError("holding D0 (--hold-d0) needs the variance estimator "
                           f"(--estimator variance), got {estimator!r}")
    if set(hold_d0) - set(AXES):
        raise FluxcalError(f"--hold-d0 takes axes x, y, z, got {', '.join(hold_d0)}")
    held_d0_values(hold_d0, base)  # the widths, before any day is read
    s = settings or FitSettings()
    total = passes * len(chunks)
    history: list[dict[str, Any]] = []
    cal = base
    result: FitResult | None = None
    resample_map: dict[str, Any] | None = None  # on Dask: the resamples on the workers

    def run(mapper: Callable[[MessengerCalibration, bool, int], list[Any]]) -> FitResult:
        nonlocal cal, result
        inputs: dict[str, str] = {}
        converged = False
        law_range: StatedRanges | None = None
        held_upper: tuple[str, ...] = ()  # once held, held in every later pass (entry 27)
        for p in range(passes):
            # merged in groups, level by level: linear in the days (a left fold copies
            # the growing variance blocks at every day), the same sums as on Dask
            merged = _merge_all(mapper(cal, p == 0, p))
            stats, vstats = merged if estimator == "variance" else (merged, None)
            inputs = inputs or stats.inputs  # hashed on the first pass only
            stats.inputs = inputs
            # the waveform columns' errors are read by no pass: stated after the loop,
            # from the table this pass starts from (entry 33)
            fitted_from = cal
            if estimator == "variance":
                result = fit_variance_calibration(
                    stats, vstats, cal, fit_delay=fit_delay, hold_d0=hold_d0,
                    max_compressive_share=max_compressive_share, start=base,
                    hold_upper=held_upper, waveform_errors=False,
                    resample_map=resample_map)
                held_upper = tuple(a for a in AXES if a in result.held_upper)
            else:
                result = fit_calibration(stats, cal, fit_delay=fit_delay,
                                         temperature_law=temperature_law,
                                         waveform_errors=False)
            # the law judged where this pass's table would state it (its T_RANGE at the
            # goal; the rest of its law is not stated: issue 34, item 1)
            law_range = judged_law_range(result, error_goal)
            changes = pass_changes(cal, result, tolerance, law_range)
            converged = changes["ratio"] <= 1.0
            if guard:  # never carry a tau out of range
                check_fit(result, final=False)
            damped = (estimator == "variance" and not converged and len(history) >= 1
                      and _reverses(history[-1]["step"], _table_step(cal, result)))
            history.append({"pass": p + 1, **result.summary(), "changes": changes,
                            "step": _table_step(cal, result), "damped": damped})
            previous, cal = cal, result.calibration
            if converged:
                break
            if damped:  # a two-state cycle: the next pass starts half way (entry 18)
                cal = _midpoint(previous, result)
        assert result is not None
        for h in history:  # the scaled steps were for the cycle test only
            h.pop("step", None)
        result.passes = history
        result.pass_start = fitted_from
        result.convergence = convergence_record(history[-1]["changes"], len(history),
                                                passes, tolerance, law_range)
        converged = result.convergence["converged"]
        if guard:
            # the named cause first: a wind too compressive for the variance estimator
            # also keeps it from converging (entry 19)
            cause = (fit_merit.compressive_refusal(result.variance.reason,
                                                   max_compressive_share)
                     if estimator == "variance" else "")
            if cause:
                raise FitRefusedError(f"{cause}; not written. Give calmer (Alfvenic) "
                                      "solar-wind days or intervals")
            if not converged:
                # the named cause first: a break outside the data's temperatures (the
                # law's upper line unseen) keeps the passes from settling (section 15)
                cause = (break_refusal(result, error=False) if estimator == "variance"
                         else "")
                if cause:
                    raise FitRefusedError(f"{cause} ({result.convergence['stop']})")
                other = also_refused(result)
                raise FitRefusedError(
                    f"{result.convergence['stop']}; not written (converged: "
                    f"{result.convergence['criterion']}). Give "
                    + (f"more passes (--passes {MAX_PASSES}: the fit stops as soon as it "
                       "converges) or " if passes < MAX_PASSES else "") + "more days"
                    + (f" (its last pass is refused as well, so more passes alone will "
                       f"not write it: {other})" if other else ""))
            check_fit(result)
        # the last pass's waveform columns' errors, as its fit would have stated them (the
        # same statistics and table, so the same splines): read only by the figure of
        # merit, so neither by any pass nor by the refusals above (entry 33)
        result.waveform_error = waveform_column_errors(result.stats, fitted_from)
        if estimator == "variance":
            fit_merit.assess(result, error_goal, max_compressive_share=max_compressive_share)
            merit_inside_range(result, error_goal)
            if guard:
                fit_merit.check_merit(result, rejudge=judged_at)
        return result

    def tick(p: int, i: int) -> None:
        if progress is not None:
            progress(f"pass {p + 1}/{passes}: reducing days", p * len(chunks) + i, total)

    if scheduler == "serial":
        def serial(c: MessengerCalibration, hashing: bool, p: int) -> list[Any]:
            start, start_cpu = time.perf_counter(), time.process_time()
            out = []
            for i, chunk in enumerate(chunks):
                out.append(reduce_chunk(chunk, c, intervals, s, hashing, estimator))
                tick(p, i + 1)
            reduced, reduced_cpu = time.perf_counter(), time.process_time()
            merged = _merge_all(out)  # run's own _merge_all of one part returns it as is
            _log.debug("pass %d: %d chunks reduced here in %.3f s, merged in %.3f s",
                       p + 1, len(chunks), reduced - start, time.perf_counter() - reduced,
                       extra={"fit_timing": {
                           "pass": p + 1, "start": start, "reduced": reduced,
                           "gathered": time.perf_counter(), "start_cpu": start_cpu,
                           "reduced_cpu": reduced_cpu, "gathered_cpu": time.process_time()}})
            return [merged]

        try:
            return run(serial)
        finally:
            release_worker_kernel_pool()
    from fluxcal.runs.cluster import (  # batch extra
        Client,
        as_completed,
        close_local_cluster,
        make_local_cluster,
    )

    cluster = make_local_cluster(n_workers) if scheduler is None else None
    try:
        with Client(cluster if cluster is not None else scheduler) as client:

            def distributed(c: MessengerCalibration, hashing: bool, p: int) -> list[Any]:
                # the calibration travels once per pass (not once per day); the days'
                # statistics are merged on the workers in day order (`_merge_tree`), so
                # the client receives one merged object per pass
                start, start_cpu = time.perf_counter(), time.process_time()
                cal_future = client.scatter(c, hash=False)
                futures = client.map(reduce_chunk, list(chunks), cal=cal_future,
                                     intervals=intervals, settings=s, hash_inputs=hashing,
                                     estimator=estimator, pure=False)
                merged = _merge_tree(client, futures)
                for i, fut in enumerate(as_completed(futures)):
                    if fut.status == "error":
                        fut.result()  # the day's own error, at once
                    tick(p, i + 1)
                reduced, reduced_cpu = time.perf_counter(), time.process_time()
                out = merged.result()
                _log.debug("pass %d: %d chunks reduced on the workers in %.3f s, merged "
                           "statistics gathered in %.3f s", p + 1, len(chunks),
                           reduced - start, time.perf_counter() - reduced,
                           extra={"fit_timing": {
                               "pass": p + 1, "start": start, "reduced": reduced,
                               "gathered": time.perf_counter(), "start_cpu": start_cpu,
                               "reduced_cpu": reduced_cpu,
                               "gathered_cpu": time.process_time()}})
                return [out]

            def map_rows(f: Callable, args: list[tuple]) -> list[Any]:
                # the bootstrap's blocks of resamples on the workers, idle while the
                # client fits (issue 34, item 7; the same numbers, entry 40)
                return client.gather([client.submit(f, *a, pure=False) for a in args])

            resample_map = {"map_rows": map_rows,
                            "n_blocks": max(1, len(client.scheduler_info()["workers"]))}
            return run(distributed)
    finally:
        if cluster is not None:
            close_local_cluster(cluster)


_log = logging.getLogger(__name__)
#: Statistics merged per task of the Dask tree reduction (`_merge_tree`).
MERGE_FAN_IN = 4


def _merge_parts(*parts: Any) -> Any:
    """Merge `reduce_chunk` outputs left to right (one node of `_merge_tree`)."""
    if isinstance(parts[0], tuple):
        return (reduce(DayStatistics.merge, [d for d, _ in parts]),
                VarianceStatistics.merge_all([v for _, v in parts]))
    return reduce(DayStatistics.merge, parts)


def _merge_all(parts: list[Any]) -> Any:
    """Merge `reduce_chunk` outputs here, in the groups and levels of `_merge_tree`."""
    level = list(parts)
    while len(level) > 1:
        level = [_merge_parts(*level[i:i + MERGE_FAN_IN])
                 for i in range(0, len(level), MERGE_FAN_IN)]
    return level[0]


def _merge_tree(client: Any, futures: list[Any]) -> Any:
    """Merge the days' statistics on the workers: consecutive groups, level by level.

    Day order is kept (the merged ``days`` and ``inputs`` list the days in order); the
    groups are those of `_merge_all`, so the sums are the serial run's, bit for bit.
    Merges run before pending reductions (priority), as soon as their days are in.
    """
    level = list(futures)
    while len(level) > 1:
        level = [client.submit(_merge_parts, *level[i:i + MERGE_FAN_IN], pure=False,
                               priority=1) if len(level[i:i + MERGE_FAN_IN]) > 1
                 else level[i] for i in range(0, len(level), MERGE_FAN_IN)]
    return level[0]
