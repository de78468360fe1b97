"""Sun-based axes: the solar rotation axis, RTN from positions, heliocentric angles.

Generic helpers for a spacecraft's Radial-Tangential-Normal frame and its
heliocentric position angles; the spacecraft is an argument (its NAIF name, and the
names a frames kernel may use for it).

* `solar_axis`: IAU_SUN +Z in J2000 (fixed, or per sample for a precessing pole);
* `rtn_from_position`: J2000 vectors into RTN built from the Sun -> spacecraft
  position (``R = sun/|sun|``, ``T = unit(Omega x R)``, ``N = R x T``);
* `is_sun_pole_rtn`: whether a loaded frame is that two-vector RTN definition;
* `spherical_rtn`: distance from the Sun, ecliptic latitude and azimuth per sample,
  on a grid and interpolated when the samples are dense.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 3.5 (RTN), sec. 10.2
       (heliocentric angles), sec. 11.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import spiceypy

from fluxcal.geometry import compiled
from fluxcal.geometry.frames import Rotator, rotation_matrices
from fluxcal.geometry.positions import rtn_spherical
from fluxcal.geometry.spans import sample_spans, span_grid

#: Grid step (s) of the heliocentric angles when the samples are denser (`spherical_rtn`).
RTN_ANGLE_STEP_S = 1.0


def _sun_pole_rtn_definition(targets: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Kernel-pool keyword -> accepted values of the two-vector Sun-pole RTN frame."""
    return {
        "CLASS": ("5",), "RELATIVE": ("J2000",), "DEF_STYLE": ("PARAMETERIZED",),
        "FAMILY": ("TWO-VECTOR",), "PRI_AXIS": ("X",),
        "PRI_VECTOR_DEF": ("OBSERVER_TARGET_POSITION",), "PRI_OBSERVER": ("SUN", "10"),
        "PRI_TARGET": tuple(str(t).upper() for t in targets), "PRI_ABCORR": ("NONE",),
        "SEC_AXIS": ("Z",), "SEC_VECTOR_DEF": ("CONSTANT",), "SEC_FRAME": ("IAU_SUN",),
        "SEC_SPEC": ("RECTANGULAR",), "SEC_VECTOR": ("0 0 1",),
    }


def pool_text(name: str) -> str | None:
    """Return a kernel-pool variable as text (whole numbers as integers), or None."""
    try:
        n, kind = spiceypy.dtpool(name)
    except spiceypy.utils.exceptions.SpiceyError:
        return None
    if kind == "C":
        return " ".join(str(v).strip().upper() for v in spiceypy.gcpool(name, 0, n))
    values = spiceypy.gdpool(name, 0, n)
    return " ".join(str(int(v)) if float(v).is_integer() else repr(float(v)) for v in values)


def is_sun_pole_rtn(frame: str, targets: Sequence[str]) -> bool:
    """Return True when the loaded ``frame`` is the two-vector Sun-pole RTN frame.

    That is: X along the Sun -> spacecraft position (no aberration correction), Z
    toward the component of the IAU_SUN +Z axis (solar rotation axis) orthogonal to X,
    relative to J2000, the spacecraft (primary target) named as one of ``targets``.
    A kernel defining the frame otherwise makes this False.

    Parameters
    ----------
    frame : str
        SPICE frame name.
    targets : sequence of str
        The names and ids (as text) the definition may give the spacecraft.
    """
    code = spiceypy.namfrm(frame)
    if code == 0:
        return False
    for key, accepted in _sun_pole_rtn_definition(targets).items():
        if pool_text(f"FRAME_{code}_{key}") not in accepted:
            return False
    return True


def solar_axis(et: np.ndarray) -> np.ndarray:
    """IAU_SUN +Z in J2000: (1, 3) when fixed over ``et``, else (n, 3) per sample."""
    ends = rotation_matrices("IAU_SUN", "J2000", et[[0, -1]], method="oracle")[:, :, 2]
    if np.allclose(ends[0], ends[1], rtol=0.0, atol=1e-15):
        return ends[:1].copy()
    # a precessing pole model: the axis per sample
    return Rotator("IAU_SUN", et).rotate("J2000", np.tile([0.0, 0.0, 1.0], (et.size, 1)))


