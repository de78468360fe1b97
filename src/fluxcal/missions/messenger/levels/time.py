"""MESSENGER levels, step 1: time (seed 000 sec. 5, 9): lag, MET -> ET, TT2000.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 5, 9.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration.rate_latency import per_sample_lag
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.levels._common import (
    _scalar,
)


def correct_time(ds: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel) -> xr.Dataset:
    """Convert each sample's MET to ET and TT2000 and subtract its net lag there.

    The lag (Table 1, seconds) is subtracted from the ET of the recorded MET, not from
    the MET before conversion: both are seconds (the SCLK rate differs from 1 by far
    less than 1e-5, i.e. < 3e-5 s on a 2.4-s lag), and a sample recorded within the lag
    after the start of an SCLK partition (e.g. partition 2, 2013-01-08) would otherwise
    need a clock reading outside its partition (docs/decisions/messenger.md).

    Parameters
    ----------
    ds : xarray.Dataset
        Raw science samples with ``partition``, ``met`` (s) and ``rate`` on ``time``.
    cal : MessengerCalibration
        Table 1 net lags.
    sclk : SclkKernel
        MESSENGER clock (id -236).

    Returns
    -------
    xarray.Dataset
        With ``met_corrected``, ``lag``, ``et``, ``et_recorded`` (uncorrected, decides
        the product day) and the coordinate ``epoch`` (TT2000 ns).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 9.
    """
    lag = per_sample_lag(ds["rate"].values, cal.net_lag_s)
    met = ds["met"].values - lag
    # the recorded MET is a valid clock reading of its partition; the lag is subtracted
    # on the ET (and TT2000) scale, so a sample recorded just after a partition start
    # does not need a clock reading before it.  TT2000 straight from the clock's TT
    # parallel time (no TDB round trip).
    et_recorded, tt2000_recorded = sclk.to_et_and_tt2000(ds["partition"].values,
                                                         ds["met"].values)
    et = et_recorded - lag
    tt2000 = tt2000_recorded - np.round(lag * 1e9).astype(np.int64)
    out = _time_dataset(ds, lag, met, et, tt2000, et_recorded)
    # Table 1's sample rates travel with the rate settings (sec. 13 gap rule)
    rate = ds["rate"]
    return out.assign(rate=xr.Variable(rate.dims, rate.values, {
        **rate.attrs, "sample_rate_hz": [float(r) for r in cal.sample_rate_hz]}))


def _time_dataset(
    ds: xr.Dataset, lag: np.ndarray, met: np.ndarray, et: np.ndarray, tt2000: np.ndarray,
    et_recorded: np.ndarray,
) -> xr.Dataset:
    out = ds.assign(
        et_recorded=_scalar(et_recorded, "s", "ephemeris time of the recorded (EDR) MET"),
        lag=_scalar(lag, "s", "net time lag subtracted from the MET (Table 1)"),
        met_corrected=_scalar(met, "s", "MET corrected for the net lag"),
        et=_scalar(et, "s", "ephemeris time (TDB seconds past J2000)"),
    )
    epoch = ("time", tt2000, {"units": "ns", "standard": "TT2000"})
    return out.assign_coords(epoch=epoch)


def aux_times_et(aux: xr.Dataset, sclk: SclkKernel) -> np.ndarray:
    """Return the ET of an auxiliary stream (heater bits, temperatures) from its MET."""
    return sclk.to_et(aux["partition"].values, aux["met"].values)
