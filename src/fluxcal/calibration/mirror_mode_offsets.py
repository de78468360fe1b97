"""Offsets from compressive, linearly polarised fluctuations (mirror-mode method).

In a mirror-mode structure the field magnitude changes while its direction stays
fixed, so the measured vectors ``B_meas = O + |B(t)| e`` of one interval lie on a
straight line along ``e`` that passes through the offset ``O`` [1]_.  The line is
found as the interval's mean vector and maximum-variance direction; many such lines
with different directions meet (in the least-squares sense) at ``O``:

    ``sum_k P_k O = sum_k P_k <B_meas>_k``,  ``P_k = I - e_k e_k^T``,

i.e. ``O`` minimises the summed squared perpendicular distances to the lines, each
interval weighted equally.  Plaschke and Narita used one component (the spin-axis
offset, the spin-plane ones being known) [1]_; here all three are solved for, as
on a three-axis stabilised spacecraft such as BepiColombo and its predecessor at Mercury [2]_.

Selection criteria (each a parameter; the first failed one is the reason):

1. ``too_few_samples``: fewer than ``min_samples`` valid samples.
2. ``not_linear``: ``lambda_max / lambda_int`` below ``min_linearity`` -- the
   fluctuations do not lie along one direction.
3. ``small_fluctuations``: ``sqrt(lambda_max)`` below ``min_relative_amplitude``
   times ``|<B_meas> - O|`` -- the line direction is then poorly defined.
4. ``oblique``: angle between the maximum-variance direction and the mean field
   ``<B_meas> - O`` above ``max_angle_deg`` -- not compressive along the field
   (e.g. a linearly polarised transverse wave) [1]_, [2]_.

Criteria 3-4 use the current offset estimate, as in
`fluxcal.calibration.variance_offsets`.

References
----------
.. [1] Plaschke, F. and Narita, Y., "On determining fluxgate magnetometer spin axis
   offsets from mirror mode observations", Ann. Geophys. 34, 759-766 (2016).
.. [2] Schmid, D. et al., "Magnetometer in-flight offset accuracy for the
   BepiColombo spacecraft", Ann. Geophys. 38, 823-832 (2020): mirror-mode offsets
   from magnetosheath data at Mercury agree with the solar-wind (Alfvenic) ones.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from fluxcal.calibration.solar_wind_offsets import (
    IntervalMoments,
    OffsetEstimate,
    bootstrap_covariance,
    check_offset_guess,
    field_moments,
    first_failure,
    settle_selection,
    solve_pooled,
)
from fluxcal.errors import InputFormatError

__all__ = ["mirror_mode_offsets", "mirror_mode_offsets_from_moments"]


def mirror_mode_offsets(
    b: ArrayLike,
    interval_index: ArrayLike | None = None,
    *,
    interval_length: int | None = None,
    **options: Any,
) -> OffsetEstimate:
    """Offsets as the common point of the lines traced by compressive intervals.

    ``field_moments(b, ...)`` followed by `mirror_mode_offsets_from_moments`, whose
    keyword ``options`` it takes.

    Parameters
    ----------
    b : array_like, shape (n, 3)
        Measured field (offset not removed); rows with a NaN are gaps.
    interval_index : array_like of int, shape (n,), optional
        Interval label per sample (negative: not used).  Or give ``interval_length``.
    interval_length : int, optional
        Consecutive blocks of this many samples as intervals.
    **options
        Selection criteria, ``offset_guess``, ``max_selection_passes``,
        ``n_bootstrap``, ``seed`` of `mirror_mode_offsets_from_moments`.

    Returns
    -------
    OffsetEstimate

    References
    ----------
    .. [1] Plaschke and Narita (2016), Schmid et al. (2020) (see module).
    """
    moments = field_moments(b, interval_index, interval_length=interval_length)
    return mirror_mode_offsets_from_moments(moments, **options)


def mirror_mode_offsets_from_moments(
    moments: IntervalMoments,
    *,
    min_samples: int = 60,
    min_linearity: float = 10.0,
    min_relative_amplitude: float = 0.05,
    max_angle_deg: float = 10.0,
    offset_guess: ArrayLike | None = None,
    max_selection_passes: int = 10,
    n_bootstrap: int = 1000,
    seed: int | np.random.Generator | None = None,
) -> OffsetEstimate:
    """Mirror-mode offsets from per-interval moments of ``B``.

    Parameters
    ----------
    moments : IntervalMoments
        From ``field_moments(b, ...)`` (not ``squared``), or several joined by
        `concatenate_moments`.
    min_samples, min_linearity, min_relative_amplitude, max_angle_deg
        Selection criteria (module docstring); defaults and reasons in
        ``docs/decisions/solar_wind_offsets.md``.
    offset_guess : array_like, shape (3,), optional
        Offset at which criteria 3-4 are first evaluated; without it the first
        estimate uses criteria 1-2 only.
    max_selection_passes : int
        Passes of select-then-solve before giving up on a stable selection.
    n_bootstrap : int
        Bootstrap resamples of the accepted intervals (0: no uncertainty).
    seed : int or Generator, optional
        For the bootstrap.

    Returns
    -------
    OffsetEstimate
        ``per_interval`` is the point of each line closest to the pooled offset
        (criteria 1-2 passed, else NaN); its distance from ``offset`` is the
        interval's residual.

    Raises
    ------
    InputFormatError
        Bad shapes or arguments.
    FluxcalError
        The lines do not fix all three components (e.g. all parallel), or the
        selection does not settle.

    References
    ----------
    .. [1] Plaschke and Narita (2016), Schmid et al. (2020) (see module).
    """
    m = moments
    if m.mean.ndim != 2 or m.mean.shape[1] != 3:
        raise InputFormatError(
            f"expected moments of B, dimension 3, got {m.mean.shape}", field="moments"
        )
    o = check_offset_guess(offset_guess)
    k = m.count.size
    labels = np.arange(k, dtype=np.int64) if m.labels is None else m.labels
    w, v = np.linalg.eigh(m.cov)
    e = v[:, :, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        linearity = np.where(w[:, 1] > 0, w[:, 2] / w[:, 1], np.inf)
    linearity[w[:, 2] <= 0] = 0.0
    projector = np.eye(3) - e[:, :, None] * e[:, None, :]
    foot_rhs = np.einsum("kij,kj->ki", projector, m.mean)
    static = [
        ("too_few_samples", m.count >= min_samples),
        ("not_linear", linearity >= min_linearity),
    ]

    def solve(reason):
        use = reason == ""
        return solve_pooled(projector[use].sum(0), foot_rhs[use].sum(0), "mirror_mode", reason)

    def checks(offset):
        mean_field = m.mean - offset
        norm = np.linalg.norm(mean_field, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.abs(np.einsum("ki,ki->k", e, mean_field)) / norm
            amplitude = np.sqrt(np.maximum(w[:, 2], 0.0)) / norm
        angle = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
        return first_failure(
            static
            + [
                ("small_fluctuations", amplitude >= min_relative_amplitude),
                ("oblique", angle <= max_angle_deg),
            ],
            k,
        )

    if offset_guess is None:
        o = solve(first_failure(static, k))
    o, reason, passes = settle_selection(checks, solve, o, max_selection_passes, "mirror_mode")
    use = reason == ""
    good = first_failure(static, k) == ""
    per_interval = np.full((k, 3), np.nan)
    along = np.einsum("ki,ki->k", e, o - m.mean)
    per_interval[good] = (m.mean + along[:, None] * e)[good]
    covariance, n_boot = bootstrap_covariance(
        projector[use], foot_rhs[use], n_bootstrap, seed, "mirror_mode"
    )
    return OffsetEstimate(
        method="mirror_mode",
        offset=o,
        covariance=covariance,
        labels=labels,
        reason=reason,
        per_interval=per_interval,
        n_bootstrap=n_boot,
        iterations=passes,
        criteria={
            "min_samples": int(min_samples),
            "min_linearity": float(min_linearity),
            "min_relative_amplitude": float(min_relative_amplitude),
            "max_angle_deg": float(max_angle_deg),
        },
    )
