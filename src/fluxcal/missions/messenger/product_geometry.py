"""One product frame's field and position, computed when that frame's products are written.

`fluxcal.missions.messenger.run` calibrates a run with the J2000 field only
(`calibration_frames`): `levels.add_geometry` then keeps ``b_j2000``, ``pos_j2000`` (the
Sun -> MESSENGER position), ``pos_mso`` and, when the SC product is requested, ``b_sc``.
Every other frame is one leg from J2000 (sec. 10.1, 11); `frame_variables` evaluates it
for one day when that frame is written, so a day holds one frame's field and position at
a time instead of every frame's (about 40 MB per array of a 20 Hz day).  The values are
those `levels.add_geometry` gives for the frame on the same samples (same legs, same
interpolators, bit for bit).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger import levels

log = logging.getLogger(__name__)

#: Position variable of each product frame (None: the SC product has none).
POSITION_VARIABLE = {"mso": "pos_mso", "j2000": "pos_j2000", "mbf": "pos_mbf",
                     "rtn": "pos_rtn", "vso": "pos_vso", "sc": None}


def calibration_frames(frames: Sequence[str]) -> tuple[str, ...]:
    """Frames `levels.add_geometry` computes for products of ``frames`` (`frame_variables`).

    J2000 when any frame but SC is requested (every other frame is one leg from it, and
    ``pos_j2000`` is the Sun position of RTN and sec. 10.2); SC when requested (its field
    is the attitude leg's input, not recomputed).
    """
    frames = tuple(frames)
    return (("j2000",) if any(f != "sc" for f in frames) else ()) + (
        ("sc",) if "sc" in frames else ())


def note_mbf_rotation(ds: xr.Dataset, frames: Sequence[str]) -> xr.Dataset:
    """Log and record (``mbf_rotation``) the built-in Mercury rotation when MBF is requested.

    What `levels.add_geometry` does when it computes MBF itself: the note goes to every
    product of the run (its attributes), so it is set before the first frame is written.
    """
    if "mbf" not in frames or not levels.mercury_orientation_is_builtin():
        return ds
    log.warning(levels.MBF_BUILTIN_NOTE)
    # where `levels.add_geometry` puts it: before the attributes `pipeline.calibrate`
    # adds last (software_version first), so the labels list it in the same place
    attrs = dict(ds.attrs)
    keys = list(attrs)
    at = keys.index("software_version") if "software_version" in keys else len(keys)
    ordered = {k: attrs[k] for k in keys[:at]}
    ordered["mbf_rotation"] = levels.MBF_BUILTIN_NOTE
    ordered.update((k, attrs[k]) for k in keys[at:])
    out = ds.copy(deep=False)
    out.attrs = ordered
    return out


def _sun_interpolator(et: np.ndarray):
    """Return the Sun-relative interpolator `levels.add_geometry` builds (None: < 4 samples)."""
    from fluxcal.geometry.positions import StateInterpolator

    if et.size < 4:
        return None
    return StateInterpolator("MESSENGER", "SUN", "J2000", float(et.min()), float(et.max()))


def frame_variables(ds: xr.Dataset, frame: str) -> dict[str, xr.Variable]:
    """Return ``b_<frame>`` and the frame's position variable (`POSITION_VARIABLE`) of ``ds``.

    Taken from ``ds`` when it holds them (a run calibrated with that frame), else
    evaluated from ``et``, ``b_j2000`` and ``pos_j2000`` (`calibration_frames`) with the
    interpolated legs of `levels.add_geometry`: MSO, MBF and VSO through
    `fluxcal.geometry.frames.Rotator` from J2000 (the MBF position from MESSENGER
    relative to Mercury in J2000, through the same leg as the field), RTN by
    `levels.rtn_from_position` (or the frame's own leg when a kernel defines MSGR_RTN
    otherwise) with the sec. 10.2 position of `levels.spherical_rtn`, VSO's position
    from SPICE.

    Raises
    ------
    InputFormatError
        When ``ds`` lacks the frame's variables and cannot give them (SC and J2000 are
        taken, never recomputed; the other frames need ``b_j2000``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
    """
    from fluxcal.geometry.frames import Rotator
    from fluxcal.geometry.positions import position

    pos_name = POSITION_VARIABLE[frame]
    names = [f"b_{frame}"] + ([pos_name] if pos_name is not None else [])
    if all(name in ds for name in names):
        return {name: ds[name].variable for name in names}
    if frame in ("sc", "j2000") or "b_j2000" not in ds:
        raise InputFormatError(f"the calibrated day has no {' or '.join(names)} and no "
                               "b_j2000 to compute them from", field=f"b_{frame}")
    et = ds["et"].values
    b_j2000 = ds["b_j2000"].values
    spice_frame = levels.FRAMES[frame][0]
    if frame == "rtn":
        sun = ds["pos_j2000"].values
        if levels.rtn_is_sun_pole_two_vector(spice_frame):
            field = levels.rtn_from_position(b_j2000, sun, et)
        else:
            field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        pos = levels.spherical_rtn(sun, et, sun_at=_sun_interpolator(et))
        pos_attrs = {"units": "km, deg, deg", "description":
                     "distance from the Sun, ecliptic latitude, azimuth (sec. 10.2)"}
    elif frame == "mbf":  # position and field through one leg, one after the other
        rotator = Rotator("J2000", et)  # (Mercury's J2000 position freed before the field)
        pos = rotator.rotate(spice_frame, position("MESSENGER", "MERCURY", "J2000", et))
        field = rotator.rotate(spice_frame, b_j2000)
        pos_attrs = {"units": "km", "description": f"MESSENGER relative to Mercury, {spice_frame}"}
    else:  # MSO (its position is in every calibrated run) and VSO
        field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        if frame == "vso":
            pos = position("MESSENGER", "VENUS", spice_frame, et)
            pos_attrs = {"units": "km", "description": "MESSENGER relative to Venus, MSGR_VSO"}
        else:
            return {f"b_{frame}": _field(field, spice_frame), pos_name: ds[pos_name].variable}
    return {f"b_{frame}": _field(field, spice_frame),
            pos_name: xr.Variable(("time", "component"), pos, pos_attrs)}


def _field(values: np.ndarray, spice_frame: str) -> xr.Variable:
    return xr.Variable(("time", "component"), values,
                       {"units": "nT", "description": f"magnetic field in {spice_frame}"})
