"""MESSENGER levels, step 5: rotation into the product frames and positions (seed 000 sec. 10, 11).

RTN and the heliocentric angles come from `fluxcal.geometry.axes`, with MESSENGER's
names (`fluxcal.missions.messenger.identity`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 3.5, 10.1, 10.2, 11.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Sequence

import numpy as np
import spiceypy
import xarray as xr

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry import axes, compiled
from fluxcal.geometry.axes import RTN_ANGLE_STEP_S, rtn_from_position
from fluxcal.geometry.frames import Rotator, rotation_matrices
from fluxcal.geometry.kernels import orientation_pck
from fluxcal.geometry.positions import StateInterpolator, position
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.identity import NAIF_NAME, NAIF_NAMES
from fluxcal.missions.messenger.levels._common import (
    _apply,
    _date_et,
    _unit_rows,
    _vector,
)

#: The package's logger (``fluxcal.missions.messenger.levels``), as before the split.
log = logging.getLogger(__package__)

#: Output frames: product key -> (SPICE frame, archive product name stem).
FRAMES: dict[str, tuple[str, str]] = {
    "mso": ("MSGR_MSO", "MAGMSOSCI"),
    "j2000": ("J2000", "MAGJ2000SCI"),
    "mbf": ("IAU_MERCURY", "MAGMBFSCI"),
    "rtn": ("MSGR_RTN", "MAGRTNSCI"),
    "sc": ("MSGR_SPACECRAFT", "MAGSCSCI"),
    "vso": ("MSGR_VSO", "MAGVSOSCI"),
}


def sensor_frame(et: np.ndarray, cal: MessengerCalibration) -> np.ndarray:
    """Return True where the sensor frame is ``MSGR_MAG`` (after boom deployment).

    Before boom deployment (2005-03-08) the sensor frame is ``MSGR_MAG_STOWED``.
    """
    return np.asarray(et) >= _date_et(cal, "boom_deployment")


def _sensor_to_spacecraft(frame: str, et: np.ndarray, method: str) -> np.ndarray:
    """(n, 3, 3) sensor -> MSGR_SPACECRAFT; one matrix when the mounting is fixed."""
    ends = rotation_matrices(frame, "MSGR_SPACECRAFT", et[[0, -1]], method="oracle")
    if method != "oracle" and np.allclose(ends[0], ends[1], rtol=0, atol=1e-14):
        return ends[:1]
    return rotation_matrices(frame, "MSGR_SPACECRAFT", et, method=method)


def _rotate_oracle(
    b_sc: np.ndarray, sun: np.ndarray, et: np.ndarray, frames: tuple[str, ...]
) -> dict[str, np.ndarray]:
    """Field in every frame and ``sun_sc`` with one ``pxform`` per sample and frame."""
    att = rotation_matrices("MSGR_SPACECRAFT", "J2000", et, method="oracle")
    b_j2000 = _apply(att, b_sc)
    out = {"sc": b_sc, "j2000": b_j2000, "sun_sc": _apply(att, _unit_rows(-sun), True)}
    for f in frames:
        if f not in out:
            out[f] = _apply(rotation_matrices("J2000", FRAMES[f][0], et, method="oracle"),
                            b_j2000)
    return out


def _rotate_interpolated(
    b_sc: np.ndarray, sun: np.ndarray, et: np.ndarray, j2000: bool, mercury_j2000: np.ndarray,
) -> dict[str, np.ndarray]:
    """J2000 field (``j2000``: when wanted), ``sun_sc`` and ``pos_mso``: one compiled pass.

    `fluxcal.geometry.compiled.attitude_frames` interpolates the attitude leg
    (MSGR_SPACECRAFT -> J2000, from the CK records) once per sample and gives the J2000
    field, the Sun direction in the spacecraft frame and, through the J2000 -> MSGR_MSO
    leg, ``mercury_j2000`` (MESSENGER relative to Mercury, J2000) in MSGR_MSO: what
    ``spkpos`` returns in that frame without aberration correction (the frame is
    evaluated at the same epoch).  Every product frame is then one leg from the J2000
    field (`frame_variables`).
    """
    n = et.size
    empty = np.empty((0, 3))
    rotator = Rotator("MSGR_SPACECRAFT", et)
    out = {"sun_sc": np.empty((n, 3)), "pos_mso": np.empty((n, 3))}
    if j2000:
        out["j2000"] = np.empty((n, 3))
    compiled.attitude_frames(
        rotator.leg_table("MSGR_SPACECRAFT"), rotator.leg_table(FRAMES["mso"][0]),
        np.ascontiguousarray(et, dtype=float), np.ascontiguousarray(b_sc, dtype=float),
        np.ascontiguousarray(sun, dtype=float), np.ascontiguousarray(mercury_j2000, dtype=float),
        out.get("j2000", empty), out["sun_sc"], (out["pos_mso"], empty))
    return out


#: Position variable of each frame (None: the SC frame has none).
POSITION_VARIABLE: dict[str, str | None] = {
    "mso": "pos_mso", "j2000": "pos_j2000", "mbf": "pos_mbf", "rtn": "pos_rtn",
    "vso": "pos_vso", "sc": None,
}


def _field_variable(frame: str, values: np.ndarray) -> xr.Variable:
    """Return ``b_<frame>`` with its attributes."""
    return _vector(values, "nT", f"magnetic field in {FRAMES[frame][0]}")


def _position_variable(frame: str, values: np.ndarray) -> xr.Variable:
    """Return the frame's position variable (`POSITION_VARIABLE`) with its attributes."""
    spice = FRAMES[frame][0]
    if frame == "j2000":
        return _vector(values, "km", "MESSENGER relative to the Sun, J2000")
    if frame == "rtn":
        return _vector(values, "km, deg, deg",
                       "distance from the Sun, ecliptic latitude, azimuth (sec. 10.2)")
    if frame == "vso":
        return _vector(values, "km", f"MESSENGER relative to Venus, {spice}")
    return _vector(values, "km", f"MESSENGER relative to Mercury, {spice}")


