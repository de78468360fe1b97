"""MESSENGER levels, step 4: corrected counts -> nT in sensor coordinates (seed 000 sec. 8).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 8, eq. 8, Table 4.
"""

from __future__ import annotations

import xarray as xr

from fluxcal.calibration.gain_matrix import counts_to_nt
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.levels._common import (
    _vector,
)


def counts_to_field(ds: xr.Dataset, cal: MessengerCalibration) -> xr.Dataset:
    """Convert corrected counts to nT in sensor coordinates (eq. 8, Table 4).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8, Table 4.
    """
    b = counts_to_nt(ds["counts_corrected"].values, ds["range"].values, cal.matrices)
    return ds.assign(b_sensor=_vector(b, "nT", "magnetic field, sensor coordinates"))
