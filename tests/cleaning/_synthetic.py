"""Synthetic 'realistic' magnetometer backgrounds shared by the cleaning tests."""

from __future__ import annotations

import numpy as np


def red_noise(n: int, fs: float, psd_1hz: float, rng: np.random.Generator, *, floor: float = 0.0):
    """(n, 3) Gaussian noise with one-sided PSD ``psd_1hz * (f / 1 Hz)^-2 + floor`` (nT^2/Hz).

    Built in the frequency domain, so the PSD is known in closed form (`red_psd`).
    """
    f = np.fft.rfftfreq(n, 1 / fs)
    psd = red_psd(f, psd_1hz, floor)
    psd[0] = 0.0
    # one-sided PSD S -> complex amplitude variance per bin: S * fs * n / 2
    amp = np.sqrt(psd * fs * n / 2.0)
    spec = (rng.normal(size=(3, f.size)) + 1j * rng.normal(size=(3, f.size))) / np.sqrt(2) * amp
    return np.fft.irfft(spec, n=n, axis=-1).T


def red_psd(f, psd_1hz: float, floor: float = 0.0):
    """Closed-form one-sided PSD of `red_noise` (nT^2/Hz)."""
    f = np.asarray(f, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(f > 0, psd_1hz * np.maximum(f, 1e-12) ** -2.0, 0.0) + floor


def rotating_field(t: np.ndarray, magnitude: float = 20.0, period: float = 4 * 3600.0):
    """A slowly rotating field (nT) of constant magnitude: the large-scale background."""
    ang = 2 * np.pi * t / period
    return magnitude * np.stack(
        [np.cos(ang) * 0.8, np.sin(ang) * 0.8, np.full_like(t, 0.6)], axis=1
    )