def rtn_from_position(b_j2000: np.ndarray, sun: np.ndarray, et: np.ndarray) -> np.ndarray:
    """Rotate J2000 vectors into RTN built from the Sun -> spacecraft position.

    ``R = sun / |sun|``, ``T = unit(Omega x R)`` with ``Omega`` the solar rotation axis
    (IAU_SUN +Z in J2000), ``N = R x T``: the two-vector RTN frame of seed 000 sec.
    3.5, evaluated from the positions already computed (no frame leg to build), in one
    compiled pass (`fluxcal.geometry.compiled.rtn_rotate`).

    Parameters
    ----------
    b_j2000 : ndarray, shape (n, 3)
        Vectors in J2000.
    sun : ndarray, shape (n, 3)
        The spacecraft relative to the Sun, J2000 (km).
    et : ndarray, shape (n,)
        Ephemeris times (for the solar rotation axis).

    Returns
    -------
    ndarray, shape (n, 3)
        The vectors in RTN.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 3.5, sec. 11.
    """
    out = np.empty_like(b_j2000)
    compiled.rtn_rotate(np.ascontiguousarray(sun, dtype=float), solar_axis(et),
                        np.ascontiguousarray(b_j2000, dtype=float), out)
    return out


def spherical_rtn(
    sun: np.ndarray, et: np.ndarray, target: str, *, method: str = "interpolate",
    step: float = RTN_ANGLE_STEP_S, sun_at: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Distance from the Sun, ecliptic latitude and azimuth (sec. 10.2) per sample.

    The distance is ``|sun|`` at every sample.  The two angles vary slowly (the
    spacecraft's heliocentric direction); when the samples are denser than ``step``
    they are evaluated by `fluxcal.geometry.positions.rtn_spherical` on a ``step`` grid
    and interpolated linearly (azimuth unwrapped).  Error bound: ``step**2 / 8`` times
    the angular acceleration, below 3.7e-9 deg/s**2 even at a 200-km periapsis
    (3.2e-3 km/s**2 at 0.3 AU), so under 5e-10 deg for 1 s -- far below the 1e-7 deg
    printed in the products (checked against the per-sample evaluation in the tests).

    Parameters
    ----------
    sun : ndarray, shape (n, 3)
        The spacecraft relative to the Sun in J2000 (km) at ``et``.
    et : ndarray, shape (n,)
        Ephemeris times, increasing.
    target : str
        The spacecraft (SPICE body name or id).
    method : {"interpolate", "oracle"}
        ``"oracle"`` evaluates every sample with one SPICE call per sample.
    step : float
        Grid step (s) of the angles.
    sun_at : callable, optional
        The spacecraft relative to the Sun (J2000) at given epochs, e.g. the
        `fluxcal.geometry.positions.StateInterpolator` that gave ``sun``; used on the
        grid instead of building another interpolator.

    Returns
    -------
    ndarray, shape (n, 3)
        ``r`` (km), latitude (deg), azimuth (deg).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.2.
    """
    out = np.empty((et.size, 3))
    # a grid over each span of samples, none over a long gap (`fluxcal.geometry.spans`)
    spans = sample_spans(et)
    covered = float(np.sum(spans[:, 1] - spans[:, 0]))
    if method == "oracle" or et.size < 4 * (covered / step + 2 * len(spans)):
        out[:, 0], out[:, 1], out[:, 2] = rtn_spherical(
            target, et, method=method, target_position=sun)
        return out
    grid = span_grid(spans, step)[0]
    _r, lat, az = rtn_spherical(
        target, grid, target_position=None if sun_at is None else sun_at(grid))
    # |sun|, np.interp of lat and of np.unwrap(az, period=360), az wrapped back
    compiled.rtn_spherical_interp(np.ascontiguousarray(sun, dtype=float),
                                  np.ascontiguousarray(et, dtype=float), grid,
                                  np.ascontiguousarray(lat, dtype=float),
                                  np.ascontiguousarray(az, dtype=float), out)
    return out
