"""A MESSENGER-like synthetic kernel set: spacecraft clock, frames, orbit and attitude.

`write_messenger_like_kernels`: SCLK -236 (fields seconds and microseconds, TDT parallel
time, two partitions with the clock reset of 2013-01-08 as in the real kernel), frames
MSGR_SPACECRAFT (CK -236000), MSGR_MAG (fixed, a 4.9 degree rotation about Y as in the
real msgr_v231.tf), MSGR_MAG_STOWED, a 12-hour eccentric Mercury orbit (periapsis
altitude 200 km, apoapsis altitude 15,200 km, inclination 82.5 deg) and a Sun-keeping
attitude (sunshade, -Y, to the Sun) with a slow roll and, optionally, intervals with +Y
to the Sun.  Written with the generic helpers of `fluxcal.geometry.synthetic`; returns
the path of a meta-kernel for `fluxcal.geometry.kernels.KernelPool`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import (
    GM_MERCURY,
    furnished,
    kepler_states,
    prepare_kernel_folder,
    sclk_text,
    smoothstep,
    tdt,
    unit,
    write_ck,
    write_meta_kernel,
    write_spk,
)
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.products.atomic import atomic_write_bytes

MESSENGER_FK = """KPL/FK

fluxcal synthetic MESSENGER-like frames kernel (ids and names as in msgr_v231.tf)

\\begindata

   NAIF_BODY_NAME              += ( 'MESSENGER' )
   NAIF_BODY_CODE              += ( -236 )

   FRAME_MSGR_SPACECRAFT       = -236000
   FRAME_-236000_NAME          = 'MSGR_SPACECRAFT'
   FRAME_-236000_CLASS         = 3
   FRAME_-236000_CLASS_ID      = -236000
   FRAME_-236000_CENTER        = -236
   CK_-236000_SCLK             = -236
   CK_-236000_SPK              = -236

   FRAME_MSGR_MAG              = -236400
   FRAME_-236400_NAME          = 'MSGR_MAG'
   FRAME_-236400_CLASS         = 4
   FRAME_-236400_CLASS_ID      = -236400
   FRAME_-236400_CENTER        = -236
   TKFRAME_-236400_RELATIVE    = 'MSGR_SPACECRAFT'
   TKFRAME_-236400_SPEC        = 'ANGLES'
   TKFRAME_-236400_UNITS       = 'DEGREES'
   TKFRAME_-236400_AXES        = ( 2, 1, 3 )
   TKFRAME_-236400_ANGLES      = ( 4.9, 0.0, 0.0 )

   FRAME_MSGR_MAG_STOWED       = -236410
   FRAME_-236410_NAME          = 'MSGR_MAG_STOWED'
   FRAME_-236410_CLASS         = 4
   FRAME_-236410_CLASS_ID      = -236410
   FRAME_-236410_CENTER        = -236
   TKFRAME_-236410_RELATIVE    = 'MSGR_SPACECRAFT'
   TKFRAME_-236410_SPEC        = 'ANGLES'
   TKFRAME_-236410_UNITS       = 'DEGREES'
   TKFRAME_-236410_AXES        = ( 3, 2, 1 )
   TKFRAME_-236410_ANGLES      = ( 180.0, 4.9, 0.0 )

