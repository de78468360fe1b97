"""Provenance attributes carried by every product, without the producer's paths.

`provenance_attrs` returns a dict to merge into a Dataset's ``attrs``: software name
and version, input files with SHA-256 checksums, calibration files (with checksums)
or versions, kernels (with checksums), the command line and the creation time.

A product names every file it depends on by **file name and SHA-256** (and version
where there is one), never by where the file sat: the folders of the machine that made
it (a temporary folder, the checkout, ``site-packages``, the user's home) are not
science and make two identical runs on two machines differ.  `portable_dataset` is the
writers' last step before the bytes: every attribute string is passed through
`portable_text`, which reduces a path to its file name (docs/decisions/products.md).

Only ``creation_time`` changes between two identical runs; writers keep it in the
label and global attributes, never in the science content (TAB rows, variables).
Set ``SOURCE_DATE_EPOCH`` (seconds since 1970) to pin it for fully reproducible files.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from contextvars import ContextVar
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import TYPE_CHECKING, Any

from fluxcal.version import software_version

if TYPE_CHECKING:
    import xarray as xr

_CHUNK = 1 << 20

#: The command line of the running ``fluxcal`` command (`fluxcal.cli.main` sets it, also
#: when called with ``argv`` from Python); ``None``: ``sys.argv``.
COMMAND_ARGS: ContextVar[tuple[str, ...] | None] = ContextVar("fluxcal_command_args",
                                                              default=None)

#: Characters that end a path inside a text (quotes of JSON, separators of lists).
_TOKEN = re.compile(r"[^\s\"'(),;=\[\]{}<>]+")
#: A file name with an extension (a letter first: ``1/2.5`` is a number, not a file).
_FILE_NAME = re.compile(r"^[^/\\]+\.[A-Za-z][A-Za-z0-9_-]{0,9}$")
_WINDOWS_ABSOLUTE = re.compile(r"^[A-Za-z]:[\\/]")


def sha256_file(path: Path | str) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(_CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def file_record(path: Path | str) -> dict[str, str]:
    """``{"name": ..., "sha256": ...}`` for an existing file (no folder: by name and checksum).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist (a product never cites a file it did not read).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "abc.csv"
    >>> _ = p.write_bytes(b"abc")
    >>> file_record(p)["name"], file_record(p)["sha256"][:8]
    ('abc.csv', 'ba7816bf')
    """
    p = Path(path)
    return {"name": p.name, "sha256": sha256_file(p)}


def creation_time() -> str:
    """UTC creation time, ISO 8601 to the second (``SOURCE_DATE_EPOCH`` honoured)."""
    sde = os.environ.get("SOURCE_DATE_EPOCH")
    now = (
        _dt.datetime.fromtimestamp(int(sde), _dt.UTC)
        if sde
        else _dt.datetime.now(_dt.UTC)
    )
    return now.strftime("%Y-%m-%dT%H:%M:%SZ")


def _base_name(token: str) -> str:
    path = PureWindowsPath(token) if "\\" in token else PurePosixPath(token)
    return path.name or token


def _is_path(token: str) -> bool:
    """Whether a word of a text is a file-system path (to be reduced to its name)."""
    if "://" in token:  # a URL is not a path of this machine
        return False
    if token.startswith(("/", "~/", "./", "../", "\\\\")) or _WINDOWS_ABSOLUTE.match(token):
        return len(token) > 1
    if "/" in token or "\\" in token:  # relative: only when it ends in a file name
        return bool(_FILE_NAME.match(_base_name(token)))
    return False


def portable_text(text: str) -> str:
    r"""Return ``text`` with every path in it reduced to its file name.

    A path is a word (between blanks, quotes, brackets, commas or ``=``) that is
    absolute (``/...``, ``~/...``, ``C:\...``), starts with ``./``/``../``, or holds a
    folder separator and ends in a file name with an extension.  Other words with a
    ``/`` (frame names such as ``67P/C-G_CSEQ``, units such as ``km/s``, URLs) stay.

    Examples
    --------
    >>> portable_text("model 006: /tmp/x/calib/RPCMAG_140801_006_CALIB_OB.TXT (v 006)")
    'model 006: RPCMAG_140801_006_CALIB_OB.TXT (v 006)'
    >>> portable_text("frame 67P/C-G_CSEQ, see https://spdf.gsfc.nasa.gov/istp_guide/")
    'frame 67P/C-G_CSEQ, see https://spdf.gsfc.nasa.gov/istp_guide/'
    """
    if "/" not in text and "\\" not in text:
        return text
    return _TOKEN.sub(lambda m: _base_name(m.group(0)) if _is_path(m.group(0))
                      else m.group(0), text)


def portable_value(value: Any) -> Any:
    """`portable_text` applied to every string in ``value`` (lists, tuples, dicts)."""
    if isinstance(value, str):
        return portable_text(value)
    if isinstance(value, Mapping):
        return {k: portable_value(v) for k, v in value.items()
                if not (k == "path" and isinstance(v, str))}
    if isinstance(value, (list, tuple)):
        return type(value)(portable_value(v) for v in value)
    return value


def portable_attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    """Return ``attrs`` with `portable_value` applied to every value."""
    return {k: portable_value(v) for k, v in attrs.items()}


def portable_dataset(ds: xr.Dataset) -> xr.Dataset:
    """Shallow copy of ``ds`` whose global and variable attrs name no folder.

    The data arrays are shared, not copied: only the attribute dicts are new.
    """
    out = ds.copy(deep=False)
    out.attrs = portable_attrs(ds.attrs)
    for var in out.variables.values():
        if var.attrs:
            var.attrs = portable_attrs(var.attrs)
    return out


def portable_command_line(argv: Sequence[str] | None = None) -> str:
    """Return the command line with the program named ``fluxcal`` and every path by name.

    An argument (or the value of ``--option=value``) that is an existing file or folder,
    or is a path by `portable_text`'s rule, is replaced by its last component.

    Examples
    --------
    >>> portable_command_line(["/venv/bin/fluxcal", "plot", "/data/x/a.cdf", "--out=/tmp/q"])
    'fluxcal plot a.cdf --out=q'
    """
    args = list((COMMAND_ARGS.get() or sys.argv) if argv is None else argv)

    def one(arg: str) -> str:
        opt, eq, value = arg.partition("=") if arg.startswith("--") else ("", "", arg)
        if (value and os.path.exists(value) and value not in (".", "..")) or _is_path(value):
            value = _base_name(value.rstrip("/\\")) or value
        return f"{opt}{eq}{value}"

    return " ".join(["fluxcal", *(one(a) for a in args[1:])]) if args else "fluxcal"


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
        Input files read; each is recorded by name with its SHA-256.
    calibration : mapping, optional
        Calibration name -> version string, or path of the calibration file (an
        existing file is recorded by name with its SHA-256, anything else as a version).
    kernels : iterable of path
        SPICE kernels loaded (existing files get a SHA-256; others, e.g. a kernel
        named inside a meta-kernel that is not on disk, are recorded by name).
    command_line : str, optional
        Default: the running command (`COMMAND_ARGS`, else ``sys.argv``) through
        `portable_command_line`; a given text passes
        through `portable_text`.

    Returns
    -------
    dict
        Keys ``software``, ``software_version``, ``inputs`` (list of dicts),
        ``calibration`` (dict name -> dict), ``kernels`` (list of dicts),
        ``command_line`` and ``creation_time``.  No value holds a folder.
    """
    cal: dict[str, dict[str, str]] = {}
    for name, value in (calibration or {}).items():
        p = Path(str(value))
        if p.is_file():
            cal[str(name)] = file_record(p)
        else:
            cal[str(name)] = {"version": portable_text(str(value))}
    kern = [file_record(k) if Path(k).is_file() else {"name": _base_name(str(k))}
            for k in kernels]
    return {
        "software": "fluxcal",
        "software_version": software_version(),
        "inputs": [file_record(p) for p in inputs],
        "calibration": cal,
        "kernels": kern,
        "command_line": (portable_command_line() if command_line is None
                         else portable_text(command_line)),
        "creation_time": creation_time(),
    }


