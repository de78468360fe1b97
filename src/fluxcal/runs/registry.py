"""The registry of missions: entry points of the group ``fluxcal.missions``.

Each entry point names a `~fluxcal.runs.contract.Mission` object; fluxcal's own
missions are registered in its ``pyproject.toml``, a mission of your own in yours::

    [project.entry-points."fluxcal.missions"]
    mymission = "my_package.mission:MISSION"

``FLUXCAL_MISSIONS`` adds missions without installing a package: a comma-separated list
of ``package.module:ATTRIBUTE`` references (a mission under development, the toy mission
of the tests).  The command line, ``fluxcal batch``, ``fluxcal demo`` and the readers of
archived products are built from `missions`; nothing generic names a mission.

The installed entry points are scanned once per process, and each mission object is
imported once (`rescan` forgets both, e.g. after installing a plugin in a notebook).
A mission that fails to load (its module missing or raising, not a `Mission`, named
otherwise than its entry point, or sharing its name with another) does not stop the
others: `missions` skips it with a `PluginWarning` naming it (as xarray does for its
backends), and asking for it (`get`, ``fluxcal <name>``) is a `FluxcalError` naming the
entry-point group, the name and what failed.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from fluxcal.errors import FluxcalError
from fluxcal.runs.contract import Mission, load_reference

#: The entry-point group missions register under.
GROUP = "fluxcal.missions"
#: Environment variable with extra ``module:attribute`` mission references.
ENV = "FLUXCAL_MISSIONS"


class PluginWarning(RuntimeWarning):
    """A registered mission (or a piece of one) failed to load and is skipped."""


@dataclass(frozen=True, order=True)
class Entry:
    """One registration: an entry point (``name = reference``) or a `ENV` reference."""

    name: str
    reference: str

    def describe(self) -> str:
        """Return where the entry comes from, for messages."""
        if self.name:
            return f"entry point {self.name} = {self.reference} (group {GROUP})"
        return f"{ENV} entry {self.reference}"


@functools.cache
def _installed() -> tuple[Entry, ...]:
    """Return the installed entry points of `GROUP` (scanned once per process)."""
    return tuple(sorted(Entry(ep.name, ep.value) for ep in entry_points(group=GROUP)))


def _environment() -> tuple[Entry, ...]:
    return tuple(Entry("", r.strip()) for r in os.environ.get(ENV, "").split(",")
                 if r.strip())


@functools.cache
def _load(entry: Entry) -> Mission | str:
    """Return the entry's mission, or why it failed (imported once per process)."""
    try:
        obj = load_reference(entry.reference)
    except FluxcalError as exc:  # no such module or attribute (the message names it)
        return f"mission plugin {entry.describe()} failed to load: {exc}"
    except Exception as exc:  # noqa: BLE001 - a broken plugin must not stop the others
        return (f"mission plugin {entry.describe()} failed to load: "
                f"{type(exc).__name__}: {exc}")
    if not isinstance(obj, Mission):
        return (f"mission plugin {entry.describe()} is not a fluxcal.runs.contract.Mission "
                f"(got {type(obj).__name__})")
    if entry.name and obj.name != entry.name:
        return (f"mission plugin {entry.describe()} calls itself {obj.name!r}: register it "
                f"under that name")
    return obj


def rescan() -> None:
    """Forget the scanned entry points and loaded missions (the next call scans again)."""
    _installed.cache_clear()
    _load.cache_clear()


def _scan() -> tuple[dict[str, Mission], dict[str, str]]:
    """Return (missions by name, name -> why it failed) of every registration."""
    found: dict[str, Mission] = {}
    where: dict[str, Entry] = {}
    broken: dict[str, str] = {}
    for entry in (*_installed(), *_environment()):
        result = _load(entry)
        if isinstance(result, str):
            broken[entry.name or entry.reference] = result
            continue
        name = result.name
        if name in broken and broken[name].startswith("two missions"):
            continue
        if name in found and found[name] != result:
            broken[name] = (f"two missions named {name!r} are registered "
                            f"({where[name].describe()}; {entry.describe()}): uninstall one")
            del found[name]
            continue
        found[name], where[name] = result, entry
    return found, broken


def broken() -> dict[str, str]:
    """Return name (or reference) -> why it failed, of every mission that did not load."""
    return _scan()[1]


def missions() -> dict[str, Mission]:
    """Return every registered mission by name (entry points, then ``FLUXCAL_MISSIONS``).

    A registration that fails to load is skipped with a `PluginWarning` naming it
    (`broken`); `get` of its name raises.
    """
    found, failed = _scan()
    for message in failed.values():
        warnings.warn(f"{message}; skipped", PluginWarning, stacklevel=2)
    return found


def get(name: str) -> Mission:
    """Return the mission registered as ``name``.

    Raises
    ------
    FluxcalError
        If the mission failed to load (the message names the entry-point group, the
        name and the error) or no mission of that name is registered (the message lists
        the known ones).
    """
    known, failed = _scan()
    if name in known:
        return known[name]
    if name in failed:
        raise FluxcalError(failed[name])
    also = f"; failed to load: {', '.join(sorted(failed))}" if failed else ""
    raise FluxcalError(f"no mission {name!r} is registered (entry-point group {GROUP}; "
                       f"known: {', '.join(sorted(known)) or 'none'}{also})")


def load_piece(mission: Mission, piece: str) -> Any:
    """Return ``mission.load(piece)``; a failure is a `FluxcalError` naming the plugin.

    Raises
    ------
    FluxcalError
        If the mission provides no ``piece`` or its reference fails to import.
    """
    try:
        return mission.load(piece)
    except FluxcalError:
        raise
    except Exception as exc:  # noqa: BLE001 - any import error of a plugin's module
        raise FluxcalError(f"mission plugin {mission.name!r} (group {GROUP}): its "
                           f"{piece.replace('_', ' ')} {getattr(mission, piece)} failed to "
                           f"load: {type(exc).__name__}: {exc}") from exc


def _pieces(piece: str) -> dict[str, Any]:
    """Return name -> loaded ``piece`` of every mission that has one (failures skipped)."""
    out: dict[str, Any] = {}
    for name, mission in missions().items():
        if getattr(mission, piece) is None:
            continue
        try:
            out[name] = load_piece(mission, piece)
        except FluxcalError as exc:
            warnings.warn(f"{exc}; skipped", PluginWarning, stacklevel=3)
    return out


def frame_kernels() -> dict[str, Path]:
    """Return frame name -> frames kernel of every registered mission (their union).

    What the command line and the runs pass to `fluxcal.geometry.kernels.KernelPool`.
    """
    out: dict[str, Path] = {}
    for frames in _pieces("frame_kernels").values():
        out.update({name: Path(p) for name, p in frames.items()})
    return out


def archived_readers() -> Mapping[str, Any]:
    """Return mission name -> archived-product reader of every mission that has one.

    What `fluxcal.read_product` passes to `fluxcal.archive.products.read_product`.
    """
    return _pieces("archived_products")
