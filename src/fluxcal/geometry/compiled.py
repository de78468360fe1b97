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
def _rotate(x, y, z, w, vx, vy, vz):
    """``R(q) v`` for ``q = (x, y, z, w)``, via ``t = 2 u x v``."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


@njit(cache=True, nogil=True, inline="always")
def _rotate_into(x, y, z, w, v, out, j):
    """``out[j] = R(q) v[j]`` for ``q = (x, y, z, w)``."""
    out[j, 0], out[j, 1], out[j, 2] = _rotate(x, y, z, w, v[j, 0], v[j, 1], v[j, 2])


@njit(cache=True, nogil=True, inline="always")
def _slerp_at(nodes, q0, ortho, theta, t, hint):
    """``(x, y, z, w, i)``: a leg's SLERPed quaternion at ``t`` (``nodes.size >= 2``).

    ``i`` is the interval of ``t`` (`_interval`, from the interval ``hint``).
    """
    i = _interval(nodes, t, hint)
    s = (t - nodes[i]) / (nodes[i + 1] - nodes[i])
    angle = s * theta[i]
    c, sn = np.cos(angle), np.sin(angle)
    return (q0[i, 0] * c + ortho[i, 0] * sn, q0[i, 1] * c + ortho[i, 1] * sn,
            q0[i, 2] * c + ortho[i, 2] * sn, q0[i, 3] * c + ortho[i, 3] * sn, i)


@njit(cache=True, nogil=True, inline="always")
def _fixed_quaternion(nodes, q0):
    """Return a still leg's quaternion: its single node, or the identity (J2000 itself)."""
    if nodes.size == 1:
        return q0[0, 0], q0[0, 1], q0[0, 2], q0[0, 3]
    return 0.0, 0.0, 0.0, 1.0


@njit(cache=True, nogil=True, inline="always")
def _compose(tx, ty, tz, tw, sx, sy, sz, sw):
    """``conj(qt) * qs`` (Hamilton product, scalar last): source -> J2000 -> target."""
    px, py, pz, pw = -tx, -ty, -tz, tw
    return (pw * sx + px * sw + py * sz - pz * sy,
            pw * sy - px * sz + py * sw + pz * sx,
            pw * sz + px * sy - py * sx + pz * sw,
            pw * sw - px * sx - py * sy - pz * sz)


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
    sx, sy, sz, sw = _fixed_quaternion(source_nodes, source_q0)
    tx, ty, tz, tw = _fixed_quaternion(target_nodes, target_q0)
    i = 0
    k = 0
    for j in range(et.size):
        t = et[j]
        if has_source:
            sx, sy, sz, sw, i = _slerp_at(source_nodes, source_q0, source_ortho,
                                          source_theta, t, i)
        if has_target:
            tx, ty, tz, tw, k = _slerp_at(target_nodes, target_q0, target_ortho,
                                          target_theta, t, k)
        x, y, z, w = _compose(tx, ty, tz, tw, sx, sy, sz, sw)
        for a in range(len(vectors)):
            if inverse[a]:
                _rotate_into(-x, -y, -z, w, vectors[a], outs[a], j)
            else:
                _rotate_into(x, y, z, w, vectors[a], outs[a], j)