def _unique(keys: Iterable[str]) -> list[str]:
    """``keys`` with a repeated one numbered (``a.csv``, ``a.csv#2``): no record lost."""
    seen: dict[str, int] = {}
    out = []
    for k in keys:
        seen[k] = seen.get(k, 0) + 1
        out.append(k if seen[k] == 1 else f"{k}#{seen[k]}")
    return out


def checksums(attrs: Mapping[str, Any]) -> dict[str, str]:
    """Map ``kind:name -> sha256`` of inputs, calibration files and kernels in provenance.

    Keys are file names (a repeated name gets ``#2``, ``#3``); used by the batch
    manifest to decide whether a day's product is up to date.
    """
    out: dict[str, str] = {}
    inputs = attrs.get("inputs", []) or []
    for key, rec in zip(_unique(r.get("name", "") for r in inputs), inputs, strict=True):
        out[f"input:{key}"] = rec.get("sha256", "")
    for name, rec in (attrs.get("calibration", {}) or {}).items():
        out[f"calibration:{name}"] = rec.get("sha256", rec.get("version", ""))
    kernels = attrs.get("kernels", []) or []
    for key, rec in zip(_unique(r.get("name", "") for r in kernels), kernels, strict=True):
        out[f"kernel:{key}"] = rec.get("sha256", "")
    return out


def file_checksums(files: Iterable[Path | str]) -> dict[str, str]:
    """Map ``input:<name>`` (numbered when repeated) to each file's SHA-256."""
    files = list(files)
    return {f"input:{k}": sha256_file(p)
            for k, p in zip(_unique(Path(p).name for p in files), files, strict=True)}

