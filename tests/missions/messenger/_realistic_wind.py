"""An independent solar-wind model for the in-flight fit tests (issue 21).

Written from the issue's description of the cruise wind, with numpy only (no fluxcal
code): ``B = |B| u`` in sensor axes,

* ``|B|``: 18 nT log-normal (sigma 0.15, a 12-h Gaussian process) times a 3 %
  compressive part (5-min correlation);
* ``u = normalise(s p + a v)``: ``p`` a fixed Parker-spiral direction (the cruise
  attitude keeps it fixed in sensor axes), ``s = +-1`` sectors flipping after 1-3 days,
  ``v`` three Gaussian components with an f^-5/3 spectrum from 12 h to 2 s (FFT
  synthesis), ``a`` set so that the rms vector fluctuation is ``dB/B`` ~ 0.5.

Intervals of constant ``|B|`` with rotating direction are the variance estimator's
premise, long-term means far from zero are what the zero-mean estimator cannot handle.
"""

from __future__ import annotations

import numpy as np

DAY_S = 86400.0


def powerlaw(rng: np.random.Generator, n: int, dims: int, slope: float, f_lo: float,
              f_hi: float) -> np.ndarray:
    """Unit-variance Gaussian series on a 1-s grid with PSD ~ f^slope in [f_lo, f_hi].

    FFT synthesis: Gaussian real and imaginary parts per frequency, amplitude
    ``f^(slope/2)`` in the band, zero outside; the series is cut to ``n`` and scaled to
    unit variance per column (also used by `_hard_worlds`).
    """
    m = 1 << int(np.ceil(np.log2(max(n, 2))))
    f = np.fft.rfftfreq(m, d=1.0)
    amp = np.zeros_like(f)
    band = (f >= f_lo) & (f <= f_hi)
    amp[band] = f[band] ** (slope / 2.0)
    spec = amp[:, None] * (rng.standard_normal((f.size, dims))
                           + 1j * rng.standard_normal((f.size, dims)))
    x = np.fft.irfft(spec, n=m, axis=0)[:n]
    return x / x.std(axis=0, keepdims=True)


def realistic_wind(rng: np.random.Generator, n: int, *, b_nt: float = 18.0,
                   rotation: float = 0.5, compressive: float = 0.03,
                   sector_days: tuple[float, float] = (1.0, 3.0),
                   parker: tuple[float, float, float] = (0.55, -0.6, 0.58),
                   broadband: bool = False) -> np.ndarray:
    """Field (nT, sensor axes) on a 1-s grid, shape (n, 3) (module docstring).

    ``broadband``: the compressive part with the rotations' f^-5/3 spectrum from 1 h to
    2 s instead of f^-2 from 1 h to 5 min (the variance estimator's assumption failing,
    docs/decisions/messenger_fit.md entry 17).
    """
    p = np.asarray(parker, dtype=float)
    p /= np.linalg.norm(p)
    v = powerlaw(rng, n, 3, -5.0 / 3.0, 1.0 / (12 * 3600.0), 0.5)
    # |u| ~ 1 with s p of unit length and a v of rms a sqrt(3) per vector: the angle
    # spread gives dB/B ~ rotation for a = rotation / sqrt(3) (small-angle)
    a = rotation / np.sqrt(3.0)
    dwell = rng.uniform(sector_days[0] * DAY_S, sector_days[1] * DAY_S,
                        size=int(n / (sector_days[0] * DAY_S)) + 3)
    flips = np.cumsum(dwell) - rng.uniform(0.0, dwell[0])
    s = rng.choice([-1.0, 1.0]) * np.where(
        np.searchsorted(flips, np.arange(n), side="right") % 2 == 0, 1.0, -1.0)
    u = s[:, None] * p[None, :] + a * v
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    g = powerlaw(rng, n, 1, -2.0, 1.0 / (4 * DAY_S), 1.0 / (12 * 3600.0))[:, 0]
    h = (powerlaw(rng, n, 1, -5.0 / 3.0, 1.0 / 3600.0, 0.5) if broadband
         else powerlaw(rng, n, 1, -2.0, 1.0 / 3600.0, 1.0 / 300.0))[:, 0]
    mag = b_nt * np.exp(0.15 * g) * (1.0 + compressive * h)
    return u * mag[:, None]
