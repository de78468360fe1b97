"""The registry of missions: entry points of the group ``fluxcal.missions``.

Each entry point names a `~fluxcal.runs.contract.Mission` object; fluxcal's own
missions are registered in its ``pyproject.toml``, a mission of your own in yours::

    [project.entry-points."fluxcal.missions"]
    mymission = "my_package.mission:MISSION"

``FLUXCAL_MISSIONS`` adds missions without installing a package: a comma-separated list
of ``package.module:ATTRIBUTE`` references (a mission under development, the toy mission
of the tests).  The command line, ``fluxcal batch``, ``fluxcal demo`` and the readers of
archived products are built from `missions`; nothing generic names a mission.
"""

from __future__ import annotations

import os
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from fluxcal.errors import FluxcalError
from fluxcal.runs.contract import Mission, load_reference

#: The entry-point group missions register under.
GROUP = "fluxcal.missions"
#: Environment variable with extra ``module:attribute`` mission references.
ENV = "FLUXCAL_MISSIONS"


def _checked(obj: object, where: str) -> Mission:
    if not isinstance(obj, Mission):
        raise FluxcalError(f"{where}: not a fluxcal.runs.contract.Mission "
                           f"(got {type(obj).__name__})")
    return obj


def missions() -> dict[str, Mission]:
    """Return every registered mission by name (entry points, then ``FLUXCAL_MISSIONS``).

    Raises
    ------
    FluxcalError
        If an entry does not load, is not a `Mission`, or two entries share a name.
    """
    found: dict[str, Mission] = {}
    refs = [(ep.name, ep.value) for ep in entry_points(group=GROUP)]
    refs += [("", r.strip()) for r in os.environ.get(ENV, "").split(",") if r.strip()]
    for name, ref in sorted(refs, key=lambda r: (r[0] == "", r[0])):
        mission = _checked(load_reference(ref), f"{ENV if not name else GROUP} entry {ref}")
        if name and mission.name != name:
            raise FluxcalError(f"{GROUP} entry {name} = {ref}: the mission calls itself "
                               f"{mission.name!r}")
        if mission.name in found and found[mission.name] != mission:
            raise FluxcalError(f"two missions named {mission.name!r} are registered ({ref})")
        found[mission.name] = mission
    return found


def get(name: str) -> Mission:
    """Return the mission registered as ``name``.

    Raises
    ------
    FluxcalError
        If no mission of that name is registered (the message lists the known ones).
    """
    known = missions()
    if name not in known:
        raise FluxcalError(f"no mission {name!r} is registered (entry-point group {GROUP}; "
                           f"known: {', '.join(sorted(known)) or 'none'})")
    return known[name]


def frame_kernels() -> dict[str, Path]:
    """Return frame name -> frames kernel of every registered mission (their union).

    The default of `fluxcal.geometry.kernels.KernelPool` (`DEFAULT_FRAMES` there).
    """
    out: dict[str, Path] = {}
    for mission in missions().values():
        if mission.frame_kernels is not None:
            out.update({name: Path(p) for name, p in mission.load("frame_kernels").items()})
    return out


def archived_readers() -> dict[str, Any]:
    """Return mission name -> archived-product reader of every mission that has one.

    The default of `fluxcal.archive.products.read_archive_product`.
    """
    return {name: m.load("archived_products") for name, m in missions().items()
            if m.archived_products is not None}
