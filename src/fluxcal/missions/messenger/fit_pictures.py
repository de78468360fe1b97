"""The pictures of a ``messenger fit`` (`fluxcal.products.fit_pictures`) from its `FitResult`.

* offsets against sensor temperature: the heater-off 10-C bin means (the seed's
  long-term averages, the decaying duty-cycle offset removed as the fit removes it)
  at each bin's mean temperature, their residuals and pulls about the law as the fit
  models each bin (averaged over the bin's temperatures), the Table 2 law (eq. 3a/3b:
  the larger of two lines) with its stated 1-sigma band (`law_band`) and the fitted range
  shaded;
* offsets against heater duty cycle: the 4-% bin means at their mean relaxed duty
  cycle and the Table 3 line ``C0 + D0 d`` (eq. 5a);
* the relaxation: the axis-combined normalised superposed epoch and the fitted step
  response (eq. 6f, `RelaxationFit`);
* pulls of the bin means about the laws;
* the variance estimator's 15-min intervals by reason on a UTC time line.

With the variance estimator (which measures no bin means: a bin mean is on the law only
in a zero-mean wind) the pictures show the law, its band and the fitted range, the
duty-cycle line and the intervals, without bin means, pulls or the relaxation (it fits tau
from the variance of ``|B|``, with no superposed epoch to draw).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 3a-3b, 5a, 6f, Tables 2-3.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fluxcal.errors import FluxcalError
from fluxcal.geometry.time import et_to_tt2000, tt2000_to_datetime64
from fluxcal.missions.messenger.fit import (
    AXES,
    FitResult,
    law_sigma,
    temperature_distribution,
)
from fluxcal.missions.messenger.fit_reduce import usable_bins
from fluxcal.products.fit_pictures import (
    Curve,
    Panel,
    Picture,
    Points,
    Pulls,
    Rejections,
    pull_values,
)
from fluxcal.products.fit_report import write_fit_report
from fluxcal.products.timeindex import default_lsk

#: Points on the drawn law (the temperature axis).
N_CURVE = 241


def law(result: FitResult, t: np.ndarray) -> np.ndarray:
    """Return the fitted temperature law (counts) at ``t`` (C), shape (n, 3): eq. 3a/3b."""
    t = np.asarray(t, float)[:, None]
    c = np.asarray(result.calibration.temperature_coefficients, float)  # (3, 4)
    return np.maximum(c[:, 0] + c[:, 1] * t, c[:, 2] + c[:, 3] * t)


def law_band(result: FitResult, t: np.ndarray) -> np.ndarray:
    """Return the law's stated 1-sigma error (counts) at ``t``, shape (n, 3).

    The fit's own ``law_error`` where the result states one (the full covariance, break
    included), else `law_sigma` (the covariance of the two lines at the chosen break).
    """
    stated = getattr(result, "law_error", None)
    return stated(t) if callable(stated) else law_sigma(result.temperature, t)


def _measured(result: FitResult) -> bool:
    """Whether the bin means are what the fit measured (the zero-mean estimator).

    The variance estimator measures none: a bin mean is the field's average, on the law
    only in a zero-mean wind (a mean field moves it hundreds of counts off), so it is
    neither drawn nor pulled.
    """
    return result.estimator != "variance"


def _bin_model(result: FitResult, ok: np.ndarray, t_mean: np.ndarray) -> np.ndarray:
    """Return the law as the fit models each used bin (averaged over its temperatures).

    The ``distribution`` estimator (docs/decisions/messenger_fit.md, entry 8) models a bin
    as the average of the law over its samples' temperatures; the ``binned-mean`` one (or
    statistics without the sub-bins) as the law at the bin's mean temperature.
    """
    if result.temperature_law == "distribution" and result.stats.temperature_fine is not None:
        try:
            t_sub, weights = temperature_distribution(result.stats, ok)
        except FluxcalError:
            return law(result, t_mean)
        used = weights.sum(axis=1) > 0
        if used.all():
            filled = np.isfinite(t_sub)
            return (weights[:, filled] @ law(result, t_sub[filled])) / weights.sum(axis=1)[:, None]
    return law(result, t_mean)


def _temperature(result: FitResult) -> tuple[Panel, np.ndarray]:
    m = result.stats.temperature
    mean, err = m.mean(), m.standard_error()
    ok = usable_bins(m, 3)
    d0 = np.asarray(result.calibration.duty_cycle_d0, float)
    y = mean[ok, :3] - mean[ok, 4:5] * d0[None, :]
    pts = Points(mean[ok, 3], y, err[ok, :3], "heater-off 10-C bin means",
                 _bin_model(result, ok, mean[ok, 3]))
    lo, hi = result.fitted_range
    seen = [v for v in (*pts.x, lo, hi) if np.isfinite(v)] or list(m.edges[[0, -1]])
    grid = np.linspace(min(seen) - 5.0, max(seen) + 5.0, N_CURVE)
    curve = Curve(grid, law(result, grid), law_band(result, grid), "Table 2 law (eq. 3a/3b)")
    ranges = result.stated_ranges  # T_RANGE, one or more intervals (entry 24)
    fitted = None if ranges is None else ranges.intervals
    panel = Panel("fit_offsets_temperature", "Offsets against sensor temperature (heater off)",
                  "sensor temperature (C)", "offset (counts)", AXES,
                  ("the heater-off bin means (decaying duty-cycle offset removed) with their "
                   "standard errors, " if _measured(result) else "")
                  + "the fitted Table 2 law and its stated 1-sigma band; right: "
                  + ("each bin minus the law as the fit models it, inside the band; "
                     if _measured(result) else "the band about the law; ")
                  + "shaded: T_RANGE, where the data determine the law",
                  pts if _measured(result) else None, curve, fitted)
    return panel, pull_values(pts, pts.model)


def _duty(result: FitResult) -> tuple[Panel, np.ndarray]:
    m = result.stats.duty
    mean, err = m.mean(), m.standard_error()
    ok = usable_bins(m, 3)
    pts = Points(mean[ok, 3], mean[ok, :3], err[ok, :3], "4-% bin means")
    c0 = np.asarray(result.calibration.duty_cycle_c0, float)
    d0 = np.asarray(result.calibration.duty_cycle_d0, float)
    grid = np.linspace(0.0, 1.1 * float(pts.x.max()) if pts.x.size else 1000.0, 101)
    line = c0[None, :] + d0[None, :] * grid[:, None]
    held = [a for a in AXES if a in result.held_d0]
    panel = Panel("fit_offsets_duty_cycle", "Offsets against heater duty cycle",
                  "relaxed duty cycle (ppt)", "offset (counts)", AXES,
                  ("the bin means inside heater periods at their mean relaxed duty cycle, "
                   "and " if _measured(result) else "")
                  + "the Table 3 line C0 + D0 d (C0 held at the law at -50 C)"
                  + (f"; D0 held for {', '.join(held)}" if held else ""),
                  pts if _measured(result) else None,
                  Curve(grid, line, None, "Table 3 line (eq. 5a)"))
    return panel, pull_values(pts, c0[None, :] + d0[None, :] * pts.x[:, None])


def _relaxation(result: FitResult) -> Panel | None:
    e = np.asarray(result.epoch_curve, float)
    if e.ndim != 2 or e.shape[0] == 0:
        return None
    r = result.relaxation
    lag = e[:, 0]
    grid = np.linspace(float(np.nanmin(lag)), float(np.nanmax(lag)), N_CURVE)
    g = np.where(grid > r.dt, -np.expm1(-np.maximum(grid - r.dt, 0.0) / r.tau), 0.0)
    model = r.y0 + r.amplitude * g + r.prior_amplitude * np.exp(-grid / r.tau)
    ok = np.isfinite(e[:, 1])
    return Panel("fit_relaxation", "Relaxation after a duty-cycle change",
                 "lag after the change (s)", "normalised epoch", ("all axes",),
                 f"the superposed epoch of the duty-cycle changes, normalised by each step "
                 f"and combined over the axes, with the fitted step response (tau "
                 f"{r.tau:.0f} +- {r.tau_err:.0f} s, dt {r.dt:.1f} s)",
                 Points(lag[ok], e[ok, 1:2], e[ok, 2:3], "epoch bins"),
                 Curve(grid, model[:, None], None, "fitted response (eq. 6f)"))


def _rejections(result: FitResult) -> Rejections | None:
    v = result.variance
    if v is None or np.size(v.interval_start) == 0:
        return None
    lsk = default_lsk()  # the fit's kernels are unloaded by now
    start = tt2000_to_datetime64(et_to_tt2000(np.asarray(v.interval_start, float), lsk), lsk)
    return Rejections("fit_intervals", "Intervals of the variance estimator by reason",
                      "every interval of the variance estimator at its UTC start: accepted, "
                      "or the first criterion it failed", start, np.asarray(v.reason))


def pictures(result: FitResult) -> list[Picture]:
    """Return the pictures of ``result`` (those its data allow), in page order."""
    temp, temp_pulls = _temperature(result)
    duty, duty_pulls = _duty(result)
    out: list[Picture] = [temp, duty]
    relax = _relaxation(result)
    if relax is not None:
        out.append(relax)
    if _measured(result):
        out.append(Pulls("fit_pulls", "Pulls of the bin means about the fitted laws",
                         "(bin mean - law) / standard error of the temperature and "
                         "duty-cycle bins, beside the unit normal: a spread near 1 when the "
                         "stated errors are honest",
                         {"temperature": temp_pulls, "duty cycle": duty_pulls}))
    rej = _rejections(result)
    if rej is not None:
        out.append(rej)
    return out


def write_fit_pictures(result: FitResult, out: Path) -> tuple[list[Path], str]:
    """Draw the pictures of ``result`` into ``out`` and write its ``index.html``.

    Returns the files written and the one-line note when the pictures need
    ``fluxcal[plot]`` (`fluxcal.products.fit_report.write_fit_report`).
    """
    return write_fit_report(out, pictures(result), f"fluxcal messenger fit: {Path(out).name}")
