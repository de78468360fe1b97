"""MESSENGER levels, step 7: offset smoothness validation (seed 000 sec. 13).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 5 Table 1, sec. 7,
       sec. 13.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration.offset_steps import largest_steps
from fluxcal.errors import ValidationError
from fluxcal.geometry.time import et_to_utc
from fluxcal.missions.messenger.levels._common import (
    COMPONENT,
)

#: Sec. 13 gap rule: a step longer than this many nominal sample spacings is a gap.
GAP_SPACINGS = 2.5


def offset_step_report(ds: xr.Dataset, max_gap_s: float = 10.0) -> dict:
    """Largest step of the applied thermal offset per axis and where (sec. 13).

    Steps across data gaps are ignored: a gap is longer than ``max_gap_s`` and than
    `GAP_SPACINGS` nominal sample spacings of the sample after it (Table 1's rate, from
    the ``sample_rate_hz`` attribute `correct_time` puts on ``rate``; without it the gap
    is ``max_gap_s``).  A step over more than ``max_gap_s`` (sample spacings of 20-100 s
    at rate settings 0-2) counts as ``step * max_gap_s / dt``: the threshold is a rate
    of change per ``max_gap_s``, the same as for denser data, so that the smooth
    relaxation of sec. 7 over a long spacing is not taken for a discontinuity.  Steps
    touching a sample before V10 that is not ``sunlit`` (stowed or in shadow: offset at
    the measured temperature, flagged uncorrectable, C = 1) and steps where the 22.4 C
    rule of sunlit pre-V10 samples starts or ends are ignored as well (sec. 7): the check
    is on the calibration of sec. 6-7, not on the sensor's temperature.

    Returns
    -------
    dict
        ``{"x": {"step_counts": ..., "utc_index": i, "et": ...}, ...}``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 7, sec. 13.
    """
    et = ds["et"].values
    max_gap: float | np.ndarray = max_gap_s
    rates = ds["rate"].attrs.get("sample_rate_hz") if "rate" in ds else None
    if rates is not None:
        spacing = 1.0 / np.asarray(rates, dtype=float)[ds["rate"].values.astype(np.int64)]
        max_gap = np.maximum(max_gap_s, GAP_SPACINGS * spacing)
    segment = None
    if "sunlit" in ds:  # V10 | pre-V10 sunlit (fixed 22.4 C) | each other pre-V10 sample
        pre = ~(et >= float(ds["sunlit"].attrs.get("v10_et", np.inf)))
        segment = np.where(~pre, -1, np.where(ds["sunlit"].values, -2,
                                              np.arange(et.size, dtype=np.int64)))
    rep = largest_steps(ds["offset"].values, segment, times=et, max_gap=max_gap,
                        time_scale=max_gap_s)
    return {
        axis: {"step_counts": float(rep.largest_step[j]), "index": int(rep.index[j]),
               "et": float(et[min(rep.index[j], et.size - 1)])}
        for j, axis in enumerate(COMPONENT)
    }


def validate_offsets(ds: xr.Dataset, threshold_counts: float = 2.0) -> dict:
    """Fail the day when the applied offset has a step above ``threshold_counts``.

    Returns
    -------
    dict
        The step report (see `offset_step_report`).

    Raises
    ------
    ValidationError
        Naming the axis, the step and the time.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13.
    """
    report = offset_step_report(ds)
    for axis, item in report.items():
        if item["step_counts"] > threshold_counts:

            utc = et_to_utc(np.array([item["et"]]))[0]
            raise ValidationError(
                f"offset {axis}: step of {item['step_counts']:.3f} counts at {utc} exceeds the "
                f"smoothness threshold {threshold_counts} counts (MESSENGER MAG EDR-to-CDR "
                "Processing, sec. 13)"
            )
    return report