\\begintext
"""


def write_messenger_like_kernels(
    out_dir: str | Path,
    start_utc: str = "2012-06-01T00:00:00",
    duration_s: float = 86400.0,
    *,
    plus_y_sunward: list[tuple[float, float]] | None = None,
    attitude_step: float = 5.0,
    margin_s: float = 3600.0,
) -> Path:
    """Write a MESSENGER-like kernel set and return its meta-kernel.

    Parameters
    ----------
    out_dir : path
        Folder for the kernels (created).
    start_utc : str
        Start of the covered interval (UTC, ISO).
    duration_s : float
        Length of the covered interval (s); the kernels cover ``margin_s`` more each side.
    plus_y_sunward : list of (start, end) seconds after ``start_utc``, optional
        Intervals in which the spacecraft turns +Y to the Sun (sensor in sunlight),
        with 10-minute slews; otherwise -Y (the sunshade side) faces the Sun.
    attitude_step : float
        Spacing of the CK pointing records (s).
    margin_s : float
        Extra coverage before and after the interval (s).

    Returns
    -------
    Path
        The meta-kernel ``messenger_synthetic.tm`` (SCLK, FK, SPK, CK, and the dynamic
        frames of `FRAME_KERNELS` copied beside them).
    """
    out, sclk_path, fk_path, spk_path, ck_path = prepare_kernel_folder(out_dir, "msgr_synthetic")
    with KernelPool([], frames={}):
        launch = tdt("2004-08-03T06:15:56.5")
        reset = tdt("2013-01-08T20:00:00")
        # partition 1: MET 0 at launch, drifting clock (rate changes once); partition 2
        # starts again near MET 1e3 s after the reset (as the real MESSENGER clock).
        p1_end = (reset - launch) * 1e6
        mid = 0.5 * p1_end
        rate1, rate2 = 1.0000001, 0.99999995
        t_mid = launch + mid / 1e6 * rate1
        p1_end_parallel = t_mid + (p1_end - mid) / 1e6 * rate2
        p2_start = 1.0e9
        triplets = [
            (0.0, launch, rate1),
            (mid, t_mid, rate2),
            (p1_end, p1_end_parallel, 1.00000002),
        ]
        atomic_write_bytes(sclk_path, sclk_text(
                SPACECRAFT_ID,
                (268435456, 1000000),
                [(0.0, p1_end), (p2_start, 2.68435456e14)],
                triplets,
                f"fluxcal synthetic MESSENGER-like SCLK (id {SPACECRAFT_ID}): seconds and "
                "microseconds.",
            ), now=True)
        atomic_write_bytes(fk_path, MESSENGER_FK, now=True)
        with furnished(sclk_path, fk_path):
            et0 = spiceypy.str2et(start_utc) - margin_s
            et1 = spiceypy.str2et(start_utc) + duration_s + margin_s
            epochs = np.arange(et0, et1 + 60.0, 60.0)
            rp, ra = 2440.0 + 200.0, 2440.0 + 15200.0
            ecc = (ra - rp) / (ra + rp)
            elements = [rp, ecc, math.radians(82.5), math.radians(30.0), math.radians(120.0),
                        0.0, et0, GM_MERCURY]
            states = kepler_states(elements, epochs)
            write_spk(spk_path, SPACECRAFT_ID, 199, epochs, states, "MESSENGER-LIKE ORBIT")
            att_epochs = np.arange(et0, et1 + attitude_step, attitude_step)
            sun = np.array(
                [spiceypy.spkpos("SUN", float(t), "J2000", "NONE", "MERCURY")[0]
                 for t in att_epochs]
            )
            cmat = _sun_keeping_attitude(att_epochs - (et0 + margin_s), unit(sun),
                                         plus_y_sunward)
            write_ck(ck_path, SPACECRAFT_ID * 1000, SPACECRAFT_ID, att_epochs, cmat,
                     "MESSENGER-LIKE ATTITUDE")
    # the dynamic frames (MSO, VSO, RTN) in the set, as the real set's msgr_dyn FK has them
    frames = [out / p.name for p in FRAME_KERNELS.values()]
    for src, dest in zip(FRAME_KERNELS.values(), frames, strict=True):
        atomic_write_bytes(dest, Path(src).read_bytes(), now=True)
    # listed last: loaded where `KernelPool` loaded them when they came from its ``frames``
    files = [sclk_path, fk_path, spk_path, ck_path, *frames]
    return write_meta_kernel(out / "messenger_synthetic.tm", files)


def _sun_keeping_attitude(
    t: np.ndarray, sun_dir: np.ndarray, plus_y: list[tuple[float, float]] | None
) -> np.ndarray:
    """C-matrices (J2000 -> spacecraft) with -Y (or +Y in ``plus_y``) to the Sun."""
    north = np.array([0.0, 0.0, 1.0])
    y_axis = -sun_dir
    x_axis = unit(np.cross(y_axis, north))
    z_axis = np.cross(x_axis, y_axis)
    roll = 2 * np.pi * t / (6 * 3600.0) + 0.05 * np.sin(2 * np.pi * t / 900.0)
    flip = np.zeros_like(t)
    for start, end in plus_y or []:
        flip = np.maximum(flip, smoothstep((t - start) / 600.0) * smoothstep((end - t) / 600.0))
    angle = np.pi * flip
    # roll about the Sun line, then turn about the rolled X axis by `angle`
    c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
    x_r = c * x_axis + s * z_axis
    z_r = -s * x_axis + c * z_axis
    ca, sa = np.cos(angle)[:, None], np.sin(angle)[:, None]
    y_f = ca * y_axis + sa * z_r
    z_f = -sa * y_axis + ca * z_r
    return np.stack([x_r, y_f, z_f], axis=1)  # rows: spacecraft axes in J2000
