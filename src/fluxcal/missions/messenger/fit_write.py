"""Write a fitted MESSENGER MAG calibration as a versioned calibration folder.

The folder holds the eight tables `load_calibration(day, folder)` reads: the fitted ones
(``offsets_temperature``, ``offsets_duty_cycle``, ``heater_signal_x/y/z`` and
``processing`` with tau, dt and the look-back replaced) one version above the base's, with headers
naming their source (``fitted by fluxcal messenger fit``), the base file, the inputs
(names and sha256), the solar-wind intervals and the fit statistics; the unfitted ones
(``latency``, ``gain_matrix``) copied byte for byte; and ``fit_report.toml`` /
``fit_report.txt``.  The layout is documented in ``docs/formats/calibration.md``.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7, Tables 2, 3, Appendix
   Tables 6-8.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import CalibrationError
from fluxcal.missions.messenger.calibration_data import (
    _NAME_RE,
    TABLE_NAMES,
    WAVEFORM_ERROR_KEY,
    WAVEFORM_PART_KEY,
    _read_table,
    data_dir,
)
from fluxcal.missions.messenger.fit import AXES, FitResult
from fluxcal.missions.messenger.fit_guards import D0_ERROR_GOAL, TAU_ERROR_GOAL
from fluxcal.missions.messenger.fit_merit import ERROR_GOAL_NT, MAX_COMPRESSIVE_SHARE
from fluxcal.missions.messenger.fit_variance import (
    MIN_RANGE_SAMPLES,
    TEMPERATURE_EDGES_C,
    VarianceSettings,
)
from fluxcal.missions.messenger.fit_waveforms import MIN_PHASE_BINS
from fluxcal.products.declared import File, write_declared
from fluxcal.products.provenance import creation_time, sha256_file
from fluxcal.version import software_version

__all__ = ["write_calibration_folder"]

FITTED = ("offsets_temperature", "offsets_duty_cycle", "heater_signal_x", "heater_signal_y",
          "heater_signal_z", "processing")
SOURCE = "fitted by fluxcal messenger fit"
#: Temperatures (C) at which the law's error band is written (header and report).
BAND_GRID_C = np.arange(-65.0, 55.5, 5.0)


def merit_lines(result: FitResult) -> list[str]:
    """Header lines: how the fit stopped and the predicted error against its goal."""
    lines = []
    c = result.convergence
    if c:
        lines.append(f"passes: {c['stop']}")
        if not c["converged"]:
            lines.append("NOT CONVERGED: written for a study of the estimator, not for use")
    m = result.merit
    if m and "total_nt" in m:
        goal = float(m["goal_nt"])
        lines.append(
            "predicted error of a recalibrated day: "
            + " / ".join(f"{v:.3f}" for v in m["total_nt"])
            + f" nT rms (x / y / z; law, D0, tau and dt from the stated covariance over the "
            f"fitted days' temperatures and duty cycles, the waveforms' stated error, the "
            f"counts' rounding); goal "
            f"{goal:g} nT")
        if "waveform_fitted_mix_nt" in m:
            lines.append(
                "its waveform part " + " / ".join(f"{v:.3f}" for v in m["waveform_nt"])
                + " nT (WAVEFORM_PART_NT) weighs each column's stated error (WAVEFORM_ERROR) "
                "by the fitted days' share of its duty bin, at least the even share over "
                "D_RANGE (a day to be calibrated has its own mix; at the fitted mix alone "
                + " / ".join(f"{v:.3f}" for v in m["waveform_fitted_mix_nt"])
                + " nT); calibrating a day whose own mix puts its predicted error above the "
                "goal, or above this by more than the part's scatter, warns")
        if goal > ERROR_GOAL_NT:
            lines.append(f"ACCEPTED ABOVE THE DEFAULT GOAL {ERROR_GOAL_NT:g} nT: --error-goal "
                         f"{goal:g}")
        if "outside" in m:
            o = m["outside"]
            lines.append(
                f"the predicted error holds for the samples inside T_RANGE "
                f"{StatedRanges.of(m['range_c'])} C; {o['samples']} of {o['of']} "
                f"fitted samples ({o['samples'] / max(o['of'], 1):.1%}) lie outside it, "
                "where the law is extrapolated (calibrating them warns); over all samples "
                "the prediction is " + " / ".join(f"{v:.3g}" for v in o["all_samples_total_nt"])
                + " nT")
    if m and "duty_range_pct" in m:
        lines.append(duty_range_line(m))
    if m and "judged" in m:
        share = float(m["max_compressive_share"])
        lines.append(f"intervals rejected as compressive: {m['compressive']} of {m['judged']} "
                     f"judged (limit {share:.0%})")
        if share > MAX_COMPRESSIVE_SHARE:
            lines.append(f"ACCEPTED ABOVE THE DEFAULT COMPRESSIVE SHARE "
                         f"{MAX_COMPRESSIVE_SHARE:.0%}: --max-compressive-share {share:g}")
    return lines + goal_confidence_lines(result)


def goal_within(goal: float, value: float, error: float) -> tuple[float, float] | None:
    """Return ``(k, p)``: the goal in stated sigmas and the chance the truth lies within it.

    ``k = goal / (|error / value|)`` with the relative error the guards use
    (`fit_guards.d0_goal_refusal`, `fit_guards.tau_goal_refusal`), and
    ``p = 2 Phi(k) - 1 = erf(k / sqrt 2)``, the two-sided normal probability that a truth
    drawn about ``value`` with the stated 1-sigma ``error`` lies within ``goal`` of it.
    None where no relative error is stated (an error that is not finite or not positive,
    or a value that is 0 or not finite).
    """
    if not (np.isfinite(value) and value != 0 and np.isfinite(error) and error > 0):
        return None
    k = goal / abs(error / value)
    return k, math.erf(k / math.sqrt(2.0))


def _k_text(k: float) -> str:
    return f"{k:.3g}" if k < 100 else f"{k:.0f}"


def _p_text(p: float) -> str:
    return ">99.9" if p > 0.999 else f"{100 * p:.1f}"


def goal_confidence_lines(result: FitResult) -> list[str]:
    """Header line: at what confidence the written tau and fitted D0 meet their goals.

    Issue 34 asks tau and D0 "within 5 %" (`TAU_ERROR_GOAL`, `D0_ERROR_GOAL`); the guards
    refuse a stated 1-sigma relative error above the goal (decision entries 38 and 43),
    so a written table meets the goal against the truth only with a probability (orbit
    seed 4111: D0 z stated +-2.04 %, 6.4 % off, verification section 56).  This
    line states it, for tau and each fitted D0 axis: the goal in stated sigmas and
    `goal_within`'s normal probability; a held D0 axis (``--hold-d0``) is named with its
    stated width instead (`fit_merit` judges it).  A quantity without a stated error is
    left out; no line when none has one.  Informative only: no refusal reads it.

    References
    ----------
    Seed 000 sec. 7, eq. 5-6 and Table 3 (tau, D0); issue 34, "Done when";
    docs/decisions/messenger_fit.md entry 59.
    """
    parts = []
    r = result.relaxation
    tau = goal_within(TAU_ERROR_GOAL, r.tau, r.tau_err)
    if tau is not None:
        parts.append(f"tau within {100 * TAU_ERROR_GOAL:g} %: {_k_text(tau[0])} sigma "
                     f"({_p_text(tau[1])} %)")
    fitted = [(a, goal_within(D0_ERROR_GOAL, f.slope, f.slope_err))
              for a, f in zip(AXES, result.duty, strict=True) if a not in result.held_d0]
    fitted = [(a, kp) for a, kp in fitted if kp is not None]
    if fitted:
        parts.append(f"D0 {' / '.join(a for a, _ in fitted)} within {100 * D0_ERROR_GOAL:g} %: "
                     + " / ".join(_k_text(kp[0]) for _, kp in fitted) + " sigma ("
                     + " / ".join(_p_text(kp[1]) for _, kp in fitted) + " %)")
    for a in AXES:
        if a in result.held_d0:
            value, width = result.held[a]
            rel = f", {100 * abs(width / value):.1f} %" if value != 0 else ""
            parts.append(f"D0 {a} held at {value:.6g} +- {width:.3g}{rel} (--hold-d0)")
    if not parts:
        return []
    return ["goals against the truth (normal, stated 1 sigma): " + "; ".join(parts)]


def duty_range_line(merit: Mapping[str, Any]) -> str:
    """Header line: the heater-on samples the prediction's waveform part holds for."""
    lo, hi = merit["duty_range_pct"]
    n, of = int(merit["samples_outside_duty_range"]), int(merit["heater_on_samples"])
    return (f"the predicted error's waveform part holds for the heater-on samples inside "
            f"D_RANGE {lo:g}..{hi:g} % (duty cycles d with {lo:g} <= d < {hi:g}); {n} of {of} "
            f"fitted heater-on samples ({n / max(of, 1):.1%}) lie outside it, where the "
            "waveform is extrapolated beyond the fitted columns (sec. 6) and its error is "
            "not stated (calibrating them warns)")