@njit(cache=True, nogil=True)
def attitude_frames(attitude, leg, et, field, sun, position, field_inertial, sun_body, leg_out):
    """Rotate a field through an attitude leg into J2000 and one more frame, in one pass.

    Per epoch: the ``body -> J2000`` attitude is interpolated once and gives the J2000
    field and the unit Sun direction in the body frame; the ``J2000 -> frame`` leg
    (``leg``) then rotates that J2000 field and a J2000 position.  Every value is bit for
    bit what the separate passes give (the same operations in the same order):
    ``slerp_rotate(attitude, J2000, [field, unit_rows(sun, -1)], inverse=[False, True])``
    and ``slerp_rotate(J2000, leg, [position, field_inertial])`` -- so a frame computed
    later from the J2000 field alone (`fluxcal.geometry.frames.Rotator`) equals the one
    computed here.  One pass instead of three, no Sun-direction temporary.

    Parameters
    ----------
    attitude : tuple of ndarray
        SLERP table ``(nodes, q0, ortho, theta)`` of the leg ``body -> J2000``
        (`slerp_table`).
    leg : tuple of ndarray
        SLERP table of a leg ``frame -> J2000`` (applied inverted); skipped when no
        output of it is written.
    et : ndarray, shape (n,)
        Epochs.
    field : ndarray, shape (n, 3)
        Field in the body frame.
    sun : ndarray, shape (n, 3)
        Body relative to the Sun, J2000 (km): the Sun direction is ``-sun / |sun|``.
    position : ndarray, shape (n, 3)
        A J2000 position rotated into the frame (e.g. relative to a planet).
    field_inertial, sun_body : ndarray, shape (n, 3) or (0, 3)
        Outputs: J2000 field, unit Sun direction in the body frame; an empty array is
        not written.
    leg_out : tuple of two ndarray, shape (n, 3) or (0, 3)
        Outputs of the leg: ``(position, field)`` in that frame (empty: not written).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 10.1 (positions in
           MSO), sec. 11 (``cspice_pxform`` + ``cspice_mxv``).
    """
    nodes, q0, ortho, theta = attitude
    n1, q1, o1, th1 = leg
    has_attitude = nodes.size >= 2
    sx, sy, sz, sw = _fixed_quaternion(nodes, q0)
    leg_pos, leg_field = leg_out
    write_pos = leg_pos.shape[0] > 0
    write_field = leg_field.shape[0] > 0
    use_leg = write_pos or write_field
    leg_moving = n1.size >= 2
    tx, ty, tz, tw = _fixed_quaternion(n1, q1)
    write_inertial = field_inertial.shape[0] > 0
    write_sun = sun_body.shape[0] > 0
    i = 0
    h = 0
    for j in range(et.size):
        t = et[j]
        if has_attitude:
            sx, sy, sz, sw, i = _slerp_at(nodes, q0, ortho, theta, t, i)
        x, y, z, w = _compose(0.0, 0.0, 0.0, 1.0, sx, sy, sz, sw)
        bx, by, bz = _rotate(x, y, z, w, field[j, 0], field[j, 1], field[j, 2])
        if write_inertial:
            field_inertial[j, 0], field_inertial[j, 1], field_inertial[j, 2] = bx, by, bz
        if write_sun:
            ux, uy, uz = _unit(sun[j, 0], sun[j, 1], sun[j, 2], -1.0)
            sun_body[j, 0], sun_body[j, 1], sun_body[j, 2] = _rotate(-x, -y, -z, w, ux, uy, uz)
        # the J2000 -> frame leg as slerp_rotate forms it with J2000 as source (conj(qt) * 1)
        if use_leg:
            if leg_moving:
                tx, ty, tz, tw, h = _slerp_at(n1, q1, o1, th1, t, h)
            x, y, z, w = _compose(tx, ty, tz, tw, 0.0, 0.0, 0.0, 1.0)
            if write_pos:
                _rotate_into(x, y, z, w, position, leg_pos, j)
            if write_field:
                leg_field[j, 0], leg_field[j, 1], leg_field[j, 2] = _rotate(
                    x, y, z, w, bx, by, bz)


@njit(cache=True, nogil=True)
def first_outside(starts, ends, et):
    """Index of the first epoch outside every window ``[starts[k], ends[k]]``, or -1.

    The windows are sorted and disjoint (a SPICE window); NaN is outside.  The window of
    each epoch is found from the previous one (`count_le`): O(1) per sorted epoch.
    """
    k = 0
    for j in range(et.size):
        t = et[j]
        k = count_le(starts, t, k)
        if k == 0 or not t <= ends[k - 1]:
            return j
    return -1


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


@njit(cache=True, nogil=True, inline="always")
def _rtn(sx, sy, sz, ox, oy, oz, vx, vy, vz):
    """``(R.v, T.v, N.v)``: ``R = sun / |sun|``, ``T = unit(pole x R)``, ``N = R x T``."""
    norm = np.sqrt(sx * sx + sy * sy + sz * sz)
    rx, ry, rz = sx / norm, sy / norm, sz / norm
    tx, ty, tz = oy * rz - oz * ry, oz * rx - ox * rz, ox * ry - oy * rx
    norm = np.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / norm, ty / norm, tz / norm
    nx, ny, nz = ry * tz - rz * ty, rz * tx - rx * tz, rx * ty - ry * tx
    return (rx * vx + ry * vy + rz * vz, tx * vx + ty * vy + tz * vz,
            nx * vx + ny * vy + nz * vz)


