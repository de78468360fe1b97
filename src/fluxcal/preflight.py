"""Checks the commands run before any work, so a bad path fails in one line at once.

Each check raises `fluxcal.errors.FluxcalError` naming the option, the path and what to
do; none leaves a file behind.  The command-line front end (`fluxcal.cli.main`) prints
that message as one line and exits with code 2.
"""

from __future__ import annotations

import os
import socket
import tempfile
from pathlib import Path
from urllib.parse import urlsplit

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.products.paths import temporary_affixes, what_stands_at

#: First bytes of compressed files a CSV/text reader cannot read as they are.
_COMPRESSED = {
    b"\x1f\x8b": ("gzip", "gunzip"),
    b"BZh": ("bzip2", "bunzip2"),
    b"\xfd7zXZ": ("xz", "unxz"),
    b"PK\x03\x04": ("zip", "unzip"),
    b"(\xb5/\xfd": ("zstd", "unzstd"),
}


def writable_folder(path: Path, option: str = "--out") -> Path:
    """Check that ``path`` is, or can be created as, a folder this process can write.

    Creates nothing that stays and writes nothing outside ``path``: an existing folder
    is probed with a temporary file (fluxcal's temporary name,
    `fluxcal.products.paths.temporary_affixes`) removed at once (``os.access`` says yes
    to root on a read-only mount, a real write does not); for a folder still to be made,
    its first existing ancestor is only asked (``os.access``), not written.

    Raises
    ------
    FluxcalError
        If a file stands where a folder is needed, or the folder cannot be written.
    """
    p = Path(path)
    probe = p
    while not os.path.lexists(probe) and probe != probe.parent:
        probe = probe.parent
    if os.path.lexists(probe) and not probe.is_dir():  # a dangling link named as such
        raise FluxcalError(f"{option} {p}: {probe} is {what_stands_at(probe)}; "
                           f"choose another {option}")
    if probe != p:
        if not os.access(probe, os.W_OK | os.X_OK):
            raise FluxcalError(f"{option} {p}: cannot create it in {probe} (permission "
                               f"denied); choose a folder you can write to")
        return p
    prefix, suffix = temporary_affixes(p / "write-test")
    try:
        fd, name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=probe)
    except OSError as exc:
        raise FluxcalError(f"{option} {p}: cannot write in {probe} ({exc.strerror}); "
                           f"choose a folder you can write to") from None
    os.close(fd)
    os.unlink(name)
    return p


def existing_folder(path: Path, option: str) -> Path:
    """Check that ``path`` is an existing folder (no silent fallback to defaults).

    Raises
    ------
    FluxcalError
        If it does not exist or is a file.
    """
    p = Path(path)
    if not p.is_dir():
        what = "is a file, not a folder" if p.exists() else "does not exist"
        raise FluxcalError(f"{option} {p} {what}; give an existing folder, or leave "
                           f"{option} out to use fluxcal's shipped files")
    return p


def existing_file(path: Path, option: str) -> Path:
    """Check that ``path`` is an existing file.

    Raises
    ------
    FluxcalError
        If it does not exist or is a folder.
    """
    p = Path(path)
    if not p.is_file():
        what = "is a folder, not a file" if p.exists() else "does not exist"
        raise FluxcalError(f"{option} {p} {what}; check the path")
    return p


def plain_text_file(path: Path, option: str, header_lines: int | None = None) -> Path:
    """Check that ``path`` exists and is not a compressed file (read as text as it is).

    With ``header_lines``, the file must also hold at least one non-blank line after
    that many header lines (a header-only CSV is refused here, before any work).

    Raises
    ------
    InputFormatError
        If the file starts with a gzip, bzip2, xz, zip or zstd signature, or has no
        data line after its header.
    FluxcalError
        If it does not exist.
    """
    p = existing_file(path, option)
    with open(p, "rb") as f:
        head = f.read(8)
    for magic, (kind, tool) in _COMPRESSED.items():
        if head.startswith(magic):
            raise InputFormatError(f"is a {kind}-compressed file; decompress it first "
                                   f"({tool} {p.name}) and give the plain CSV",
                                   path=str(p), field=option)
    if header_lines is not None:
        with open(p, "rb") as f:
            for _ in range(header_lines):
                f.readline()
            if not any(line.strip() for line in f):
                raise InputFormatError(f"no data records after the {header_lines}-line "
                                       "header; give a file with data",
                                       path=str(p), field=option)
    return p


def reachable_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Check that a Dask scheduler address accepts a TCP connection.

    Raises
    ------
    FluxcalError
        If the address has no host and port, or nothing answers within ``timeout_s``.
    """
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or not port:
        raise FluxcalError(f"--scheduler {address!r}: expected tcp://HOST:PORT of a running "
                           "Dask scheduler, 'serial', or leave it out for a local cluster")
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise FluxcalError(f"--scheduler {address}: no Dask scheduler answers ({reason}); "
                           "start it (dask scheduler) or leave --scheduler out for a local "
                           "cluster") from None
