"""A Rosetta-like synthetic kernel set: spacecraft clock, frames, comet and escort orbit.

`write_rosetta_like_kernels`: SCLK -226 (65536 ticks/s, OBT seconds since 2003-01-01),
ROS_SPACECRAFT (CK -226000), comet 67P (1000012) on a heliocentric orbit and the
spacecraft escorting it at ~30 km, attitude pointing +Z at the comet.  Written with the
generic helpers of `fluxcal.geometry.synthetic`; returns the path of a meta-kernel for
`fluxcal.geometry.kernels.KernelPool`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import (
    AU,
    GM_SUN,
    conics_pos,
    furnished,
    kepler_states,
    prepare_kernel_folder,
    sclk_text,
    tdt,
    unit,
    write_ck,
    write_meta_kernel,
    write_spk,
)
from fluxcal.missions.rosetta.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.products.atomic import atomic_write_bytes

ROSETTA_FK = """KPL/FK

fluxcal synthetic Rosetta-like frames kernel (ids and names as in ROS_V38.TF)

\\begindata

   NAIF_BODY_NAME              += ( 'ROSETTA', '67P/C-G' )
   NAIF_BODY_CODE              += ( -226, 1000012 )

   FRAME_ROS_SPACECRAFT        = -226000
   FRAME_-226000_NAME          = 'ROS_SPACECRAFT'
   FRAME_-226000_CLASS         = 3
   FRAME_-226000_CLASS_ID      = -226000
   FRAME_-226000_CENTER        = -226
   CK_-226000_SCLK             = -226
   CK_-226000_SPK              = -226

\\begintext
"""


def write_rosetta_like_kernels(
    out_dir: str | Path,
    start_utc: str = "2014-09-01T00:00:00",
    duration_s: float = 86400.0,
    *,
    attitude_step: float = 10.0,
    margin_s: float = 3600.0,
) -> Path:
    """Write a Rosetta-like kernel set (comet escort) and return its meta-kernel.

    Parameters
    ----------
    out_dir : path
        Folder for the kernels (created).
    start_utc : str
        Start of the covered interval (UTC, ISO).
    duration_s : float
        Length of the interval (s).
    attitude_step : float
        Spacing of the CK records (s).
    margin_s : float
        Extra coverage each side (s).

    Returns
    -------
    Path
        The meta-kernel ``rosetta_synthetic.tm`` (SCLK, FK, SPK, CK, and the frames of
        `FRAME_KERNELS` copied beside them, listed last as a pool loaded them before).
    """
    out, sclk_path, fk_path, spk_path, ck_path = prepare_kernel_folder(out_dir, "ros_synthetic")
    with KernelPool([], frames={}):
        epoch0 = tdt("2003-01-01T00:00:00")
        atomic_write_bytes(sclk_path, sclk_text(
                SPACECRAFT_ID,
                (4294967296, 65536),
                [(0.0, 2.81474976710655e14)],
                [
                    (0.0, epoch0, 1.0000003),
                    (65536.0 * 3.5e8, epoch0 + 3.5e8 * 1.0000003, 0.9999998),
                ],
                f"fluxcal synthetic Rosetta-like SCLK (id {SPACECRAFT_ID}): OBT seconds since "
                "2003-01-01.",
            ), now=True)
        atomic_write_bytes(fk_path, ROSETTA_FK, now=True)
        with furnished(sclk_path, fk_path):
            et0 = spiceypy.str2et(start_utc) - margin_s
            et1 = spiceypy.str2et(start_utc) + duration_s + margin_s
            epochs = np.arange(et0, et1 + 600.0, 600.0)
            comet_elements = [1.243 * AU, 0.641, math.radians(7.04), math.radians(50.1),
                              math.radians(12.8), math.radians(-20.0), et0, GM_SUN]
            comet = kepler_states(comet_elements, epochs)
            write_spk(spk_path, 1000012, 10, epochs, comet, "67P-LIKE ORBIT")
            # spacecraft on a slow 30 km circular orbit about the comet (mass ~1e13 kg)
            gm_comet = 6.674e-20 * 1.0e13
            sc_elements = [30.0, 0.0, math.radians(70.0), 0.0, 0.0, 0.0, et0, gm_comet]
            sc = kepler_states(sc_elements, epochs)
            write_spk(spk_path, SPACECRAFT_ID, 1000012, epochs, sc, "ROSETTA-LIKE ESCORT",
                      append=True)
            att_epochs = np.arange(et0, et1 + attitude_step, attitude_step)
            to_comet = unit(-np.array([conics_pos(sc_elements, t) for t in att_epochs]))
            sun = unit(-np.array([conics_pos(comet_elements, t) for t in att_epochs]))
            z_axis = to_comet
            y_axis = unit(np.cross(z_axis, sun))
            x_axis = np.cross(y_axis, z_axis)
            cmat = np.stack([x_axis, y_axis, z_axis], axis=1)
            write_ck(ck_path, SPACECRAFT_ID * 1000, SPACECRAFT_ID, att_epochs, cmat,
                     "ROSETTA-LIKE ATTITUDE")
    # the comet-centred frame (CSEQ) in the set, as the real set's comet FK has it
    frames = [out / p.name for p in FRAME_KERNELS.values()]
    for src, dest in zip(FRAME_KERNELS.values(), frames, strict=True):
        atomic_write_bytes(dest, Path(src).read_bytes(), now=True)
    return write_meta_kernel(out / "rosetta_synthetic.tm",
                             [sclk_path, fk_path, spk_path, ck_path, *frames])
