"""RPC-MAG LEVEL_C: field in ECLIPJ2000 or CSEQ with the spacecraft position.

The frame is chosen by date unless given: ECLIPJ2000 (position from the Sun) before the
comet phase, CSEQ (position from the comet) from `COMET_PHASE_START` on, the "Update 2014"
of sec. 4.4.1 (docs/decisions/rosetta.md, decision 28).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.4.1.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.errors import FluxcalError
from fluxcal.geometry.frames import rotate
from fluxcal.geometry.positions import position
from fluxcal.geometry.time import tt2000_to_et, utc_to_tt2000

SPACECRAFT_FRAME = "ROS_SPACECRAFT"
SPACECRAFT = "ROSETTA"
COMET = "67P/C-G"
FRAMES = {"ECLIPJ2000": "ECLIPJ2000", "CSEQ": "67P/C-G_CSEQ"}
#: Start of the comet phase (UTC): the end of deep-space hibernation, 2014-01-20; from
#: then on LEVEL_C is in CSEQ by default ("Update 2014", sec. 4.4.1).
COMET_PHASE_START = "2014-01-20T00:00:00"


def default_frame(epoch: np.ndarray, lsk=None) -> tuple[str, str]:
    """``(frame, centre)`` of LEVEL_C for data at ``epoch`` (TT2000 ns).

    ``("CSEQ", "67P/C-G")`` from `COMET_PHASE_START` on, ``("ECLIPJ2000", "SUN")`` before.

    Raises
    ------
    FluxcalError
        The data span the start of the comet phase (choose ``frame`` explicitly).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.4.1 ("Update 2014: ... the standard
       coordinate system for the LEVEL C data is the CSEQ-system").
    """
    epoch = np.asarray(epoch, dtype=np.int64)
    start = int(utc_to_tt2000(np.array([COMET_PHASE_START]), lsk)[0])
    comet = epoch >= start
    if comet.any() and not comet.all():
        raise FluxcalError(
            f"the data span the start of the comet phase ({COMET_PHASE_START}, LEVEL_C "
            "ECLIPJ2000 before, CSEQ after): process the two parts separately or choose "
            "--frame"
        )
    return ("CSEQ", COMET) if comet.size and comet[0] else ("ECLIPJ2000", "SUN")


def resolve_frame(
    epoch: np.ndarray, frame: str = "auto", centre: str = "auto", lsk=None
) -> tuple[str, str]:
    """SPICE frame name and position centre for ``frame``/``centre`` (``"auto"`` by date).

    An explicit frame with ``centre="auto"`` takes the comet for CSEQ, else the Sun.
    """
    if str(frame).lower() == "auto":
        frame, auto_centre = default_frame(epoch, lsk)
    else:
        auto_centre = COMET if FRAMES.get(frame.upper(), frame) == FRAMES["CSEQ"] else "SUN"
    to_frame = FRAMES.get(str(frame).upper(), frame)
    return to_frame, (auto_centre if str(centre).lower() == "auto" else centre)


def level_c(
    level_b: xr.Dataset,
    *,
    frame: str = "auto",
    centre: str = "auto",
    spacecraft_frame: str = SPACECRAFT_FRAME,
    method: str = "interpolate",
    lsk=None,
) -> xr.Dataset:
    """Convert LEVEL_B (s/c coordinates) to LEVEL_C (ECLIPJ2000 or CSEQ) plus position.

    Kernels (SCLK, attitude CK, SPK) must be loaded (`fluxcal.geometry.kernels.KernelPool`).

    Parameters
    ----------
    level_b : xarray.Dataset
    frame : {"auto", "ECLIPJ2000", "CSEQ"} or any SPICE frame name
        Target frame; ``"CSEQ"`` is ``67P/C-G_CSEQ``; ``"auto"`` (default) chooses by date
        (`default_frame`).
    centre : str
        Body the position is measured from; ``"auto"`` (default): the comet for CSEQ, the
        Sun otherwise.
    spacecraft_frame : str
        SPICE name of the s/c frame of LEVEL_B.
    method : {"interpolate", "oracle"}
        Rotation/position evaluation (`fluxcal.geometry.frames.rotate`).

    Returns
    -------
    xarray.Dataset
        ``b`` (nT) in ``frame``, ``position`` (km, ROSETTA relative to ``centre`` in
        ``frame``), ``et``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.4.1.
    """
    to_frame, centre = resolve_frame(level_b["epoch"].values, frame, centre, lsk)
    et = tt2000_to_et(level_b["epoch"].values, lsk)
    b = rotate(level_b["b"].values, et, spacecraft_frame, to_frame, method=method)
    pos = position(SPACECRAFT, centre, to_frame, et, method=method)
    out = level_b.copy()
    out["b"] = (("time", "component"), b, {"units": "nT", "frame": to_frame})
    out["position"] = (
        ("time", "component"),
        pos,
        {"units": "km", "frame": to_frame, "centre": centre},
    )
    out["et"] = ("time", et, {"units": "s", "description": "TDB seconds past J2000"})
    out.attrs.update(
        level="C", output_frame=to_frame, position_centre=centre, geometry_method=method
    )
    return out
