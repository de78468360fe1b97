"""Lower-triangular gain/alignment matrices (counts -> nT) and their use per sample.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8, Table 4.
"""

from __future__ import annotations

import numpy as np

from fluxcal.calibration._compiled import apply_per_range_kernel


def lower_triangular_matrix(
    kx: float, ky: float, kz: float, alpha: float, beta: float, gamma: float
) -> np.ndarray:
    """Return the counts-to-nT matrix of eq. 8.

    ``B_x = kx c_x``; ``B_y = alpha kx c_x + ky c_y``;
    ``B_z = beta kx c_x + gamma ky c_y + kz c_z``.

    Parameters
    ----------
    kx, ky, kz : float
        Gains (nT per count).
    alpha, beta, gamma : float
        Cross-axis terms: X in Y, X in Z, Y in Z.

    Returns
    -------
    ndarray, shape (3, 3)

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8, Table 4.
    """
    return np.array(
        [
            [kx, 0.0, 0.0],
            [alpha * kx, ky, 0.0],
            [beta * kx, gamma * ky, kz],
        ]
    )


def apply_per_range(
    vectors: np.ndarray, range_flag: np.ndarray, matrices: np.ndarray
) -> np.ndarray:
    """Multiply each vector by the matrix of its own range.

    One compiled pass (`fluxcal.calibration._compiled.apply_per_range_kernel`);
    `apply_per_range_reference` is the numpy version the tests compare with.

    Parameters
    ----------
    vectors : ndarray, shape (n, 3)
    range_flag : ndarray of int, shape (n,)
        Index into ``matrices`` for each sample.
    matrices : ndarray, shape (m, 3, 3)

    Returns
    -------
    ndarray, shape (n, 3)

    Raises
    ------
    ValueError
        When a range flag is outside ``0..m-1``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8, Table 4.
    """
    v = np.asarray(vectors, dtype=float)
    flags = np.asarray(range_flag)
    m = np.ascontiguousarray(matrices, dtype=float)
    if (v.ndim != 2 or v.shape[1] != 3 or m.ndim != 3 or m.shape[1:] != (3, 3)
            or flags.shape != v.shape[:1] or flags.dtype.kind not in "iu"):
        return apply_per_range_reference(vectors, range_flag, matrices)
    out = np.empty_like(v)
    used = np.any(m != 0.0, axis=0)  # terms the reference does not skip
    bad = apply_per_range_kernel(v, flags, m, used, out)
    if bad >= 0:
        raise ValueError(f"range_flag: values outside 0..{m.shape[0] - 1}")
    return out


def apply_per_range_reference(
    vectors: np.ndarray, range_flag: np.ndarray, matrices: np.ndarray
) -> np.ndarray:
    """Numpy reference of `apply_per_range` (the tests compare the two).

    Parameters and returns as `apply_per_range`.
    """
    vectors = np.asarray(vectors, dtype=float)
    range_flag = np.asarray(range_flag)
    matrices = np.asarray(matrices, dtype=float)
    if range_flag.size and (range_flag.min() < 0 or range_flag.max() >= matrices.shape[0]):
        raise ValueError(f"range_flag: values outside 0..{matrices.shape[0] - 1}")
    # per-sample matrix elements gathered from the small table: out_i = sum_j M[r]_ij v_j
    m = matrices.reshape(matrices.shape[0], 9)
    out = np.zeros_like(vectors)
    for i in range(3):
        for j in range(3):
            coef = m[:, 3 * i + j]
            if not coef.any():
                continue
            c = coef[0] if np.all(coef == coef[0]) else coef.take(range_flag)
            out[:, i] += c * vectors[:, j]
    return out


def counts_to_nt(counts: np.ndarray, range_flag: np.ndarray, matrices: np.ndarray) -> np.ndarray:
    """Convert offset-corrected counts to nT with each sample's range matrix (eq. 8).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 8, eq. 8.
    """
    return apply_per_range(counts, range_flag, matrices)


def nt_to_counts(field_nt: np.ndarray, range_flag: np.ndarray, matrices: np.ndarray) -> np.ndarray:
    """Invert eq. 8: nT -> (unquantised) counts for each sample's range."""
    return apply_per_range(field_nt, range_flag, np.linalg.inv(matrices))


def range_conversion(matrices: np.ndarray, reference: int = 0) -> np.ndarray:
    """Return ``M_r^-1 M_ref`` for every range ``r`` (shape (m, 3, 3)).

    An offset known in counts of range ``reference`` (the fine range in seed 000)
    expressed in counts of range ``r`` is ``M_r^-1 M_ref c_ref`` (same field in nT).
    """
    return np.linalg.inv(matrices) @ matrices[reference]