def held_upper_lines(result: FitResult) -> list[str]:
    """Header lines: the upper segments held because no accepted interval saw them."""
    return [f"{a}: upper segment (eq. 3b) held: no accepted interval determines it "
            f"(fewer than 2 5-C bins above the break, or its free break +- more than 10 C, "
            f"or its free B1 - B0 +- more than its size); "
            f"Tm held at {h['Tm_c'][0]:.2f} +- "
            f"{h['Tm_c'][1]:.3g} C, B1 - B0 at {h['slope_change'][0]:.4g} +- "
            f"{h['slope_change'][1]:.3g} counts/C (the widths enter every stated error; "
            "the upper line follows the fitted lower one, eq. 4)"
            for a, h in result.held_upper.items()]


def break_outside_lines(result: FitResult) -> list[str]:
    """Header lines: a free break beyond T_RANGE, which the stated law does not rest on.

    Inside T_RANGE the table then applies one line of eq. 3 only; the break itself lies
    where the law is not stated, so no temperature the table states checks it. Said
    out loud because such a break was found 2-3x its stated error off (a 4-day late-peak
    fit: verification section 50, entry 56), and because the passes judge the law's
    convergence over T_RANGE's span only (`fit_passes.pass_changes`), so such a break
    may still have been moving at the last pass. A break that is not a number is skipped.

    References
    ----------
    Seed 000 sec. 7, eq. 3a-3b and 4 (the two lines meet at the break); issue 34, "Done
    when" (T_m's pulls inside the stated range).
    """
    ranges = result.stated_ranges
    if ranges is None:
        return []
    lo, hi = ranges.span
    out = []
    for a, f in zip(AXES, result.temperature, strict=True):
        if a in result.held_upper or not np.isfinite(f.x_m) or lo <= f.x_m <= hi:
            continue
        side = f"{f.x_m - hi:.1f} C above" if f.x_m > hi else f"{lo - f.x_m:.1f} C below"
        out.append(f"{a}: the break Tm = {f.x_m:.2f} +- {f.x_m_err:.3g} C lies {side} "
                   f"T_RANGE ({ranges}): inside T_RANGE the law is one line of eq. 3; Tm and "
                   "its error rest on data where the law is not stated and are not checked "
                   "by it, nor is its convergence (calibrating beyond T_RANGE warns)")
    return out