def position_frames(frames: tuple[str, ...]) -> tuple[str, ...]:
    """Frames whose position `add_geometry` adds for the field ``frames``, in order.

    ``mso`` always (the quicklook's distance from Mercury and the MSO product), every
    other frame's position only with its field: an unrequested position is a 40-MB array
    per 20 Hz day and, for MBF, a whole J2000 -> IAU_MERCURY leg.
    """
    return tuple(f for f in ("j2000", "mso", "mbf", "rtn", "vso") if f == "mso" or f in frames)


def calibration_frames(frames: Sequence[str]) -> tuple[str, ...]:
    """Frames `add_geometry` computes for the products of ``frames`` (`frame_variables`).

    J2000 when any frame but SC is requested (every other frame is one leg from it, and
    ``pos_j2000`` is the Sun position of RTN and sec. 10.2); SC when requested (its field
    is the attitude leg's input, not recomputed).  A run calibrated with these holds one
    product frame's field and position at a time, each evaluated when that frame is
    written, instead of every frame's (about 40 MB per array of a 20 Hz day).
    """
    frames = tuple(frames)
    return (("j2000",) if any(f != "sc" for f in frames) else ()) + (
        ("sc",) if "sc" in frames else ())


def _sun_interpolator(et: np.ndarray):
    """MESSENGER relative to the Sun (J2000) over the spans of ``et`` (None: < 4 samples)."""
    if et.size < 4:
        return None
    return StateInterpolator.over_samples(NAIF_NAME, "SUN", "J2000", et)


