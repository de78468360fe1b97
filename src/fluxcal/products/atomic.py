"""Atomic file output: write under a temporary name in the same folder, then rename.

A crash (or any exception) before the rename leaves no file under the final name and
no temporary file behind.  ``os.replace`` is atomic on POSIX when source and target
are on the same file system, which a temporary name in the same folder guarantees.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(final: Path, *, directory: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``final``; rename it to ``final`` on success.

    Parameters
    ----------
    final : Path
        The path the product must finally have.
    directory : bool
        The product is a directory (e.g. a Zarr store) rather than a file.

    Yields
    ------
    Path
        A not-yet-existing temporary path in ``final``'s folder, with the same suffix
        (some writers, e.g. cdflib, insist on the suffix).

    Notes
    -----
    On any exception the temporary file (or folder) is removed and the exception
    propagates; the final name is left untouched (an older product stays intact).
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{final.name}.", suffix=f".tmp{final.suffix}", dir=final.parent
    )
    os.close(fd)
    tmp = Path(tmp_name)
    tmp.unlink()  # writers create it themselves (cdflib refuses an existing file)
    try:
        yield tmp
        if directory:
            _replace_dir(tmp, final)
        else:
            os.replace(tmp, final)
    except BaseException:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        elif tmp.exists():
            tmp.unlink()
        raise


def _replace_dir(tmp: Path, final: Path) -> None:
    """Swap a finished directory in (a directory cannot be replaced in one syscall)."""
    if final.exists():
        old = final.with_name(f".{final.name}.old")
        if old.exists():
            shutil.rmtree(old)
        os.replace(final, old)
        os.replace(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, final)


def atomic_write_bytes(final: Path, data: bytes) -> Path:
    """Write ``data`` to ``final`` atomically and return ``final``."""
    with atomic_path(final) as tmp:
        tmp.write_bytes(data)
    return Path(final)
