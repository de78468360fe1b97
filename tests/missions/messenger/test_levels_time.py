"""Sec. 5 lag subtracted on the ET scale, next to an SCLK partition start (issue 11)."""

import numpy as np
import spiceypy
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import load_calibration

# Table 1 net lags (s) of rate settings 0 and 10
NET_LAG = {0: 2.358, 10: 0.042}


def test_lag_just_after_the_partition_2_start(shared_kernels):
    # partition 2 of the real MESSENGER SCLK starts at 1e9 ticks = 1000 s (1e6 ticks/s);
    # a sample recorded 1 s after it at rate 0 (lag 2.358 s) was corrected to MET 998.642,
    # outside partition 2: the whole run failed.  The lag is now subtracted from the ET.
    cal = load_calibration("2013-01-09")
    met = np.array([1001.0, 1001.0, 5000.25])
    rate = np.array([0, 10, 0])
    ds = xr.Dataset({"partition": ("time", np.array([2, 2, 2])), "met": ("time", met),
                     "rate": ("time", rate)})
    with KernelPool([shared_kernels / "messenger" / "messenger_2548.tsc"]):
        out = levels.correct_time(ds, cal, SclkKernel.from_pool(-236))
        # independent: SPICE scs2e of the recorded reading (seconds:microseconds), minus
        # the Table 1 lag; TT2000 = TT seconds past J2000 (unitim) in ns
        want = np.array([spiceypy.scs2e(-236, f"2/{int(m)}:{round((m % 1) * 1e6)}")
                         - NET_LAG[int(r)] for m, r in zip(met, rate, strict=True)])
        want_tt = np.array([spiceypy.unitim(e, "TDB", "TT") for e in want])
    # 1e-6 s: the numpy SCLK conversion against scs2e (rounding of the encoded ticks)
    np.testing.assert_allclose(out["et"].values, want, rtol=0, atol=1e-6)
    np.testing.assert_allclose(out["epoch"].values.astype(float), want_tt * 1e9, rtol=0,
                               atol=1e3)
    np.testing.assert_allclose(out["met_corrected"].values, met - [2.358, 0.042, 2.358])