def band_lines(result: FitResult) -> list[str]:
    """Header lines: the law's stated error (counts, 1 sigma) on `BAND_GRID_C`."""
    band = result.law_error(BAND_GRID_C)
    return [f"law error band (counts, 1 sigma, full covariance with the break) at "
            f"{BAND_GRID_C[0]:.0f}..{BAND_GRID_C[-1]:.0f} C every "
            f"{BAND_GRID_C[1] - BAND_GRID_C[0]:.0f} C, {a}: {_fmt(band[:, j], 3)}"
            for j, a in enumerate(AXES)]


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if np.isnan(f):
            return "nan"
        if np.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    text = str(v).replace("\\", "\\\\").replace('"', '\\"')
    return f'"{text}"'


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_value(str(key))


def dump_toml(doc: Mapping[str, Any], prefix: str = "") -> str:
    """Return ``doc`` (scalars, strings, lists, nested dicts) as TOML text."""
    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in doc.items()
             if not isinstance(v, Mapping)]
    for k, v in doc.items():
        if isinstance(v, Mapping):
            name = f"{prefix}.{_toml_key(k)}" if prefix else _toml_key(k)
            lines += ["", f"[{name}]", dump_toml(v, name)]
    return "\n".join(lines)


def _next_version(base_folder: Path, name: str, current: int) -> int:
    versions = [int(m["version"]) for p in base_folder.glob(f"{name}_v*.*")
                if (m := _NAME_RE.match(p.name)) and m["name"] == name]
    return max([current, *versions]) + 1


def d0_field_lines(result: FitResult) -> list[str]:
    """Header lines: D0's error along the field's mean direction (entry 28), if added.

    And the law-D0 split's widening in a compressive wind (entry 52), if made.
    """
    f = result.d0_field
    if not f:
        return []
    split = f.get("law_d0_split") or {}
    lines = [] if not split else [
        "compressive wind: D0 errors include "
        + " / ".join(f"{x:.3g}" for x in split["added_counts_per_ppt"])
        + " counts/ppt (x / y / z) traded with the law at -50 C (their resamples' correlation "
        + " / ".join(f"{x:+.2f}" for x in split["rho"])
        + "), drawn once more: the data pin cT(-50 C) + D0 R, not its split (decision 52)"]
    if not f.get("added_nt_per_ppt"):
        return lines
    return lines + [f"D0 errors include {f['added_nt_per_ppt']:.3g} nT/ppt along the field's mean "
            f"direction ({' '.join(f'{x:+.3f}' for x in f['direction'])}, sensor axes; "
            f"one-sided {f['balance']:.2f}) added to the bootstrap's {f['along_nt_per_ppt']:.3g}"
            ": the measured bias of D0 there, which no resample sees (decision 28)"]


def _header(title: str, form: str, version: int, base_file: Path, base_header: dict,
            provenance: Mapping[str, Any], extra: list[str]) -> list[str]:
    lines = [
        f"# {title}",
        f"# source: {SOURCE} {software_version()} from flight data ({form})",
        f"# version: {version}",
        f"# valid_from: {base_header['valid_from']}",
        f"# valid_to: {base_header['valid_to']}",
        f"# created: {creation_time()}",
        f"# based on: {base_file.name} sha256={sha256_file(base_file)}",
        f"# intervals: {provenance.get('intervals', 'all data')}",
        f"# days: {provenance.get('days', '')}",
    ]
    lines += [f"# input: {name} sha256={sha}"
              for name, sha in sorted(provenance.get("inputs", {}).items())]
    return lines + [f"# fit {e}" for e in extra]


def _fmt(values: np.ndarray, digits: int = 6) -> str:
    return ",".join(f"{v:.{digits}g}" for v in np.asarray(values, dtype=float))


