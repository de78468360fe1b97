"""The day edges of an RPC-MAG batch day: its checks, the previous day's tail, the stitch state.

A batch day folder holds the raw records whose telemetry time is in that UTC day
(`check_day_records`); the filter time shifts are delays, never negative
(`check_shifts_nonnegative`), so a day's products need the previous day's file (its
records shifted past midnight: `previous_day_records`, `previous_day_tail`,
`merge_tail`) and never the next day's.  The extended model's stitching state carries
from one day to the next in a file (`read_stitch_state`, `stitch_state_text`).  The run
around them is `fluxcal.missions.rosetta.routes.RosettaRun` (docs/formats/rosetta.md,
"Day edges").

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (stitching), 4.2.3.5 (time shifts).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.missions.rosetta import archive, calib, level_a
from fluxcal.missions.rosetta.products import _utc


def check_day_records(raw: xr.Dataset, bounds: tuple[int, int], path: Path, lsk=None) -> None:
    """Refuse a raw file with a record stamped outside the UTC day ``bounds``.

    The batch's day folders are split at midnight of the telemetry time (before the
    filter shift, docs/formats/rosetta.md "Day edges").

    Raises
    ------
    InputFormatError
        Naming the file, the line of the first such record and its time.
    """
    epoch = raw["epoch"].values
    outside = (epoch < bounds[0]) | (epoch >= bounds[1])
    if not np.any(outside):
        return
    i = int(np.flatnonzero(outside)[0])
    line = int(raw["row"].values[i]) if "row" in raw else i + 2
    day = str(_utc(np.array([bounds[0]]), lsk)[0])[:10]
    raise InputFormatError(
        f"record stamped {_utc(epoch[i:i + 1], lsk)[0]} UTC is not in {day}, the day of "
        f"its folder ({int(outside.sum())} such records); a day folder holds the records "
        "whose telemetry time (before the filter shift) is in that UTC day",
        path=str(raw.attrs.get("source", path)), line=line, field="time_utc",
    )


def check_shifts_nonnegative(shifts: calib.TimeShiftTable) -> None:
    """Refuse a filter time-shift table with a negative shift (the batch's day edges).

    Seed 003 sec. 4.2.3.5: the shifts are filter delays (0 to 1023.95 s), added to the
    time stamp; a day's product then never needs the next day's raw file.
    """
    for name in ("primary", "secondary"):
        col = np.asarray(getattr(shifts, name), dtype=float)
        neg = np.flatnonzero(col < 0)
        if neg.size:
            raise FluxcalError(
                f"{shifts.source}: SID {int(shifts.sid[neg[0]])} has a negative {name} "
                f"filter time shift ({col[neg[0]]} s); the batch needs shifts >= 0 "
                "(RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 4.2.3.5: filter delays)"
            )


def previous_day_records(
    path: Any,
    sensor: str,
    bounds: tuple[int, int],
    shifts: calib.TimeShiftTable,
    *,
    primary: str = "OB",
    sclk=None,
    lsk=None,
) -> xr.Dataset | None:
    """Raw records of the previous day's file that its tail past midnight is made from.

    ``bounds`` are the TT2000 of the start and end (``midnight``) of that file's UTC day
    (`fluxcal.geometry.days.day_bounds`); the file's records must be stamped in it
    (`check_day_records`).
    Returned: the file's first good record plus the records within the largest filter
    shift of the table (+1 s) before ``midnight`` (`previous_day_tail` calibrates them);
    ``None`` when there are none.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (stitching), 4.2.3.5 (time shifts).
    """
    raw = archive.read_science(path, sensor, sclk=sclk, lsk=lsk)
    check_day_records(raw, bounds, path, lsk)
    midnight = bounds[1]
    primary_sensor = calib.check_sensor(sensor) == calib.check_sensor(primary)
    col = np.asarray(shifts.primary if primary_sensor else shifts.secondary, dtype=float)
    reach = int(np.ceil((np.nanmax(col) + 1.0) * 1e9))
    good = np.flatnonzero(level_a.good_vectors(raw["quality"].values))
    near = np.flatnonzero(raw["epoch"].values >= midnight - reach)
    if good.size == 0 or near.size == 0:
        return None
    return raw.isel(time=np.union1d(good[:1], near))


def previous_day_tail(
    records: xr.Dataset,
    midnight: int,
    cal: calib.GroundCalibration,
    shifts: calib.TimeShiftTable,
    nominal: dict,
    models: dict,
    *,
    primary: str = "OB",
    stitch_gap_s: float = level_a.STITCH_GAP_S,
    previous: level_a.StitchState | None = None,
    lsk=None,
) -> xr.Dataset | None:
    """LEVEL_A vectors of the previous day's records (`previous_day_records`) past midnight.

    Calibrated exactly as that day's own run calibrates them: ``previous`` is the
    stitching state at the start of that day; the extended-model offset of a day depends
    on its vectors' own temperatures and on the day's first and last good vectors only
    (`extended_model.stitch_day`), so the values equal those of the whole file.
    ``None`` when no vector crosses ``midnight`` (TT2000 ns).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (stitching), 4.2.3.5 (time shifts).
    """
    a = level_a.level_a(records, cal, shifts, nominal, daily_models=models, primary=primary,
                        stitch_gap_s=stitch_gap_s, previous=previous, lsk=lsk)
    keep = np.flatnonzero(a["epoch"].values >= midnight)
    return a.isel(time=keep) if keep.size else None


def merge_tail(tail: xr.Dataset, a: xr.Dataset) -> xr.Dataset:
    """Put the previous day's tail in front of the day's LEVEL_A, in time order.

    Mode segments (one calibrated table each) continue across midnight: the tail's last
    segment and the day's first are one segment when they have the same SID (a run of
    one SID in telemetry order, docs/formats/rosetta.md).  Attributes are the day's.
    """
    seg_t = tail["mode_segment"].values.astype(np.int64)
    seg_a = a["mode_segment"].values.astype(np.int64)
    last = int(seg_t.max())
    offset = last + 1
    if seg_a.size:
        first = int(seg_a.min())
        same = tail["sid"].values[seg_t == last][0] == a["sid"].values[seg_a == first][0]
        offset = last - first + (0 if same else 1)
    a = a.assign_coords(mode_segment=("time", (seg_a + offset).astype(np.int32),
                                      a["mode_segment"].attrs))
    tail = tail.assign_coords(mode_segment=("time", seg_t.astype(np.int32),
                                            a["mode_segment"].attrs))
    merged = xr.concat([tail, a], dim="time", combine_attrs="override")
    merged.attrs = dict(a.attrs)
    order = np.argsort(merged["epoch"].values, kind="stable")
    return merged.isel(time=order)


def read_stitch_state(path: Path | None) -> level_a.StitchState | None:
    """Read the end-of-day stitching state (`stitch_state_text`; ``None`` if absent)."""
    if path is None or not Path(path).is_file():
        return None
    try:
        return level_a.StitchState.from_attrs(json.loads(Path(path).read_text(encoding="utf-8")))
    except (ValueError, KeyError, TypeError) as exc:
        raise FluxcalError(f"{path}: not a fluxcal stitching state file ({exc})") from None


def stitch_state_text(state: dict | None) -> str | None:
    """Return the end-of-day stitching state file (``stitch_*`` attributes) as JSON text.

    ``None`` when the day had no extended model (``state`` empty: the chain is broken,
    a stale file is removed).
    """
    return json.dumps(state, indent=1) if state else None
