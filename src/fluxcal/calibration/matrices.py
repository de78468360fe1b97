"""Calibration matrices: orthogonalisation (misalignment), sensitivity, stacked products.

The orthogonalisation matrix omega of a three-axis fluxgate with angles xi_xy, xi_xz,
xi_yz between its axes is upper triangular.  Seed 003 prints two forms:

- sec. 3.2.1: ``omega[0, 2] = cos(xi_xz) / sin(xi_xy)``,
- sec. 3.2.2.3 / 4.2.3.2: ``omega[0, 2] = cos(xi_xz)``,

with the other elements equal.  fluxcal uses the second (``form="unit"``, every column a
unit vector: the sensor axes expressed in an orthogonal frame); ``form="sec321"`` gives
the first for comparison (docs/decisions/rosetta.md).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2.1, 3.2.2.3, 4.2.3.2 item 5.
"""

from __future__ import annotations

import numpy as np


def orthogonalisation_matrix(
    xi_xy: np.ndarray, xi_xz: np.ndarray, xi_yz: np.ndarray, *, form: str = "unit"
) -> np.ndarray:
    """Return omega(xi) for every sample, shape ``(n, 3, 3)``; angles in degrees.

    Parameters
    ----------
    xi_xy, xi_xz, xi_yz : array_like, shape (n,)
        Angles between the sensor axes, degrees (90 = orthogonal).
    form : {"unit", "sec321"}
        ``"unit"``: seed 003 sec. 3.2.2.3 / 4.2.3.2 (omega[0,2] = cos xi_xz); ``"sec321"``:
        seed 003 sec. 3.2.1 (omega[0,2] = cos xi_xz / sin xi_xy).

    Returns
    -------
    ndarray, shape (n, 3, 3)

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2.1 and 3.2.2.3.
    """
    if form not in ("unit", "sec321"):
        raise ValueError(f"form must be 'unit' or 'sec321', not {form!r}")
    a, b, c = (np.deg2rad(np.asarray(v, dtype=float)) for v in (xi_xy, xi_xz, xi_yz))
    cxy, sxy, cxz, sxz, cyz = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c)
    w12 = (cyz - cxy * cxz) / sxy
    out = np.zeros(a.shape + (3, 3))
    out[..., 0, 0] = 1.0
    out[..., 0, 1] = cxy
    out[..., 0, 2] = cxz if form == "unit" else cxz / sxy
    out[..., 1, 1] = sxy
    out[..., 1, 2] = w12
    out[..., 2, 2] = np.sqrt(sxz**2 - w12**2)
    return out


def apply(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Apply ``(n, 3, 3)`` (or one ``(3, 3)``) matrices to ``(n, 3)`` vectors.

    Written as nine multiply-adds on contiguous component arrays: several times faster
    than ``np.einsum`` or ``vectors @ m.T`` for long ``(n, 3)`` arrays.
    """
    m = np.asarray(matrices, dtype=float)
    v = np.asarray(vectors, dtype=float)
    cols = [np.ascontiguousarray(v[:, j]) for j in range(3)]
    out = np.empty((v.shape[0], 3))
    for i in range(3):
        if m.ndim == 2:
            out[:, i] = m[i, 0] * cols[0] + m[i, 1] * cols[1] + m[i, 2] * cols[2]
        else:
            out[:, i] = m[:, i, 0] * cols[0] + m[:, i, 1] * cols[1] + m[:, i, 2] * cols[2]
    return out


def apply_lookup(table: np.ndarray, index: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Apply ``table[index[k]]`` (``(m, 3, 3)`` table) to ``vectors[k]``, no ``(n, 3, 3)`` array.

    For matrices that depend on a quantised quantity (e.g. a 16-bit temperature word):
    the table holds one matrix per word and ``index`` picks it per sample.
    """
    v = np.asarray(vectors, dtype=float)
    cols = [np.ascontiguousarray(v[:, j]) for j in range(3)]
    out = np.empty((v.shape[0], 3))
    flat = table.reshape(table.shape[0], 9)
    for i in range(3):
        acc = np.zeros(v.shape[0])
        for j in range(3):
            if np.any(flat[:, 3 * i + j] != 0.0):
                acc += np.take(flat[:, 3 * i + j], index) * cols[j]
        out[:, i] = acc
    return out


def solve(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Return ``x`` with ``matrices @ x = vectors`` per sample (inverse of `apply`)."""
    m = np.asarray(matrices, dtype=float)
    v = np.asarray(vectors, dtype=float)
    if m.ndim == 2:
        return np.linalg.solve(m, v.T).T
    return np.linalg.solve(m, v[..., None])[..., 0]
