"""``edr2cdr`` as a function: calibrate the streams, then declare every day's outputs.

The driver (`fluxcal.runs.driver`) writes what `run_products` declares.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.calibration.gain_matrix import counts_to_nt
from fluxcal.errors import InputFormatError, ValidationError
from fluxcal.geometry.days import from_day_of_year
from fluxcal.geometry.time import utc_to_et
from fluxcal.missions.messenger import defects, levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration, load_calibration
from fluxcal.missions.messenger.chain import calibrate, check_frames, day_of
from fluxcal.missions.messenger.levels import calibration_frames, note_mbf_rotation
from fluxcal.missions.messenger.options import (
    DEFAULT_FRAMES,
    FORMATS,
    REPORT_FIGURE,
    MessengerOptions,
)
from fluxcal.missions.messenger.products import (
    Progress,
    day_code,
    day_products,
    quicklook,
    recorded_et,
    split_days,
)
from fluxcal.missions.messenger.validation_report import load_figure_support, report_files
from fluxcal.products.declared import Declared, Refused

log = logging.getLogger(__name__)


def prepare_formats(formats: Sequence[str]) -> None:
    """Refuse a format not in `FORMATS` (one line, field ``formats``); load the figure's support.

    For every route that writes MESSENGER products to call before it reads any data
    (`load_figure_support` when the report's figure is asked for).
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise InputFormatError(f"unknown format(s) {', '.join(map(str, unknown))}; "
                               f"expected some of {', '.join(FORMATS)}",
                               field="formats")
    if REPORT_FIGURE in formats:
        load_figure_support()  # before any data exists (see there)


#: Raw telemetry columns of the science stream that no product, report or quicklook
#: reads after calibration (33 MB of a 20 Hz day): dropped from the calibrated run.
RAW_UNWRITTEN = ("counts", "met", "partition", "range")


def calibrate_run(
    sci: xr.Dataset,
    heat: xr.Dataset,
    temp: xr.Dataset,
    *,
    frames: Sequence[str] = DEFAULT_FRAMES,
    quicklook_frame: str | None = None,
    calibration_folder: Path | None = None,
    progress: Progress | None = None,
) -> tuple[xr.Dataset, MessengerCalibration]:
    """Calibrate loaded streams (kernels loaded) for the products of ``frames``.

    The run keeps the J2000 (and, for an SC product, the spacecraft) field, the Sun and
    Mercury positions of `levels.calibration_frames`; each product frame is
    computed when its products are written (`levels.frame_variables`), so the
    run never holds every frame at once.  The raw columns no output reads
    (`RAW_UNWRITTEN`) are dropped: once the caller drops the streams too, their memory
    is free.  With ``quicklook_frame`` the applied offsets in nT (``offset_nt``, fine
    range, eq. 8, Table 4) are added for the quicklook.

    Returns
    -------
    xarray.Dataset, MessengerCalibration
        The calibrated run and the calibration used.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-12.
    """
    if quicklook_frame is not None and quicklook_frame not in levels.FRAMES:
        raise InputFormatError(
            f"quicklook frame {quicklook_frame!r}; expected one of "
            f"{', '.join(sorted(levels.FRAMES))}",
            field="quicklook_frame",
        )
    check_frames(frames)
    cal = load_calibration(day_of(sci), calibration_folder)
    log.info("calibration tables: %s", ", ".join(f"{name} v{version}"
                                                 for name, version in cal.files))
    if progress is not None:
        progress("calibrating (sec. 5-12)", 0, 1)
    wanted = tuple(frames) + ((quicklook_frame,) if quicklook_frame is not None else ())
    ds = calibrate(sci, heat, temp, cal, frames=calibration_frames(wanted),
                   max_offset_step=None, keep_intermediates=False)
    ds = note_mbf_rotation(ds.drop_vars([v for v in RAW_UNWRITTEN if v in ds]), wanted)
    if quicklook_frame is not None:  # the quicklook's offsets in nT: fine-range matrix of eq. 8
        fine = np.zeros(ds.sizes["time"], dtype=np.int8)
        ds = ds.assign(offset_nt=(("time", "component"), counts_to_nt(
            ds["offset"].values, fine, cal.matrices), {"units": "nT"}))
    if progress is not None:
        progress("calibrated", 1, 1)
    return ds, cal


def run_products(ds: xr.Dataset, cal: MessengerCalibration,
                 options: MessengerOptions) -> Iterator[Declared]:
    """Declare every day's outputs of a calibrated run (`calibrate_run`), day after day.

    A day (`split_days`; a lag-sized fragment recorded just after a midnight joins its
    day first, `merge_fragment_days`, as a batch day decides it, `batch_day_rows`) is
    checked (sec. 13), then declares its products (`day_products`), its offset report
    (`report_files`) and, with ``options.quicklook``, its quicklook (`quicklook`).  A day
    that fails the check is `Refused`: nothing of it is written, the other days are, then
    `ValidationError` names every failed day (`fluxcal.products.declared.write_declared`).
    """
    days = merge_fragment_days(ds, split_days(ds), float(np.max(cal.net_lag_s)))
    spans = defects.span_records(ds)
    attrs = {"calibration_tables": cal.provenance()}
    look = quicklook_frame_of(options.frames, options.quicklook, options.quicklook_frame)
    for day in days:
        # each day's products and report list the defect spans that touch it (issue 23)
        day = defects.set_span_attrs(day, defects.day_spans(spans, day["et"].values))
        yield from _day_outputs(day, options, attrs, look)


def _day_outputs(day: xr.Dataset, options: MessengerOptions, attrs: Mapping[str, Any],
                 quicklook_frame: str | None) -> Iterator[Declared]:
    """One day's declarations: refused when its offsets fail sec. 13, else every output."""
    year, doy, yyddd = day_code(day)
    date = from_day_of_year(year, doy)
    threshold = options.max_offset_step
    try:
        steps = levels.validate_offsets(day, threshold) if threshold is not None else None
    except ValidationError as exc:
        log.error("day %s failed validation: %s", yyddd, exc)
        yield Refused(ValidationError(f"day {yyddd}: {exc}"), date)
        return
    products = [f for f in options.formats if f != REPORT_FIGURE]
    yield from day_products(day, options.frames, products, options.averages, options.version,
                            attrs)
    yield from report_files(day, f"MAGOFFSETS{yyddd}", threshold, steps, date,
                            figure=REPORT_FIGURE in options.formats)
    if quicklook_frame is not None:
        yield quicklook(day, quicklook_frame, date)


def quicklook_frame_of(frames: Sequence[str], quicklook: bool,
                       quicklook_frame: str | None) -> str | None:
    """Frame of the quicklook: ``quicklook_frame``, else the first of ``frames`` (else MSO).

    ``None`` without ``quicklook``.
    """
    if not quicklook:
        return None
    return quicklook_frame or (frames[0] if frames else "mso")


def _is_fragment(recorded_et: np.ndarray, midnight_et: float, max_lag_s: float) -> bool:
    """Whether samples (all of one UTC day) were all recorded within ``max_lag_s`` of its start."""
    return recorded_et.size > 0 and float(recorded_et.max()) - midnight_et < max_lag_s


def merge_fragment_days(
    ds: xr.Dataset, days: list[xr.Dataset], max_lag_s: float
) -> list[xr.Dataset]:
    """Merge each EDR day that is only a lag-sized fragment into the whole day before it.

    A product day holds the samples recorded (EDR time) in that UTC day (`split_days`).
    An input cut at midnight of the corrected (true) time, as a simulation or a
    hand-made extract is, leaves its last samples recorded up to one net lag
    (Table 1, at most 2.358 s) after that midnight; they would make a whole second
    product set of a few samples.  A day whose samples were all recorded less than
    ``max_lag_s`` after its midnight joins the product of the day before it when that
    day is in the data and is not such a fragment itself (a warning says how many); the
    field values are untouched (0 nT), the product then ends at most ``max_lag_s``
    after its UTC day (docs/decisions/messenger.md).  The rule looks at the two days
    only, so a batch day decides it as a run of every file does
    (`batch_day_rows`, docs/decisions/products.md).

    Parameters
    ----------
    ds : xarray.Dataset
        The calibrated run, of which ``days`` are consecutive slices.
    days : list of xarray.Dataset
        `split_days` of ``ds``.
    max_lag_s : float
        Largest net lag of the calibration (s).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (Table 1 net lags).
    """
    if len(days) < 2:
        return days
    dates = [from_day_of_year(*day_code(d)[:2]) for d in days]
    midnights = utc_to_et(np.array([f"{d}T00:00:00" for d in dates]))
    fragment = [_is_fragment(recorded_et(d), float(m), max_lag_s)
                for d, m in zip(days, midnights, strict=True)]
    starts = np.cumsum([0] + [d.sizes["time"] for d in days])
    groups: list[list[int]] = []
    for k in range(len(days)):
        if (k and fragment[k] and not fragment[k - 1]
                and dates[k] - dates[k - 1] == np.timedelta64(1, "D")):
            log.warning(
                "%d sample(s) recorded less than %.3f s (the largest net lag) after %s "
                "00:00 UTC join the previous day's product instead of making a product "
                "set of their own", days[k].sizes["time"], max_lag_s, dates[k])
            groups[-1][1] = k
        else:
            groups.append([k, k])
    return [days[a] if a == b else ds.isel(time=slice(int(starts[a]), int(starts[b + 1])))
            for a, b in groups]


def batch_day_rows(recorded_et: np.ndarray, day: _dt.date, max_lag_s: float,
                   context_et: np.ndarray | None = None) -> tuple[np.ndarray, str | None]:
    """Select the science samples a batch day's products hold, of all the samples it read.

    A batch day reads the science files of the day before, the day and the day after
    (a file may hold samples of the days beside its own: a stream across midnight given
    as one day's files); it keeps the samples recorded in its own UTC day, so every
    sample goes to the product of its recorded day whichever file holds it, as in a run
    of all the files (`split_days`).  The lag-sized fragments of `merge_fragment_days`
    follow the same rule: the next day's samples join this day when they are only such
    a fragment and this day is not; this day's own samples, when they are a fragment
    and the day before is not, are left to the day before (returned as no row, with the
    reason).

    Parameters
    ----------
    recorded_et : ndarray
        Recorded (EDR) ET of every science sample read (s).
    day : datetime.date
        The batch day.
    max_lag_s : float
        Largest net lag of the calibration (s, Table 1).
    context_et : ndarray, optional
        Recorded ET of samples not read, for the fragment decisions only: the first and
        last samples of a neighbour's file that holds none of this day's (`batch_day`),
        which decide them as all its samples would (its records are in time order).

    Returns
    -------
    ndarray of bool, str or None
        The rows of ``recorded_et`` to keep; why none are kept when the day's samples
        join the day before.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (EDR day, Table 1 net lags).
    """
    one = _dt.timedelta(days=1)
    m = utc_to_et(np.array([f"{day + k * one}T00:00:00" for k in (-1, 0, 1, 2)]))
    n = np.size(recorded_et)
    rec = np.concatenate([np.asarray(recorded_et, dtype=float),
                          np.asarray([] if context_et is None else context_et, dtype=float)])
    before, own, after = ((rec >= m[k]) & (rec < m[k + 1]) for k in range(3))
    own_fragment = _is_fragment(rec[own], float(m[1]), max_lag_s)
    if own_fragment and before.any() and not _is_fragment(rec[before], float(m[0]), max_lag_s):
        return np.zeros(n, dtype=bool), (
            f"its {int(own.sum())} sample(s), recorded less than {max_lag_s:.3f} s after "
            f"{day} 00:00 UTC, join the product of {day - one}")
    if own.any() and not own_fragment and _is_fragment(rec[after], float(m[2]), max_lag_s):
        return (own | after)[:n], None
    return own[:n], None
