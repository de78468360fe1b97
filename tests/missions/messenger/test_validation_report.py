"""The sec. 13 offset report text: steps planted in a smooth offset, read back from the text.

Expected values are the planted steps (closed form), and the UTC of the planted sample from
SPICE's own ``et2utc`` (not fluxcal's conversion).
"""

from __future__ import annotations

import numpy as np
import pytest
import spiceypy
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.levels import validate_offsets
from fluxcal.missions.messenger.validation_report import report_text


@pytest.fixture(scope="module")
def pool():
    with KernelPool([]):  # the package's generic LSK
        yield


def _day(steps: dict[int, float], sign: float) -> xr.Dataset:
    n = 2000
    et = 4.0e8 + np.arange(n) * 0.05  # 20 Hz, no gap
    offset = np.zeros((n, 3))
    offset += 0.001 * np.arange(n)[:, None]  # a smooth drift: 0.001 counts per sample
    for axis, at in steps.items():
        offset[at:, axis] += sign * (axis + 1) * 0.5  # x 0.5, y 1.0, z 1.5 counts
    return xr.Dataset({"et": ("time", et), "offset": (("time", "component"), offset)})


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_report_lists_each_planted_step_where_it_is(pool, sign):
    at = {0: 300, 1: 1200, 2: 1999}
    ds = _day(at, sign)
    given = validate_offsets(ds, threshold_counts=2.0)
    text = report_text(ds, 2.0, given)
    assert text == report_text(ds, 2.0)  # the report passed in is the one computed
    rows = [line.split(",") for line in text.splitlines() if line[:2] in ("x,", "y,", "z,")]
    for j, (axis, step, utc) in enumerate(rows):
        # |planted step| plus the drift of one sample (steps are differences of samples)
        assert float(step) == pytest.approx(abs(sign * (j + 1) * 0.5 + 0.001), abs=1e-9)
        expect = spiceypy.et2utc(float(ds["et"].values[at[j]]), "ISOC", 3)
        assert utc.startswith(expect[:19]), (axis, utc, expect)
