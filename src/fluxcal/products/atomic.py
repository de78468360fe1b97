"""Atomic file output: write under a temporary name in the same folder, then rename.

A crash (or any exception) before the rename leaves no file under the final name and
no temporary file behind.  ``os.replace`` is atomic on POSIX when source and target
are on the same file system, which a temporary name in the same folder guarantees.
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from fluxcal.products.paths import (
    check_write,
    make_folder,
    note_created,
    old_copy,
    temporary_affixes,
    temporary_owner,
)

__all__ = ["atomic_group", "atomic_path", "atomic_write_bytes", "pending_renames",
           "process_alive", "temporary_owner", "ungrouped"]

# Pending (temporary, final, is_directory) renames of the innermost `atomic_group`.
_GROUP: ContextVar[list[tuple[Path, Path, bool]] | None] = ContextVar("_GROUP", default=None)


@contextmanager
def atomic_path(final: Path, *, directory: bool = False, now: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``final``; rename it to ``final`` on success.

    Parameters
    ----------
    final : Path
        The path the product must finally have.
    directory : bool
        The product is a directory (e.g. a Zarr store) rather than a file.
    now : bool
        Rename at once, inside an `atomic_group` too (an input, a kernel or a table the
        same command reads back).

    Yields
    ------
    Path
        A not-yet-existing temporary path in ``final``'s folder, with the same suffix
        (some writers, e.g. cdflib, insist on the suffix):
        ``.<name>.<pid>.<random>.fluxcal-tmp<suffix>``
        (`fluxcal.products.paths.temporary_affixes`).  The process id lets a clean-up of
        stale temporaries (`temporary_owner`) spare those of a process still running.

    Notes
    -----
    On any exception the temporary file (or folder) is removed and the exception
    propagates; the final name is left untouched (an older product stays intact).  A
    full disk (``ENOSPC``, ``EDQUOT``) is re-raised as a plain `OSError` naming
    ``final`` (the libraries' own messages name the temporary, or nothing).
    """
    final = check_write(Path(final))  # inside the run's --out (paths rule 1)
    make_folder(final.parent)
    prefix, suffix = temporary_affixes(final)
    fd, tmp_name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=final.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    tmp.unlink()  # writers create it themselves (cdflib refuses an existing file)
    group = None if now else _GROUP.get()
    try:
        yield tmp
        if group is not None:
            group.append((tmp, final, directory))
        else:
            _commit(tmp, final, directory)
    except OSError as exc:
        _discard(tmp)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):  # one plain line naming the product
            raise OSError(exc.errno, os.strerror(exc.errno), str(final)) from exc
        raise
    except BaseException:
        _discard(tmp)
        raise


def process_alive(pid: int) -> bool:
    """Whether a process with id ``pid`` exists (signal 0 probes without signalling)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def _commit(tmp: Path, final: Path, directory: bool) -> None:
    new = not os.path.lexists(final)
    if directory:
        _replace_dir(tmp, final)
    else:
        os.replace(tmp, final)  # replaces a link at ``final``, never writes through it
    if new:
        note_created(final)  # a failed run removes it again (`fluxcal.products.staging`)


def _discard(tmp: Path) -> None:
    if tmp.is_dir() and not tmp.is_symlink():
        shutil.rmtree(tmp, ignore_errors=True)
    elif os.path.lexists(tmp):
        tmp.unlink()


def pending_renames() -> list[tuple[Path, Path]] | None:
    """Return the (temporary, final) paths the innermost `atomic_group` will rename.

    None outside a group.  A run's report can list its products under their final
    names while reading them from their temporaries (`fluxcal.products.html_report`).
    """
    group = _GROUP.get()
    return None if group is None else [(tmp, final) for tmp, final, _directory in group]


@contextmanager
def ungrouped() -> Iterator[None]:
    """Rename each `atomic_path` into place as soon as it is complete, inside a group too.

    For work that reads back what it wrote (a demo tour, a simulator writing inputs that
    the next step reads): each file is still written atomically, but does not wait for
    the enclosing `atomic_group`'s end.
    """
    token = _GROUP.set(None)
    try:
        yield
    finally:
        _GROUP.reset(token)


@contextmanager
def atomic_group() -> Iterator[None]:
    """Defer the renames of every `atomic_path` inside the block to its successful end.

    Several files that form one product (``.TAB`` + ``.LBL`` + ``.cdf`` ...) are all
    written under temporary names first; only when every one is complete are they
    renamed into place.  An exception anywhere in the block removes every temporary,
    so a failed product leaves no file at all (an older product stays intact).
    """
    if _GROUP.get() is not None:  # nested: the outermost group commits
        yield
        return
    pending: list[tuple[Path, Path, bool]] = []
    token = _GROUP.set(pending)
    try:
        yield
    except BaseException:
        _GROUP.reset(token)
        for tmp, _final, _directory in pending:
            _discard(tmp)
        raise
    _GROUP.reset(token)
    done = 0
    try:
        for tmp, final, directory in pending:
            _commit(tmp, final, directory)
            done += 1
    except BaseException:
        for tmp, _final, _directory in pending[done:]:
            _discard(tmp)
        raise


def _replace_dir(tmp: Path, final: Path) -> None:
    """Swap a finished directory in (a directory cannot be replaced in one syscall)."""
    if os.path.lexists(final):
        old = old_copy(final)
        os.replace(final, old)
        os.replace(tmp, final)
        _discard(old)  # a link or a file that stood there is removed, not followed
    else:
        os.replace(tmp, final)


def atomic_write_bytes(final: Path, data: bytes | str, *, now: bool = False) -> Path:
    """Write ``data`` (text as UTF-8) to ``final`` atomically and return ``final``.

    Every file fluxcal writes goes through `atomic_path`, so the path rule holds for it
    (`fluxcal.products.paths`: inside the run's ``--out``, recorded for a failed run's
    clean-up, a temporary name fluxcal alone uses).  ``now``: see `atomic_path`.
    """
    with atomic_path(final, now=now) as tmp:
        tmp.write_bytes(data.encode() if isinstance(data, str) else data)
    return Path(final)
