"""The whole MESSENGER MAG EDR -> CDR chain on in-memory datasets.

`calibrate` runs the pure levels (`fluxcal.missions.messenger.levels`, each
``Dataset -> Dataset``) in the order of sec. 5-13 and warns where a day's samples lie
outside what the calibration tables state (`warn_outside_range` and its uses,
`warn_unseen_duty_cycle`, `warn_waveform_part`).  Reading the streams and writing the
products around it is `fluxcal.missions.messenger.run` on the generic driver
(`fluxcal.missions.messenger.routes`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import xarray as xr

from fluxcal.calibration.heater_error import (
    duty_bin_counts,
    exceeds_stated,
    part_scatter,
    waveform_part,
)
from fluxcal.calibration.heater_signal import HeaterPeriods, period_index
from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel, et_to_utc
from fluxcal.missions.messenger import defects, levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.fit_reduce import WAVEFORM_FOLDS
from fluxcal.missions.messenger.options import DEFAULT_FRAMES
from fluxcal.version import software_version

log = logging.getLogger(__name__)


#: Intermediates of sec. 6-9 that no product, offset report (``et``, ``rate``, ``sunlit``,
#: ``offset``) or quicklook reads, by the last step that needs them: dropped after
#: `levels.counts_to_field`, and after `levels.assign_quality`, when `calibrate` is
#: called with ``keep_intermediates=False`` (about 280 MB of a 20 Hz day).
UNWRITTEN_BEFORE_GEOMETRY = ("heater_signal", "temperature", "offset_applied",
                             "counts_corrected", "lag")
UNWRITTEN_AFTER_QUALITY = ("heater_applied", "duty_cycle_offset", "b_sensor", "sun_sc")


def check_frames(frames: Sequence[str]) -> None:
    """Refuse a frame key that is not one of `levels.FRAMES` (one line, field ``frames``)."""
    unknown = set(frames) - set(levels.FRAMES)
    if unknown:
        raise InputFormatError(
            f"unknown frame(s) {', '.join(map(repr, sorted(map(str, unknown))))}; expected some of "
            f"{', '.join(sorted(levels.FRAMES))}",
            field="frames",
        )


def calibrate(
    science: xr.Dataset,
    heater: xr.Dataset,
    temperature: xr.Dataset,
    cal: MessengerCalibration,
    *,
    frames: tuple[str, ...] = DEFAULT_FRAMES,
    max_offset_step: float | None = 2.0,
    method: str = "interpolate",
    keep_intermediates: bool = True,
) -> xr.Dataset:
    """Run sec. 5-13 on raw streams; kernels must be loaded (`KernelPool`).

    Parameters
    ----------
    science, heater, temperature : xarray.Dataset
        Raw streams as returned by `fluxcal.missions.messenger.readers`.
    cal : MessengerCalibration
        Calibration valid for the day (`load_calibration`).
    frames : tuple of str
        Keys of `levels.FRAMES` to produce.
    max_offset_step : float or None
        Smoothness threshold (counts) of sec. 13; ``None`` skips the check.
    method : {"interpolate", "oracle"}
        Geometry evaluation: vectorized (default) or one SPICE call per sample.
    keep_intermediates : bool
        ``False`` drops the steps no product reads (`UNWRITTEN_BEFORE_GEOMETRY`,
        `UNWRITTEN_AFTER_QUALITY`) as soon as they are used (lower peak memory).

    Returns
    -------
    xarray.Dataset
        Every intermediate (unless ``keep_intermediates`` is false) and final variable;
        attrs carry provenance and the offset step report.

    Raises
    ------
    ValidationError
        When the offsets are not smooth (sec. 13).
    """
    check_frames(frames)
    if science.sizes.get("time", 0) == 0:
        raise InputFormatError("no science samples", field="met")
    sclk = SclkKernel.from_pool(levels.SC_ID)
    ds = levels.correct_time(science, cal, sclk)
    levels.check_heater_coverage(ds, heater, cal, sclk)
    periods, changes = levels.find_heater_periods(heater, cal, sclk)
    warn_unseen_duty_cycle(ds, heater, changes, cal, sclk)
    ds = levels.correct_heater_signal(ds, periods, cal)
    warn_outside_duty_range(ds, periods, cal)
    ds = levels.mark_sunlit(ds, cal, method=method)
    temperature = defects.drop_temperature_glitches(temperature)  # issue 23
    ds = levels.correct_offsets(ds, temperature, changes, cal, sclk)
    warn_outside_temperature_range(ds, cal)
    warn_waveform_part(ds, periods, cal)
    ds = levels.counts_to_field(ds, cal)
    if not keep_intermediates:
        ds = ds.drop_vars(UNWRITTEN_BEFORE_GEOMETRY)
    ds = levels.add_geometry(ds, cal, frames, method=method)
    ds = levels.assign_quality(ds, cal)
    ds = defects.flag_defects(ds, heater, temperature, cal, sclk)  # issue 23
    if not keep_intermediates:
        ds = ds.drop_vars(UNWRITTEN_AFTER_QUALITY)
    report = (
        levels.validate_offsets(ds, max_offset_step)
        if max_offset_step is not None
        else levels.offset_step_report(ds)
    )
    ds.attrs.update(
        software_version=f"fluxcal {software_version()}",
        calibration_files=cal.provenance(),
        offset_largest_step_counts=", ".join(
            f"{a}: {r['step_counts']:.4f}" for a, r in report.items()
        ),
        heater_periods=int(len(periods)),
        duty_cycle_changes=int(len(changes)),
        references="MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016)",
    )
    for key in ("defect_spans", "defect_records"):  # last: after any attribute that
        if key in ds.attrs:  # `levels.note_mbf_rotation` places before software_version
            ds.attrs[key] = ds.attrs.pop(key)
    log.info("calibrated %d samples, %d heater periods", ds.sizes["time"], len(periods))
    return ds


def warn_unseen_duty_cycle(
    ds: xr.Dataset, heater: xr.Dataset, changes, cal: MessengerCalibration, sclk: SclkKernel
) -> bool:
    """Warn when the duty cycle assumed before the heater stream enters the science.

    A heater stream that starts inside heater operation has its first duty cycle taken
    as steady before it (a change at ``-inf``, `levels.find_heater_periods`).  That
    assumption matters only for heater-modelled (V10) samples less than the sec. 7
    look-back interval (``look_back_s``, 5000 s) after the first heater record: later
    samples see it decayed by at least exp(-5000 s / 872 s) = 0.3 %, the look-back's own
    truncation.  A batch day given the previous day's heater file is therefore quiet.

    Returns
    -------
    bool
        Whether the warning was logged.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7.
    """
    if not len(changes) or not np.isneginf(changes.time[0]) or heater.sizes.get(
            "heater_time", 0) == 0:
        return False
    t0 = float(levels.aux_times_et(heater.isel(heater_time=slice(0, 1)), sclk)[0])
    et = ds["et"].values
    look_back_s = float(cal.constants["relaxation"]["look_back_s"])
    hit = (et >= levels._date_et(cal, "heater_mode_v10")) & (et < t0 + look_back_s)
    if not hit.any():
        return False
    first_file = str(heater.attrs.get("inputs", "in memory")).split(";")[0]
    log.warning(
        "the heater stream starts inside heater operation (first file %s): the duty cycle "
        "before it (%.0f ppt) is taken as steady for %d science samples within the sec. 7 "
        "look-back (%.0f s) of its start; give the previous day's heater file",
        first_file, changes.duty_cycle_ppt[0], int(hit.sum()), look_back_s,
    )
    return True


def warn_outside_range(values: np.ndarray, stated: StatedRanges | tuple[float, float] | None,
                       *, samples: str, quantity: str, key: str, unit: str, table: str,
                       consequence: str, gap_consequence: str | None = None,
                       upper_open: bool = False) -> bool:
    """Warn once when ``values`` lie outside the range(s) a calibration table states.

    One implementation for every stated range (``T_RANGE``, ``D_RANGE``): the warning
    counts the values outside ``stated`` (`StatedRanges.contains`; NaN is not judged)
    among all ``values`` and says how far below and above the range they reach and,
    with several intervals, how many lie in the gaps between them and how far from the
    nearest.  ``upper_open``: the range's upper end is excluded (``lo <= v < hi``).

    Returns
    -------
    bool
        True when it warned; False for no stated range or every value inside.
    """
    if stated is None:
        return False
    ranges = StatedRanges.of(stated)
    lo, hi = ranges.span
    v = np.asarray(values, dtype=float)
    inside = ranges.contains(v)
    if upper_open:
        inside &= v < hi
    outside = ~inside & ~np.isnan(v)
    n = int(outside.sum())
    if n == 0:
        return False
    below = outside & (v < lo)
    above = outside & (v >= hi)
    gap = outside & ~below & ~above
    far = []
    if below.any():
        low = float(v[below].min())
        far.append(f"down to {low:.1f} {unit} ({lo - low:.1f} {unit} below)")
    if above.any():
        high = float(v[above].max())
        far.append(f"up to {high:.1f} {unit} ({high - hi:.1f} {unit} above)")
    if gap.any():
        far.append(f"{int(gap.sum())} in the gaps between its intervals (up to "
                   f"{float(ranges.distance(v[gap]).max()):.1f} {unit} from the nearest)")
    edge = ", upper edge excluded" if upper_open else ""
    how = gap_consequence if gap.any() and gap_consequence else consequence
    log.warning("%d of %d %s lie at %s outside the range %s states (%s %s %s%s), %s: %s",
                n, v.size, samples, quantity, table, key, f"{ranges:.1f}", unit, edge,
                " and ".join(far), how)
    return True


def _table_name(cal: MessengerCalibration, stem: str, default: str) -> str:
    """Return the file name of the calibration table ``stem`` in use (for a warning)."""
    return next((f for f, _ in cal.files if f.startswith(stem)), default)


def warn_outside_temperature_range(ds: xr.Dataset, cal: MessengerCalibration) -> bool:
    """Warn when samples lie outside the temperatures the Table 2 file states.

    A fitted Table 2 states ``T_RANGE`` (`MessengerCalibration.temperature_range`, one
    or more intervals), the sensor temperatures over which its law is determined;
    outside it the law is extrapolated, or between two intervals poorly determined
    (issue 34, docs/decisions/messenger_fit.md entries 21 and 24).  The warning
    counts the samples (`StatedRanges.contains`) and says how far below and above the
    range they reach and, with several intervals, how many lie in the gaps between
    them and how far from the nearest interval (`warn_outside_range`).

    Returns
    -------
    bool
        True when it warned; False for a table without ``T_RANGE`` or every sample inside.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3-4, Table 2.
    """
    if "temperature" not in ds:
        return False
    return warn_outside_range(
        ds["temperature"].values, cal.temperature_range, samples="samples",
        quantity="sensor temperatures", key="T_RANGE", unit="C",
        table=_table_name(cal, "offsets_temperature", "Table 2"),
        consequence="the temperature law is extrapolated there (its header states the error)",
        gap_consequence="the temperature law is extrapolated there or, in the gaps, "
                        "determined less well than the limit its header states (its header "
                        "states the error)")


def warn_outside_duty_range(ds: xr.Dataset, periods: HeaterPeriods,
                            cal: MessengerCalibration) -> bool:
    """Warn when heater-on samples lie at duty cycles outside the stated waveform range.

    Fitted heater-signal tables state ``D_RANGE`` (`MessengerCalibration.duty_range`,
    percent, ``lo <= d < hi``), the duty cycles whose samples determined the waveform
    columns; outside it the pipeline extrapolates the columns (sec. 6: the 36-40 %
    slope above 40 %) and no table states the error (issue 34, entry 25; in the
    Mercury-orbit world 0.1-0.3 nT there).  The warning counts the samples whose heater
    signal is subtracted (``heater_applied``) in periods of a duty cycle outside the
    range, and says how far (`warn_outside_range`).  No quality flag is set: Table 5's
    contamination digit already says "corrected", which these samples are.

    Returns
    -------
    bool
        True when it warned; False for tables without ``D_RANGE``, no heater-on sample,
        or every heater-on sample inside.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    if cal.duty_range is None or "heater_applied" not in ds or not len(periods):
        return False
    applied = ds["heater_applied"].values.astype(bool)
    if not applied.any():
        return False
    k = period_index(ds["et"].values[applied], periods)
    duty = np.where(k >= 0, np.asarray(periods.duty_cycle)[np.maximum(k, 0)] * 100.0, np.nan)
    return warn_outside_range(
        duty[np.isfinite(duty)], cal.duty_range, samples="heater-on samples",
        quantity="heater duty cycles", key="D_RANGE", unit="%",
        table=_table_name(cal, "heater_signal", "Tables 6-8"),
        consequence="the heater waveform is extrapolated there beyond the fitted columns "
                    "(sec. 6; no table states its error)", upper_open=True)


