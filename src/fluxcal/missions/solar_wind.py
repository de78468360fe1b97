"""A realistic solar-wind magnetic field for the missions' forward models (issue 21).

Shared by the simulators (`fluxcal.missions.messenger.flight_sim`,
`fluxcal.missions.messenger.simulate`, `fluxcal.missions.rosetta.simulate`); numpy and
scipy only, no calibration or pipeline code (``tests/missions/test_forward_independence.py``).

The field is ``B = |B| u`` on a regular grid (docs/decisions/messenger_fit_verification.md,
section 2):

* **direction** ``u = normalise(s p + c v)``: ``p`` a fixed mean (Parker-spiral) direction,
  ``s = +-1`` the sector polarity, flipping after dwell times drawn uniformly from
  ``sector_days``, ``v`` three independent unit-variance Gaussian components with a
  power spectrum ``f^-5/3`` between the periods ``longest_s`` (12 h) and ``shortest_s``
  (2 s), synthesised in Fourier space (`power_law_process`), ``c`` the weight that
  gives the rms rotation ``dB/B``:
  Alfvenic rotations at nearly constant ``|B|`` (Belcher and Davis 1971);
* **magnitude** ``|B| = b_median exp(sigma g) (1 + f h)``: ``g`` a smooth unit-variance
  process of correlation time about ``b_correlation_s`` (two cascaded relaxations of half
  that time each: almost no change within an hour), ``h`` a unit-variance relaxation of
  ``compressive_correlation_s``, ``f`` the compressive fraction (3 %).

A run is a function of the `numpy.random.Generator` passed in; no per-sample Python loop.

References
----------
.. [1] Belcher, J. W., and L. Davis (1971), Large-amplitude Alfven waves in the
   interplanetary medium, 2, J. Geophys. Res., 76, 3534.
.. [2] Bruno, R., and V. Carbone (2013), The solar wind as a turbulence laboratory,
   Living Rev. Solar Phys., 10, 2 (the f^-5/3 inertial range, dB/B ~ 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.fft import irfft, next_fast_len
from scipy.signal import lfilter

DAY_S = 86_400.0


@dataclass
class AlfvenicWind:
    """Statistics of the realistic solar wind (nT, s; directions in the frame of the grid).

    Attributes
    ----------
    b_median_nt, b_log_sigma, b_correlation_s : float
        ``|B|`` is ``b_median_nt exp(b_log_sigma g)``, ``g`` smooth, unit variance,
        correlation time about ``b_correlation_s``.
    rotation_weight : float
        ``c`` of ``normalise(s p + c v)``; 0.40 gives an rms rotation ``dB/B`` of 0.55
        (measured, docs/decisions/messenger_fit_verification.md section 2).
    spectral_index : float
        ``v``'s power spectrum falls as ``f^-spectral_index`` between the periods
        ``longest_s`` and ``shortest_s``.
    longest_s, shortest_s : float
        Periods (s) bounding the power law (no power outside).
    compressive_fraction, compressive_correlation_s : float
        Relative rms and correlation time of the compressive factor ``1 + f h``.
    mean_direction : tuple of float
        ``p`` (normalised), fixed in the grid's frame.
    sector_days : tuple of float or None
        Range (days) of the sector dwell times, uniform; None: one polarity throughout.
    """

    b_median_nt: float = 18.0
    b_log_sigma: float = 0.15
    b_correlation_s: float = 12 * 3600.0
    rotation_weight: float = 0.40
    spectral_index: float = 5.0 / 3.0
    longest_s: float = 12 * 3600.0
    shortest_s: float = 2.0
    compressive_fraction: float = 0.03
    compressive_correlation_s: float = 300.0
    mean_direction: tuple[float, float, float] = (0.55, -0.6, 0.58)
    sector_days: tuple[float, float] | None = (1.0, 3.0)


def relaxation(rng: np.random.Generator, n: int, tau_s: float, dims: int = 1,
               step_s: float = 1.0) -> np.ndarray:
    """Stationary unit-variance first-order relaxation (AR(1)) on a grid, shape (n, dims).

    ``x[k] = a x[k-1] + sqrt(1 - a^2) e[k]`` with ``a = exp(-step_s / tau_s)``, started from
    its stationary distribution (no burn-in).
    """
    a = float(np.exp(-step_s / tau_s))
    x0 = rng.standard_normal((1, dims))
    e = rng.standard_normal((n, dims))
    return lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], e, axis=0, zi=a * x0)[0]


def smooth_process(rng: np.random.Generator, n: int, correlation_s: float, dims: int = 1,
                   step_s: float = 1.0) -> np.ndarray:
    """Unit-variance Gaussian process of two cascaded relaxations of ``correlation_s / 2``.

    Spectrum ``f^-4`` above its corner: nearly constant over intervals much shorter than
    ``correlation_s``.  Started ``6 correlation_s`` early so the start is stationary.
    """
    tau = 0.5 * correlation_s
    a = float(np.exp(-step_s / tau))
    burn = int(6 * correlation_s / step_s) + 1
    x = rng.standard_normal((n + burn, dims))
    for _ in range(2):
        x = lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], x, axis=0)
    return x[burn:] / np.sqrt((1.0 + a * a) / (1.0 - a * a))


def power_law_process(rng: np.random.Generator, n: int, dims: int = 3, *,
                      spectral_index: float = 5.0 / 3.0, longest_s: float = 12 * 3600.0,
                      shortest_s: float = 2.0, step_s: float = 1.0) -> np.ndarray:
    """Unit-variance Gaussian process with a power spectrum ``f^-spectral_index``, (n, dims).

    Synthesised in Fourier space: independent complex Gaussian coefficients of amplitude
    ``f^(-index/2)`` for ``1/longest_s <= f <= 1/shortest_s`` (none outside: no aliasing
    onto the grid), one real inverse FFT per component over at least four times
    ``longest_s`` (a short series keeps the power of the long periods), the first ``n``
    samples kept.  Normalised by the spectrum's own variance, not the sample's.
    """
    m = next_fast_len(max(n, int(np.ceil(4.0 * longest_s / step_s))), real=True)
    f = np.fft.rfftfreq(m, d=step_s)
    amp = np.zeros_like(f)
    band = (f >= 1.0 / longest_s) & (f <= 1.0 / shortest_s) & (f < 0.5 / step_s)
    if not band.any():
        raise ValueError(f"no frequency of a {step_s:g}-s grid lies between 1/{longest_s:g} "
                         f"and 1/{shortest_s:g} Hz")
    amp[band] = f[band] ** (-0.5 * spectral_index)
    # irfft of X_k = amp_k (a + i b) adds (2 / m) Re(X_k exp(2 pi i k t / m)) for each
    # interior k, of variance 4 amp_k^2 / m^2 (a, b unit normals)
    scale = m / (2.0 * np.sqrt(np.sum(amp**2)))
    out = np.empty((n, dims))
    for j in range(dims):
        coef = amp * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
        out[:, j] = irfft(coef, n=m)[:n] * scale
    return out


def sector_polarity(rng: np.random.Generator, n: int, days: tuple[float, float],
                    step_s: float = 1.0) -> np.ndarray:
    """Sector polarity ``+-1`` on a grid of ``n`` steps: flips after uniform dwell times."""
    lo, hi = days[0] * DAY_S, days[1] * DAY_S
    dwell = rng.uniform(lo, hi, size=int(n * step_s / lo) + 3)
    flips = np.cumsum(dwell) - rng.uniform(0.0, dwell[0])
    sign = rng.choice([-1.0, 1.0])
    count = np.searchsorted(flips, np.arange(n) * step_s, side="right")
    return sign * np.where(count % 2 == 0, 1.0, -1.0)


def alfvenic_wind(rng: np.random.Generator, n: int, model: AlfvenicWind | None = None,
                  step_s: float = 1.0) -> np.ndarray:
    """Return the realistic field (nT) on a grid of ``n`` steps of ``step_s``, (n, 3).

    See the module docstring; ``model`` defaults to `AlfvenicWind()` (18 nT, dB/B 0.55,
    f^-5/3 from 12 h to 2 s, 3 % compressive, sectors of 1-3 days).
    """
    m = model or AlfvenicWind()
    p = np.asarray(m.mean_direction, dtype=float)
    p = p / np.linalg.norm(p)
    v = power_law_process(rng, n, 3, spectral_index=m.spectral_index, longest_s=m.longest_s,
                          shortest_s=m.shortest_s, step_s=step_s)
    s = (sector_polarity(rng, n, m.sector_days, step_s) if m.sector_days is not None
         else np.ones(n))
    u = s[:, None] * p + m.rotation_weight * v
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    g = smooth_process(rng, n, m.b_correlation_s, 1, step_s)[:, 0]
    h = relaxation(rng, n, m.compressive_correlation_s, 1, step_s)[:, 0]
    mag = m.b_median_nt * np.exp(m.b_log_sigma * g) * (1.0 + m.compressive_fraction * h)
    return u * mag[:, None]
