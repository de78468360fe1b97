"""Spacecraft positions, vectorized: Cartesian in any frame, and the spherical RTN set.

`position` evaluates ``spkezr`` (position and velocity) on a grid and interpolates with
cubic Hermite polynomials; the grid step is halved until the error measured against
``spkpos`` at the grid mid-points is below the tolerance (1e-4 km by default).
``method="oracle"`` calls ``spkpos`` once per sample.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 10.1 "Cartesian
       Coordinates" and sec. 10.2 "Spherical Coordinates".
"""

from __future__ import annotations

import numpy as np
import spiceypy

from fluxcal.errors import KernelError
from fluxcal.geometry import compiled
from fluxcal.geometry.cspice_loops import spkezr_into
from fluxcal.geometry.kernels import spice_errors
from fluxcal.geometry.spans import sample_spans, span_grid

#: Default accuracy of interpolated positions (km).
DEFAULT_POSITION_TOLERANCE = 1e-4


def _utc(et: float) -> str:
    try:
        return spiceypy.et2utc(float(et), "ISOC", 3)
    except spiceypy.utils.exceptions.SpiceyError:
        return f"ET {et:.3f}"


def _per_epoch(call, et: np.ndarray, out: np.ndarray, what: str) -> np.ndarray:
    """Fill ``out[i] = call(et[i])``, one SPICE call per epoch (the reference paths).

    A SPICE error is raised again by `spice_errors` naming ``what`` and the failing
    epoch's UTC; the context (with its UTC string) is built only for that epoch.
    """
    i = 0
    try:
        for i, t in enumerate(et):
            out[i] = call(float(t))
    except spiceypy.utils.exceptions.SpiceyError:
        with spice_errors(f"{what} at {_utc(et[i])}"):
            call(float(et[i]))
    return out


def states_oracle(target: str, observer: str, frame: str, et: np.ndarray) -> np.ndarray:
    """Return (n, 6) states (km, km/s) with one ``spkezr`` call per epoch, abcorr NONE.

    The calls go through `fluxcal.geometry.cspice_loops.spkezr_into` (``spkezr_c``
    without spiceypy's per-call wrapping, the same values).
    """
    et = np.atleast_1d(np.asarray(et, dtype=float))
    out = np.empty((et.size, 6))
    if spkezr_into(target, observer, frame, et, out):  # the same CSPICE call, one loop
        return out
    # an error: repeat through spiceypy to raise naming the epoch
    return _per_epoch(lambda t: spiceypy.spkezr(target, t, frame, "NONE", observer)[0], et,
                      out, f"state of {target} relative to {observer} in {frame}")


def position_oracle(target: str, observer: str, frame: str, et: np.ndarray) -> np.ndarray:
    """Return (n, 3) positions (km) with one ``spkpos`` call per epoch (the reference path)."""
    et = np.atleast_1d(np.asarray(et, dtype=float))
    return _per_epoch(lambda t: spiceypy.spkpos(target, t, frame, "NONE", observer)[0], et,
                      np.empty((et.size, 3)),
                      f"position of {target} relative to {observer} in {frame}")


def hermite_coefficients(nodes: np.ndarray, states: np.ndarray) -> np.ndarray:
    """Per-interval cubic coefficients of the Hermite interpolant, shape (m - 1, 4, 3).

    On interval ``i`` with ``s = (t - t_i) / h_i``, the position is
    ``c0 + s c1 + s**2 c2 + s**3 c3`` with the node positions ``p`` and velocities ``v``.
    """
    h = np.diff(nodes)[:, None]
    p0, p1 = states[:-1, :3], states[1:, :3]
    v0, v1 = states[:-1, 3:] * h, states[1:, 3:] * h
    c2 = -3.0 * p0 - 2.0 * v0 + 3.0 * p1 - v1
    c3 = 2.0 * p0 + v0 - 2.0 * p1 + v1
    return np.stack([p0, v0, c2, c3], axis=1)


