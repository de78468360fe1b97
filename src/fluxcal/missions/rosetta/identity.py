"""Rosetta's identity for SPICE: spacecraft id, names and fluxcal's frame kernels.

One place names the spacecraft: every Rosetta module takes its NAIF id and names from
here, and hands them to the generic geometry code as arguments.

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1), sec. 4.4.1
       (frames).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

#: NAIF id of the spacecraft and of its clock (SCLK, OBT).
SPACECRAFT_ID = -226
#: NAIF body name of the spacecraft.
NAIF_NAME = "ROSETTA"
#: The names SPICE accepts for the spacecraft (name and id).
NAIF_NAMES = (NAIF_NAME, str(SPACECRAFT_ID))
#: Prefix of the mission's SPICE frame names.
FRAME_PREFIX = "ROS_"


def _frames_kernel(name: str) -> Path:
    return Path(str(resources.files("fluxcal.missions.rosetta") / "data" / "frames" / name))


#: Frames fluxcal defines for Rosetta (the comet-centred CSEQ frame), loaded by
#: `fluxcal.geometry.kernels.KernelPool` only for names the user's kernels do not define.
FRAME_KERNELS: dict[str, Path] = {
    "67P/C-G_CSEQ": _frames_kernel("cg_cseq.tf"),
}
