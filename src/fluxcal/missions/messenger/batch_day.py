"""The science samples of one ``fluxcal batch messenger`` day, whichever file holds them.

A batch day D keeps the samples recorded in its UTC day (`run.batch_day_rows`) from the
science files of D-1, D and D+1: a stream across midnight may be given as one day's
files (issue 31).  A neighbour's file whose first and last records show that it holds
none of the samples D keeps (`holds_nothing_of`) is not parsed: its two records enter
the fragment decisions instead (`run.batch_day_rows`, ``context_et``), which they decide
as all its samples would, since a file's records are in time order (the readers check
it).  In the documented layout (one file per recorded day) a day therefore parses
its own science file only, as before.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (EDR day, Table 1 net lags).
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.identity import SPACECRAFT_ID
from fluxcal.missions.messenger.readers import read_science
from fluxcal.missions.messenger.run import batch_day_rows
from fluxcal.runs.batch import DayWithoutData

log = logging.getLogger(__name__)

#: Bytes read from the end of a file for its last record.
TAIL_BYTES = 4096


def day_file(folder: Path, stream: str, day: _dt.date) -> Path:
    """Return ``folder/MAG<stream>_YYYYDDD.csv`` (the batch input layout)."""
    return Path(folder) / f"MAG{stream}_{day:%Y%j}.csv"


def record_span(path: Path) -> list[tuple[int, float]] | None:
    """Return (partition, MET) of a science CSV's first and last records, or None.

    None when the file is not plain enough to tell from its two ends (no such column, a
    record not of plain numbers, an unreadable file): the caller then reads it whole.
    """
    try:
        with Path(path).open("rb") as fh:
            header = fh.readline().decode("utf-8-sig")
            first = fh.readline().decode("utf-8")
            fh.seek(0, 2)
            fh.seek(max(0, fh.tell() - TAIL_BYTES))
            tail = fh.read().decode("utf-8", errors="replace")
    except (OSError, UnicodeDecodeError):
        return None
    names = [h.strip().strip('"').strip() for h in header.strip().split(",")]
    lines = [ln for ln in tail.splitlines() if ln.strip()]
    if "partition" not in names or "met" not in names or not first.strip() or not lines:
        return None
    ip, im = names.index("partition"), names.index("met")
    out = []
    for line in (first, lines[-1]):
        cells = line.strip().split(",")
        if len(cells) != len(names):
            return None
        try:
            out.append((int(float(cells[ip])), float(cells[im])))
        except ValueError:
            return None
    return out


def holds_nothing_of(first_et: float, last_et: float, midnights: Sequence[float],
                     lag_s: float) -> bool:
    """Whether a time-ordered file spanning ``first_et..last_et`` holds no sample a day keeps.

    ``midnights``: the day's start, the next midnight and the one after (ET).  True when
    the file ends before the day, or starts after the next day's lag fragment window, or
    starts in the next day and ends in it at least ``lag_s`` after its midnight (the next
    day is then no fragment, so none of its samples join this day; `run.batch_day_rows`).
    Its first and last samples then decide the fragments as all its samples would.
    """
    m0, m1, m2 = (float(v) for v in midnights)
    return (last_et < m0 or first_et >= m1 + lag_s
            or (first_et >= m1 and m1 + lag_s <= last_et < m2))


def read_day_science(files: Sequence[Path], own: Path, day: _dt.date,
                     calib: Path | None) -> tuple[xr.Dataset, list[Path]]:
    """Read the science samples of batch day ``day`` (kernels loaded).

    Parameters
    ----------
    files : sequence of Path
        The science files of the day before, the day and the day after that exist.
    own : Path
        The day's own science file (always read when it exists).
    day : datetime.date
        The batch day.
    calib : Path, optional
        Calibration folder (its Table 1 net lags decide the fragments).

    Returns
    -------
    xarray.Dataset, list of Path
        The day's samples (`read_science` of the files read, then `run.batch_day_rows`)
        and the files read.

    Raises
    ------
    DayWithoutData
        When no sample belongs to the day (none, or they join the day before).
    """
    sclk = SclkKernel.from_pool(SPACECRAFT_ID)
    lag = float(np.max(load_calibration(f"{day}T00:00:00", calib).net_lag_s))
    one = _dt.timedelta(days=1)
    m = utc_to_et(np.array([f"{day + k * one}T00:00:00" for k in (-1, 0, 1, 2)]))
    read, context = [], []
    for path in map(Path, files):
        span = None if path == Path(own) else record_span(path)
        if span is not None:
            et = sclk.to_et(np.array([p for p, _ in span]), np.array([t for _, t in span]))
            if holds_nothing_of(float(et[0]), float(et[-1]), m[1:], lag):
                context += [float(v) for v in et]
                continue
        read.append(path)
    names = ", ".join(p.name for p in map(Path, files))
    if not read:
        raise DayWithoutData(f"no science sample of {day} in {names}")
    science = read_science(read)
    recorded = sclk.to_et(science["partition"].values, science["met"].values)
    keep, joined = batch_day_rows(recorded, day, lag, np.array(context))
    if joined is not None:
        raise DayWithoutData(f"{day}: {joined}")
    present = {p.name for p in map(Path, files)}
    for k, other in ((0, day - one), (2, day + one)):
        n = int(((recorded >= m[k]) & (recorded < m[k + 1]) & ~keep).sum())
        if n and day_file(Path(), "SCI", other).name not in present:
            log.warning("%d science sample(s) recorded on %s in %s: that day has no science "
                        "file, its products hold them only when the batch runs %s too",
                        n, other, ", ".join(p.name for p in read), other)
    if not keep.any():
        raise DayWithoutData(f"no science sample of {day} in {names}")
    return science.isel(time=np.flatnonzero(keep)), read
