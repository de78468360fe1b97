"""The public API is documented, and it is what ``__all__`` names (issue 32).

The public API: ``fluxcal.__all__`` and, from each package the API reference lists
(docs/api.rst), what its ``__all__`` names: public modules (walked in turn) and the
objects it re-exports; a module without ``__all__`` contributes the classes and functions
it defines.  Every module, class, function, public method and property reached has a
docstring (a NamedTuple field: its entry in the class's ``Attributes``), and no internal
module (command line, demo, simulator, compiled kernels) is reached, so the reference
built from the same ``__all__`` (docs/conf.py) holds the public API only.
"""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path
from types import ModuleType

import fluxcal

API_RST = Path(__file__).resolve().parents[1] / "docs" / "api.rst"
#: Module names that are internal wherever they are.
INTERNAL = re.compile(r"(^|\.)(_\w*|cli|\w+_cli|cli_help|\w*demo\w*|simulate|flight_sim|"
                      r"synthetic\w*|compiled|cspice_loops)$")


def _roots() -> list[str]:
    block = API_RST.read_text().split(".. autosummary::", 1)[1]
    return [line.strip() for line in block.splitlines()
            if line.strip().startswith("fluxcal")]


def _documented(doc: str | None) -> bool:
    return bool(doc and doc.strip()) and not doc.startswith("Alias for field number")


def _names(module: ModuleType) -> list[str]:
    if hasattr(module, "__all__"):
        return list(module.__all__)
    return [n for n, o in vars(module).items() if not n.startswith("_")
            and (inspect.isclass(o) or inspect.isfunction(o))
            and o.__module__ == module.__name__]


def _members(cls: type) -> list[tuple[str, object]]:
    """Public methods, properties and NamedTuple fields defined on ``cls``."""
    out = []
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(value, property):
            out.append((name, value.fget))
        elif isinstance(value, (classmethod, staticmethod)):
            out.append((name, value.__func__))
        elif inspect.isfunction(value) or type(value).__name__ == "_tuplegetter":
            out.append((name, value))
    return out


def _walk(module: ModuleType, seen: dict[str, list[str]]) -> None:
    """Record in ``seen`` each module's public objects and the undocumented ones."""
    if module.__name__ in seen:
        return
    seen[module.__name__] = []
    if not _documented(module.__doc__):
        seen[module.__name__].append("<module docstring>")
    for name in _names(module):
        obj = getattr(module, name, None)
        if obj is None and hasattr(module, "__path__"):  # a submodule not imported yet
            obj = importlib.import_module(f"{module.__name__}.{name}")
        if inspect.ismodule(obj):
            _walk(obj, seen)
            continue
        if not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue  # a constant: documented by its ``#:`` comment
        seen.setdefault("<objects>", []).append(f"{module.__name__}.{name}")
        if not _documented(obj.__doc__):
            seen[module.__name__].append(name)
        if inspect.isclass(obj):
            for member, value in _members(obj):
                seen["<objects>"].append(f"{module.__name__}.{name}.{member}")
                if type(value).__name__ == "_tuplegetter":
                    attributes = (obj.__doc__ or "").partition("Attributes")[2]
                    if not re.search(rf"\b{member}\b", attributes):
                        seen[module.__name__].append(f"{name}.{member}")
                elif not _documented(value.__doc__):
                    seen[module.__name__].append(f"{name}.{member}")


def _public() -> dict[str, list[str]]:
    seen: dict[str, list[str]] = {}
    _walk(fluxcal, seen)
    for root in _roots():
        _walk(importlib.import_module(root), seen)
    return seen


def test_every_public_object_has_a_docstring():
    seen = _public()
    objects = seen.pop("<objects>")
    assert len(objects) > 600, len(objects)  # the walk reached the API (1000+ today)
    missing = {module: names for module, names in seen.items() if names}
    assert missing == {}


def test_the_public_api_holds_no_internal_module():
    modules = [m for m in _public() if not m.startswith("<")]
    assert {"fluxcal.api", "fluxcal.runs.contract", "fluxcal.missions.messenger.levels",
            "fluxcal.geometry.time", "fluxcal.products.writer"} <= set(modules)
    assert [m for m in modules if INTERNAL.search(m)] == []


def test_calibrate_and_read_product_are_the_top_level_api():
    assert {"calibrate", "read_product"} <= set(fluxcal.__all__)
    assert set(fluxcal.__all__) <= set(dir(fluxcal))  # ``fluxcal.<TAB>`` completes them
    assert fluxcal.calibrate is importlib.import_module("fluxcal.api").calibrate
    for name in ("fluxcal.products", "fluxcal.archive"):
        assert "read_product" not in importlib.import_module(name).__all__  # internal
