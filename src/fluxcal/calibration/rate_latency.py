"""Per-sample time-lag correction from each sample's own rate setting.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5, Table 1.
"""

from __future__ import annotations

import numpy as np

from fluxcal.calibration._compiled import per_sample_lag_kernel


def per_sample_lag(rate_setting: np.ndarray, net_lag_s: np.ndarray) -> np.ndarray:
    """Return the net lag (s) of every sample from its rate setting.

    Parameters
    ----------
    rate_setting : ndarray of int, shape (n,)
        Rate setting of each sample (index into ``net_lag_s``).
    net_lag_s : ndarray, shape (m,)
        Net lag per rate setting (Table 1).

    Raises
    ------
    ValueError
        When a rate setting is outside ``0..m-1``.

    Notes
    -----
    One compiled pass (check and gather,
    `fluxcal.calibration._compiled.per_sample_lag_kernel`).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5, Table 1.
    """
    rate = np.asarray(rate_setting)
    lags = np.asarray(net_lag_s, dtype=float)
    if rate.ndim == 1 and rate.dtype.kind in "iu" and lags.ndim == 1:
        out = np.empty(rate.size)
        if per_sample_lag_kernel(rate, lags, out) >= 0:
            raise ValueError(f"rate_setting: values must lie in 0..{lags.size - 1}")
        return out
    return per_sample_lag_reference(rate_setting, net_lag_s)


def per_sample_lag_reference(rate_setting: np.ndarray, net_lag_s: np.ndarray) -> np.ndarray:
    """Numpy reference of `per_sample_lag` (check, then gather; the tests compare)."""
    rate = np.asarray(rate_setting)
    lags = np.asarray(net_lag_s, dtype=float)
    if rate.size and (rate.min() < 0 or rate.max() >= lags.size):
        raise ValueError(f"rate_setting: values must lie in 0..{lags.size - 1}")
    return lags[rate]


def correct_latency(
    met_s: np.ndarray, rate_setting: np.ndarray, net_lag_s: np.ndarray
) -> np.ndarray:
    """Return the corrected clock reading ``met - lag(rate)`` (sec. 5)."""
    return np.asarray(met_s, dtype=float) - per_sample_lag(rate_setting, net_lag_s)
