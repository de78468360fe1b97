"""Geometry: SPICE kernels, exact TT2000 time, frames, positions and day boundaries.

Vectorised over samples (no SPICE call per sample; `fluxcal.geometry.kernels.KernelPool`
scopes the loaded kernels).  ``__all__`` lists the public modules; ``compiled``,
``cspice_loops`` and ``synthetic`` (the forward model's kernels) are internal.
"""

__all__ = [
    "axes",
    "days",
    "frames",
    "kernels",
    "positions",
    "time",
]
