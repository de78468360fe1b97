"""In-flight MESSENGER MAG calibration: flight data in, calibration tables out.

The offsets of sec. 7 (Table 2 temperature law, Table 3 duty-cycle law, the relaxation
time tau and the heater delay dt) and the heater waveforms of sec. 6 (Tables 6-8) are
estimated from long-term averages of solar-wind data, whose mean field is zero:

* `fluxcal.missions.messenger.fit_reduce.reduce_day` reduces each day to mergeable
  `DayStatistics` given the current estimate of every term;
* `fit_calibration` turns merged statistics into new estimates (`FitResult`); with
  ``estimator="variance"`` `fit_variance_calibration` (the statistics reduced and solved
  by `fluxcal.missions.messenger.fit_variance`, the breaks chosen and the bootstrap's
  resamples solved by `fluxcal.missions.messenger.fit_breaks`);
* `fit_days` iterates: reduce all days (serially or on a Dask cluster), merge, fit, and
  reduce again with the new estimates, ``passes`` times (each step then removes the
  others' current estimates, sec. 7: "iterative");
* `fluxcal.missions.messenger.fit_holds` holds with a stated width what the data do not
  decide (a D0 the user holds, an upper law segment no accepted interval determines);
* `fluxcal.missions.messenger.fit_guards.check_fit` refuses a table whose parameters lie
  outside their physical range or that the data do not determine to their goal (tau's
  range after every pass, everything after the last);
* `fluxcal.missions.messenger.fit_write.write_calibration_folder` writes a versioned
  folder that `load_calibration(day, folder)` and ``edr2cdr --calib`` read.

Order inside one pass (docs/decisions/messenger_fit.md, entry 1): the statistics of all
four analyses are reduced with the previous pass's estimates; then (1) the temperature
law is fitted, (2) the duty-cycle law with its intercept held at the *new* temperature
law at -50 C, (3) tau (and dt) from the epoch with the own step added back using the
previous D0, combined over the axes with the *new* D0, (4) the waveforms, with zero mean
over the heater cycle (the shipped Tables 6-8 have means below 0.01 count; the mean of
each duty-cycle bin belongs to the duty-cycle law).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 7 eq. 2-7, Tables 2-3,
   Appendix Tables 6-8.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import reduce
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats as sps

from fluxcal.calibration.constrained_fits import (
    LineFit,
    PeriodicSplineFit,
    RelaxationFit,
    TwoSegmentFit,
    fit_line_fixed_intercept,
    fit_periodic_spline,
    fit_periodic_splines,
    fit_relaxation,
    fit_two_segment,
)
from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import FitRefusedError, FluxcalError, InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import fit_breaks as fb
from fluxcal.missions.messenger import fit_merit
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.batch_task import default_kernels
from fluxcal.missions.messenger.calibration_data import (
    MessengerCalibration,
    required_look_back_s,
)
from fluxcal.missions.messenger.fit_guards import break_refusal, check_fit
from fluxcal.missions.messenger.fit_holds import (
    HoldD0,
    held_d0_values,
    held_upper_segments,
    undetermined_upper,
)
from fluxcal.missions.messenger.fit_reduce import (
    MIN_BIN_SAMPLES,
    TAU_STEP,
    DayStatistics,
    FitSettings,
    intervals_to_et,
    reduce_day,
    relaxation_response,
    usable_bins,
)
from fluxcal.missions.messenger.fit_variance import VarianceStatistics, reduce_variance
from fluxcal.missions.messenger.fit_waveform_error import (
    effective_folds,
    jackknife_error,
    jackknife_scale,
    leave_one_out,
)
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.routes import EDR_MAPPING, day_file_groups
from fluxcal.products.provenance import sha256_file
from fluxcal.runs.batch import release_worker_kernel_pool, worker_kernel_pool

__all__ = ["ESTIMATORS", "TEMPERATURE_LAWS", "FitResult", "check_fit", "fit_calibration",
           "fit_days", "fit_variance_calibration", "law_sigma", "reduce_day"]

AXES = ("x", "y", "z")
#: Fewest filled temperature bins (the two-segment fit has 4 free parameters + 1 dof).
MIN_TEMPERATURE_BINS = 5
#: Alternations of steps 1 and 2 on the merged statistics (`_fit_offsets`).
INNER_ITERATIONS = 50
#: Iterations of tau inside one pass, on the statistics linearised in tau (`fit_calibration`).
TAU_ITERATIONS = 30
#: Largest tau change per pass (fraction) for which that linearisation is used.
MAX_TAU_SHIFT = 0.3
#: Fewest duty-cycle changes for tau.
MIN_EVENTS = 3
#: Fewest filled phase bins (of 100) for a heater-waveform column to be fitted.
MIN_PHASE_BINS = 50
#: The fitted delay dt is adopted only when its standard error is below this (s).
MAX_DELAY_ERROR_S = 3.0
#: Estimators of the temperature law (docs/decisions/messenger_fit.md, entry 8):
#: ``distribution`` models each 10-C bin as the average of the law over its samples'
#: temperatures (default); ``binned-mean`` is the seed's, the law at the bin's mean
#: temperature (biased by up to 1.25 (B1 - B0) in the bin holding the break).
TEMPERATURE_LAWS = ("distribution", "binned-mean")
#: Estimators of the temperature law, D0, tau and dt (docs/decisions/messenger_fit.md,
#: entry 11): ``zero-mean`` (the seed's long-term averages: the field averages to zero
#: over each bin's samples) and ``variance`` (`fit_variance`: ``|B|`` nearly constant within
#: 15-min intervals while the field rotates; no condition on its mean).
ESTIMATORS = ("zero-mean", "variance")


@dataclass
class FitResult:
    """Outcome of `fit_calibration`: the new calibration and the fits behind it.

    Attributes
    ----------
    calibration : MessengerCalibration
        The base calibration with the fitted terms replaced.
    temperature : list of TwoSegmentFit
        Per axis x, y, z (Table 2 form, total offset in fine counts).
    duty : list of LineFit
        Per axis (Table 3 form; ``intercept`` = C0 = cT(-50 C)).
    relaxation : RelaxationFit
        Fit of the axis-combined normalised epoch (tau, dt).
    delay_fitted : bool
        Whether the fitted dt was adopted (else the base value was held).
    waveform : list of list of PeriodicSplineFit or None
        ``[axis][duty bin]``; None where the bin had too little data (base column kept).
    stats : DayStatistics
        The merged statistics the fits used.
    epoch_curve : ndarray, shape (n_lag, 4)
        Lag bin centre, axis-combined normalised epoch, its standard error, samples.
    passes : list of dict
        Summary of every pass (`fit_days`).
    temperature_law : str
        Estimator of the temperature law (`TEMPERATURE_LAWS`).
    estimator : str
        `ESTIMATORS`: which estimator gave the temperature law, D0, tau and dt.
    variance : VarianceStatistics or None
        The variance estimator's statistics (intervals accepted and rejected, with
        their reasons), when it was used.
    fitted_range : tuple of float
        Temperature range (C) over which the data constrain the law (the variance
        estimator: `VarianceStatistics.fitted_range`); ``(nan, nan)``: the filled
        heater-off bins (`check_fit`).  After `fit_merit.assess`: the span of
        ``temperature_ranges``.
    temperature_ranges : StatedRanges or None
        The temperatures over which the table states its law (``T_RANGE``, one or more
        intervals; `fit_merit.stated_range`, entry 24); None: not assessed, or
        determined nowhere.
    held_d0 : tuple of str
        Axes whose D0 was held at the user's request (``--hold-d0``).
    held : dict
        ``axis -> (value, width)`` of the held D0 (`held_d0_values`).
    held_upper : dict
        ``axis -> {"Tm_c": (value, width), "slope_change": (value, width)}`` of the
        upper segments no accepted interval determines (`held_upper_segments`): held
        at the start table's values, each resample drawing them from their widths.
    bootstrap : dict or None
        The variance estimator's resamples of the tables' parameters (widened):
        ``law`` (n, 3, 4) as ``(a, b, c, T_m)``, ``d0`` (n, 3), ``tau`` (n,), ``dt``
        (n,); every stated error and the law's band come from them; ``break_shift``
        (n, 3): each resample's own break shift (C, `fit_breaks.BREAK_SHIFTS_C`, 0: the
        linearised step), kept so that spread estimators can be compared offline
        (``benchmarks/messenger_fit_pulls.py --summarise DIR --estimators``, entry 39).
    break_shift : ndarray, shape (3,)
        The break shifts (C) the last pass took (0: the linearised step).
    convergence : dict
        `fit_days`: passes run, whether they converged, why the fit stopped and every
        pass's changes (`pass_changes`).
    merit : dict
        `fit_merit.predicted_error` of the written tables and the goal it was held to.
    waveform_error : ndarray, shape (3, n_duty_bins) or None
        Stated rms error (counts) of each waveform column (`_fit_waveforms`).
    d0_field : dict
        The variance estimator: the field's mean direction weighted as D0's information
        (``direction``, ``balance`` 0..1), D0's bootstrap error along it and the error
        added there (``along_nt_per_ppt``, ``added_nt_per_ppt``;
        `fit_variance.widen_d0_along_field`, docs/decisions/messenger_fit.md entry 28).
    """

    calibration: MessengerCalibration
    temperature: list[TwoSegmentFit]
    duty: list[LineFit]
    relaxation: RelaxationFit
    delay_fitted: bool
    waveform: list[list[PeriodicSplineFit | None]]
    stats: DayStatistics
    epoch_curve: np.ndarray
    passes: list[dict[str, Any]] = field(default_factory=list)
    temperature_law: str = "distribution"
    estimator: str = "zero-mean"
    variance: Any = None
    fitted_range: tuple[float, float] = (float("nan"), float("nan"))
    temperature_ranges: StatedRanges | None = None
    held_d0: tuple[str, ...] = ()
    held: dict[str, tuple[float, float]] = field(default_factory=dict)
    held_upper: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    bootstrap: dict[str, np.ndarray] | None = None
    break_shift: np.ndarray = field(default_factory=lambda: np.zeros(3))
    convergence: dict[str, Any] = field(default_factory=dict)
    merit: dict[str, Any] = field(default_factory=dict)
    waveform_error: np.ndarray | None = None
    d0_field: dict[str, Any] = field(default_factory=dict)

    @property
    def stated_ranges(self) -> StatedRanges | None:
        """``T_RANGE``: `temperature_ranges`, else the one interval ``fitted_range``.

        None where neither is (the range is not finite).
        """
        if self.temperature_ranges is not None:
            return self.temperature_ranges
        lo, hi = self.fitted_range
        ok = np.isfinite(lo) and np.isfinite(hi) and lo < hi
        return StatedRanges(((lo, hi),)) if ok else None

    def law_error(self, t: np.ndarray) -> np.ndarray:
        """Stated standard error (counts) of the law at temperatures ``t``, per axis.

        The variance estimator: the spread of the resampled laws at each temperature
        (the full covariance of the law's parameters, break included); else `law_sigma`.
        Shape ``(len(t), 3)``.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.bootstrap is None:
            return law_sigma(self.temperature, t)
        return np.std(fv.law_values(self.bootstrap["law"], t), axis=0)

    @property
    def duty_range(self) -> tuple[float, float] | None:
        """``D_RANGE`` (percent, ``lo <= d < hi``): the duty cycles the waveforms are fitted on.

        `supported_duty_range` of the merged statistics' own bin counts and the fitted
        columns; None when no column was fitted (entry 25).
        """
        fitted = np.array([[fit is not None for fit in axis] for axis in self.waveform],
                          dtype=bool)
        count = np.stack([w.count for w in self.stats.waveform])
        return supported_duty_range(count, fitted,
                                    self.calibration.heater_duty_bins_percent)

    def summary(self) -> dict[str, Any]:
        """Return the headline numbers (for the pass history and the report)."""
        cal = self.calibration
        return {
            "temperature_coefficients": np.round(cal.temperature_coefficients, 5).tolist(),
            "D0": [round(float(v), 6) for v in cal.duty_cycle_d0],
            "tau_s": round(float(cal.constants["relaxation"]["tau_s"]), 2),
            "delay_s": round(float(cal.constants["relaxation"]["delay_s"]), 2),
        }


def _temperature_distribution(stats: DayStatistics, ok: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
    """Sub-bin mean temperatures and samples per (used 10-C bin, sub-bin).

    ``temperature_fine`` nests in the 10-C bins; each sub-bin belongs to the bin holding
    its centre.  Raises if the two do not hold the same samples (a reduction without the
    distribution, e.g. statistics saved before it existed).
    """
    fine = stats.temperature_fine
    owner = np.searchsorted(stats.temperature.edges, fine.centers, side="right") - 1
    per_bin = np.bincount(owner[(owner >= 0) & (owner < stats.temperature.n_bins)],
                          weights=fine.count[(owner >= 0) & (owner < stats.temperature.n_bins)],
                          minlength=stats.temperature.n_bins)
    if not np.array_equal(per_bin.astype(np.int64), stats.temperature.count):
        raise FluxcalError(
            "temperature law (distribution estimator): the temperature sub-bins hold "
            f"{int(fine.count.sum())} samples, the 10-C bins {int(stats.temperature.count.sum())}"
            "; reduce the days again, or choose the binned-mean estimator")
    bins = np.flatnonzero(ok)
    weights = np.where(owner[None, :] == bins[:, None], fine.count[None, :], 0).astype(float)
    return fine.mean()[:, 0], weights


def _bin_list(centres: np.ndarray) -> str:
    return ", ".join(f"{c:.0f}" for c in centres) or "none"


def _too_few_temperature_bins(stats: DayStatistics, ok: np.ndarray,
                              tau: float | None) -> str:
    """Return the true reason the temperature law has too few bins (decision entry 3).

    Tells a lack of heater-off data apart from heater-off data that all lie within the
    decay of the preceding heater period's offset (relaxed duty cycle above the cut of
    `FitSettings.max_relaxed_off_ppt`, which a wrong tau stretches).
    """
    t = stats.temperature
    centres = t.centers
    need = (f"the temperature law (sec. 7) needs heater-off samples in at least "
            f"{MIN_TEMPERATURE_BINS} of the 10-C bins (at least {MIN_BIN_SAMPLES} samples "
            "each) after the offset of the preceding heater period has decayed (relaxed "
            f"duty cycle below {FitSettings().max_relaxed_off_ppt:.0f} ppt)")
    off = stats.heater_off
    any_off = off is not None and off.count.sum() > 0
    off_ok = (off.count >= MIN_BIN_SAMPLES) if any_off else np.zeros(t.n_bins, dtype=bool)
    if off_ok.sum() >= MIN_TEMPERATURE_BINS:
        decay = ("" if tau is None else
                 f" at tau = {tau:.0f} s (a 400-ppt offset takes {tau * np.log(8.0):.0f} s "
                 "to decay below 50 ppt)")
        return (f"{need}: heater-off samples fill {int(off_ok.sum())} bins (C: "
                f"{_bin_list(centres[off_ok])}; {int(off.count.sum())} samples), but only "
                f"{int(ok.sum())} of them (C: {_bin_list(centres[ok])}) hold samples whose "
                f"offset has decayed{decay}; the heater-off stretches are too short for "
                "that decay, or tau is wrong: check the relaxation time of the previous "
                "pass, or give longer heater-off stretches")
    return (f"{need}: heater-off samples fill only {int(off_ok.sum() if any_off else ok.sum())}"
            f" bins; filled bins (C): {_bin_list(centres[off_ok if any_off else ok])}; empty "
            f"bins (C): {_bin_list(centres[~(off_ok if any_off else ok)])}. Give more days or "
            "intervals with the heater off, over a wider temperature range")


def _fit_temperature(stats: DayStatistics, d0: np.ndarray, shift: float,
                     law: str = "distribution", tau: float | None = None
                     ) -> list[TwoSegmentFit]:
    t = stats.temperature
    ok = usable_bins(t)
    if ok.sum() < MIN_TEMPERATURE_BINS:
        raise FluxcalError(_too_few_temperature_bins(stats, ok, tau))
    mean = t.mean()[ok]
    w = np.sqrt(t.count[ok].astype(float))
    # the duty-cycle offset still decaying after the heater stopped: D0 times the mean
    # relaxed duty cycle of the bin (at tau + shift, to first order)
    relaxed = mean[:, 4:5] + shift * mean[:, 5:6]
    y = mean[:, :3] - relaxed * np.asarray(d0, dtype=float)[None, :]
    # the seed's estimator models a bin at its mean temperature; the default models it
    # as the bin average of the law over the samples' temperatures (entry 8)
    dist = _temperature_distribution(stats, ok) if law == "distribution" else None
    return [fit_two_segment(mean[:, 3], y[:, j], w, x_distribution=dist) for j in range(3)]


def _fit_duty(stats: DayStatistics, c_ref: np.ndarray, shift: float) -> list[LineFit]:
    d = stats.duty
    ok = usable_bins(d)
    if not ok.any():
        raise FluxcalError(
            "duty-cycle law (sec. 7): no sample inside heater periods with a duty cycle of "
            "10 % or more; give days or intervals with the heater regulating"
        )
    if ok.sum() < 2:
        raise FluxcalError(
            f"duty-cycle law (sec. 7): samples in only one 4-% bin (centre "
            f"{d.centers[ok][0] / 10:.0f} %); need two for an error estimate"
        )
    mean = d.mean()[ok]
    w = np.sqrt(d.count[ok].astype(float))
    relaxed = mean[:, 3] + shift * mean[:, 4]
    return [fit_line_fixed_intercept(relaxed, mean[:, j], w, 0.0, float(c_ref[j]))
            for j in range(3)]


def _fit_offsets(
    stats: DayStatistics, base: MessengerCalibration, shift: float = 0.0,
    law: str = "distribution",
) -> tuple[list[TwoSegmentFit], list[LineFit], np.ndarray]:
    """Fit steps 1 and 2 alternately on the merged statistics until D0 settles.

    The temperature law needs D0 (the decaying duty-cycle offset of heater-off samples)
    and the duty-cycle law needs the temperature law at -50 C (its intercept); both are
    linear in the stored bin means, so they are alternated here without a data pass.
    """
    t_ref = base.reference_temperature_c
    d0 = np.asarray(base.duty_cycle_d0, dtype=float)
    tau = float(base.constants["relaxation"]["tau_s"])  # the reduction's decay cut used it
    for _ in range(INNER_ITERATIONS):
        temperature = _fit_temperature(stats, d0, shift, law, tau)
        total = np.array([[f.a0, f.b0, f.a1, f.b1] for f in temperature])
        c_ref = two_segment_offset(np.array([t_ref]), total)[0]
        duty = _fit_duty(stats, c_ref, shift)
        new = np.array([f.slope for f in duty])
        settled = np.all(np.abs(new - d0) <= 1e-7 + 1e-6 * np.abs(new))
        d0 = new
        if settled:
            break
    return temperature, duty, np.asarray(c_ref, dtype=float)


def _fit_relaxation(
    stats: DayStatistics, base: MessengerCalibration, d0_new: np.ndarray, fit_delay: bool,
    shift: float = 0.0,
) -> tuple[RelaxationFit, bool, np.ndarray]:
    n_events = int(stats.n_samples.get("events", 0))
    if n_events < MIN_EVENTS:
        raise FluxcalError(
            f"relaxation time (sec. 7): {n_events} duty-cycle change(s) of at least the "
            f"minimum step in the data, need {MIN_EVENTS}; give more days with the heater "
            "regulating"
        )
    ep = stats.epoch
    rel = base.constants["relaxation"]
    lag = ep.centers
    tau_p, dt_p = float(rel["tau_s"]), float(rel["delay_s"])
    own = relaxation_response(lag, tau_p, dt_p)
    # the own step in the stored columns, linearised in tau the same way (the finite
    # difference of `fit_reduce.reduce_day`), so that it cancels exactly and only the
    # other changes are removed with the shifted tau
    own = own + shift * (relaxation_response(lag, tau_p * (1.0 + TAU_STEP), dt_p) - own) / (
        tau_p * TAU_STEP)
    d0 = np.asarray(d0_new, dtype=float)
    d0_old = np.asarray(base.duty_cycle_d0, dtype=float)
    den = stats.epoch_weight.mean()[:, 0]  # mean squared step per lag bin
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = ep.mean() / den[:, None]
    # residual with the new D0 and tau + shift (relaxed duty cycle and its tau derivative
    # are columns 3, 4; first order in the shift), the change's own step added back
    y = (mean[:, :3] - mean[:, 3:4] * (d0 - d0_old)[None, :]
         - shift * mean[:, 4:5] * d0[None, :] + own[:, None] * d0[None, :])
    with np.errstate(invalid="ignore", divide="ignore"):
        se = ep.standard_error()[:, :3] / den[:, None]
    norm = float(d0 @ d0)
    combined = (y @ d0) / norm
    combined_se = np.sqrt((se**2) @ (d0**2)) / norm
    curve = np.column_stack([lag, combined, combined_se, ep.count])
    ok = (ep.count >= MIN_BIN_SAMPLES) & np.isfinite(combined) & (combined_se > 0)
    w = 1.0 / combined_se[ok]
    fit = fit_relaxation(lag[ok], combined[ok], w, fit_delay=fit_delay,
                         delay=float(rel["delay_s"]))
    adopted = fit_delay and np.isfinite(fit.dt_err) and fit.dt_err < MAX_DELAY_ERROR_S and (
        fit.dt >= 0.0)
    if fit_delay and not adopted:
        fit = fit_relaxation(lag[ok], combined[ok], w, fit_delay=False,
                             delay=float(rel["delay_s"]))
    return fit, bool(adopted), curve


def unmix_waveforms(stats: DayStatistics, waveform: Sequence | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per phase bin, the waveform columns whose interpolation gives the bin averages.

    A duty-cycle bin holds periods of several duty cycles; each period's waveform is the
    pipeline's linear interpolation between the columns (sec. 6), so the average of bin
    ``b`` at phase ``p`` is ``sum_j A[b, j] W_j(p)`` with ``A`` the mean interpolation
    weights (`fluxcal.missions.messenger.fit_reduce.interpolation_weights`).  Solved for
    ``W`` by weighted least squares (``sqrt(N)`` per bin) at each phase bin; a column no
    period leans on stays NaN.

    Returns
    -------
    phase : ndarray, shape (n_phase,)
        Mean phase of each phase bin (s).
    columns : ndarray, shape (n_phase, n_columns, 3)
        Unmixed waveform (counts), NaN where undetermined.
    support : ndarray, shape (n_phase, n_columns)
        Samples leaning on each column (sum of weights).
    """
    waveform = stats.waveform if waveform is None else waveform
    count, mean, usable, support = _unmixing_design(waveform)
    with np.errstate(invalid="ignore"):
        phase = np.nansum(np.where(usable, mean[:, :, 3] * count, 0.0), axis=0) / np.sum(
            np.where(usable, count, 0), axis=0)
    columns = np.full((count.shape[1], len(waveform), 3), np.nan)
    for p in range(count.shape[1]):  # phase bins (100), each a small least-squares problem
        got = _phase_system(count, mean, usable, support, p)
        if got is None:
            continue
        cols, a, y = got
        sol, *_ = np.linalg.lstsq(a, y, rcond=None)
        columns[p, cols] = sol
    return phase, columns, support


def _unmixing_design(waveform: Sequence) -> tuple[np.ndarray, ...]:
    """Return the counts, means, usable bins and samples leaning on each column.

    Shapes ``(nb, n_phase)``, ``(nb, n_phase, 4 + nb)``, ``(nb, n_phase)`` and
    ``(n_phase, nb)``: the design of `unmix_waveforms` and `unmixing_variance`.
    """
    count = np.stack([w.count for w in waveform])
    mean = np.stack([w.mean() for w in waveform])
    usable = count >= MIN_BIN_SAMPLES
    support = np.einsum("bp,bpj->pj", np.where(usable, count, 0).astype(float),
                        np.where(usable[:, :, None], np.abs(mean[:, :, 4:]), 0.0))
    return count, mean, usable, support


def _phase_system(count, mean, usable, support, p: int):
    """Return, at phase bin ``p``, the columns solved, the weighted design and the data.

    Each bin weighted by ``sqrt(N)``; None when nothing is solved there.
    """
    rows = usable[:, p]
    cols = support[p] >= MIN_BIN_SAMPLES
    if not rows.any() or not cols.any():
        return None
    w = np.sqrt(count[rows, p].astype(float))[:, None]
    return cols, mean[rows, p, 4:][:, cols] * w, mean[rows, p, :3] * w


def unmixing_variance(waveform: Sequence) -> np.ndarray:
    """Return the variance of `unmix_waveforms`' solution per unit sample variance.

    Per phase bin and column: ``diag(A+ A+')`` of the weighted design (``A+`` its
    pseudo-inverse, the solution `numpy.linalg.lstsq` gives), shape
    ``(n_phase, n_columns)``, NaN where the column is not solved.  It depends on the
    counts and interpolation weights alone: how much a set of samples determines each
    column (`fit_waveform_error.jackknife_scale`).
    """
    count, mean, usable, support = _unmixing_design(waveform)
    out = np.full(support.shape, np.nan)
    for p in range(count.shape[1]):
        got = _phase_system(count, mean, usable, support, p)
        if got is not None:
            cols, a, _ = got
            out[p, cols] = (np.linalg.pinv(a) ** 2).sum(axis=1)
    return out


def few_folds_widening(own: np.ndarray, folds: int) -> float:
    """Factor (>= 1) on a waveform column's jackknife error when its own samples lie in few folds.

    ``own`` holds the column's own samples (its duty-cycle bin's) in each fold.  The
    refits' spread pools 100 phases, so for a column whose own samples fill every fold
    it covers the truth as it is (entries 29 and 34).  With its own samples in
    ``K_eff = N^2 / sum n_k^2`` effective folds (Kish), the spread compares
    ``K_eff - 1`` of them: widened by the Student-t ratio
    ``t_nu(0.841) / t_{K-1}(0.841)``, ``nu = max(K_eff - 1, 1)``, the t quantile of one
    normal standard deviation (two equal folds: 1.54 for four folds).
    """
    k_eff = effective_folds(own)
    if k_eff <= 0 or folds < 2:
        return 1.0
    q = sps.norm.cdf(1.0)
    nu = max(k_eff - 1.0, 1.0)
    return float(max(sps.t.ppf(q, nu) / sps.t.ppf(q, folds - 1), 1.0))


def _fit_waveforms(
    stats: DayStatistics, base: MessengerCalibration, *, errors: bool = True
) -> tuple[np.ndarray, list[list[PeriodicSplineFit | None]], np.ndarray | None]:
    """Fit the waveform columns (sec. 6), and state their error by refitting without each fold.

    Returns the table, the splines (None where kept from ``base``) and, per axis and
    duty bin, the rms (counts, over the phase) of the delete-a-fold jackknife error of
    the fitted column (the same fit on the statistics without each fold of 30-min
    blocks, `DayStatistics.waveform_folds`, `fit_waveform_error.leave_one_out`,
    `fit_waveform_error.jackknife_error`), widened when the column's own samples lie in
    few folds (`few_folds_widening`; scaled by the information each fold gives the
    column where those are fewer than three, `fit_waveform_error.jackknife_scale`,
    entry 37), and the spline's smoothing bias added in
    quadrature (the smoothing applied once more to the fitted curve, ``(S - I) f_hat``:
    common to the refits, so not in their spread); a column kept from ``base`` is given
    its own rms (its error unknown, entries 19 and 29), and a fitted column that some
    fold's removal leaves unfitted (it rests on one fold), or with fewer than two folds
    holding samples, the larger of its rms and the shipped column's (entry 34).

    With ``errors=False`` the refits are not done and the error is None: no pass
    reads it, so `fit_days` states it once, from the last pass's statistics and
    table (entry 33).
    """
    table = np.array(base.heater_signal, dtype=float)
    nb = len(stats.waveform)
    fits: list[list[PeriodicSplineFit | None]] = [[None] * nb for _ in AXES]
    error = np.sqrt(np.mean(table[:, :100, :] ** 2, axis=1))  # (axis, bin): base's own rms
    phase, columns, support = unmix_waveforms(stats)
    loo = [h for h in leave_one_out(stats.waveform_folds) if h is not None] if errors else []
    without = [unmix_waveforms(stats, h) for h in loo]
    if errors:  # how much each fold determines each column (jackknife_scale)
        info = unmixing_variance(stats.waveform)
        info_without = np.stack([unmixing_variance(h) for h in loo]) if loo else None
    own = np.array([[w.count.sum() for w in h] for h in stats.waveform_folds], dtype=float)

    def splines(ph, col, sup, b):
        # the three axes of a column share its phases and weights: one decomposition
        # (`fit_periodic_splines`, the same fits as one at a time; entry 40)
        ok = np.isfinite(ph) & np.all(np.isfinite(col[:, b]), axis=1)
        if ok.sum() < MIN_PHASE_BINS:
            return [None] * 3
        out = []
        for fit in fit_periodic_splines(ph[ok], [col[ok, b, j] for j in range(3)],
                                        np.sqrt(sup[ok, b]), 100.0):
            values = fit.table(1.0)[1]
            out.append((fit, values - values[:-1].mean()))
        return out

    def smoothing_bias(fit, ph, col, sup, b):
        # the spline's own smoothing applied to the fitted curve: (S - I) f_hat, the
        # plug-in estimate of (S - I) f, a bias the folds share (entry 29)
        ok = np.isfinite(ph) & np.all(np.isfinite(col[:, b]), axis=1)
        f_hat = fit(ph[ok])
        again = fit_periodic_spline(ph[ok], f_hat, np.sqrt(sup[ok, b]), 100.0,
                                    smoothing=fit.lam, n_knots=fit.n_knots)
        return float(np.sqrt(np.mean((again(ph[ok]) - f_hat) ** 2)))

    for b in range(nb):
        got_b = splines(phase, columns, support, b)
        refits_b = ([splines(*h, b) for h in without]
                    if errors and got_b[0] is not None else [])
        for j in range(3):
            got = got_b[j]
            if got is None:
                continue
            fits[j][b], table[j, :, b] = got
            if not errors:
                continue
            refits = [r[j] for r in refits_b]
            err = float("nan")
            if len(refits) >= 2 and all(r is not None for r in refits):
                scale = jackknife_scale(own[:, b], info[:, b], info_without[:, :, b])
                err = jackknife_error(np.stack([r[1][:-1] for r in refits]), scale)
                err *= few_folds_widening(own[:, b], len(stats.waveform_folds))
                err = np.hypot(err, smoothing_bias(fits[j][b], phase, columns, support, b))
            # unknown (the column rests on one fold): as large as the column itself,
            # fitted or shipped, not the shipped one's rms alone (entry 34)
            error[j, b] = err if np.isfinite(err) else max(
                error[j, b], float(np.sqrt(np.mean(table[j, :100, b] ** 2))))
    return table, fits, (error if errors else None)


def waveform_column_errors(stats: DayStatistics, base: MessengerCalibration) -> np.ndarray:
    """Stated error (counts) of each waveform column, shape (3, n_duty_bins).

    What `_fit_waveforms` states for the fit of ``stats`` from ``base``: `fit_days` calls
    it once after its passes, for the last one, whose fit skipped it (entry 33).
    """
    return _fit_waveforms(stats, base)[2]


def supported_duty_range(count: np.ndarray, fitted: np.ndarray, centres: np.ndarray
                         ) -> tuple[float, float] | None:
    """Return the duty-cycle range (percent) over which the heater waveforms are determined.

    A duty-cycle bin (4 % wide around each column's centre, sec. 6) is *supported* when
    its own heater-on samples fill at least `MIN_PHASE_BINS` of its phase bins with
    `MIN_BIN_SAMPLES` each (the rule `_fit_waveforms` fits a column by, applied to the
    bin's own samples, not to those of its neighbours that lean on the column through
    the interpolation) and its column was fitted on every axis.  The range is the
    contiguous run of supported bins around the one holding the most samples, from the
    lower edge of its first bin to the upper edge of its last (``lo <= d < hi``: the fit
    bins a period of duty ``d`` by ``floor((d - lo) / 4)``).  Between two supported
    columns the pipeline interpolates two fitted columns; within half a bin beyond the
    last centre it extends the last two (sec. 6), as it did for the bin's own samples
    in the fit; further out it extrapolates what no sample determined (issue 34,
    docs/decisions/messenger_fit.md entry 25).

    Parameters
    ----------
    count : ndarray, shape (n_bins, n_phase)
        Samples per phase bin of each duty-cycle bin (`DayStatistics.waveform` counts).
    fitted : ndarray of bool, shape (n_axes, n_bins)
        Whether each axis's column was fitted (not kept from the base table).
    centres : ndarray, shape (n_bins,)
        Evenly spaced bin centres (percent; 12..40 in Tables 6-8).

    Returns
    -------
    tuple of float or None
        ``(lo, hi)`` in percent; None when no bin is supported.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (4 % bins, centres 12-40 %,
       linear between bins, the 36-40 % slope extended above 40 %).
    """
    count = np.asarray(count)
    centres = np.asarray(centres, dtype=float)
    filled = (count >= MIN_BIN_SAMPLES).sum(axis=1) >= MIN_PHASE_BINS
    ok = filled & np.all(np.asarray(fitted, dtype=bool), axis=0)
    if not ok.any():
        return None
    total = np.where(ok, count.sum(axis=1), -1)
    a = b = int(np.argmax(total))
    while a > 0 and ok[a - 1]:
        a -= 1
    while b < ok.size - 1 and ok[b + 1]:
        b += 1
    half = 0.5 * float(centres[1] - centres[0])
    return float(centres[a] - half), float(centres[b] + half)


def look_back_for(tau: float) -> float:
    """Look-back interval (s) of sec. 7 for a relaxation time ``tau`` (entry 10).

    Sec. 7 looks back 5000 s for tau = 872 s: an offset assumed zero before the look-back
    errs by at most ``200 exp(-5000 / tau) = 0.6`` DN, below one count.  The fit keeps
    that ratio for a longer tau (`calibration_data.required_look_back_s`, rounded up to
    0.1 s), so the truncation stays below the 0.65-count bound, and never looks back less
    than 5000 s (a shorter tau then truncates less).  The shipped tau gives back exactly
    the shipped 5000 s.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (the 5000-s look-back).
    """
    return float(np.ceil(round(required_look_back_s(float(tau)) * 10.0, 6)) / 10.0)


def fit_calibration(
    stats: DayStatistics,
    base: MessengerCalibration,
    *,
    fit_delay: bool = True,
    temperature_law: str = "distribution",
    waveform_errors: bool = True,
) -> FitResult:
    """Fit the four calibration terms of sec. 6-7 to merged statistics (one pass).

    Parameters
    ----------
    stats : DayStatistics
        Reduced with ``base`` as the current estimate (`reduce_day`).
    base : MessengerCalibration
        The calibration the statistics were reduced with; its unfitted terms (Table 1,
        Table 4, dates) are kept.
    fit_delay : bool
        Also fit the heater delay dt (adopted when its error is below 3 s).
    temperature_law : {"distribution", "binned-mean"}
        ``distribution`` (default) fits the Table 2 law so that its average over each
        10-C bin's heater-off temperatures matches the bin mean; ``binned-mean`` is the
        seed's estimator, the law at the bins' mean temperatures
        (docs/decisions/messenger_fit.md, entry 8).
    waveform_errors : bool
        State the waveform columns' errors (`_fit_waveforms`); False leaves
        ``waveform_error`` None (`fit_days`'s passes: entry 33).

    Returns
    -------
    FitResult

    Raises
    ------
    FluxcalError
        Naming the analysis and what is missing: too few heater-off temperature bins
        (listing the empty ones), no heater periods, too few duty-cycle changes; an
        unknown ``temperature_law``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 7 eq. 2-5, Tables 2-3,
       Appendix Tables 6-8.
    """
    if temperature_law not in TEMPERATURE_LAWS:
        raise FluxcalError(f"temperature_law must be one of {', '.join(TEMPERATURE_LAWS)}, "
                           f"got {temperature_law!r}")
    tau_base = float(base.constants["relaxation"]["tau_s"])
    tau = tau_base
    for _ in range(TAU_ITERATIONS):  # tau inside the pass, to first order (entry 1)
        shift = float(np.clip(tau - tau_base, -MAX_TAU_SHIFT * tau_base,
                              MAX_TAU_SHIFT * tau_base))
        temperature, duty, c_ref = _fit_offsets(stats, base, shift, temperature_law)
        d0 = np.array([f.slope for f in duty])
        relaxation, delay_fitted, curve = _fit_relaxation(stats, base, d0, fit_delay, shift)
        done = abs(relaxation.tau - tau) <= 1e-4 * tau
        tau = relaxation.tau
        if done or abs(tau - tau_base) > MAX_TAU_SHIFT * tau_base:
            break
    total = np.array([[f.a0, f.b0, f.a1, f.b1] for f in temperature])
    heater, waveform, waveform_error = _fit_waveforms(stats, base, errors=waveform_errors)
    table2 = total.copy()
    if base.prelaunch_offsets_reading == "added_to_table2":
        table2[:, 0] -= base.prelaunch_offsets[0]
        table2[:, 2] -= base.prelaunch_offsets[0]
    constants = copy.deepcopy(base.constants)
    constants["relaxation"]["tau_s"] = float(relaxation.tau)
    constants["relaxation"]["delay_s"] = float(relaxation.dt)
    constants["relaxation"]["look_back_s"] = look_back_for(float(relaxation.tau))
    cal = dataclasses.replace(
        base,
        temperature_coefficients=table2,
        breakpoint_temperature_c=np.array([f.x_m for f in temperature]),
        duty_cycle_c0=np.asarray(c_ref, dtype=float),
        duty_cycle_d0=d0,
        heater_signal=heater,
        constants=constants,
    )
    return FitResult(calibration=cal, temperature=temperature, duty=duty,
                     relaxation=relaxation, delay_fitted=delay_fitted, waveform=waveform,
                     stats=stats, epoch_curve=curve, temperature_law=temperature_law,
                     waveform_error=waveform_error)


def law_sigma(temperature: Sequence[TwoSegmentFit], t: np.ndarray) -> np.ndarray:
    """Stated standard error (counts) of the fitted law at temperatures ``t``, per axis.

    Propagated from each axis's covariance of ``(A0, B0, A1, B1)`` through the line in
    force at ``t`` (the larger of the two, eq. 3a/3b); shape ``(len(t), 3)``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    out = np.zeros((t.size, len(temperature)))
    for j, f in enumerate(temperature):
        cov = np.asarray(f.covariance, dtype=float)[:4, :4]
        upper = f.a1 + f.b1 * t > f.a0 + f.b0 * t
        g = np.zeros((t.size, 4))
        g[:, 0] = np.where(upper, 0.0, 1.0)
        g[:, 1] = np.where(upper, 0.0, t)
        g[:, 2] = np.where(upper, 1.0, 0.0)
        g[:, 3] = np.where(upper, t, 0.0)
        out[:, j] = np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", g, cov, g), 0.0))
    return out


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
    return out


def with_tables(base: MessengerCalibration, law: np.ndarray, d0: np.ndarray, tau: float,
                dt: float, heater: np.ndarray) -> MessengerCalibration:
    """Return ``base`` with the law ``(a, b, c, T_m)`` per axis, D0, tau, dt and waveforms.

    C0 is the law at the reference temperature (eq. 5a); the look-back follows tau
    (`look_back_for`); Table 2 is written without the pre-launch offsets where the base
    adds them to it.
    """
    table2 = fv.law_to_table(law)
    if base.prelaunch_offsets_reading == "added_to_table2":
        table2[:, 0] -= base.prelaunch_offsets[0]
        table2[:, 2] -= base.prelaunch_offsets[0]
    constants = copy.deepcopy(base.constants)
    rel = constants["relaxation"]
    c_ref = fv.law_at(law, base.reference_temperature_c)
    rel["tau_s"] = float(tau)
    rel["delay_s"] = float(dt)
    rel["look_back_s"] = look_back_for(float(tau))
    return dataclasses.replace(
        base, temperature_coefficients=table2,
        breakpoint_temperature_c=np.asarray(law[:, 3], dtype=float),
        duty_cycle_c0=np.asarray(c_ref, dtype=float), duty_cycle_d0=np.asarray(d0, dtype=float),
        heater_signal=np.asarray(heater, dtype=float), constants=constants)


def fit_variance_calibration(
    stats: DayStatistics,
    vstats: Any,
    base: MessengerCalibration,
    *,
    fit_delay: bool = True,
    n_bootstrap: int = 200,
    hold_d0: HoldD0 = (),
    max_compressive_share: float = fit_merit.MAX_COMPRESSIVE_SHARE,
    start: MessengerCalibration | None = None,
    hold_upper: tuple[str, ...] = (),
    waveform_errors: bool = True,
    resample_map: Mapping[str, Any] | None = None,
) -> FitResult:
    """One Gauss-Newton step of the variance estimator (`fit_variance`), and the waveforms.

    The temperature law, D0, tau and dt come from the normal equations ``vstats``
    (reduced with ``base`` as the linearisation point); their errors are the standard
    deviations over a bootstrap of the blocks, each resample choosing its own break
    temperatures (each shifted break placed in its shift's cell, entries 27, 47) and drawing
    each held D0 from its width (entry 18); the waveforms from ``stats`` as in
    `fit_calibration`.  dt is adopted under the same rule as there
    (error below 3 s, not negative), else held.

    Parameters
    ----------
    stats : DayStatistics
        Reduced with ``base`` (`reduce_day`), for the waveforms.
    vstats : VarianceStatistics
        Reduced with ``base`` (`fluxcal.missions.messenger.fit_variance.reduce_variance`).
    base : MessengerCalibration
    fit_delay : bool
    n_bootstrap : int
    hold_d0 : tuple of str or mapping
        Axes whose D0 is held (`held_d0_values`: value and width).
    max_compressive_share : float
        Named as the cause when too little accepted data remain
        (`fit_merit.compressive_refusal`).
    start : MessengerCalibration, optional
        The table the fit started from (default ``base``): an upper segment no accepted
        interval determines is held at its values (`held_upper_segments`, entry 21).
    hold_upper : tuple of str
        Axes whose upper segment is held whatever the data (set by the re-solve when a
        free break comes out with an error above `fit_guards.MAX_BREAK_ERROR_C` or a free slope
        change with an error above its size (`undetermined_upper`), and by `fit_days`
        for the axes an earlier pass held: a hold that came and went from pass to pass
        kept the late-peak Mercury orbit from converging, entry 27).
    waveform_errors : bool
        State the waveform columns' errors (`_fit_waveforms`); False leaves
        ``waveform_error`` None (`fit_days`'s passes: entry 33).
    resample_map : mapping, optional
        ``map_rows`` and ``n_blocks`` of `fit_variance.solve_variance`: the bootstrap's
        resamples solved in blocks elsewhere (`fit_days` on Dask: on the workers), the
        same numbers; None: here.

    Returns
    -------
    FitResult

    Raises
    ------
    FluxcalError
        No accepted interval (the rejections counted by reason), or too few blocks for
        a bootstrap.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 7 eq. 2-7.
    """
    cause = fit_merit.compressive_refusal(vstats.reason, max_compressive_share)

    def too_little(text: str) -> FluxcalError:
        # too little accepted data: name the compressive wind when it is the cause
        return FitRefusedError(f"{cause}; {text}") if cause else FluxcalError(text)

    accepted = int(np.count_nonzero(vstats.reason == ""))
    if accepted == 0 or vstats.normal.shape[0] == 0:
        raise too_little(
            f"variance estimator: no interval of {fv.VarianceSettings().interval_s:.0f} s "
            f"passes the selection (rejected: {vstats.rejections() or 'none'}); give "
            "solar-wind data with rotating field, or, only if the field averages to zero "
            "over the days (sec. 7's premise; not the solar wind, entry 11), choose "
            "--estimator zero-mean (its tables state no predicted error)")
    t_range = vstats.fitted_range()
    if not np.all(np.isfinite(t_range)):
        raise too_little(
            f"variance estimator: no 5-C temperature bin holds {fv.MIN_RANGE_SAMPLES} "
            f"accepted samples (accepted per bin: {int(vstats.temperature_count.max())} at "
            "most); the temperature law is not constrained: give more days of solar wind")
    held = held_d0_values(hold_d0, base)
    d0_base = np.asarray(base.duty_cycle_d0, dtype=float)
    columns: dict[int, tuple[float, float]] = {
        AXES.index(a) * fb.PER_AXIS + 4: (value - d0_base[AXES.index(a)], width)
        for a, (value, width) in held.items()}
    # an upper segment no accepted interval sees: its break and slope change held at the
    # start table's values, with widths (the columns d(c) and -c d(T_m))
    now = fv.law_parameters(base)
    upper = held_upper_segments(vstats, base if start is None else start, hold_upper)
    for a, h in upper.items():
        j = AXES.index(a)
        (tm, w_tm), (c, w_c) = h["Tm_c"], h["slope_change"]
        columns[j * fb.PER_AXIS + 2] = (c - now[j, 2], w_c)
        columns[j * fb.PER_AXIS + 3] = (-now[j, 2] * (tm - now[j, 3]), abs(now[j, 2]) * w_tm)
    try:
        sol = fv.solve_variance(vstats, fit_delay=fit_delay, n_bootstrap=n_bootstrap,
                                law=now, held=columns, **(resample_map or {}))
    except FluxcalError as exc:  # too few blocks: name the compressive cause if it is one
        if cause:
            raise too_little(str(exc)) from None
        raise
    law, d0, tau, dt = fv.apply_step(base, sol.step, break_shift=sol.break_shift)
    # the errors from the unclipped resamples: clipping them to the step's range (30 % of
    # tau, 10 C of a break) would cap a stated error at that range, below the guard's 30 %
    b_law, b_d0, b_tau, b_dt = fv.apply_steps(base, sol.boot, max_tau_shift=np.inf,
                                              max_break_shift_c=np.inf,
                                              break_shifts=sol.boot_shift)
    b_law[:, :, 3] += sol.boot_dither  # a shifted break inside its cell (entries 27, 47)
    # finite-sample correction of the pairs bootstrap, like a regression's n - p: the
    # resamples' spread about their mean widened by sqrt(n / (n - p)) about the solution
    # (entry 13), in the tables' parameters (each resample has its own break choice);
    # a held D0 keeps its own draws (its width is the user's, not the data's)
    # a free break the bootstrap leaves undetermined (its upper segment seen in too few
    # or too short intervals): held like an unseen one, the fit solved again (entry 21)
    # and a free slope change whose error exceeds its size (not even its sign known,
    # entry 35): held in the same way
    undetermined = undetermined_upper(law, b_law, sol.widening)
    loose = tuple(a for j, a in enumerate(AXES) if a not in upper and undetermined[j])
    if loose:
        return fit_variance_calibration(stats, vstats, base, fit_delay=fit_delay,
                                        n_bootstrap=n_bootstrap, hold_d0=hold_d0,
                                        max_compressive_share=max_compressive_share,
                                        start=start, hold_upper=(*hold_upper, *loose),
                                        waveform_errors=waveform_errors,
                                        resample_map=resample_map)
    w = sol.widening
    drawn, drawn_law = b_d0.copy(), b_law.copy()
    b_law = law + w * (b_law - b_law.mean(axis=0))
    b_d0 = d0 + w * (b_d0 - b_d0.mean(axis=0))
    b_tau = tau + w * (b_tau - b_tau.mean())
    b_dt = dt + w * (b_dt - b_dt.mean())
    for a in held:
        b_d0[:, AXES.index(a)] = drawn[:, AXES.index(a)]
    for a in upper:  # the held slope change and break keep their draws too
        b_law[:, AXES.index(a), 2:] = drawn_law[:, AXES.index(a), 2:]
    # in a compressive wind the law at -50 C and D0 are pinned as their sum, not apart:
    # the split's share of their error drawn once more (entry 52)
    split: dict[str, Any] = {}
    if fit_merit.compressive_wind(*fit_merit.compressive_share(vstats.reason)):
        b_law, b_d0, split = fv.widen_law_d0_split(
            b_law, b_d0, base.reference_temperature_c,
            np.array([a not in held for a in AXES]), np.array([a not in upper for a in AXES]))
    # D0's error along the field's mean direction that no resample sees (entry 28)
    direction, balance = fv.d0_field_balance(vstats)
    b_d0, along, added = fv.widen_d0_along_field(
        b_d0, d0, np.asarray(base.matrices[0], dtype=float), direction, balance,
        np.array([a not in held for a in AXES]))
    dt_err = float(np.std(b_dt))
    adopted = fit_delay and dt_err < MAX_DELAY_ERROR_S and dt >= 0.0
    if fit_delay and not adopted:
        return fit_variance_calibration(stats, vstats, base, fit_delay=False,
                                        n_bootstrap=n_bootstrap, hold_d0=hold_d0,
                                        max_compressive_share=max_compressive_share,
                                        start=start, hold_upper=hold_upper,
                                        waveform_errors=waveform_errors,
                                        resample_map=resample_map)
    rel = base.constants["relaxation"]
    if not fit_delay:
        dt, dt_err = float(rel["delay_s"]), 0.0
        b_dt = np.full_like(b_tau, dt)
    total = fv.law_to_table(law)
    b_total = np.stack([fv.law_to_table(x) for x in b_law])
    t_ref = base.reference_temperature_c
    c_ref = fv.law_at(law, t_ref)
    chi2 = sol.chi2
    temperature = []
    for j in range(3):
        cols = np.column_stack([b_total[:, j, :], b_law[:, j, 3]])
        cov = np.cov(cols, rowvar=False)
        err = np.sqrt(np.diag(cov))
        temperature.append(TwoSegmentFit(
            a0=float(total[j, 0]), b0=float(total[j, 1]), a1=float(total[j, 2]),
            b1=float(total[j, 3]), x_m=float(law[j, 3]), a0_err=float(err[0]),
            b0_err=float(err[1]), a1_err=float(err[2]), b1_err=float(err[3]),
            x_m_err=float(err[4]), covariance=cov, chi2=chi2, dof=sol.dof))
    duty = [LineFit(slope=float(d0[j]), slope_err=float(np.std(b_d0[:, j])),
                    intercept=float(c_ref[j]), intercept_err=0.0, x0=0.0, y0=float(c_ref[j]),
                    chi2=chi2, dof=sol.dof) for j in range(3)]
    relaxation = RelaxationFit(
        tau=float(tau), tau_err=float(np.std(b_tau)), dt=float(dt), dt_err=dt_err,
        amplitude=1.0, amplitude_err=0.0, y0=0.0, y0_err=0.0, fit_delay=bool(fit_delay),
        covariance=np.cov(np.column_stack([b_tau, b_dt]), rowvar=False), chi2=chi2,
        dof=sol.dof)
    heater, waveform, waveform_error = _fit_waveforms(stats, base, errors=waveform_errors)
    cal = with_tables(base, law, d0, tau, dt, heater)
    return FitResult(calibration=cal, temperature=temperature, duty=duty,
                     relaxation=relaxation, delay_fitted=bool(fit_delay), waveform=waveform,
                     stats=stats, epoch_curve=np.empty((0, 4)), estimator="variance",
                     variance=vstats, fitted_range=t_range, held_d0=tuple(held),
                     held=held, held_upper=upper,
                     bootstrap={"law": b_law, "d0": b_d0, "tau": b_tau,
                                           "dt": b_dt,
                                "break_shift": np.asarray(sol.boot_shift, dtype=float)},
                     break_shift=np.asarray(sol.break_shift, dtype=float),
                     waveform_error=waveform_error,
                     d0_field={"direction": direction.tolist(), "balance": balance,
                               "along_nt_per_ppt": along, "added_nt_per_ppt": added,
                               **({"law_d0_split": split} if split else {})})


# ---------------------------------------------------------------------------------------
# the driver: map (days) -> reduce (merge) -> fit, repeated
# ---------------------------------------------------------------------------------------
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
#: than this many fine counts (0.2 x 0.047 = 0.009 nT) anywhere in -65..+55 C: the law and
#: its break can still move after tau and D0 have settled (docs/decisions/messenger_fit.md,
#: entry 16: 0.19 nT left on y in a 32-day fit that stopped on tau and D0 alone).
LAW_TOLERANCE_COUNTS = 0.2
#: Temperatures (C) over which the law's change between passes is taken.
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


def pass_changes(old: MessengerCalibration, new: FitResult,
                 tolerance: float = 2e-3) -> dict[str, Any]:
    """Change of every parameter from ``old`` to ``new`` and its allowance (entry 18).

    Each change is compared with the larger of an absolute tolerance (``tolerance``
    of tau and of each D0; `DELAY_TOLERANCE_S`; `LAW_TOLERANCE_COUNTS` of the law at
    every temperature of `LAW_CHANGE_GRID_C`) and `CONVERGENCE_SIGMA` times its stated
    error (the law's at each temperature, `FitResult.law_error`).  ``ratio`` is the
    largest change over its allowance: the pass has converged when it is at most 1.
    """
    cal = new.calibration
    r = new.relaxation
    rel_old, rel_new = old.constants["relaxation"], cal.constants["relaxation"]
    d_tau = float(rel_new["tau_s"]) - float(rel_old["tau_s"])
    d_dt = float(rel_new["delay_s"]) - float(rel_old["delay_s"])
    d0_new = np.asarray(cal.duty_cycle_d0, dtype=float)
    d_d0 = d0_new - np.asarray(old.duty_cycle_d0, dtype=float)
    law_new = two_segment_offset(LAW_CHANGE_GRID_C, cal.offset_coefficients())
    d_law = law_new - two_segment_offset(LAW_CHANGE_GRID_C, old.offset_coefficients())
    allow_law = np.maximum(LAW_TOLERANCE_COUNTS,
                           CONVERGENCE_SIGMA * np.nan_to_num(new.law_error(LAW_CHANGE_GRID_C)))
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
    items += [(f"law {a} at {LAW_CHANGE_GRID_C[at[j]]:+.0f} C", float(d_law[at[j], j]),
               float(allow_law[at[j], j]), "counts") for j, a in enumerate(AXES)]
    ratios = [abs(c) / allow if allow > 0 else (0.0 if c == 0 else np.inf)
              for _, c, allow, _ in items]
    return {
        "tau_s": d_tau, "delay_s": d_dt, "D0": d_d0.tolist(),
        "law_counts": np.abs(d_law).max(axis=0).tolist(),
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


def convergence_criterion(tolerance: float) -> str:
    """Return the stated convergence criterion (report and refusal)."""
    return (f"every parameter changed by less than the larger of an absolute tolerance "
            f"(tau and each D0 {tolerance:g} of their value, dt {DELAY_TOLERANCE_S:g} s, the "
            f"law {LAW_TOLERANCE_COUNTS:g} counts at every temperature of "
            f"{LAW_CHANGE_GRID_C[0]:.0f}..{LAW_CHANGE_GRID_C[-1]:.0f} C) and "
            f"{CONVERGENCE_SIGMA:g} of its stated error")


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
        `DELAY_TOLERANCE_S`, the law by `LAW_TOLERANCE_COUNTS`, and `CONVERGENCE_SIGMA`
        of its stated error).
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
            changes = pass_changes(cal, result, tolerance)
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
        last = history[-1]["changes"]
        result.convergence = {
            "passes_run": len(history), "max_passes": passes, "converged": converged,
            "criterion": convergence_criterion(tolerance),
            "stop": (f"converged after {len(history)} passes: the last changed every "
                     f"parameter by at most {last['ratio']:.2g} of its allowance"
                     if converged else
                     f"not converged after {len(history)} passes: the last changed "
                     + ", ".join(last["over"])),
        }
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
                raise FitRefusedError(
                    f"{result.convergence['stop']}; not written (converged: "
                    f"{convergence_criterion(tolerance)}). Give "
                    + (f"more passes (--passes {MAX_PASSES}: the fit stops as soon as it "
                       "converges) or " if passes < MAX_PASSES else "") + "more days")
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