@njit(cache=True, nogil=True)
def rtn_rotate(sun, pole, vectors, out):
    """Rotate J2000 vectors into RTN built from the Sun -> spacecraft position per sample.

    ``R = sun / |sun|``, ``T = unit(pole x R)``, ``N = R x T``; ``out = (R.v, T.v, N.v)``.
    ``pole`` is (1, 3) (a fixed solar rotation axis) or (n, 3).
    """
    per_sample = pole.shape[0] > 1
    for j in range(sun.shape[0]):
        p = j if per_sample else 0
        out[j, 0], out[j, 1], out[j, 2] = _rtn(
            sun[j, 0], sun[j, 1], sun[j, 2], pole[p, 0], pole[p, 1], pole[p, 2],
            vectors[j, 0], vectors[j, 1], vectors[j, 2])


@njit(cache=True, nogil=True)
def apply_matrix(matrix, vectors, out):
    """``out[j] = matrix @ vectors[j]`` for one fixed (3, 3) matrix."""
    for j in range(vectors.shape[0]):
        vx, vy, vz = vectors[j, 0], vectors[j, 1], vectors[j, 2]
        for k in range(3):
            out[j, k] = matrix[k, 0] * vx + matrix[k, 1] * vy + matrix[k, 2] * vz


@njit(cache=True, nogil=True, inline="always")
def _unit(x, y, z, sign):
    """``sign * v / |v|``."""
    scale = sign / np.sqrt(x * x + y * y + z * z)
    return x * scale, y * scale, z * scale


@njit(cache=True, nogil=True)
def unit_rows(v, sign, out):
    """``out[j] = sign * v[j] / |v[j]|``; returns nothing (in place into ``out``)."""
    for j in range(v.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = _unit(v[j, 0], v[j, 1], v[j, 2], sign)


@njit(cache=True, nogil=True)
def row_norms(v, out):
    """``out[j] = |v[j]|``."""
    for j in range(v.shape[0]):
        out[j] = np.sqrt(v[j, 0] * v[j, 0] + v[j, 1] * v[j, 1] + v[j, 2] * v[j, 2])


@njit(cache=True, nogil=True)
def _slopes(xp, fp):
    """``(fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])`` per interval (numpy's ``slopes``)."""
    out = np.empty(max(xp.size - 1, 0))
    for j in range(out.size):
        out[j] = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    return out


@njit(cache=True, nogil=True)
def interp_into(x, xp, fp, out):
    """``out[:] = np.interp(x, xp, fp)`` bit for bit, for increasing ``xp`` (size >= 1).

    numpy's ``arr_interp`` (``compiled_base.c``) case by case: NaN for a NaN ``x``, the
    end values outside ``xp``, ``fp[j]`` at a node ``j``, else ``slopes[j] * (x - xp[j])
    + fp[j]`` (from the right node when that is NaN) with numpy's ``slopes``.  The
    interval is found from the previous one (`count_le`): O(1) for sorted ``x``.  (Written
    out flat: numba compiles this as a helper with several returns ~5x slower.)
    """
    m = xp.size
    slopes = _slopes(xp, fp)
    k = 0
    for i in range(x.size):
        t = x[i]
        if t != t:
            v = t
        elif t > xp[m - 1]:
            v = fp[m - 1]
        elif t < xp[0]:
            v = fp[0]
        else:
            k = count_le(xp, t, k)
            j = k - 1
            if j == m - 1 or xp[j] == t:
                v = fp[j]
            else:
                v = slopes[j] * (t - xp[j]) + fp[j]
                if v != v:
                    v = slopes[j] * (t - xp[j + 1]) + fp[j + 1]
                    if v != v and fp[j] == fp[j + 1]:
                        v = fp[j]
        out[i] = v


@njit(cache=True, nogil=True)
def rtn_spherical_interp(sun, et, grid, lat, az, out):
    """Sec. 10.2 per sample from angles on a grid (`interp_into`, no temporaries).

    ``out[:, 0] = |sun|``; ``out[:, 1] = np.interp(et, grid, lat)``; ``out[:, 2] =
    np.interp(et, grid, np.unwrap(az, period=360))`` (`unwrap_degrees`), wrapped back by
    ``(a + 180) % 360 - 180`` where ``|a| > 180`` -- the numpy expressions of
    `fluxcal.geometry.axes.spherical_rtn`, bit for bit (``grid``
    increasing).  One compiled function for the whole step: one numba cache load.
    """
    unwrapped = np.empty(az.size)
    unwrap_degrees(az, unwrapped)
    interp_into(et, grid, lat, out[:, 1])
    interp_into(et, grid, unwrapped, out[:, 2])
    row_norms(sun, out[:, 0])
    for j in range(et.size):
        a = out[j, 2]
        if abs(a) > 180.0:
            out[j, 2] = (a + 180.0) % 360.0 - 180.0


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
