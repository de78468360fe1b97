"""In-flight MESSENGER MAG calibration: flight data in, calibration tables out.

The offsets of sec. 7 (Table 2 temperature law, Table 3 duty-cycle law, the relaxation
time tau and the heater delay dt) and the heater waveforms of sec. 6 (Tables 6-8) are
estimated from long-term averages of solar-wind data, whose mean field is zero.  This
module holds the fits of one pass, merged statistics in, tables out (`FitResult`); the
other steps have their own modules:

* `fluxcal.missions.messenger.fit_reduce.reduce_day` reduces each day to mergeable
  `DayStatistics` given the current estimate of every term;
* `fit_calibration` turns merged statistics into new estimates (`FitResult`); with
  ``estimator="variance"`` `fit_variance_calibration` (the statistics reduced and solved
  by `fluxcal.missions.messenger.fit_variance`, the breaks chosen and the bootstrap's
  resamples solved by `fluxcal.missions.messenger.fit_breaks`); both fit the heater
  waveforms with `fluxcal.missions.messenger.fit_waveforms`;
* `fluxcal.missions.messenger.fit_passes.fit_days` iterates: reduce all days (serially
  or on a Dask cluster), merge, fit, and reduce again with the new estimates,
  ``passes`` times (each step then removes the others' current estimates, sec. 7:
  "iterative");
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

``__all__`` still names `check_fit` and `reduce_day` (defined in `fit_guards` and
`fit_reduce`), as the API reference documents them here.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 7 eq. 2-7, Tables 2-3,
   Appendix Tables 6-8.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fluxcal.calibration.constrained_fits import (
    LineFit,
    PeriodicSplineFit,
    RelaxationFit,
    TwoSegmentFit,
    fit_line_fixed_intercept,
    fit_relaxation,
    fit_two_segment,
)
from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import FitRefusedError, FluxcalError
from fluxcal.missions.messenger import fit_breaks as fb
from fluxcal.missions.messenger import fit_merit
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.calibration_data import (
    MessengerCalibration,
    required_look_back_s,
)
from fluxcal.missions.messenger.fit_guards import check_fit
from fluxcal.missions.messenger.fit_holds import (
    HoldD0,
    held_d0_values,
    held_upper_segments,
    undetermined_upper,
)
from fluxcal.missions.messenger.fit_merit import AXES
from fluxcal.missions.messenger.fit_reduce import (
    MIN_BIN_SAMPLES,
    TAU_STEP,
    DayStatistics,
    FitSettings,
    reduce_day,
    relaxation_response,
    usable_bins,
)
from fluxcal.missions.messenger.fit_waveforms import fit_waveforms, supported_duty_range

__all__ = ["ESTIMATORS", "TEMPERATURE_LAWS", "FitResult", "check_fit", "fit_calibration",
           "fit_variance_calibration", "law_sigma", "reduce_day"]

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
        Summary of every pass (`fit_passes.fit_days`).
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
        `fit_passes.fit_days`: passes run, whether they converged, why the fit stopped
        and every pass's changes (`fit_passes.pass_changes`).
    merit : dict
        `fit_merit.predicted_error` of the written tables and the goal it was held to.
    waveform_error : ndarray, shape (3, n_duty_bins) or None
        Stated rms error (counts) of each waveform column (`fit_waveforms`).
    d0_field : dict
        The variance estimator: the field's mean direction weighted as D0's information
        (``direction``, ``balance`` 0..1), D0's bootstrap error along it and the error
        added there (``along_nt_per_ppt``, ``added_nt_per_ppt``;
        `fit_variance.widen_d0_along_field`, docs/decisions/messenger_fit.md entry 28).
    pass_start : MessengerCalibration or None
        `fit_passes.fit_days`: the table the last pass started from, so that its changes
        can be judged again over the T_RANGE of another goal (`fit_passes.judged_at`).
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
    pass_start: MessengerCalibration | None = None

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


def temperature_distribution(stats: DayStatistics, ok: np.ndarray
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
    dist = temperature_distribution(stats, ok) if law == "distribution" else None
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
        State the waveform columns' errors (`fit_waveforms`); False leaves
        ``waveform_error`` None (`fit_passes.fit_days`'s passes: entry 33).

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
    heater, waveform, waveform_error = fit_waveforms(stats, base, errors=waveform_errors)
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
        change with an error above its size (`undetermined_upper`), and by
        `fit_passes.fit_days` for the axes an earlier pass held: a hold that came and went
        from pass to pass kept the late-peak Mercury orbit from converging, entry 27).
    waveform_errors : bool
        State the waveform columns' errors (`fit_waveforms`); False leaves
        ``waveform_error`` None (`fit_passes.fit_days`'s passes: entry 33).
    resample_map : mapping, optional
        ``map_rows`` and ``n_blocks`` of `fit_variance.solve_variance`: the bootstrap's
        resamples solved in blocks elsewhere (`fit_passes.fit_days` on Dask: on the
        workers), the same numbers; None: here.

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
    heater, waveform, waveform_error = fit_waveforms(stats, base, errors=waveform_errors)
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

