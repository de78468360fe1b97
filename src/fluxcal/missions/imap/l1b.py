"""IMAP MAG L1B: counts -> nT with the range-dependent matrices of the calibration file.

``B = M[range] @ (counts * 2**(16 - W))`` per vector
(`fluxcal.calibration.matrices.apply_lookup`): a compressed packet's counts keep ``W``
bits of the sensor's 16-bit output, so they are brought back to 16-bit counts first
(``W = 18``: / 4; ``W = 13``: * 8; uncompressed vectors as they are); the matrix of the
sensor and range from `fluxcal.missions.imap.calibration`; the time tag moved by the
sensor's time shift (``OTS``/``ITS``).

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing (MIT License),
   ``mag/l1b/mag_l1b.py`` ``rescale_vector``: ``M = 2 ^ (16 - width)`` for compressed
   vectors; the team's L1b validation cases T009 (W = 18) and T010 (W = 16).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration.matrices import apply_lookup
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import tt2000_to_utc
from fluxcal.missions.imap.calibration import MagCalibration
from fluxcal.products.timeindex import default_lsk


def compression_scale(l1a: xr.Dataset) -> np.ndarray:
    """Per vector ``2**(16 - W)`` for compressed vectors (``compression = 1``), else 1."""
    compressed = l1a["compression"].values == 1
    width = l1a["compression_width"].values
    return np.where(compressed, np.exp2(16.0 - np.where(compressed, width, 16)), 1.0)


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
    b = apply_lookup(calibration.matrices[sensor], rng,
                     l1a["counts"].values * compression_scale(l1a)[:, None])
    epoch = l1a["epoch"].values + calibration.time_shift_ns[sensor]
    inside = (epoch >= calibration.valid_from) & (epoch <= calibration.valid_to)
    keep = ["range", "sequence", "coarse", "fine", "compression", "compression_width"]
    ds = l1a[keep].assign(
        b=(("time", "component"), b, {"units": "nT", "description":
                                      "Magnetic field, sensor unit reference frame"}),
    ).assign_coords(epoch=("time", epoch), component=l1a["component"].values)
    ds.attrs = {**l1a.attrs, "level": "l1b", "calibration_file": calibration.path.name,
                **validity_attrs(epoch, inside, calibration)}
    return ds


def validity_attrs(epoch: np.ndarray, inside: np.ndarray,
                   calibration: MagCalibration) -> dict[str, str]:
    """``calibration_valid`` (yes, or no with the samples and why) and ``calibration_validity``.

    A calibration used outside its validity is recorded, not refused (docs/decisions/
    imap.md decision 7): the product says how many of its samples, over which span, lie
    outside the file's validity, and that the file's matrices were applied as given.
    ``calibration_validity`` names the file and its validity (UTC).
    """
    lsk = default_lsk()
    span = tt2000_to_utc(np.array([calibration.valid_from, calibration.valid_to],
                                  dtype=np.int64), digits=0, lsk=lsk)
    attrs = {"calibration_validity": f"{calibration.path.name}: {span[0]} .. {span[1]} UTC"}
    outside = np.flatnonzero(~np.asarray(inside, dtype=bool))
    if outside.size == 0:
        return {"calibration_valid": "yes", **attrs}
    first, last = tt2000_to_utc(np.asarray(epoch)[outside[[0, -1]]], digits=0, lsk=lsk)
    attrs["calibration_valid"] = (
        f"no: {outside.size} of {np.size(epoch)} samples ({first} .. {last} UTC) are "
        "outside the calibration file's validity (see calibration_validity); its matrices "
        "were applied as given")
    return attrs
