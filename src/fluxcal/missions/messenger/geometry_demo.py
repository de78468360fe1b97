"""Geometry part of ``make demo``: a day of a MESSENGER-like orbit."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fluxcal.geometry.frames import Rotator
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.positions import position, rtn_spherical
from fluxcal.geometry.time import SclkKernel, et_to_tt2000, tt2000_to_utc
from fluxcal.missions.messenger.identity import FRAME_KERNELS, NAIF_NAME, SPACECRAFT_ID
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.paths import make_folder

MERCURY_RADIUS_KM = 2440.0


def run_geometry_demo(out: Path, rate_hz: float = 1.0) -> str:
    """Write synthetic kernels, convert a day of clock readings and rotate, return a summary.

    Parameters
    ----------
    out : Path
        Folder for the kernels and ``geometry_summary.txt``.
    rate_hz : float
        Sample rate of the simulated clock readings.

    Returns
    -------
    str
        The printed summary.
    """
    make_folder(out)
    meta = write_messenger_like_kernels(out / "kernels", "2012-06-01T00:00:00", 86400.0,
                                        plus_y_sunward=[(30000.0, 34000.0)])
    lines = [f"Synthetic MESSENGER-like kernels: {meta}"]
    with KernelPool([meta], frames=FRAME_KERNELS):
        clock = SclkKernel.from_pool(SPACECRAFT_ID)
        part0, met0 = clock.from_et(np.array([_str2et("2012-06-01T00:00:00")]))
        met = met0[0] + np.arange(0.0, 86400.0, 1.0 / rate_hz)
        t0 = time.perf_counter()
        et = clock.to_et(np.full(met.size, part0[0]), met)
        tt2000 = et_to_tt2000(et)
        doy = tt2000_to_utc(tt2000[[0, -1]], style="doy")
        t_time = time.perf_counter() - t0
        t0 = time.perf_counter()
        rot = Rotator("MSGR_MAG", et)
        mats = {f: rot.matrices(f) for f in ("J2000", "MSGR_MSO", "IAU_MERCURY", "MSGR_RTN")}
        t_rot = time.perf_counter() - t0
        t0 = time.perf_counter()
        pos_mso = position(NAIF_NAME, "MERCURY", "MSGR_MSO", et)
        r_sun, lat, az = rtn_spherical(NAIF_NAME, et)
        t_pos = time.perf_counter() - t0
    alt = np.linalg.norm(pos_mso, axis=1) - MERCURY_RADIUS_KM
    lines += [
        f"{met.size} clock readings (MET {met[0]:.3f} .. {met[-1]:.3f} s, partition {part0[0]})",
        f"  UTC {doy[0]} .. {doy[-1]}  (archive form, MESSENGER MAG EDR-to-CDR Processing, sec. 9)",
        f"  SCLK -> ET -> TT2000 in {t_time:.3f} s",
        f"Altitude over Mercury: {alt.min():.1f} .. {alt.max():.1f} km",
        f"Distance from the Sun: {r_sun.min() / 1.495978707e8:.4f} .. "
        f"{r_sun.max() / 1.495978707e8:.4f} AU; ecliptic latitude {lat.mean():.3f} deg, "
        f"azimuth from the Earth-Sun line {az.mean():.2f} deg",
        f"Rotations MSGR_MAG -> J2000, MSO, MBF, RTN in {t_rot:.3f} s; positions in {t_pos:.3f} s",
        "MSGR_MAG -> MSGR_MSO at the first sample:",
        *["  " + " ".join(f"{v:+.6f}" for v in row) for row in mats["MSGR_MSO"][0]],
    ]
    summary = "\n".join(lines)
    atomic_write_bytes(out / "geometry_summary.txt", summary + "\n", now=True)
    return summary


def _str2et(text: str) -> float:
    import spiceypy

    return spiceypy.str2et(text)
