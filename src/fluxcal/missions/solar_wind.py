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
  (2 s) (`power_law_process`), ``c`` the weight that gives the rms rotation ``dB/B``:
  Alfvenic rotations at nearly constant ``|B|`` (Belcher and Davis 1971);
* **magnitude** ``|B| = b_median exp(sigma g) (1 + f h)``: ``g`` a smooth unit-variance
  process of correlation time about ``b_correlation_s`` (two cascaded relaxations of half
  that time each: almost no change within an hour), ``h`` a unit-variance relaxation of
  ``compressive_correlation_s``, ``f`` the compressive fraction (3 %).

A run is a function of the `numpy.random.Generator` passed in; no per-sample Python loop
(a loop over the ~18 relaxation stages and the sector dwell times only).

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
        Periods (s) bounding the power law (flat below ``1/longest_s``, ``f^-2`` above
        ``1/shortest_s``).
    stages_per_decade : int
        Relaxation stages per decade of the power law (4: ripple of a few percent).
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
    stages_per_decade: int = 4
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
                      shortest_s: float = 2.0, stages_per_decade: int = 4,
                      step_s: float = 1.0) -> np.ndarray:
    """Unit-variance Gaussian process with a power spectrum ``f^-spectral_index``, (n, dims).

    A weighted sum of independent stationary relaxations (`relaxation`) whose corner
    frequencies ``1 / (2 pi tau_k)`` are spaced ``stages_per_decade`` per decade from
    ``1 / longest_s`` to ``1 / shortest_s``: each stage has the Lorentzian spectrum
    ``2 tau / (1 + (2 pi f tau)^2)``, and weights ``w_k^2 ~ tau_k^(index - 1)`` make the sum
    follow ``f^-index`` between the corners (flat below, ``f^-2`` above).  Memory: two
    (n, dims) arrays; time: one IIR pass per stage.
    """
    if not 0.0 < spectral_index < 2.0:
        raise ValueError(f"spectral_index must be in (0, 2), got {spectral_index}")
    decades = np.log10(longest_s / shortest_s)
    count = max(int(np.ceil(decades * stages_per_decade)) + 1, 2)
    tau = np.logspace(np.log10(shortest_s), np.log10(longest_s), count) / (2.0 * np.pi)
    weight = tau ** (0.5 * (spectral_index - 1.0))
    weight /= np.sqrt(np.sum(weight**2))
    out = np.zeros((n, dims))
    for w, t in zip(weight, tau, strict=True):
        out += w * relaxation(rng, n, float(t), dims, step_s)
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
                          shortest_s=m.shortest_s, stages_per_decade=m.stages_per_decade,
                          step_s=step_s)
    s = (sector_polarity(rng, n, m.sector_days, step_s) if m.sector_days is not None
         else np.ones(n))
    u = s[:, None] * p + m.rotation_weight * v
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    g = smooth_process(rng, n, m.b_correlation_s, 1, step_s)[:, 0]
    h = relaxation(rng, n, m.compressive_correlation_s, 1, step_s)[:, 0]
    mag = m.b_median_nt * np.exp(m.b_log_sigma * g) * (1.0 + m.compressive_fraction * h)
    return u * mag[:, None]
