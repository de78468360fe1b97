"""Minimum variance analysis (MVA) of a vector time series.

The eigenvectors of the 3x3 covariance matrix of the field define the
*minimum variance frame*.  fluxcal orders and signs them deterministically:

* order: ``x`` = maximum variance, ``y`` = intermediate, ``z`` = minimum variance
  (the heater procedure of seed 003 works on the maximum variance component, which the
  seed calls "B_x of the minimum variance system");
* sign: the minimum variance axis points along the mean vector
  (``e_min . <B> >= 0``); the maximum variance axis has its largest Cartesian
  component positive; the intermediate axis completes a right-handed triad,
  ``e_int = e_min x e_max`` (so ``e_max x e_int = e_min`` and
  ``det([e_max, e_int, e_min]) = +1``).

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1),
   sec. 4.11 (LEVEL_J) and sec. 4.12.1 (minimum variance frame for heater steps).
.. [2] Sonnerup, B. U. O. and Scheible, M., "Minimum and maximum variance
   analysis", ISSI Scientific Report SR-001, ch. 8 (1998).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fluxcal.errors import InputFormatError

__all__ = ["MinimumVarianceResult", "minimum_variance"]


@dataclass(frozen=True)
class MinimumVarianceResult:
    """Result of `minimum_variance`.

    Attributes
    ----------
    eigenvalues : ndarray, shape (3,)
        Variances along the axes, in descending order (max, intermediate, min), in
        the squared units of the input (e.g. nT^2).
    eigenvectors : ndarray, shape (3, 3)
        Unit axes as **columns** ``[e_max, e_int, e_min]`` in the input frame; a proper
        rotation (right-handed, determinant +1).
    mean : ndarray, shape (3,)
        Mean vector of the analysed samples.
    """

    eigenvalues: NDArray[np.float64]
    eigenvectors: NDArray[np.float64]
    mean: NDArray[np.float64]

    @property
    def ratio(self) -> float:
        """Intermediate-to-minimum eigenvalue ratio ``lambda_int / lambda_min``.

        A large ratio (conventionally > 10) means the minimum variance direction is well
        defined.  ``inf`` when the minimum eigenvalue is zero.
        """
        lmin = self.eigenvalues[2]
        return float(np.inf) if lmin <= 0 else float(self.eigenvalues[1] / lmin)

    @property
    def max_ratio(self) -> float:
        """Maximum-to-intermediate eigenvalue ratio (how well the max axis is defined)."""
        lint = self.eigenvalues[1]
        return float(np.inf) if lint <= 0 else float(self.eigenvalues[0] / lint)

    def to_frame(self, vectors: ArrayLike) -> NDArray[np.float64]:
        """Components of ``vectors`` (n, 3) along ``(e_max, e_int, e_min)``."""
        return np.asarray(vectors, dtype=float) @ self.eigenvectors

    def from_frame(self, components: ArrayLike) -> NDArray[np.float64]:
        """Inverse of `to_frame`: vectors in the input frame from MVA components."""
        return np.asarray(components, dtype=float) @ self.eigenvectors.T


def minimum_variance(vectors: ArrayLike) -> MinimumVarianceResult:
    """Minimum variance analysis of a vector series.

    Parameters
    ----------
    vectors : array_like, shape (n, 3)
        Field samples (n >= 3, finite).

    Returns
    -------
    MinimumVarianceResult
        Eigenvalues (descending), eigenvectors (columns, right-handed, signs fixed by
        the convention of this module's docstring) and mean.

    Raises
    ------
    InputFormatError
        If ``vectors`` is not (n, 3) with n >= 3 or contains non-finite values.

    References
    ----------
    .. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028), sec. 4.12.1.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 1000, endpoint=False)
    >>> b = np.stack([3 * np.sin(t), np.cos(t), 0.01 * np.sin(3 * t) + 5], axis=1)
    >>> mva = minimum_variance(b)
    >>> np.round(mva.eigenvectors[:, 2], 3) + 0.0
    array([0., 0., 1.])
    >>> round(mva.ratio)
    10000
    """
    b = np.asarray(vectors, dtype=float)
    if b.ndim != 2 or b.shape[1] != 3 or b.shape[0] < 3:
        raise InputFormatError(
            f"expected an (n, 3) array with n >= 3, got shape {b.shape}", field="vectors"
        )
    if not np.all(np.isfinite(b)):
        raise InputFormatError("contains non-finite values", field="vectors")
    mean = b.mean(axis=0)
    d = b - mean
    cov = d.T @ d / b.shape[0]
    values, vecs = np.linalg.eigh(cov)  # ascending
    values = values[::-1].copy()
    vecs = vecs[:, ::-1].copy()
    e_max, e_min = vecs[:, 0], vecs[:, 2]
    if e_max[np.argmax(np.abs(e_max))] < 0:
        e_max = -e_max
    ref = mean if np.linalg.norm(mean) > 0 else np.ones(3)
    if float(e_min @ ref) < 0 or (float(e_min @ ref) == 0 and e_min[np.argmax(np.abs(e_min))] < 0):
        e_min = -e_min
    e_int = np.cross(e_min, e_max)
    axes = np.column_stack([e_max, e_int, e_min])
    return MinimumVarianceResult(
        eigenvalues=np.clip(values, 0.0, None), eigenvectors=axes, mean=mean
    )