def frame_variables(ds: xr.Dataset, frame: str) -> dict[str, xr.Variable]:
    """Return ``b_<frame>`` and the frame's position variable (`POSITION_VARIABLE`) of ``ds``.

    Taken from ``ds`` when it holds them, else evaluated from ``et``, ``b_j2000``,
    ``pos_j2000`` and ``pos_mso`` (what `add_geometry` gives with `calibration_frames`)
    through the interpolated legs: MSO, MBF and VSO through
    `fluxcal.geometry.frames.Rotator` from J2000 (the MBF position from MESSENGER
    relative to Mercury in J2000, through the same leg as the field), RTN by
    `rtn_from_position` (or the frame's own leg when a kernel defines MSGR_RTN
    otherwise) with the sec. 10.2 position of `spherical_rtn`, VSO's position from
    SPICE.  `add_geometry` obtains every frame but J2000 and SC here, and the product
    writer each frame when it is written: one implementation, the same bits.

    Raises
    ------
    InputFormatError
        When ``ds`` lacks the frame's variables and cannot give them (SC and J2000 are
        taken, never recomputed; the other frames need ``b_j2000``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
    """
    pos_name = POSITION_VARIABLE[frame]
    names = [f"b_{frame}"] + ([pos_name] if pos_name is not None else [])
    if all(name in ds for name in names):
        return {name: ds[name].variable for name in names}
    if frame in ("sc", "j2000") or "b_j2000" not in ds:
        raise InputFormatError(f"the calibrated day has no {' or '.join(names)} and no "
                               "b_j2000 to compute them from", field=f"b_{frame}")
    et = ds["et"].values
    b_j2000 = ds["b_j2000"].values
    spice_frame = FRAMES[frame][0]
    if frame == "rtn":
        sun = ds["pos_j2000"].values
        if rtn_is_sun_pole_two_vector(spice_frame):
            field = rtn_from_position(b_j2000, sun, et)
        else:
            field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        pos = spherical_rtn(sun, et, sun_at=_sun_interpolator(et))
    elif frame == "mbf":  # position and field through one leg, one after the other
        rotator = Rotator("J2000", et)  # (Mercury's J2000 position freed before the field)
        pos = rotator.rotate(spice_frame, position(NAIF_NAME, "MERCURY", "J2000", et))
        field = rotator.rotate(spice_frame, b_j2000)
    else:  # MSO (its position is in every calibrated run) and VSO
        field = Rotator("J2000", et).rotate(spice_frame, b_j2000)
        if frame == "mso":
            return {"b_mso": _field_variable(frame, field), "pos_mso": ds["pos_mso"].variable}
        pos = position(NAIF_NAME, "VENUS", spice_frame, et)
    return {f"b_{frame}": _field_variable(frame, field), pos_name: _position_variable(frame, pos)}


#: The MSGR_RTN definition `rtn_from_position` reproduces (fluxcal's msgr_rtn.tf):
#: kernel-pool keyword -> accepted values.

def rtn_is_sun_pole_two_vector(frame: str) -> bool:
    """Return True when the loaded ``frame`` is the two-vector RTN frame of fluxcal's FK.

    That is: X along the Sun -> MESSENGER position (no aberration correction), Z toward
    the component of the IAU_SUN +Z axis (solar rotation axis) orthogonal to X, relative
    to J2000 (`fluxcal.geometry.axes.is_sun_pole_rtn`).  A mission kernel defining the
    frame otherwise makes this False (and the pipeline then rotates with SPICE's
    definition through the interpolated legs).
    """
    return axes.is_sun_pole_rtn(frame, NAIF_NAMES)


