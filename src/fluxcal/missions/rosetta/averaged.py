"""RPC-MAG LEVEL_E, F, G: n-second averages of LEVEL_A, B, C.

All vectors in ``[t0 + k n, t0 + (k+1) n)`` (``t0`` the UTC midnight of the first vector's
day) are summed and divided by their number; the time tag is the middle of the
interval; intervals without data are omitted.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.6 (E), 4.7 (F), 4.8 (G).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration import averaging
from fluxcal.errors import InputFormatError
from fluxcal.geometry.days import day_midnight

NEXT_LEVEL = {"A": "E", "B": "F", "C": "G"}


def average(level: xr.Dataset, seconds: float = 1.0, *, lsk=None) -> xr.Dataset:
    """Average a LEVEL_A/B/C dataset into LEVEL_E/F/G (``seconds`` per interval).

    Vector and scalar float variables are averaged, ``quality`` is OR-ed (maximum),
    ``obt`` is carried to the interval middle, and ``n_samples`` counts the vectors.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.6-4.8.
    """
    if not seconds > 0:  # NaN too
        raise InputFormatError(f"{seconds:g} s: an averaging interval must be above 0 s",
                               field="seconds")
    epoch = level["epoch"].values.astype(np.int64)
    width = int(round(seconds * 1e9))
    origin = day_midnight(int(epoch[0]), lsk) if epoch.size else 0
    bins = averaging.bin_index(epoch, width, origin)
    out = averaging.average_dataset(level, bins, origin, maximum=("quality",),
                                    centred=("obt",), drop=("sid", "row", "et"))
    src = level.attrs.get("level", "?")
    out.attrs.update(
        level=NEXT_LEVEL.get(src, src + "avg"),
        average_seconds=float(seconds),
        average_origin_tt2000=int(origin),
    )
    return out