def hermite(
    nodes: np.ndarray, states: np.ndarray, et: np.ndarray, coefficients: np.ndarray | None = None
) -> np.ndarray:
    """Cubic Hermite interpolation of positions from node positions and velocities.

    Parameters
    ----------
    nodes : ndarray, shape (m,)
        Increasing node times.
    states : ndarray, shape (m, 6)
        Position (km) and velocity (km/s) at the nodes.
    et : ndarray, shape (n,)
        Times within ``[nodes[0], nodes[-1]]``.
    coefficients : ndarray, optional
        `hermite_coefficients` of ``nodes, states`` when already computed.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    if coefficients is None:
        coefficients = hermite_coefficients(nodes, states)
    i = np.clip(np.searchsorted(nodes, et, side="right") - 1, 0, nodes.size - 2)
    s = ((et - nodes.take(i)) / np.diff(nodes).take(i))[:, None]
    c = coefficients.take(i, axis=0)
    out = c[:, 3] * s
    out += c[:, 2]
    out *= s
    out += c[:, 1]
    out *= s
    out += c[:, 0]
    return out


class StateInterpolator:
    """Positions of ``target`` relative to ``observer`` in ``frame`` on a verified grid.

    Parameters
    ----------
    target, observer : str
        SPICE body names or ids (e.g. a spacecraft's name or NAIF id, ``"MERCURY"``).
    frame : str
        Frame of the output positions.
    tmin, tmax : float
        Interval (ET) to cover.
    tolerance : float
        Accuracy in km.
    step : float
        First grid step in seconds.
    spans : ndarray, shape (k, 2), optional
        Intervals (ET) with samples (`fluxcal.geometry.spans.sample_spans`); the grid
        covers each and nothing between them (default: ``[[tmin, tmax]]``).
        `over_samples` builds it for given epochs.
    """

    #: Samples per block of the Hermite evaluation (keeps temporaries in cache).
    CHUNK = 1 << 15

    def __init__(
        self,
        target: str,
        observer: str,
        frame: str,
        tmin: float,
        tmax: float,
        *,
        tolerance: float = DEFAULT_POSITION_TOLERANCE,
        step: float = 300.0,
        spans: np.ndarray | None = None,
    ) -> None:
        self.target, self.observer, self.frame = target, observer, frame
        if spans is None:
            n = max(int(np.ceil((tmax - tmin) / step)), 1)
            nodes, check = np.linspace(tmin, tmax, n + 1), np.ones(n, dtype=bool)
        else:  # no node, and no check, in a gap between spans
            nodes, check = span_grid(spans, step)
        if nodes.size < 2:  # one epoch: its exact state, held
            nodes = np.r_[nodes, nodes[0] + step]
            check = np.zeros(1, dtype=bool)
            states = states_oracle(target, observer, frame, nodes[:1])
            states = np.vstack([states, states])
        else:
            states = states_oracle(target, observer, frame, nodes)
        # bisect every interval whose mid-point error exceeds the tolerance
        for _ in range(40):
            idx = np.flatnonzero(check)
            mids = 0.5 * (nodes[idx] + nodes[idx + 1])
            truth = states_oracle(target, observer, frame, mids) if idx.size else \
                np.empty((0, 6))
            error = np.abs(hermite(nodes, states, mids) - truth[:, :3]).max(axis=1)
            bad = error > tolerance
            if not bad.any():
                self.nodes, self.states = nodes, states
                self.coefficients = np.ascontiguousarray(hermite_coefficients(nodes, states))
                return
            where = idx[bad] + 1
            nodes = np.insert(nodes, where, mids[bad])
            states = np.insert(states, where, truth[bad], axis=0)
            new_pos = where + np.arange(where.size)
            check = np.zeros(nodes.size - 1, dtype=bool)
            check[new_pos - 1] = True
            check[new_pos] = True
        raise KernelError(
            f"positions of {target} relative to {observer} cannot be interpolated to "
            f"{tolerance} km; use method='oracle'"
        )

    @classmethod
    def over_samples(cls, target: str, observer: str, frame: str, et: np.ndarray,
                     **kwargs: float) -> StateInterpolator:
        """Return the interpolator over the spans of ``et`` (`sample_spans`), not its gaps.

        SPICE is asked only about the spans where samples are: two files of one run
        months apart need no kernel for the months between them.
        """
        spans = sample_spans(et)
        return cls(target, observer, frame, float(spans[0, 0]), float(spans[-1, 1]),
                   spans=spans, **kwargs)

    def __call__(self, et: np.ndarray) -> np.ndarray:
        """Return (n, 3) interpolated positions (km) at ``et``.

        The compiled loop `compiled.hermite_positions`; `hermite` is its numpy reference.
        """
        et = np.ascontiguousarray(np.atleast_1d(et), dtype=float)
        out = np.empty((et.size, 3))
        compiled.hermite_positions(self.nodes, self.coefficients, et, out)
        return out

    def states_at(self, et: np.ndarray) -> np.ndarray:
        """Return (n, 6) interpolated states (velocity from the Hermite derivative)."""
        et = np.asarray(et, dtype=float)
        nodes, states = self.nodes, self.states
        i = np.clip(np.searchsorted(nodes, et, side="right") - 1, 0, nodes.size - 2)
        h = (nodes[i + 1] - nodes[i])[:, None]
        s = ((et - nodes[i]) / h[:, 0])[:, None]
        p0, v0, p1, v1 = states[i, :3], states[i, 3:], states[i + 1, :3], states[i + 1, 3:]
        d00 = (6 * s * s - 6 * s) / h
        d10 = 3 * s * s - 4 * s + 1
        d01 = (-6 * s * s + 6 * s) / h
        d11 = 3 * s * s - 2 * s
        vel = d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1
        return np.hstack([self(et), vel])


def position(
    target: str,
    observer: str,
    frame: str,
    et: np.ndarray,
    *,
    method: str = "interpolate",
    tolerance: float = DEFAULT_POSITION_TOLERANCE,
) -> np.ndarray:
    """Return the position of ``target`` relative to ``observer`` in ``frame`` (km).

    No light-time correction (``abcorr = 'NONE'``), as seed 000 sec. 10.1 prescribes.

    Parameters
    ----------
    target, observer : str
        SPICE body names or ids.
    frame : str
        Output frame (e.g. ``"J2000"``, a mission's dynamic frame, ``"IAU_MERCURY"``).
    et : array_like, shape (n,)
        Ephemeris times.
    method : {"interpolate", "oracle"}
        Verified Hermite interpolation (default) or one ``spkpos`` per sample.
    tolerance : float
        Accuracy of the interpolated path (km).

    Returns
    -------
    ndarray, shape (n, 3)

    Examples
    --------
    A spacecraft relative to the Sun in J2000 and to Mercury in its body-fixed frame
    (seed 000 sec. 10.1)::

        position(spacecraft, "SUN", "J2000", et)
        position(spacecraft, "MERCURY", "IAU_MERCURY", et)
    """
    et = np.atleast_1d(np.asarray(et, dtype=float))
    if method == "oracle":
        return position_oracle(target, observer, frame, et)
    if method != "interpolate":
        raise ValueError(f"method must be 'interpolate' or 'oracle', not {method!r}")
    if et.size < 4:
        return position_oracle(target, observer, frame, et)
    interp = StateInterpolator.over_samples(target, observer, frame, et, tolerance=tolerance)
    return interp(et)


def rtn_spherical(
    target: str,
    et: np.ndarray,
    *,
    observer: str = "SUN",
    frame: str = "J2000",
    method: str = "interpolate",
    target_position: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spherical heliocentric position of seed 000 sec. 10.2.

    Parameters
    ----------
    target : str
        The spacecraft (SPICE name or NAIF id).
    et : array_like, shape (n,)
        Ephemeris times.
    observer : str
        Centre, the Sun.
    frame : str
        Inertial frame in which the vectors are formed (``pframe``); the angles do not
        depend on it.
    method : {"interpolate", "oracle"}
        As for `position`.
    target_position : ndarray, shape (n, 3), optional
        The target's position relative to ``observer`` in ``frame`` when the caller
        already has it (saves recomputing it).

    Returns
    -------
    r_km : ndarray
        Distance from the Sun (km).
    lat_deg : ndarray
        Latitude above the instantaneous ecliptic plane, the plane normal to
        ``r_earth x v_earth`` (deg).
    az_deg : ndarray
        Azimuth in that plane from the Sun->Earth direction, positive in the direction of
        the Earth's orbital motion (deg).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 10.2 (the
       ``cspice_vcrss``/``vsep``/``vperp``/``vprjp`` sequence, written here in numpy).
    """
    et = np.atleast_1d(np.asarray(et, dtype=float))
    if target_position is None:
        target_position = position(target, observer, frame, et, method=method)
    m_pos = np.asarray(target_position, dtype=float)
    if method == "oracle" or et.size < 4:
        earth_states = lambda t: states_oracle("EARTH", observer, frame, t)  # noqa: E731
    else:
        earth_states = StateInterpolator.over_samples("EARTH", observer, frame, et).states_at
    r = np.empty(et.size)
    lat = np.empty(et.size)
    az = np.empty(et.size)
    for start in range(0, et.size, StateInterpolator.CHUNK):
        block = slice(start, start + StateInterpolator.CHUNK)
        r[block], lat[block], az[block] = _ecliptic_angles(m_pos[block], earth_states(et[block]))
    return r, lat, az


def _ecliptic_angles(
    m_pos: np.ndarray, earth: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance, latitude and azimuth of ``m_pos`` from the Earth's heliocentric state."""
    r_e, v_e = earth[:, :3], earth[:, 3:]
    r = np.linalg.norm(m_pos, axis=1)
    normal = np.cross(r_e, v_e)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    height = np.einsum("ij,ij->i", normal, m_pos)
    lat = np.degrees(np.arcsin(np.clip(height / r, -1.0, 1.0)))
    proj = m_pos - height[:, None] * normal
    # vperp(v_earth, r_earth): component of the Earth velocity orthogonal to its position
    e_hat = r_e / np.linalg.norm(r_e, axis=1)[:, None]
    v_perp = v_e - np.einsum("ij,ij->i", v_e, e_hat)[:, None] * e_hat
    sign = np.where(np.einsum("ij,ij->i", v_perp, proj) < 0, -1.0, 1.0)
    cos_az = np.einsum("ij,ij->i", e_hat, proj) / np.linalg.norm(proj, axis=1)
    az = sign * np.degrees(np.arccos(np.clip(cos_az, -1.0, 1.0)))
    return r, lat, az