def day_waveform_part(ds: xr.Dataset, periods: HeaterPeriods, cal: MessengerCalibration
                      ) -> tuple[np.ndarray, dict[str, int | float]] | None:
    """Return the heater waveforms' error (nT, sensor x y z) this day's duty cycles give.

    The columns' stated errors (`MessengerCalibration.waveform_error`) weighted by the
    day's own heater-on samples per duty bin (`heater_error.waveform_part`), over the
    fine-range samples inside ``T_RANGE``, the heater-on ones outside ``D_RANGE`` left
    out (as the fit's prediction holds, docs/decisions/messenger_fit.md entries 25 and
    32).  None without stated column errors or samples.  Also returned: the
    counts (``samples``, ``heater_on``) and the duty bin (%) holding most heater-on
    samples (``fullest_pct``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 8 eq. 8, Appendix
       Tables 6-8.
    """
    if cal.waveform_error is None or "heater_applied" not in ds or "temperature" not in ds:
        return None
    use = ds["range"].values == 0 if "range" in ds else np.ones(ds.sizes["time"], dtype=bool)
    temp = ds["temperature"].values
    use &= np.isfinite(temp)
    if cal.temperature_range is not None:
        use &= cal.temperature_range.contains(temp)
    on = use & ds["heater_applied"].values.astype(bool)
    bins = np.asarray(cal.heater_duty_bins_percent, dtype=float)
    duty = np.full(int(on.sum()), np.nan)
    if len(periods) and on.any():
        k = period_index(ds["et"].values[on], periods)
        duty = np.where(k >= 0, np.asarray(periods.duty_cycle)[np.maximum(k, 0)] * 100.0,
                        np.nan)
    counts, beyond = duty_bin_counts(duty, bins)
    inside = np.ones(bins.size, dtype=bool)
    if cal.duty_range is not None:
        inside = (bins > cal.duty_range[0]) & (bins < cal.duty_range[1])
    n = float(use.sum()) - float(counts[~inside].sum()) - beyond
    if n <= 0:
        return None
    counts = np.where(inside, counts, 0.0)
    part = waveform_part(cal.waveform_error, counts, n, np.asarray(cal.matrices[0]))
    return part, {"samples": int(n), "heater_on": int(counts.sum()),
                  "fullest_pct": float(bins[int(np.argmax(counts))])}