def refuse_out_with_tables(out: Path) -> None:
    """Refuse an ``--out`` folder that already holds calibration tables (versions would mix).

    `run_fit` asks before any input is read, `write_calibration_folder` again before it
    writes (README, "an unusable --out is exit 2 before any input is read").

    Raises
    ------
    CalibrationError
        Naming the folder and the tables in it.
    """
    out = Path(out)
    stale = sorted(p.name for p in out.glob("*_v*.*") if _NAME_RE.match(p.name)) if (
        out.is_dir()) else []
    if stale:
        raise CalibrationError(f"{out}: already holds calibration tables ({', '.join(stale)});"
                               " give an empty or new folder")


def write_calibration_folder(
    result: FitResult,
    out_dir: Path,
    base_folder: Path | None,
    provenance: Mapping[str, Any],
    *,
    study: bool = False,
) -> list[Path]:
    """Write ``result`` as a calibration folder that ``load_calibration`` reads.

    A result whose passes did not converge (``result.convergence``) is refused unless
    ``study`` (a study of the estimator; every header then says so).

    Parameters
    ----------
    result : FitResult
        From `fluxcal.missions.messenger.fit_passes.fit_days` or `fit_calibration`.
    out_dir : Path
        Folder to write (created; must not already hold calibration tables).
    base_folder : Path or None
        Folder of the base tables (None: the packaged ones), for the version numbers.
    provenance : mapping
        ``inputs`` (name -> sha256), ``intervals`` (text), ``days`` (text),
        ``command`` (text); recorded in every header and the report.

    Returns
    -------
    list of Path
        The files written (eight tables and the two reports).

    Raises
    ------
    CalibrationError
        When ``out_dir`` already holds calibration tables (versions would mix), or the
        fit did not converge (and not ``study``).
    """
    out = Path(out_dir)
    if result.convergence and not result.convergence["converged"] and not study:
        raise CalibrationError(f"{out}: {result.convergence['stop']}; not written (the "
                               "last pass of a fit that has not converged is no result)")
    base_folder = data_dir() if base_folder is None else Path(base_folder)
    cal = result.calibration
    refuse_out_with_tables(out)
    base_files = {_NAME_RE.match(p.name)["name"]: p for p in cal.paths}
    missing = [n for n in TABLE_NAMES if n not in base_files]
    if missing:
        raise CalibrationError(f"base calibration lacks tables {missing}")
    base = {n: _read_table(base_files[n]) for n in TABLE_NAMES}
    version = {n: _next_version(base_folder, n, base[n].version) for n in FITTED}
    texts: dict[str, str] = {}
    # Table 2 form
    t = result.temperature
    extra = [f"{a}: chi2 {f.chi2:.4g} dof {f.dof}; errors A0 {f.a0_err:.3g} B0 {f.b0_err:.3g} "
             f"A1 {f.a1_err:.3g} B1 {f.b1_err:.3g} Tm {f.x_m_err:.3g}"
             for a, f in zip(AXES, t, strict=True)]
    tm = result.stats.temperature
    if result.estimator == "variance":
        extra += [_range_line(result), *held_upper_lines(result),
                  *break_outside_lines(result), *band_lines(result)]
    else:
        extra += [f"bins (C): {_fmt(tm.centers, 4)}", f"N per bin: {_fmt(tm.count, 12)}",
                  f"estimator: {result.temperature_law} (bin "
                  "averages of the law over each bin's temperatures, or the law at the bins' "
                  "mean temperatures)"]
    rows = ["axis,A0,B0,A1,B1,Tm_c"] + [
        f"{a},{c[0]:.6f},{c[1]:.6f},{c[2]:.6f},{c[3]:.6f},{tmv:.4f}"
        for a, c, tmv in zip(AXES, cal.temperature_coefficients, cal.breakpoint_temperature_c,
                             strict=True)]
    # the range the law is stated over, read back by `load_calibration` (calibrating a
    # sample outside it warns: `chain.warn_outside_temperature_range`); one or more
    # intervals, ``lo hi`` pairs separated by commas (entry 24)
    ranges = result.stated_ranges
    t_range = ([f"# T_RANGE: {ranges.header_text()}"] if result.estimator == "variance"
               and ranges is not None else [])
    texts["offsets_temperature"] = "\n".join(_header(
        "MESSENGER MAG offsets versus sensor temperature, two-segment line (eq. 3a, 3b, 4)",
        "MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, Table 2 form; heater off, 10-C bins,"
        " sqrt(N) weights", version["offsets_temperature"], base_files["offsets_temperature"],
        base["offsets_temperature"].header, provenance,
        ["units: A0, A1 = counts (fine range); B0, B1 = counts per degC; Tm_c = degC", *extra,
         *merit_lines(result)],
    ) + t_range + rows) + "\n"
    # Table 3 form
    d = result.duty
    dm = result.stats.duty
    extra = [f"{a}: D0 held at {result.held[a][0]:.6g} +- {result.held[a][1]:.3g} (--hold-d0; "
             "the width enters every stated error)" if a in result.held_d0 else
             f"{a}: chi2 {f.chi2:.4g} dof {f.dof}; D0 error {f.slope_err:.3g}"
             for a, f in zip(AXES, d, strict=True)]
    extra += [f"bins (ppt): {_fmt(dm.centers, 4)}", f"N per bin: {_fmt(dm.count, 12)}",
              "C0 = cT(-50 C) of the fitted temperature law (held, eq. 5a)"]
    extra += d0_field_lines(result)
    rows = ["axis,C0,D0"] + [f"{a},{c:.4f},{s:.6f}" for a, c, s in zip(
        AXES, cal.duty_cycle_c0, cal.duty_cycle_d0, strict=True)]
    texts["offsets_duty_cycle"] = "\n".join(_header(
        "MESSENGER MAG steady-state offsets versus heater duty cycle (eq. 5a, 5b)",
        "MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, Table 3 form; 4-% bins, sqrt(N) "
        "weights, intercept held", version["offsets_duty_cycle"],
        base_files["offsets_duty_cycle"], base["offsets_duty_cycle"].header, provenance,
        ["units: C0 = counts (fine range); D0 = counts per part-per-1000 of duty cycle",
         *extra, *merit_lines(result)]) + rows) + "\n"
    # Tables 6-8 form
    bins = cal.heater_duty_bins_percent
    # the duty cycles the waveforms are fitted on, read back by `load_calibration`
    # (calibrating a heater-on sample outside it warns: `chain.warn_outside_duty_range`)
    d_range = result.duty_range
    d_line = ([f"# D_RANGE: {d_range[0]:g} {d_range[1]:g}"] if d_range is not None else [])
    part = waveform_part_line(result)
    for j, axis in enumerate(AXES):
        name = f"heater_signal_{axis}"
        table_no = 6 + j
        fitted = [f"{b:.0f}" for b, fit in zip(bins, result.waveform[j], strict=True) if fit]
        kept = [f"{b:.0f}" for b, fit in zip(bins, result.waveform[j], strict=True) if not fit]
        extra = [f"duty bins fitted (%): {' '.join(fitted) or 'none'}",
                 f"duty bins kept from {base_files[name].name} (too little data): "
                 f"{' '.join(kept) or 'none'}",
                 _duty_range_text(d_range),
                 f"N per duty bin: {_fmt([w.count.sum() for w in result.stats.waveform], 12)}",
                 "zero mean over the 100-s cycle (the mean belongs to the duty-cycle law)"]
        extra += [f"{b:.0f}%: chi2 {fit.chi2:.4g} dof {fit.dof:.4g} max error "
                  f"{np.max(fit.value_err):.3g}" for b, fit in zip(bins, result.waveform[j],
                                                                   strict=True) if fit]
        rows = ["t_s," + ",".join(f"{b:.0f}" for b in bins)] + [
            f"{t_s}," + ",".join(f"{v:.5f}" for v in cal.heater_signal[j, t_s])
            for t_s in range(cal.heater_signal.shape[1])]
        texts[name] = "\n".join(_header(
            f"MESSENGER MAG heater signal, sensor {axis.upper()} axis, counts (fine range)",
            f"MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Table {table_no} form;"
            " periodic smoothing spline of the phase-binned residual", version[name],
            base_files[name], base[name].header, provenance,
            ["units: counts; t_s = seconds since the heater-bit rising edge; columns = "
             "duty-cycle bin centres in percent", *extra, *merit_lines(result)]) + d_line
            + waveform_error_lines(result, j) + part + rows) + "\n"
    # processing: tau, dt and the look-back that follows tau replaced
    r = result.relaxation
    text = base_files["processing"].read_text()
    text = re.sub(r"(?m)^version\s*=.*$", f"version = {version['processing']}\n"
                  f'source = "{SOURCE} {software_version()}: [relaxation] tau_s, delay_s, '
                  f'look_back_s; the rest '
                  f'copied from {base_files["processing"].name}"', text, count=1)
    text = re.sub(r"(?m)^tau_s\s*=.*$", f"tau_s = {r.tau:.3f}  # fitted, error {r.tau_err:.3g} s",
                  text, count=1)
    look_back = float(cal.constants["relaxation"]["look_back_s"])
    text = re.sub(r"(?m)^look_back_s\s*=.*$", f"look_back_s = {look_back:.1f}  # follows the "
                  f"fitted tau (5000 s x tau / 872 s, at least 5000 s)", text, count=1)
    note = (f"fitted, error {r.dt_err:.3g} s" if result.delay_fitted
            else "held at the base value (the data did not determine it)")
    text = re.sub(r"(?m)^delay_s\s*=.*$", f"delay_s = {r.dt:.3f}  # {note}", text, count=1)
    text = text.rstrip("\n") + "\n\n" + dump_toml({"fit": {
        "source": SOURCE, "based_on": base_files["processing"].name,
        "based_on_sha256": sha256_file(base_files["processing"]),
        "tau_s": r.tau, "tau_err_s": r.tau_err, "delay_s": r.dt, "delay_err_s": r.dt_err,
        "delay_fitted": result.delay_fitted, "amplitude": r.amplitude,
        "amplitude_err": r.amplitude_err, "chi2": r.chi2, "dof": r.dof,
        "events": int(result.stats.n_samples.get("events", 0)),
        "intervals": str(provenance.get("intervals", "all data")),
        **({"passes_run": result.convergence["passes_run"],
            "converged": result.convergence["converged"],
            "stop": result.convergence["stop"]} if result.convergence else {}),
        **({"predicted_error_nt": result.merit["total_nt"],
            "error_goal_nt": result.merit["goal_nt"]} if "total_nt" in result.merit else {}),
    }}) + "\n"
    texts["processing"] = text
    report = fit_report(result, base_files, version, provenance)
    files = [File(f"{name}_v{version[name]}.{'toml' if name == 'processing' else 'csv'}",
                  texts[name]) for name in FITTED]
    files += [File(base_files[name].name, base_files[name].read_bytes())
              for name in ("latency", "gain_matrix")]
    files += [File("fit_report.toml", dump_toml(report) + "\n"),
              File("fit_report.txt", report_text(result, provenance) + "\n")]
    # one all-or-nothing group (the tables record their own provenance in their headers)
    written = write_declared(files, out, provenance=lambda product: {})
    return written


