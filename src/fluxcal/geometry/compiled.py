"""Compiled per-sample loops of the geometry hot path (numba).

Each function here does, in one pass over the samples and without temporaries, what a
chain of numpy expressions in `fluxcal.geometry.frames` and `fluxcal.geometry.positions`
does over whole arrays: locate the node interval of each epoch, interpolate (SLERP of
quaternions, cubic Hermite of positions) and apply the result to vectors.  The numpy
versions stay as the reference implementations; the tests compare the two.

All loops walk the epochs with a moving interval hint: sorted epochs (the usual case)
cost O(1) per sample, unsorted ones fall back to a binary search.  Quaternions are scalar
last, as in `fluxcal.geometry.frames`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 10 (positions), sec. 11
       (``cspice_pxform`` + ``cspice_mxv`` per sample, here interpolated).
.. [2] NAIF, "CK Required Reading": type 3 C-kernels interpolate at constant angular rate
       about a fixed axis between records, i.e. SLERP.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _bisect_right(nodes, x):
    """``np.searchsorted(nodes, x, side="right")`` (NaN sorts after every node)."""
    lo = 0
    hi = nodes.size
    while lo < hi:
        mid = (lo + hi) >> 1
        if x < nodes[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True, nogil=True, inline="always")
def count_le(nodes, x, hint):
    """``np.searchsorted(nodes, x, side="right")`` given the answer for a nearby ``x``.

    Parameters
    ----------
    nodes : ndarray, shape (m,)
        Non-decreasing.
    x : float
    hint : int
        An earlier answer (``0..m``); the next interval is tried before a bisection.

    Notes
    -----
    Shared by the compiled loops of `fluxcal.calibration._compiled` and
    `fluxcal.geometry.time`.  numba's on-disk cache of those loops does not notice an
    edit here (numba issue #1833): after changing this function, clear the
    ``__pycache__/*.nbi``/``*.nbc`` files of the importing modules.
    """
    m = nodes.size
    k = hint
    if (k == 0 or nodes[k - 1] <= x) and (k == m or x < nodes[k]):
        return k
    if k < m and nodes[k] <= x and (k + 1 == m or x < nodes[k + 1]):
        return k + 1
    return _bisect_right(nodes, x)


@njit(cache=True, nogil=True, inline="always")
def _interval(nodes, t, hint):
    """Index ``i`` in ``[0, m - 2]`` with ``nodes[i] <= t < nodes[i + 1]`` (clipped).

    `count_le` from the interval ``hint`` of the previous epoch: O(1) per sample for
    sorted epochs, a binary search otherwise.
    """
    return min(max(count_le(nodes, t, hint + 1) - 1, 0), nodes.size - 2)


@njit(cache=True, nogil=True, inline="always")
def _rotate_into(x, y, z, w, v, out, j):
    """``out[j] = R(q) v[j]`` for ``q = (x, y, z, w)``, via ``t = 2 u x v``."""
    vx, vy, vz = v[j, 0], v[j, 1], v[j, 2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out[j, 0] = vx + w * tx + (y * tz - z * ty)
    out[j, 1] = vy + w * ty + (z * tx - x * tz)
    out[j, 2] = vz + w * tz + (x * ty - y * tx)


@njit(cache=True, nogil=True)
def slerp_rotate(
    source_nodes, source_q0, source_ortho, source_theta,
    target_nodes, target_q0, target_ortho, target_theta,
    et, vectors, inverse, outs,
):
    """Rotate vectors by ``R(J2000 -> target) R(source -> J2000)`` SLERPed per epoch.

    Parameters
    ----------
    source_nodes, source_q0, source_ortho, source_theta : ndarray
        SLERP table of the leg ``source -> J2000`` (see `slerp_table`); an empty
        ``source_nodes`` means the source is J2000 itself.
    target_nodes, target_q0, target_ortho, target_theta : ndarray
        The same for ``target -> J2000`` (applied inverted); empty for J2000.
    et : ndarray, shape (n,)
        Epochs.
    vectors : tuple of ndarray, shape (n, 3) each
        Vectors in the source frame (C-contiguous float64).
    inverse : tuple of bool
        Per array: apply the inverse rotation (``target -> source``) instead.
    outs : tuple of ndarray, shape (n, 3) each
        Outputs, written in place.
    """
    has_source = source_nodes.size >= 2
    has_target = target_nodes.size >= 2
    sx, sy, sz, sw = 0.0, 0.0, 0.0, 1.0
    tx, ty, tz, tw = 0.0, 0.0, 0.0, 1.0
    if source_nodes.size == 1:
        sx, sy, sz, sw = source_q0[0, 0], source_q0[0, 1], source_q0[0, 2], source_q0[0, 3]
    if target_nodes.size == 1:
        tx, ty, tz, tw = target_q0[0, 0], target_q0[0, 1], target_q0[0, 2], target_q0[0, 3]
    i = 0
    k = 0
    for j in range(et.size):
        t = et[j]
        # the SLERP of each leg is written out here: numba compiles a helper returning
        # the quaternion as a tuple 3-4x slower than this flat form
        if has_source:
            i = _interval(source_nodes, t, i)
            s = (t - source_nodes[i]) / (source_nodes[i + 1] - source_nodes[i])
            angle = s * source_theta[i]
            c, sn = np.cos(angle), np.sin(angle)
            sx = source_q0[i, 0] * c + source_ortho[i, 0] * sn
            sy = source_q0[i, 1] * c + source_ortho[i, 1] * sn
            sz = source_q0[i, 2] * c + source_ortho[i, 2] * sn
            sw = source_q0[i, 3] * c + source_ortho[i, 3] * sn
        if has_target:
            k = _interval(target_nodes, t, k)
            s = (t - target_nodes[k]) / (target_nodes[k + 1] - target_nodes[k])
            angle = s * target_theta[k]
            c, sn = np.cos(angle), np.sin(angle)
            tx = target_q0[k, 0] * c + target_ortho[k, 0] * sn
            ty = target_q0[k, 1] * c + target_ortho[k, 1] * sn
            tz = target_q0[k, 2] * c + target_ortho[k, 2] * sn
            tw = target_q0[k, 3] * c + target_ortho[k, 3] * sn
        # q = conj(qt) * qs (Hamilton product, scalar last)
        px, py, pz, pw = -tx, -ty, -tz, tw
        x = pw * sx + px * sw + py * sz - pz * sy
        y = pw * sy - px * sz + py * sw + pz * sx
        z = pw * sz + px * sy - py * sx + pz * sw
        w = pw * sw - px * sx - py * sy - pz * sz
        for a in range(len(vectors)):
            if inverse[a]:
                _rotate_into(-x, -y, -z, w, vectors[a], outs[a], j)
            else:
                _rotate_into(x, y, z, w, vectors[a], outs[a], j)


@njit(cache=True, nogil=True)
def slerp_quaternions(nodes, q0, ortho, theta, et, out):
    """Write the SLERPed (n, 4) quaternions of one leg at ``et`` into ``out``."""
    i = 0
    for j in range(et.size):
        t = et[j]
        i = _interval(nodes, t, i)
        angle = (t - nodes[i]) / (nodes[i + 1] - nodes[i]) * theta[i]
        c, sn = np.cos(angle), np.sin(angle)
        for k in range(4):
            out[j, k] = q0[i, k] * c + ortho[i, k] * sn


@njit(cache=True, nogil=True)
def hermite_positions(nodes, coefficients, et, out):
    """Cubic Hermite positions ``c0 + s c1 + s^2 c2 + s^3 c3`` per epoch into ``out``.

    ``coefficients`` is `fluxcal.geometry.positions.hermite_coefficients` (m - 1, 4, 3);
    ``s = (t - t_i) / h_i`` on the interval holding ``t``.
    """
    h = 0
    for j in range(et.size):
        t = et[j]
        i = _interval(nodes, t, h)
        h = i
        s = (t - nodes[i]) / (nodes[i + 1] - nodes[i])
        for k in range(3):
            out[j, k] = ((coefficients[i, 3, k] * s + coefficients[i, 2, k]) * s
                         + coefficients[i, 1, k]) * s + coefficients[i, 0, k]


@njit(cache=True, nogil=True)
def rtn_rotate(sun, pole, vectors, out):
    """Rotate J2000 vectors into RTN built from the Sun -> spacecraft position per sample.

    ``R = sun / |sun|``, ``T = unit(pole x R)``, ``N = R x T``; ``out = (R.v, T.v, N.v)``.
    ``pole`` is (1, 3) (a fixed solar rotation axis) or (n, 3).
    """
    per_sample = pole.shape[0] > 1
    for j in range(sun.shape[0]):
        p = j if per_sample else 0
        sx, sy, sz = sun[j, 0], sun[j, 1], sun[j, 2]
        norm = np.sqrt(sx * sx + sy * sy + sz * sz)
        rx, ry, rz = sx / norm, sy / norm, sz / norm
        ox, oy, oz = pole[p, 0], pole[p, 1], pole[p, 2]
        tx, ty, tz = oy * rz - oz * ry, oz * rx - ox * rz, ox * ry - oy * rx
        norm = np.sqrt(tx * tx + ty * ty + tz * tz)
        tx, ty, tz = tx / norm, ty / norm, tz / norm
        nx, ny, nz = ry * tz - rz * ty, rz * tx - rx * tz, rx * ty - ry * tx
        vx, vy, vz = vectors[j, 0], vectors[j, 1], vectors[j, 2]
        out[j, 0] = rx * vx + ry * vy + rz * vz
        out[j, 1] = tx * vx + ty * vy + tz * vz
        out[j, 2] = nx * vx + ny * vy + nz * vz


@njit(cache=True, nogil=True)
def apply_matrix(matrix, vectors, out):
    """``out[j] = matrix @ vectors[j]`` for one fixed (3, 3) matrix."""
    for j in range(vectors.shape[0]):
        vx, vy, vz = vectors[j, 0], vectors[j, 1], vectors[j, 2]
        for k in range(3):
            out[j, k] = matrix[k, 0] * vx + matrix[k, 1] * vy + matrix[k, 2] * vz


@njit(cache=True, nogil=True)
def unit_rows(v, sign, out):
    """``out[j] = sign * v[j] / |v[j]|``; returns nothing (in place into ``out``)."""
    for j in range(v.shape[0]):
        x, y, z = v[j, 0], v[j, 1], v[j, 2]
        scale = sign / np.sqrt(x * x + y * y + z * z)
        out[j, 0] = x * scale
        out[j, 1] = y * scale
        out[j, 2] = z * scale


@njit(cache=True, nogil=True)
def row_norms(v, out):
    """``out[j] = |v[j]|``."""
    for j in range(v.shape[0]):
        out[j] = np.sqrt(v[j, 0] * v[j, 0] + v[j, 1] * v[j, 1] + v[j, 2] * v[j, 2])


@njit(cache=True, nogil=True, inline="always")
def interp_at(xp, fp, x, hint):
    """``(np.interp(x, xp, fp), j)`` for increasing ``xp`` (size >= 1); ``j`` the next hint.

    numpy's ``arr_interp`` (``compiled_base.c``) case by case, so the value is numpy's bit
    for bit: the end values outside ``xp``, ``fp[-1]`` at ``xp[-1]``, ``fp[j]`` at a
    node, else ``slope * (x - xp[j]) + fp[j]`` (from the right node when that is NaN);
    NaN for a NaN ``x``.  ``hint`` is the previous answer (`count_le`).
    """
    m = xp.size
    if x != x:
        return x, hint
    if x > xp[m - 1] or m == 1 and x >= xp[0]:
        return fp[m - 1], hint
    if x < xp[0]:
        return fp[0], hint
    k = count_le(xp, x, hint)
    j = k - 1
    if j == m - 1 or xp[j] == x:
        return fp[j], k
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    value = slope * (x - xp[j]) + fp[j]
    if value != value:
        value = slope * (x - xp[j + 1]) + fp[j + 1]
        if value != value and fp[j] == fp[j + 1]:
            value = fp[j]
    return value, k


@njit(cache=True, nogil=True)
def rtn_spherical_interp(sun, et, grid, lat, az, out):
    """Sec. 10.2 per sample from angles on a grid, in one pass.

    ``out[:, 0] = |sun|``; ``out[:, 1] = np.interp(et, grid, lat)``; ``out[:, 2] =
    np.interp(et, grid, az)`` (``az`` unwrapped), wrapped back by ``(a + 180) % 360 -
    180`` where ``|a| > 180`` -- the numpy expressions of
    `fluxcal.missions.messenger.levels.spherical_rtn`, bit for bit.
    """
    hint = 0
    for j in range(et.size):
        x, y, z = sun[j, 0], sun[j, 1], sun[j, 2]
        out[j, 0] = np.sqrt(x * x + y * y + z * z)
        t = et[j]
        out[j, 1], _ = interp_at(grid, lat, t, hint)
        a, hint = interp_at(grid, az, t, hint)  # the same interval as lat's
        if abs(a) > 180.0:
            a = (a + 180.0) % 360.0 - 180.0
        out[j, 2] = a


@njit(cache=True, nogil=True)
def unwrap_degrees(angle, out):
    """``out[:] = np.unwrap(angle, period=360.0)`` in one pass, no temporaries.

    The same operations in the same order as numpy's ``unwrap`` (floor-mod of the step
    + 180, -180 turned to +180 for a positive step, no correction below 180 deg,
    sequential sum of the corrections, a NaN step making the rest NaN), so the result
    is bit for bit numpy's.
    """
    n = angle.shape[0]
    if n == 0:
        return
    out[0] = angle[0]
    correction = 0.0
    for j in range(1, n):
        step = angle[j] - angle[j - 1]
        wrapped = (step + 180.0) % 360.0 - 180.0
        if wrapped == -180.0 and step > 0.0:
            wrapped = 180.0
        if not abs(step) < 180.0:  # numpy zeroes only where |step| < 180: NaN propagates
            correction += wrapped - step
        out[j] = angle[j] + correction


def slerp_table(nodes: np.ndarray, quats: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per-interval SLERP terms ``(nodes, q0, ortho, theta)`` of a leg.

    ``q(s) = q0 cos(s theta) + ortho sin(s theta)`` on each interval (the form of
    `fluxcal.geometry.frames.slerp`); a single node gives ``q0 = quats`` and empty terms.
    """
    nodes = np.ascontiguousarray(nodes, dtype=float)
    quats = np.ascontiguousarray(quats, dtype=float)
    if nodes.size < 2:
        return nodes, quats, np.zeros_like(quats), np.zeros(quats.shape[0])
    q0, q1 = quats[:-1], quats[1:]
    dot = np.clip(np.einsum("ij,ij->i", q0, q1), -1.0, 1.0)
    theta = np.maximum(np.arccos(dot), 1e-12)
    ortho = (q1 - q0 * dot[:, None]) / np.sin(theta)[:, None]
    return nodes, np.ascontiguousarray(q0), np.ascontiguousarray(ortho), theta


#: The table of the identity leg (J2000 itself).
IDENTITY_TABLE = (np.empty(0), np.empty((0, 4)), np.empty((0, 4)), np.empty(0))