def warn_waveform_part(ds: xr.Dataset, periods: HeaterPeriods,
                       cal: MessengerCalibration) -> bool:
    """Warn when this day's duty cycles put its error beyond what the table states.

    A fitted table states the waveform part of its predicted error
    (``WAVEFORM_PART_NT``, `MessengerCalibration.waveform_part_nt`) for the duty-cycle
    mix it was stated for, each column's error (``WAVEFORM_ERROR``), and in its
    processing file the predicted error and the goal it was accepted at (``[fit]``
    ``predicted_error_nt``, ``error_goal_nt``).  A day that spends its heater-on time
    in worse-determined columns carries more (`day_waveform_part`): its own total is
    the stated one with the day's waveform part (`heater_error.day_total`).  It warns
    when, on some axis, that total exceeds the goal, or exceeds the stated total by
    more than the stated part's own scatter (`heater_error.part_scatter`, the columns'
    jackknife over `WAVEFORM_FOLDS` folds: 0.41 of the part); a day within both is what
    the table states (docs/decisions/messenger_fit.md entries 32 and 36).  A table
    without ``[fit]`` numbers is judged with its waveform part as the whole total and
    no goal.  The one line gives the day's part, the stated part and its scatter, the
    day's total, the stated total and the goal (nT, x / y / z).

    Returns
    -------
    bool
        True when it warned; False for tables without the two header fields, or a day
        within.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    stated = cal.waveform_part_nt
    got = day_waveform_part(ds, periods, cal)
    if stated is None or got is None:
        return False
    part, n = got
    stated = np.asarray(stated, dtype=float)
    total, goal = _stated_total_and_goal(cal, stated)
    beyond, day_total = exceeds_stated(part, stated, total, goal, WAVEFORM_FOLDS)
    if not beyond.any():
        return False
    over_goal = day_total > goal
    reasons = (["above the goal"] if over_goal.any() else []) + (
        ["beyond the table's by more than the part's scatter"]
        if np.any(beyond & ~over_goal) else [])

    def nt(v):
        return " / ".join(f"{x:.3f}" for x in v)

    log.warning("the heater waveforms' error on this day's %d samples (fine range, inside "
                "T_RANGE and D_RANGE; %d heater-on, most at the %g-%% column) is %s nT (x "
                "/ y / z) from its duty cycles, against the %s nT +- %s %s states "
                "(WAVEFORM_PART_NT; +- its columns' jackknife scatter over %d folds, "
                "WAVEFORM_ERROR): the day's predicted error is %s nT against the table's "
                "%s nT and %s, %s (sec. 6)",
                n["samples"], n["heater_on"], n["fullest_pct"], nt(part), nt(stated),
                nt(part_scatter(stated, WAVEFORM_FOLDS)),
                _table_name(cal, "heater_signal", "Tables 6-8"), WAVEFORM_FOLDS,
                nt(day_total), nt(total),
                f"its goal {goal:g} nT" if np.isfinite(goal) else "no goal stated",
                " and ".join(reasons))
    return True


def _stated_total_and_goal(cal: MessengerCalibration, stated_part: np.ndarray
                           ) -> tuple[np.ndarray, float]:
    """Return the table's stated predicted error (nT, x y z) and goal (nT) from ``[fit]``.

    Written by `fit_write` (``predicted_error_nt``, ``error_goal_nt``).  Absent (the
    seed's tables, fits before they were written): the waveform part stands for the
    total and there is no goal (``inf``); so too ``nan`` on every axis, the fit's own
    "no figure" (`fit_merit.predicted_error` without a bootstrap), and a goal of
    ``inf``.  Present but not three positive numbers (or three ``nan``) and one positive
    number: `InputFormatError` naming the processing file and the field, not a quieter
    warning.
    """
    fit = cal.constants.get("fit") if isinstance(cal.constants, dict) else None
    if not isinstance(fit, dict) or "predicted_error_nt" not in fit:
        return stated_part, np.inf
    where = str(next((q for q in cal.paths if q.name.startswith("processing")),
                     _table_name(cal, "processing", "the processing file")))

    def numbers(key: str, shape: tuple[int, ...], text: str) -> np.ndarray:
        try:
            v = np.asarray(fit[key], dtype=float)
        except (TypeError, ValueError):
            v = np.full(1, -1.0)
        if v.shape != shape or not (np.all(np.isnan(v)) or np.all(v > 0)):
            raise InputFormatError(f"{key} = {fit[key]!r}: expected {text} (written by "
                                   "`messenger fit`; entry 36)", path=where,
                                   field=f"[fit] {key}")
        return v

    total = numbers("predicted_error_nt", (3,), "three positive numbers in nT (x, y, z)")
    if np.all(np.isnan(total)):
        total = stated_part
    if "error_goal_nt" not in fit:
        return total, np.inf
    goal = float(numbers("error_goal_nt", (), "one positive number in nT"))
    return total, goal if goal > 0 else np.inf


def day_of(science: xr.Dataset) -> np.datetime64:
    """Return the UTC instant of the first science sample (selects the calibration)."""
    sclk = SclkKernel.from_pool(levels.SC_ID)
    et = sclk.to_et(science["partition"].values[:1], science["met"].values[:1])
    return np.datetime64(str(et_to_utc(et, digits=0)[0]), "s")
