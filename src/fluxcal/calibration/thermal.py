"""Temperature models: thermistor polynomials and temperature-dependent coefficients.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2.2, 3.3.3, 4.2.3.2, 4.2.3.3.
"""

from __future__ import annotations

import numpy as np


def polynomial(coefficients: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate ``sum_k c[k] x**k`` (Horner), vectorized over ``x`` and trailing axes of ``c``.

    Parameters
    ----------
    coefficients : array_like, shape (m,) or (m, k)
        ``c[0]`` is the constant term.  With shape ``(m, k)`` each of the ``k`` columns is a
        separate polynomial (e.g. x, y, z components).
    x : array_like, shape (n,)
        Variable.

    Returns
    -------
    ndarray, shape (n,) or (n, k)
    """
    c = np.asarray(coefficients, dtype=float)
    x = np.asarray(x, dtype=float)
    while len(c) > 1 and not np.any(c[-1]):  # trailing zero orders (e.g. P_4 = P_5 = 0)
        c = c[:-1]
    xs = x[:, None] if c.ndim == 2 else x
    out = np.zeros(xs.shape[:1] + c.shape[1:]) + c[-1]
    for ck in c[-2::-1]:
        out = out * xs + ck
    return out


def thermistor_temperature(
    voltage: np.ndarray, coefficients: np.ndarray, offset: float = 0.0
) -> np.ndarray:
    """Calibrated thermistor temperature ``T^c = c0 + c1 U + c2 U^2 + c3 U^3 - T^O`` (deg C).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.3.3 and 4.2.3.2 item 1.
    """
    return polynomial(coefficients, voltage) - offset


def thermistor_voltage(
    temperature: np.ndarray, coefficients: np.ndarray, offset: float = 0.0, *, guess: float = 1.25
) -> np.ndarray:
    """Invert `thermistor_temperature` by Newton iteration (forward models).

    The cubic of seed 003 sec. 3.3.3 is monotonic over the thermistor's voltage range
    (0.5 - 1.6 V), so Newton from ``guess`` converges to machine precision in a few steps.
    """
    target = np.asarray(temperature, dtype=float) + offset
    c = np.asarray(coefficients, dtype=float)
    dc = c[1:] * np.arange(1, len(c))
    u = np.full(target.shape, guess)
    for _ in range(50):
        step = (polynomial(c, u) - target) / polynomial(dc, u)
        u = u - step
        if np.all(np.abs(step) < 1e-15):
            break
    return u


def pt_divider_voltage(resistance: np.ndarray, u_ref: float, r_series: float) -> np.ndarray:
    """Voltage across a thermistor of ``resistance`` fed from ``u_ref`` through ``r_series``.

    ``U = U_ref / (R_ser / R + 1)`` (seed 003, sec. 4.2.1).
    """
    return u_ref / (r_series / np.asarray(resistance, dtype=float) + 1.0)


def linear_in_temperature(coefficients: np.ndarray, temperature: np.ndarray) -> np.ndarray:
    """``c[0] + c[1] T`` per component: offsets, sensitivities and angles of seed 003 sec. 3.2.2.

    Parameters
    ----------
    coefficients : array_like, shape (2, k)
    temperature : array_like, shape (n,)

    Returns
    -------
    ndarray, shape (n, k)
    """
    c = np.asarray(coefficients, dtype=float)
    return c[0] + np.asarray(temperature, dtype=float)[:, None] * c[1]
