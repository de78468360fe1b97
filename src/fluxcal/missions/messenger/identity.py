"""MESSENGER's identity for SPICE: spacecraft id, names and fluxcal's frame kernels.

One place names the spacecraft: every MESSENGER module takes its NAIF id and names from
here, and hands them to the generic geometry code as arguments.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (seed 000), sec. 3 (frames), sec. 9
       (spacecraft clock), sec. 10 (positions).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

#: NAIF id of the spacecraft and of its clock (SCLK).
SPACECRAFT_ID = -236
#: NAIF body name of the spacecraft.
NAIF_NAME = "MESSENGER"
#: The names SPICE accepts for the spacecraft in frame definitions (name and id).
NAIF_NAMES = (NAIF_NAME, str(SPACECRAFT_ID))
#: Prefix of the mission's SPICE frame names.
FRAME_PREFIX = "MSGR_"


def _frames_kernel(name: str) -> Path:
    return Path(str(resources.files("fluxcal.missions.messenger") / "data" / "frames" / name))


#: Frames fluxcal defines for MESSENGER (seed 000 sec. 3), loaded by
#: `fluxcal.geometry.kernels.KernelPool` only for names the user's kernels do not define.
FRAME_KERNELS: dict[str, Path] = {
    "MSGR_MSO": _frames_kernel("msgr_mso.tf"),
    "MSGR_VSO": _frames_kernel("msgr_vso.tf"),
    "MSGR_RTN": _frames_kernel("msgr_rtn.tf"),
}
