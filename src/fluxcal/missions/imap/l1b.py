"""IMAP MAG L1B: counts -> nT with the range-dependent matrices of the calibration file.

``B = M[range] @ counts`` per vector (`fluxcal.calibration.matrices.apply_lookup`), the
matrix of the sensor and range from `fluxcal.missions.imap.calibration`, and the time
tag moved by the sensor's time shift (``OTS``/``ITS``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration.matrices import apply_lookup
from fluxcal.errors import InputFormatError
from fluxcal.missions.imap.calibration import MagCalibration


def calibrate(l1a: xr.Dataset, calibration: MagCalibration) -> xr.Dataset:
    """L1B dataset of one (mode, sensor) L1A dataset: ``b`` (time, component) in nT.

    Keeps ``range``, ``sequence``, ``coarse``, ``fine``, ``compression`` and
    ``compression_width``; ``epoch`` is the L1A time plus the sensor's time shift; the
    validity of the calibration is recorded in ``calibration_valid``.

    Raises
    ------
    InputFormatError
        A range outside 0..3 (naming the first sample).
    """
    sensor = l1a.attrs["sensor"]
    rng = l1a["range"].values
    bad = (rng < 0) | (rng > 3)
    if bad.any():
        raise InputFormatError(f"{sensor} sample {int(np.flatnonzero(bad)[0])}: range "
                               f"{int(rng[bad][0])} is not 0..3", field="range")
    b = apply_lookup(calibration.matrices[sensor], rng, l1a["counts"].values)
    epoch = l1a["epoch"].values + calibration.time_shift_ns[sensor]
    inside = (epoch >= calibration.valid_from) & (epoch <= calibration.valid_to)
    keep = ["range", "sequence", "coarse", "fine", "compression", "compression_width"]
    ds = l1a[keep].assign(
        b=(("time", "component"), b, {"units": "nT", "description":
                                      "Magnetic field, sensor unit reference frame"}),
    ).assign_coords(epoch=("time", epoch), component=l1a["component"].values)
    ds.attrs = {**l1a.attrs, "level": "l1b", "calibration_file": calibration.path.name,
                "calibration_valid": "yes" if inside.all() else
                f"no: {int((~inside).sum())} samples outside the file's validity"}
    return ds