def spherical_rtn(
    sun: np.ndarray, et: np.ndarray, *, method: str = "interpolate",
    step: float = RTN_ANGLE_STEP_S, sun_at: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Distance from the Sun, ecliptic latitude and azimuth of MESSENGER (sec. 10.2).

    `fluxcal.geometry.axes.spherical_rtn` for MESSENGER: ``sun`` is MESSENGER relative
    to the Sun in J2000 (km) at ``et``; returns ``r`` (km), latitude (deg), azimuth
    (deg) per sample.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.2.
    """
    return axes.spherical_rtn(sun, et, NAIF_NAME, method=method, step=step, sun_at=sun_at)


MBF_BUILTIN_NOTE = (
    "MBF (IAU_MERCURY) uses the IAU 2009 Mercury rotation built into fluxcal: no mission "
    "PCK redefines it. The MESSENGER PCK pck00010_msgr_v23.tpc differs by about 0.094 "
    "deg (0.5 nT on 300 nT); load the mission PCK for archive-grade MBF"
)


def mercury_orientation_is_builtin() -> bool:
    """Return True when the pool's Mercury orientation is fluxcal's IAU 2009 subset.

    Compares ``BODY199_POLE_RA``, ``BODY199_POLE_DEC`` and ``BODY199_PM`` in the kernel
    pool with the values in `fluxcal.geometry.kernels.orientation_pck`: equal means no
    mission PCK (loaded after the generic kernels) redefined them.
    """
    text = orientation_pck().read_text()
    for name in ("BODY199_POLE_RA", "BODY199_POLE_DEC", "BODY199_PM"):
        match = re.search(rf"{name}\s*=\s*\(([^)]*)\)", text)
        if match is None:  # pragma: no cover - the shipped file defines all three
            raise FluxcalError(f"{orientation_pck()}: {name} not found")
        builtin = [float(v) for v in match.group(1).split()]
        try:
            pool = spiceypy.gdpool(name, 0, len(builtin))
        except spiceypy.utils.exceptions.SpiceyError:
            return False
        if len(pool) != len(builtin) or any(a != b for a, b in zip(pool, builtin, strict=True)):
            return False
    return True


def note_mbf_rotation(ds: xr.Dataset, frames: Sequence[str]) -> xr.Dataset:
    """Log and record the built-in Mercury rotation when MBF is in ``frames``.

    When MBF is produced with fluxcal's built-in Mercury rotation (no mission PCK,
    `mercury_orientation_is_builtin`): logs `MBF_BUILTIN_NOTE` as a warning, sets it as
    the ``mbf_rotation`` attribute (which every product of the run carries; placed before
    ``software_version`` when present, the attributes `chain.calibrate` adds last, so
    the labels list it in the same place whether MBF is computed by `add_geometry` or
    when written) and notes ``rotation_model`` on ``b_mbf`` when ``ds`` holds it.
    Otherwise returns ``ds`` itself.
    """
    if "mbf" not in frames or not mercury_orientation_is_builtin():
        return ds
    log.warning(MBF_BUILTIN_NOTE)
    attrs = dict(ds.attrs)
    keys = list(attrs)
    at = keys.index("software_version") if "software_version" in keys else len(keys)
    ordered = {k: attrs[k] for k in keys[:at]}
    ordered["mbf_rotation"] = MBF_BUILTIN_NOTE
    ordered.update((k, attrs[k]) for k in keys[at:])
    out = ds.copy(deep=False)
    out.attrs = ordered
    if "b_mbf" in out:
        out["b_mbf"].attrs["rotation_model"] = "IAU 2009 (fluxcal built-in), no mission PCK"
    return out


def add_geometry(
    ds: xr.Dataset,
    cal: MessengerCalibration,
    frames: tuple[str, ...] = ("mso", "j2000", "mbf", "rtn", "sc"),
    *,
    method: str = "interpolate",
) -> xr.Dataset:
    """Rotate the sensor field into the requested frames and add positions (sec. 10, 11).

    The field goes sensor -> MSGR_SPACECRAFT (fixed mounting of MSGR_MAG, or
    MSGR_MAG_STOWED before boom deployment) -> J2000 (attitude, CK) -> each frame, the
    composition SPICE's ``pxform`` performs.  Adds ``b_<frame>`` for each requested key
    of `FRAMES`, ``sun_sc`` (unit Sun direction in MSGR_SPACECRAFT, for the S flag) and
    ``pos_mso`` (relative to Mercury in MSGR_MSO, for the MSO product and the quicklook's
    distance); the other positions (`POSITION_VARIABLE`) only with their frame
    (`position_frames`): ``pos_j2000`` (MESSENGER relative to the Sun, J2000),
    ``pos_mbf`` (relative to Mercury in IAU_MERCURY), ``pos_rtn`` (r km, latitude deg,
    azimuth deg of sec. 10.2) and ``pos_vso`` (relative to Venus in MSGR_VSO).  With
    ``method="interpolate"`` the J2000 field, ``sun_sc`` and ``pos_mso`` come from one
    compiled pass and every other frame from them through `frame_variables` (what the
    product writer uses).  What is computed for a requested frame does not depend on the
    other frames requested.  Kernels must be loaded.  MBF produced with fluxcal's
    built-in Mercury rotation is noted (`note_mbf_rotation`).

    Parameters
    ----------
    ds : xarray.Dataset
        With ``et`` and ``b_sensor``.
    cal : MessengerCalibration
        For the boom deployment date.
    frames : tuple of str
        Keys of `FRAMES`.
    method : {"interpolate", "oracle"}
        Vectorized geometry, or one SPICE call per sample (the reference).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10.1, 10.2, 11.
    """
    et = ds["et"].values
    b = ds["b_sensor"].values
    deployed = sensor_frame(et, cal)
    b_sc = np.empty_like(b)
    for name, sel in (("MSGR_MAG", deployed), ("MSGR_MAG_STOWED", ~deployed)):
        if sel.all():
            b_sc = _apply(_sensor_to_spacecraft(name, et, method), b)
        elif sel.any():
            b_sc[sel] = _apply(_sensor_to_spacecraft(name, et[sel], method), b[sel])
    # MESSENGER relative to the Sun (J2000): pos_j2000, the Sun direction and sec. 10.2
    sun_at = None if method == "oracle" else _sun_interpolator(et)
    if sun_at is None:
        sun = position(NAIF_NAME, "SUN", "J2000", et, method=method)
    else:
        sun = sun_at(et)
    fields: dict[str, xr.Variable] = {}
    positions: dict[str, xr.Variable] = {}
    if method == "oracle":
        out = _rotate_oracle(b_sc, sun, et, frames)
        for f in position_frames(frames):
            if f == "j2000":
                pos = sun
            elif f == "rtn":
                pos = spherical_rtn(sun, et, method=method, sun_at=sun_at)
            else:
                target = "VENUS" if f == "vso" else "MERCURY"
                pos = position(NAIF_NAME, target, FRAMES[f][0], et, method=method)
            positions[f] = _position_variable(f, pos)
        fields = {f: _field_variable(f, out.pop(f)) for f in frames}
        sun_sc = out.pop("sun_sc")
    else:
        mercury = position(NAIF_NAME, "MERCURY", "J2000", et, method=method)
        out = _rotate_interpolated(b_sc, sun, et, "j2000" in calibration_frames(frames),
                                   mercury_j2000=mercury)
        del mercury
        sun_sc = out.pop("sun_sc")
        positions["mso"] = _position_variable("mso", out.pop("pos_mso"))
        if "sc" in frames:
            fields["sc"] = _field_variable("sc", b_sc)
        if "j2000" in out:  # every other frame is one leg from J2000 (sec. 10.1, 11)
            fields["j2000"] = _field_variable("j2000", out.pop("j2000"))
            positions["j2000"] = _position_variable("j2000", sun)
            legs = xr.Dataset({"et": ds["et"].variable, "b_j2000": fields["j2000"],
                               "pos_j2000": positions["j2000"], "pos_mso": positions["mso"]})
            for f in frames:
                if f not in ("sc", "j2000"):
                    got = frame_variables(legs, f)
                    fields[f] = got[f"b_{f}"]
                    if f != "mso":
                        positions[f] = got[POSITION_VARIABLE[f]]
            del legs
    del b_sc, out, sun  # the Sun position stays only as pos_j2000 (J2000 requested)
    variables = {f"b_{f}": fields[f] for f in frames}
    variables.update((POSITION_VARIABLE[f], positions[f]) for f in position_frames(frames))
    variables["sun_sc"] = _vector(sun_sc, "1", "unit Sun direction in MSGR_SPACECRAFT")
    del fields, positions
    return note_mbf_rotation(ds.assign(variables), frames)
