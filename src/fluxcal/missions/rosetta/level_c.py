"""RPC-MAG LEVEL_C: field in ECLIPJ2000 (or CSEQ) with the spacecraft position.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.4.1.
"""

from __future__ import annotations

import xarray as xr

SPACECRAFT_FRAME = "ROS_SPACECRAFT"
SPACECRAFT = "ROSETTA"
FRAMES = {"ECLIPJ2000": "ECLIPJ2000", "CSEQ": "67P/C-G_CSEQ"}


def level_c(
    level_b: xr.Dataset,
    *,
    frame: str = "ECLIPJ2000",
    centre: str = "SUN",
    spacecraft_frame: str = SPACECRAFT_FRAME,
    method: str = "interpolate",
    lsk=None,
) -> xr.Dataset:
    """LEVEL_B (s/c coordinates) -> LEVEL_C (ECLIPJ2000 or CSEQ) plus position.

    Kernels (SCLK, attitude CK, SPK) must be loaded (`fluxcal.geometry.kernels.KernelPool`).

    Parameters
    ----------
    level_b : xarray.Dataset
    frame : {"ECLIPJ2000", "CSEQ"} or any SPICE frame name
        Target frame; ``"CSEQ"`` is ``67P/C-G_CSEQ``.
    centre : str
        Body the position is measured from (default the Sun).
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
    from fluxcal.geometry.frames import rotate
    from fluxcal.geometry.positions import position
    from fluxcal.geometry.time import tt2000_to_et

    to_frame = FRAMES.get(frame.upper(), frame)
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