def waveform_error_lines(result: FitResult, axis: int) -> list[str]:
    """Header lines of one heater-signal file: its columns' stated errors (entry 32).

    ``# WAVEFORM_ERROR: e_1 ... e_n`` (counts, 1 sigma, rms over the phase; one per
    column, in the table's column order), read back by `load_calibration`
    (`MessengerCalibration.waveform_error`): calibrating a day computes the waveform
    part of its own duty-cycle mix from them (`chain.warn_waveform_part`).
    """
    err = result.waveform_error
    if err is None or not np.all(np.isfinite(err)):
        return []
    text = " ".join(f"{v:.4g}" for v in np.asarray(err, dtype=float)[axis])
    return [f"# {WAVEFORM_ERROR_KEY}: {text}"]


def waveform_part_line(result: FitResult) -> list[str]:
    """Header line: the waveform part of the stated prediction (nT, x y z), or none."""
    m = result.merit
    if (not m or "waveform_nt" not in m or result.waveform_error is None
            or not np.all(np.isfinite(m["waveform_nt"]))):
        return []
    return [f"# {WAVEFORM_PART_KEY}: " + " ".join(f"{v:.4g}" for v in m["waveform_nt"])]


def _duty_range_text(d_range: tuple[float, float] | None) -> str:
    """Return the duty-cycle range the waveforms are fitted on, with its rule (entry 25)."""
    if d_range is None:
        return "D_RANGE: none (no column fitted; every column kept from the base table)"
    return (f"D_RANGE {d_range[0]:g}..{d_range[1]:g} %: the duty cycles (lo <= d < hi) of "
            f"the contiguous fitted 4-% bins around the fullest (each bin's own samples in "
            f">= {MIN_PHASE_BINS} phase bins, its column fitted on every axis); outside it the "
            "pipeline extrapolates the columns (sec. 6) and nothing states the error")


