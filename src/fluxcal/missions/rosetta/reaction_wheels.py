"""Reader of Rosetta reaction-wheel rate tables (input of LEVEL_H).

Format: CSV with the header ``time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz``; ``time_utc`` is
ISO 8601 UTC, strictly increasing; the rates are the wheels' rotation frequencies in
Hz (>= 0).  An empty rate field means "wheel rate unknown": no line is removed for
that wheel at that time.  Lines starting with ``#`` are comments.  Every error names
the file, line and field.

The seed's sources (DDS binary, Imperial College SCHK7.TXT) are converted to this
table outside fluxcal.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.9 ("Provide the Reaction wheel frequency
   data ...").
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import utc_to_tt2000

__all__ = ["REACTION_WHEEL_COLUMNS", "ReactionWheelTable", "read_reaction_wheels"]

REACTION_WHEEL_COLUMNS = ("time_utc", "rw1_hz", "rw2_hz", "rw3_hz", "rw4_hz")
_HEADER = ",".join(REACTION_WHEEL_COLUMNS)


@dataclass(frozen=True)
class ReactionWheelTable:
    """Wheel rates versus time.

    Attributes
    ----------
    epoch : ndarray (m,) int64
        TT2000 ns of each row.
    frequencies : ndarray (m, 4)
        Rotation rates in Hz (NaN: unknown).
    source : str
        File the table was read from.
    """

    epoch: NDArray[np.int64]
    frequencies: NDArray[np.float64]
    source: str = ""


def read_reaction_wheels(path: Path | str, lsk=None) -> ReactionWheelTable:
    """Read a reaction-wheel CSV (see module docstring).

    Parameters
    ----------
    path : path-like
        The CSV file.
    lsk : LeapSecondTable, optional
        Leap seconds for the UTC conversion (default: the loaded LSK).

    Returns
    -------
    ReactionWheelTable

    Raises
    ------
    InputFormatError
        Wrong header, wrong number of fields, unparsable time or rate, negative rate,
        times not strictly increasing, or no data rows; the message names file, line
        and field.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFormatError("reaction wheel file not found", path=str(path))
    times: list[str] = []
    rates: list[list[float]] = []
    lines: list[int] = []
    header_seen = False
    with path.open(newline="") as fh:
        for lineno, row in enumerate(csv.reader(fh), start=1):
            if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                continue
            cells = [c.strip() for c in row]
            if not header_seen:
                if tuple(c.lower() for c in cells) != REACTION_WHEEL_COLUMNS:
                    raise InputFormatError(
                        f"header {','.join(cells)!r}; expected {_HEADER!r}",
                        path=str(path),
                        line=lineno,
                    )
                header_seen = True
                continue
            if len(cells) != len(REACTION_WHEEL_COLUMNS):
                raise InputFormatError(
                    f"{len(cells)} fields; expected {len(REACTION_WHEEL_COLUMNS)}",
                    path=str(path),
                    line=lineno,
                )
            values = []
            for name, text in zip(REACTION_WHEEL_COLUMNS[1:], cells[1:], strict=True):
                if text == "":
                    values.append(np.nan)
                    continue
                try:
                    v = float(text)
                except ValueError:
                    raise InputFormatError(
                        f"cannot read {text!r} as a rate in Hz",
                        path=str(path),
                        line=lineno,
                        field=name,
                    ) from None
                if not np.isfinite(v) or v < 0:
                    raise InputFormatError(
                        f"rate {text!r} must be a finite number >= 0 Hz",
                        path=str(path),
                        line=lineno,
                        field=name,
                    )
                values.append(v)
            times.append(cells[0])
            rates.append(values)
            lines.append(lineno)
    if not header_seen:
        raise InputFormatError("empty file: no header", path=str(path))
    if not times:
        raise InputFormatError("no data rows after the header", path=str(path))
    try:
        epoch = utc_to_tt2000(np.array(times), lsk).astype(np.int64)
    except InputFormatError:
        for k, text in enumerate(times):  # find the failing row to name its line
            try:
                utc_to_tt2000(np.array([text]), lsk)
            except InputFormatError:
                raise InputFormatError(
                    f"cannot parse UTC time {text!r}; expected YYYY-MM-DDTHH:MM:SS[.fff]",
                    path=str(path),
                    line=lines[k],
                    field="time_utc",
                ) from None
        raise
    bad = np.flatnonzero(np.diff(epoch) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputFormatError(
            f"time {times[k]!r} does not follow {times[k - 1]!r}: times must increase",
            path=str(path),
            line=lines[k],
            field="time_utc",
        )
    return ReactionWheelTable(epoch=epoch, frequencies=np.array(rates, float), source=str(path))
