"""The IMAP MAG L1B calibration file: range matrices and time shifts per sensor.

The team's ``imap_calibration_mag_<yyyymmdd>_v<nn>.cdf`` (also published as
``imap_mag_l1b-calibration_<yyyymmdd>_v<nnn>.cdf``; not shipped with fluxcal: the user
names it with ``--calib``) holds, for MAGo
(``MFOTOURFO``) and MAGi (``MFITOURFI``), a 3x3 matrix per range 0..3 stored as a
(3, 3, 4) array (the last axis is the range), the sensors' time shifts ``OTS``/``ITS``
(s) and the validity ``STARTVALIDITY``/``ENDVALIDITY`` (TT2000).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cdflib
import numpy as np

from fluxcal.errors import CalibrationError

_VARIABLES = {"mago": ("MFOTOURFO", "OTS"), "magi": ("MFITOURFI", "ITS")}


@dataclass(frozen=True)
class MagCalibration:
    """Matrices (range, 3, 3) and time shifts (ns) per sensor, validity, source file."""

    matrices: dict[str, np.ndarray]
    time_shift_ns: dict[str, int]
    valid_from: int
    valid_to: int
    path: Path


def load_calibration(path: Path | str | None) -> MagCalibration:
    """Read a calibration CDF.

    Raises
    ------
    CalibrationError
        None given (names ``--calib``), or naming the file and variable: unreadable
        file, missing variable, a matrix that is not (3, 3, 4) or not finite.
    """
    if path is None:
        raise CalibrationError("--calib: L1B needs the IMAP MAG team's calibration CDF "
                               "(e.g. ../shared/data/imap/imap_calibration_mag_20240229_v01"
                               ".cdf): give --calib PATH, or ask for --level l1a")
    path = Path(path)
    try:
        cdf = cdflib.CDF(str(path))
    except Exception as exc:  # noqa: BLE001 - cdflib raises many kinds on a bad file
        raise CalibrationError(f"{path}: not a readable CDF ({type(exc).__name__}: {exc})"
                               ) from exc
    names = set(cdf.cdf_info().zVariables) | set(cdf.cdf_info().rVariables)

    def get(name: str) -> np.ndarray:
        if name not in names:
            raise CalibrationError(f"{path}: variable '{name}' is missing")
        return np.asarray(cdf.varget(name))

    matrices, shifts = {}, {}
    for sensor, (mat_name, shift_name) in _VARIABLES.items():
        m = get(mat_name)
        if m.shape != (3, 3, 4) or not np.all(np.isfinite(m)):
            raise CalibrationError(f"{path}: variable '{mat_name}' must be finite (3, 3, 4) "
                                   f"(matrix per range), got shape {m.shape}")
        matrices[sensor] = np.ascontiguousarray(np.moveaxis(m, 2, 0))
        shifts[sensor] = int(np.rint(float(get(shift_name).reshape(-1)[0]) * 1e9))
    return MagCalibration(matrices, shifts, int(get("STARTVALIDITY").reshape(-1)[0]),
                          int(get("ENDVALIDITY").reshape(-1)[0]), path)