def _range_line(result: FitResult) -> str:
    """Return the stated temperature range and the law's stated error at its ends."""
    ranges = result.stated_ranges
    lo, hi = result.fitted_range if ranges is None else ranges.span
    err = result.law_error(np.array([lo, hi]))
    data = result.merit.get("data_range_c") if result.merit else None
    stated = f"{lo:.0f}..{hi:.0f}" if ranges is None else str(ranges)
    narrowed = (f", narrowed from {data[0]:.0f}..{data[1]:.0f} C to the 1-C bins where the "
                "law's stated error, or that of the offset the table applies there (the law "
                "with D0 and tau as the fitted samples carry them), is within "
                f"{result.merit['band_limit_nt']:g} nT"
                if data is not None and (ranges is None or ranges.intervals
                                         != ((data[0], data[1]),)) else "")
    return (f"fitted range: {stated} C (5-C bins holding >= {MIN_RANGE_SAMPLES} "
            f"samples of accepted intervals{narrowed}); the law is not constrained outside "
            "it; stated "
            f"error at {lo:.0f} C {_fmt(err[0], 3)} counts, at {hi:.0f} C {_fmt(err[1], 3)} "
            "counts (x, y, z)")


def fit_report(result: FitResult, base_files: Mapping[str, Path], version: Mapping[str, int],
               provenance: Mapping[str, Any]) -> dict[str, Any]:
    """Return the ``fit_report.toml`` document (every number of the fit)."""
    cal = result.calibration
    st = result.stats
    doc: dict[str, Any] = {
        "source": f"{SOURCE} {software_version()}",
        "created": creation_time(),
        "command": str(provenance.get("command", "")),
        "intervals": str(provenance.get("intervals", "all data")),
        "days": list(st.days),
        "samples": {k: int(v) for k, v in sorted(st.n_samples.items())},
        "files": {n: (f"{n}_v{version[n]}." + ("toml" if n == "processing" else "csv"))
                  if n in version else base_files[n].name for n in base_files},
        "base": {p.name: sha256_file(p) for p in base_files.values()},
        "inputs": dict(sorted(provenance.get("inputs", {}).items())),
        "temperature": {
            "bin_centre_c": st.temperature.centers, "n": st.temperature.count,
            **{a: {"A0": f.a0, "B0": f.b0, "A1": f.a1, "B1": f.b1, "Tm": f.x_m,
                   "A0_err": f.a0_err, "B0_err": f.b0_err, "A1_err": f.a1_err,
                   "B1_err": f.b1_err, "Tm_err": f.x_m_err, "chi2": f.chi2, "dof": f.dof,
                   "bin_mean": st.temperature.mean()[:, j]}
               for j, (a, f) in enumerate(zip(AXES, result.temperature, strict=True))},
        },
        "duty_cycle": {
            "bin_centre_ppt": st.duty.centers, "n": st.duty.count,
            **{a: {"C0": f.intercept, "D0": f.slope, "D0_err": f.slope_err,
                   "D0_held": a in result.held_d0,
                   **({"D0_held_value": result.held[a][0], "D0_held_width": result.held[a][1]}
                      if a in result.held_d0 else {}),
                   "chi2": f.chi2,
                   "dof": f.dof, "bin_mean": st.duty.mean()[:, j]}
               for j, (a, f) in enumerate(zip(AXES, result.duty, strict=True))},
            **({"D0_along_field": result.d0_field} if result.d0_field else {}),
        },
        "relaxation": {
            "tau_s": result.relaxation.tau, "tau_err_s": result.relaxation.tau_err,
            "delay_s": result.relaxation.dt, "delay_err_s": result.relaxation.dt_err,
            "delay_fitted": result.delay_fitted, "amplitude": result.relaxation.amplitude,
            "chi2": result.relaxation.chi2, "dof": result.relaxation.dof,
            "events": int(st.n_samples.get("events", 0)),
            "lag_s": result.epoch_curve[:, 0], "normalised_epoch": result.epoch_curve[:, 1],
        },
        "waveform": {
            "duty_bins_percent": cal.heater_duty_bins_percent,
            "n": [int(w.count.sum()) for w in st.waveform],
            **({"D_RANGE": list(result.duty_range)} if result.duty_range is not None else {}),
            "duty_range_rule": _duty_range_text(result.duty_range),
            **{a: {"fitted": [fit is not None for fit in result.waveform[j]],
                   "rms_counts": np.sqrt(np.mean(cal.heater_signal[j, :100] ** 2, axis=0))}
               for j, a in enumerate(AXES)},
        },
        "passes": {f"pass_{p['pass']}": {k: v for k, v in p.items() if k != "pass"}
                   for p in result.passes},
        "estimator": result.estimator,
        "convergence": {k: v for k, v in result.convergence.items()},
        "merit": dict(result.merit),
    }
    doc["temperature"]["band_temperature_c"] = BAND_GRID_C
    band = result.law_error(BAND_GRID_C)
    for j, a in enumerate(AXES):
        doc["temperature"][a]["band_counts"] = band[:, j]
    v = result.variance
    if v is not None:
        doc["variance_intervals"] = {
            "accepted": int(np.count_nonzero(v.reason == "")), "total": int(v.reason.size),
            "rejected_by_reason": v.rejections(),
            "rejected_start_et": v.interval_start[v.reason != ""],
            "rejected_reason": [str(x) for x in v.reason[v.reason != ""]],
            "bootstrap_blocks": int(v.block_start.size),
            "interval_s": VarianceSettings().interval_s,
            "segment_s": VarianceSettings().segment_s, "segments": int(v.segments)}
        doc["temperature"]["fitted_range_c"] = list(result.fitted_range)
        ranges = result.stated_ranges
        # [[lo, hi], ...]: one or more intervals (entry 24)
        doc["temperature"]["T_RANGE"] = ([] if ranges is None else
                                         [list(pair) for pair in ranges.intervals])
        for a, h in result.held_upper.items():
            doc["temperature"][a].update({
                "upper_held": True, "Tm_held_value": h["Tm_c"][0],
                "Tm_held_width": h["Tm_c"][1], "slope_change_held_value":
                h["slope_change"][0], "slope_change_held_width": h["slope_change"][1]})
        doc["temperature"]["fitted_range_rule"] = (
            f"5-C bins holding >= {MIN_RANGE_SAMPLES} samples of accepted intervals")
        doc["temperature"]["variance_bin_edges_c"] = TEMPERATURE_EDGES_C
        doc["temperature"]["variance_bin_samples"] = v.temperature_count
    return _plain(doc)


