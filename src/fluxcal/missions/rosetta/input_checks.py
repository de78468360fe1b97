"""Dubious Rosetta RPC-MAG inputs reported, not refused (issue 23, item 2).

A record's time may be wrong without the file being unreadable: two records with the same
time, or a ``time_utc`` that disagrees with the spacecraft clock ``obt`` (a day off, a
clock-correlation slip).  fluxcal keeps the data (but for the second of two records at one
time, dropped and counted: `fluxcal.missions.rosetta.io.drop_repeated_times`) and says so
once per file, naming the file, the first line and the size, so the user can judge;
errors that make the data unusable (time going backwards, unparsable fields) stay
refusals (`fluxcal.missions.rosetta.io`).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.2 (TIME.UTC and TIME.OBT of each record).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import utc_to_tt2000

log = logging.getLogger(__name__)

#: Largest accepted difference (s) between ``time_utc`` and ``obt`` (through the SCLK, or
#: relative to the first record without one).  Rosetta's clock correlation is good to
#: milliseconds; a second is far outside it and far inside "a day off".
UTC_OBT_TOLERANCE_S = 1.0
#: Records whose ``time_utc`` is parsed to compare with the SCLK time (evenly spaced,
#: first and last included): enough to see a shifted stretch of a day, cheap at 20 Hz.
UTC_CHECK_RECORDS = 2001


def report_time_defects(
    epoch: np.ndarray,
    utc: np.ndarray,
    obt: np.ndarray,
    *,
    path: Path | str,
    line_of: Callable[[int], int],
    names: tuple[str, str] = ("time_utc", "obt"),
    from_obt: bool,
    lsk=None,
    tolerance_s: float = UTC_OBT_TOLERANCE_S,
) -> list[str]:
    """Log (warning) and return what is dubious about the record times of one file.

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        TT2000 (ns) of each record, as fluxcal uses it.
    utc, obt : ndarray, shape (n,)
        The records' ``time_utc`` text and ``obt`` seconds.
    path : Path or str
        The file, for the message.
    line_of : callable
        Record index -> the line (or row) number the message names.
    names : (str, str)
        The file's names of the UTC and OBT fields.
    from_obt : bool
        ``epoch`` comes from ``obt`` through the SCLK (then ``time_utc`` is compared with
        it); else from ``time_utc`` (then ``obt`` is compared record to record: its steps
        must match the UTC steps).
    lsk : optional
        Leapseconds, for parsing ``time_utc``.
    tolerance_s : float
        Largest accepted disagreement (s).

    Returns
    -------
    list of str
        One message per defect found (also logged as warnings).
    """
    out: list[str] = []
    epoch = np.asarray(epoch, dtype=np.int64)
    if epoch.size < 1:
        return out
    dup = np.flatnonzero(np.diff(epoch) == 0) + 1
    if dup.size:
        i = int(dup[0])
        out.append(
            f"{path}, line {line_of(i)}, field '{names[1] if from_obt else names[0]}': "
            f"{dup.size} record(s) repeat the time of the record before (first {utc[i]}); "
            "dropped, the first of each time kept"
        )
    if from_obt:
        pick = np.unique(np.linspace(0, epoch.size - 1, min(epoch.size, UTC_CHECK_RECORDS))
                         .astype(np.int64))
        try:
            parsed = utc_to_tt2000(np.asarray(utc)[pick], lsk).astype(np.int64)
        except InputFormatError:
            parsed = None
            out.append(f"{path}: field '{names[0]}' not compared with '{names[1]}' "
                       "(a time_utc does not parse)")
        if parsed is not None:
            diff = (parsed - epoch[pick]) / 1e9
            k = int(np.argmax(np.abs(diff)))
            if abs(diff[k]) > tolerance_s:
                i = int(pick[k])
                out.append(
                    f"{path}, line {line_of(i)}, field '{names[0]}': {utc[i]} is "
                    f"{diff[k]:+.3f} s from the time of {names[1]} {obt[i]} through the "
                    f"SCLK (more than {tolerance_s:g} s); fluxcal uses {names[1]}"
                )
    else:
        rel = (epoch - epoch[0]) / 1e9 - (np.asarray(obt, dtype=float) - float(obt[0]))
        rel -= np.median(rel)
        k = int(np.argmax(np.abs(rel)))
        if abs(rel[k]) > tolerance_s:
            out.append(
                f"{path}, line {line_of(k)}, field '{names[0]}': {utc[k]} disagrees with "
                f"{names[1]} {obt[k]} by {rel[k]:+.3f} s relative to the file's other "
                f"records (more than {tolerance_s:g} s); fluxcal uses {names[0]} (pass "
                "--kernels to time the records from obt)"
            )
    for text in out:
        log.warning("%s", text)
    return out
