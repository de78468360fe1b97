"""Provenance attributes carried by every product.

`provenance_attrs` returns a dict to merge into a Dataset's ``attrs``: software name
and version, input files with SHA-256 checksums, calibration files (with checksums)
or versions, kernels (with checksums), the command line and the creation time.

Only ``creation_time`` changes between two identical runs; writers keep it in the
label and global attributes, never in the science content (TAB rows, variables).
Set ``SOURCE_DATE_EPOCH`` (seconds since 1970) to pin it for fully reproducible files.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from fluxcal.version import software_version

_CHUNK = 1 << 20


def sha256_file(path: Path | str) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(_CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def file_record(path: Path | str) -> dict[str, str]:
    """``{"path": ..., "name": ..., "sha256": ...}`` for an existing file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist (a product never cites a file it did not read).
    """
    p = Path(path)
    return {"name": p.name, "path": str(p), "sha256": sha256_file(p)}


def creation_time() -> str:
    """UTC creation time, ISO 8601 to the second (``SOURCE_DATE_EPOCH`` honoured)."""
    sde = os.environ.get("SOURCE_DATE_EPOCH")
    now = (
        _dt.datetime.fromtimestamp(int(sde), _dt.UTC)
        if sde
        else _dt.datetime.now(_dt.UTC)
    )
    return now.strftime("%Y-%m-%dT%H:%M:%SZ")


def provenance_attrs(
    inputs: Iterable[Path | str] = (),
    calibration: Mapping[str, str | Path] | None = None,
    kernels: Iterable[Path | str] = (),
    command_line: str | None = None,
) -> dict[str, Any]:
    """Provenance attributes for a product's Dataset ``attrs``.

    Parameters
    ----------
    inputs : iterable of path
        Input files read; each is recorded with its SHA-256.
    calibration : mapping, optional
        Calibration name -> version string, or path of the calibration file (an
        existing file is recorded with its SHA-256, anything else as a version).
    kernels : iterable of path
        SPICE kernels loaded (existing files get a SHA-256; others, e.g. a kernel
        named inside a meta-kernel that is not on disk, are recorded by name).
    command_line : str, optional
        Default: ``sys.argv`` joined by spaces.

    Returns
    -------
    dict
        Keys ``software``, ``software_version``, ``inputs`` (list of dicts),
        ``calibration`` (dict name -> dict), ``kernels`` (list of dicts),
        ``command_line`` and ``creation_time``.
    """
    cal: dict[str, dict[str, str]] = {}
    for name, value in (calibration or {}).items():
        p = Path(str(value))
        if p.is_file():
            cal[str(name)] = file_record(p)
        else:
            cal[str(name)] = {"version": str(value)}
    kern = [file_record(k) if Path(k).is_file() else {"name": Path(k).name, "path": str(k)}
            for k in kernels]
    return {
        "software": "fluxcal",
        "software_version": software_version(),
        "inputs": [file_record(p) for p in inputs],
        "calibration": cal,
        "kernels": kern,
        "command_line": command_line if command_line is not None else " ".join(sys.argv),
        "creation_time": creation_time(),
    }


def checksums(attrs: Mapping[str, Any]) -> dict[str, str]:
    """Map ``name -> sha256`` of inputs, calibration files and kernels in provenance attrs.

    Used by the batch manifest to decide whether a day's product is up to date.
    """
    out: dict[str, str] = {}
    for rec in attrs.get("inputs", []) or []:
        out[f"input:{rec['path']}"] = rec.get("sha256", "")
    for name, rec in (attrs.get("calibration", {}) or {}).items():
        out[f"calibration:{name}"] = rec.get("sha256", rec.get("version", ""))
    for rec in attrs.get("kernels", []) or []:
        out[f"kernel:{rec.get('path', rec.get('name'))}"] = rec.get("sha256", "")
    return out