def _plain(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def report_text(result: FitResult, provenance: Mapping[str, Any]) -> str:
    """Return the human summary ``fit_report.txt``."""
    cal = result.calibration
    st = result.stats
    r = result.relaxation
    lines = [
        f"MESSENGER MAG in-flight calibration ({SOURCE} {software_version()})",
        # the --input files are one reduction labelled "files", whatever days they span
        ("days: the --input files, one reduction" if list(st.days) == ["files"] else
         f"days: {len(st.days)} ({', '.join(st.days[:3])}"
         f"{' ...' if len(st.days) > 3 else ''})"),
        f"intervals: {provenance.get('intervals', 'all data')}",
        f"samples used: {st.n_samples.get('used', 0)} of {st.n_samples.get('total', 0)} "
        f"(coarse {st.n_samples.get('coarse', 0)}, outside intervals "
        f"{st.n_samples.get('outside_intervals', 0)}, before V10 "
        f"{st.n_samples.get('before_v10', 0)})",
        f"estimator: {result.estimator} (temperature law, D0, tau, dt; "
        + (f"|B| least variable within {VarianceSettings().segment_s:g}-s segments of the "
           "accepted intervals: rotations at nearly constant |B|)"
           if result.estimator == "variance" else
           "long-term averages: the field averages to zero over each bin's samples)"),
    ]
    v = result.variance
    if v is not None:
        accepted = int(np.count_nonzero(v.reason == ""))
        lines.append(f"intervals: {accepted} accepted of {v.reason.size}; rejected by "
                     f"reason: {v.rejections() or 'none'}; errors: bootstrap over "
                     f"{v.block_start.size} blocks")
        bad = np.flatnonzero(v.reason != "")
        lines += [f"  rejected: interval at ET {v.interval_start[i]:.0f} s: {v.reason[i]}"
                  for i in bad[:20]]
        if bad.size > 20:
            lines.append(f"  ... and {bad.size - 20} more")
    lines += [
        "",
        "temperature law (Table 2 form, fine counts):",
    ]
    if result.estimator == "variance":
        lines.append(f"  {_range_line(result)}")
        lines += [f"  {x}" for x in held_upper_lines(result)]
    for a, f in zip(AXES, result.temperature, strict=True):
        lines.append(f"  {a}: A0 {f.a0:9.3f} +- {f.a0_err:.3f}  B0 {f.b0:7.4f} +- {f.b0_err:.4f}"
                     f"  A1 {f.a1:9.3f} +- {f.a1_err:.3f}  B1 {f.b1:7.4f} +- {f.b1_err:.4f}"
                     f"  Tm {f.x_m:7.2f} +- {f.x_m_err:.2f} C")
    lines.append("duty-cycle law (Table 3 form):")
    for a, f in zip(AXES, result.duty, strict=True):
        d0 = (f"D0 {f.slope:.5f} +- {f.slope_err:.5f} (held at {result.held[a][0]:.5g} +- "
              f"{result.held[a][1]:.3g}: --hold-d0)" if a in result.held_d0
              else f"D0 {f.slope:.5f} +- {f.slope_err:.5f}")
        lines.append(f"  {a}: C0 {f.intercept:9.3f} (held)  {d0}")
    lines.append(f"relaxation: tau {r.tau:.1f} +- {r.tau_err:.1f} s; dt {r.dt:.1f} s "
                 + (f"+- {r.dt_err:.1f} (fitted)" if result.delay_fitted else "(held)")
                 + f"; {st.n_samples.get('events', 0)} duty-cycle changes")
    lines.append("heater waveform rms (counts) per duty bin "
                 + " ".join(f"{b:.0f}%" for b in cal.heater_duty_bins_percent) + ":")
    for j, a in enumerate(AXES):
        rms = np.sqrt(np.mean(cal.heater_signal[j, :100] ** 2, axis=0))
        marks = ["" if fit else "*" for fit in result.waveform[j]]
        lines.append(f"  {a}: " + " ".join(f"{v:.2f}{m}" for v, m in zip(rms, marks,
                                                                         strict=True)))
    lines.append("  (* kept from the base table: too little data)")
    lines.append(f"  {_duty_range_text(result.duty_range)}")
    lines.append("passes: " + "; ".join(
        f"{p['pass']}: tau {p['tau_s']} s, D0 {p['D0']}" for p in result.passes))
    if result.convergence:
        lines.append(f"  {result.convergence['stop']}")
        lines.append(f"  (converged: {result.convergence['criterion']})")
    if result.estimator == "variance":
        lines += [f"  {x}" for x in band_lines(result)]
    m = result.merit
    if m and "total_nt" in m:
        lines.append(
            "predicted error of a recalibrated day (nT rms, x / y / z): "
            + " / ".join(f"{v:.3f}" for v in m["total_nt"]) + f" (goal {m['goal_nt']:g}); law "
            + " / ".join(f"{v:.3f}" for v in m["law_nt"]) + ", D0 "
            + " / ".join(f"{v:.3f}" for v in m["d0_nt"]) + ", tau and dt "
            + " / ".join(f"{v:.3f}" for v in m["relaxation_nt"]) + ", waveforms "
            + " / ".join(f"{v:.3f}" for v in m["waveform_nt"]))
        lines += [x for x in merit_lines(result) if x.startswith(("the predicted error holds",
                                                                   "the predicted error's"))]
    lines += goal_confidence_lines(result)
    return "\n".join(lines)
