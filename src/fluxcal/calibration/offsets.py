"""Temperature-dependent offsets as a two-segment line.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 3a, 3b, 4, Table 2.
"""

from __future__ import annotations

import numpy as np

from fluxcal.calibration._compiled import two_segment_kernel


def breakpoint_temperature(coefficients: np.ndarray) -> np.ndarray:
    """Return ``T_m = (A0 - A1) / (B1 - B0)`` per axis (eq. 4).

    Parameters
    ----------
    coefficients : ndarray, shape (3, 4)
        ``A0, B0, A1, B1`` per axis.
    """
    a0, b0, a1, b1 = np.asarray(coefficients, dtype=float).T
    return (a0 - a1) / (b1 - b0)


def two_segment_offset(temperature_c: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """Return the offset ``cT_j(T)`` of eq. 3a/3b for every sample and axis.

    One compiled pass (`fluxcal.calibration._compiled.two_segment_kernel`);
    `two_segment_offset_reference` is the numpy version the tests compare with.

    Parameters
    ----------
    temperature_c : ndarray, shape (n,)
        Sensor temperature (degC).
    coefficients : ndarray, shape (3, 4)
        ``A0, B0, A1, B1`` per axis (Table 2).

    Returns
    -------
    ndarray, shape (n, 3)
        Offset in counts: ``A0 + B0 T`` for ``T <= T_m``, ``A1 + B1 T`` above.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 3a, 3b, 4, Table 2.
    """
    t = np.ascontiguousarray(temperature_c, dtype=float)
    coefficients = np.ascontiguousarray(coefficients, dtype=float)
    if t.ndim != 1 or coefficients.ndim != 2 or coefficients.shape[1] != 4:
        return two_segment_offset_reference(temperature_c, coefficients)
    out = np.empty((t.size, coefficients.shape[0]))
    two_segment_kernel(t, coefficients, breakpoint_temperature(coefficients), out)
    return out


def two_segment_offset_reference(temperature_c: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """Numpy reference of `two_segment_offset` (the tests compare the two).

    Parameters and returns as `two_segment_offset`.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 3a, 3b, 4, Table 2.
    """
    t = np.asarray(temperature_c, dtype=float)
    coefficients = np.asarray(coefficients, dtype=float)
    tm = breakpoint_temperature(coefficients)
    out = np.empty((t.size, coefficients.shape[0]))
    for j, (a0, b0, a1, b1) in enumerate(coefficients):
        out[:, j] = np.where(t <= tm[j], a0 + b0 * t, a1 + b1 * t)
    return out
