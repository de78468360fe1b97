"""A batch day's manifest: what its products were made with, and whether that changed.

After a day succeeds, ``<out>/manifests/<name>_<day>.json`` records the products (size,
SHA-256) and the day's *key*: the inputs and calibration with their SHA-256 (or version,
``task.inputs(day)``), the options that change a product (`task_settings`) and the
software version.  `stale_reason` says which part of the key changed (the day is
redone) or None (the day is skipped); the batch report carries it (issue 32).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.provenance import sha256_file
from fluxcal.version import software_version

MANIFEST_DIR = "manifests"


def manifest_path(out_dir: Path, name: str, day: _dt.date) -> Path:
    """Path of a day's manifest."""
    return Path(out_dir) / MANIFEST_DIR / f"{name}_{day.isoformat()}.json"


def current_inputs(task: Any, day: _dt.date) -> Any:
    """Return ``task.inputs(day)`` (a `fluxcal.runs.batch.DayInputs`), or None without it."""
    fn = getattr(task, "inputs", None)
    return fn(day) if callable(fn) else None


#: Fields of a dataclass task that are not options (the fallback of `task_settings`).
_NOT_SETTINGS = frozenset({"input_dir", "out_dir", "name"})


def _path_digest(path: Path) -> str:
    """Content digest of a path option: a file's SHA-256, or a folder's files' (by name)."""
    if path.is_file():
        return f"sha256:{sha256_file(path)}"
    if path.is_dir():
        h = hashlib.sha256()
        for p in sorted(q for q in path.rglob("*") if q.is_file()):
            h.update(f"{p.relative_to(path).as_posix()}:{sha256_file(p)}\n".encode())
        return f"folder-sha256:{h.hexdigest()}"
    return f"missing:{path.name}"


def settings_value(value: Any) -> Any:
    """Return an option's value as the manifest records it (JSON, no path of this machine).

    A path is recorded by its content (`_path_digest`: a calibration folder moved
    elsewhere is the same key, one with a changed file is not); tuples become lists,
    dates ISO strings, a dataclass the dict of its fields.
    """
    if isinstance(value, Path):
        return _path_digest(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: settings_value(getattr(value, f.name))
                for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): settings_value(v) for k, v in sorted(value.items(), key=str)}
    if isinstance(value, (list, tuple, set, frozenset)):
        items = [settings_value(v) for v in value]
        return sorted(items, key=str) if isinstance(value, (set, frozenset)) else items
    if isinstance(value, (_dt.date, _dt.datetime)):
        return value.isoformat()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def task_settings(task: Any) -> dict[str, Any]:
    """Return the options of ``task`` that change its products (part of the manifest key).

    ``task.settings()`` when the task has it (`fluxcal.runs.driver.DayTask`: the fields
    of its options dataclass); else, for a dataclass task, its fields but
    ``input_dir``, ``out_dir`` and ``name``; else nothing.  Values as `settings_value`.
    """
    fn = getattr(task, "settings", None)
    if callable(fn):
        raw: Mapping[str, Any] = fn()
    elif dataclasses.is_dataclass(task) and not isinstance(task, type):
        raw = {f.name: getattr(task, f.name) for f in dataclasses.fields(task)
               if f.name not in _NOT_SETTINGS}
    else:
        raw = {}
    return {str(k): settings_value(v) for k, v in raw.items()}


_ABSENT = object()


def _changed(kind: str, recorded: Mapping[str, Any], current: Mapping[str, Any]) -> str | None:
    """Name what differs between two keyed records (at most three names), or None."""
    names = sorted(set(recorded) | set(current))
    diff = [n for n in names if recorded.get(n, _ABSENT) != current.get(n, _ABSENT)]
    if not diff:
        return None
    parts = []
    for n in diff[:3]:
        if n not in recorded:
            parts.append(f"{n} added")
        elif n not in current:
            parts.append(f"{n} removed")
        elif kind == "option":
            parts.append(f"{n} {_short(recorded[n])} -> {_short(current[n])}")
        else:
            parts.append(f"{n} changed")
    more = f" and {len(diff) - 3} more" if len(diff) > 3 else ""
    return f"{kind}{'s' if len(diff) > 1 else ''} " + ", ".join(parts) + more


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def stale_reason(task: Any, day: _dt.date, out_dir: Path, name: str) -> str | None:
    """Return why the day must be (re)done, or None when it is up to date.

    The day is up to date when its manifest is present and readable; was written by the
    same fluxcal version; every recorded product exists with its recorded size; the task
    declares ``inputs(day)`` and the current inputs and calibration are exactly the
    recorded ones (by file name and SHA-256); and the options that change a product
    (`task_settings`) equal the recorded ones.  The reason names the first part of the
    key that changed (e.g. ``option formats ["tab"] -> ["cdf"]``).
    """
    path = manifest_path(out_dir, name, day)
    if not path.exists():
        return "no manifest (first run of the day, or it did not finish)"
    try:
        man = json.loads(path.read_text())
    except (OSError, ValueError):
        return "manifest unreadable"
    if man.get("software_version") != software_version():
        return (f"fluxcal version {man.get('software_version')} -> {software_version()}")
    for prod in man.get("products", []):
        p = Path(out_dir) / prod["path"]
        if not p.exists():
            return f"product {prod['path']} missing"
        if p.is_file() and p.stat().st_size != prod["size"]:
            return f"product {prod['path']} changed size"
    try:
        current = current_inputs(task, day)
        # the manifest names inputs by file name only: a task that cannot say its
        # current inputs cannot be checked, and its day is redone
        if current is None:
            return "the task does not list its inputs (always redone)"
        changed = _changed("input", man.get("inputs", {}), current.checksums())
        if changed:
            return changed
        if "settings" not in man:
            return "options not recorded (manifest of an older fluxcal)"
        return _changed("option", man["settings"], task_settings(task))
    except OSError as exc:
        return f"inputs unreadable ({type(exc).__name__})"


def is_up_to_date(task: Any, day: _dt.date, out_dir: Path, name: str) -> bool:
    """Whether the day's manifest key is unchanged (`stale_reason` is None)."""
    return stale_reason(task, day, out_dir, name) is None


def write_manifest(out_dir: Path, name: str, day: _dt.date, result: Any, inputs: Any,
                   settings: Mapping[str, Any]) -> None:
    """Write the day's manifest: its products (size, SHA-256) and its key, atomically.

    ``result``: the day's `fluxcal.runs.batch.DayResult`; ``inputs``: its
    `fluxcal.runs.batch.DayInputs` (or None); ``settings``: `task_settings` of its task.
    """
    prods = []
    for p in result.products:
        p = Path(p)
        rel = os.path.relpath(p, out_dir)
        size = p.stat().st_size if p.is_file() else 0
        prods.append({"path": rel, "size": size,
                      "sha256": sha256_file(p) if p.is_file() else ""})
    man = {
        "name": name,
        "day": day.isoformat(),
        "software_version": software_version(),
        "products": prods,
        "inputs": inputs.checksums() if inputs is not None else {},
        "settings": dict(settings),
        "n_vectors": result.n_vectors,
    }
    atomic_write_bytes(manifest_path(out_dir, name, day),
                       json.dumps(man, indent=1, sort_keys=True).encode())
