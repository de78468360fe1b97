"""The path rule: where fluxcal may write, read and remove (decisions/products.md, 66).

Every path fluxcal handles on a user's behalf follows four rules, all owned here:

1. **Inside the named folder.**  What a run writes resolves (symbolic links of the
   existing folders included) inside the ``--out`` folder the user named
   (`inside`; `write_scope` sets that folder for a run, and `check_write` refuses
   anything else).  A pointer read from a label (PDS3 ``^TABLE``) names a file in the
   label's own folder (`pointer_target`).
2. **No link followed for what fluxcal creates or removes.**  The output folder's lock
   is opened with ``O_NOFOLLOW`` and must be a regular file (`open_lock_file`);
   temporaries are created with ``O_EXCL`` (`tempfile.mkstemp`) and renamed, which
   replaces a link instead of writing through it; removal never follows a link
   (`remove_created`).
3. **Names from metadata are plain names** (`plain_name`): a value read from an input
   file (a ``SENSOR`` attribute, ...) that becomes part of a file name holds no path
   separator, no ``..`` and no control character.
4. **Only fluxcal's own temporaries are removed.**  Their names carry an unmistakable
   pattern (``.<name>.<pid>.<random>.fluxcal-tmp<suffix>``, and a directory product's
   ``.<name>.<pid>.fluxcal-old`` during its swap; `temporary_affixes`,
   `own_leftover`); a user's ``.draft.tmp`` or ``.bashrc.old`` never matches.  A
   failed run removes only the files and folders it created itself (`note_created`,
   `created_paths`), never a file another run wrote into a folder nested below its
   ``--out``.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import stat
from collections.abc import Iterator, Mapping
from contextvars import ContextVar
from pathlib import Path
from typing import Any

from fluxcal.errors import FluxcalError, InputFormatError

#: Lock file of an output folder (an ``flock``; held by single runs and batches alike).
LOCK_NAME = ".fluxcal.lock"

#: Mark in the name of every temporary fluxcal writes (rule 4).
TEMP_MARK = "fluxcal-tmp"
#: Mark of a directory product's previous copy during its swap.
OLD_MARK = "fluxcal-old"

# `tempfile.mkstemp`'s random part: 8 characters of [a-z0-9_]
_TEMP = re.compile(rf"^\.(?P<name>.+)\.(?P<pid>\d+)\.[a-z0-9_]{{8}}\.{TEMP_MARK}(\.[^./]*)?$")
_OLD = re.compile(rf"^\.(?P<name>.+)\.(?P<pid>\d+)\.{OLD_MARK}$")
# What a lock file holds: nothing (just made) or the holder's pid (`staging.output_lock`)
_LOCK_TEXT = re.compile(rb"^(\d{1,10}\n?)?$")

# The folder a run may write into, and the paths it created (`write_scope`).
_ROOT: ContextVar[Path | None] = ContextVar("_ROOT", default=None)
_CREATED: ContextVar[list[Path] | None] = ContextVar("_CREATED", default=None)


class PathOutsideFolder(FluxcalError):  # noqa: N818 - reads as what is wrong
    """A path fluxcal was about to write or read lies outside the folder it belongs to."""


def _real(path: Path) -> Path:
    """``path`` with its folder's links resolved; its last part kept (never followed)."""
    path = Path(os.path.abspath(path))
    return Path(os.path.realpath(path.parent)) / path.name


def inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies in ``folder`` (or is it), links of both folders resolved.

    The last part of ``path`` is not resolved: fluxcal replaces it by a rename, which
    never writes through a link.

    Examples
    --------
    >>> inside(Path("/data/out/a/P.TAB"), Path("/data/out"))
    True
    >>> inside(Path("/data/out/a/../../x.TAB"), Path("/data/out"))
    False
    >>> inside(Path("/data/out"), Path("/data/out"))  # a link the user named as --out too
    True
    """
    if Path(path).name in ("..", "."):
        path = Path(path) / "x"
    if os.path.normpath(os.path.abspath(path)) == os.path.normpath(os.path.abspath(folder)):
        return True  # the folder itself, as named (``--out`` may be a link the user made)
    real = Path(os.path.normpath(_real(Path(path))))
    root = Path(os.path.realpath(folder))
    return real == root or real.is_relative_to(root)


def check_write(path: Path) -> Path:
    """Refuse a write outside the folder of the current `write_scope` (rule 1).

    Outside a scope (the Python API, a batch worker) nothing is checked here; the
    callers build their paths from the folder they were given.

    Raises
    ------
    PathOutsideFolder
        ``path`` resolves outside the run's ``--out`` folder.
    """
    root = _ROOT.get()
    if root is not None and not inside(path, root):
        raise PathOutsideFolder(
            f"--out {root}: refusing to write {path}, which lies outside this folder "
            "(a name from the input, or a link in the folder, leads out of it); nothing was "
            "written there")
    return Path(path)


@contextlib.contextmanager
def write_scope(folder: Path) -> Iterator[list[Path]]:
    """Confine the writes of the block to ``folder`` and record what it creates.

    Yields the list `note_created` fills (files, then folders, in creation order).
    """
    root = _ROOT.set(Path(folder))
    created: list[Path] = []
    token = _CREATED.set(created)
    try:
        yield created
    finally:
        _CREATED.reset(token)
        _ROOT.reset(root)


def current_folder() -> Path | None:
    """Return the folder of the current `write_scope` (None outside one)."""
    return _ROOT.get()


def note_created(path: Path) -> None:
    """Record ``path`` as created by the current `write_scope` (a failed run removes it)."""
    created = _CREATED.get()
    if created is not None:
        created.append(Path(path))


def make_folder(path: Path) -> Path:
    """Create ``path`` and its missing parents (checked by `check_write`, each recorded).

    Returns
    -------
    Path
        ``path``.
    """
    path = check_write(Path(path))
    missing: list[Path] = []
    p = path
    while not os.path.lexists(p) and p != p.parent:
        missing.append(p)
        p = p.parent
    for folder in reversed(missing):
        try:
            folder.mkdir()
        except FileExistsError:
            continue  # made meanwhile by another process: not ours
        note_created(folder)
    if not path.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(path))
    return path


def what_stands_at(path: Path) -> str:
    """Say what stands at ``path`` where a folder is needed (for a one-line error).

    ``"a link to <target>, which does not exist"`` for a dangling link (``path.exists()``
    is False for it, so a plain check would call it missing, or make a folder through
    it), ``"a file, not a folder"`` for anything else that is no folder.

    Examples
    --------
    >>> what_stands_at(Path(__file__))
    'a file, not a folder'
    """
    path = Path(path)
    if path.is_symlink() and not path.exists():
        return f"a link to {os.readlink(path)}, which does not exist"
    return "a file, not a folder"


def move_into(source: Path, dest: Path) -> Path:
    """Rename a finished file of this run to ``dest`` (checked, recorded; no link followed).

    Returns
    -------
    Path
        ``dest``.
    """
    dest = check_write(Path(dest))
    new = not os.path.lexists(dest)
    os.replace(source, dest)
    if new:
        note_created(dest)
    return dest


def remove_created(paths: list[Path]) -> None:
    """Remove what a failed run created (`note_created`), newest first; no link followed.

    Files (and links) are unlinked; a folder is removed only once it is empty, so a
    file someone else put into a folder the run created stays.
    """
    for p in reversed(paths):
        try:
            st = os.lstat(p)
        except FileNotFoundError:
            continue
        try:
            if stat.S_ISDIR(st.st_mode):
                if _TEMP.match(p.name) or _OLD.match(p.name):
                    shutil.rmtree(p)  # a store fluxcal was writing (rmtree follows no link)
                else:
                    os.rmdir(p)
            else:
                os.unlink(p)
        except OSError:
            continue  # not empty (someone else's files), or already gone


def plain_name(value: object, *, what: str, path: str | None = None) -> str:
    """Return ``value`` as a name that can be part of a file name (rule 3).

    Parameters
    ----------
    value : object
        A name read from input metadata (e.g. a ``SENSOR`` attribute).
    what : str
        The field it came from (named in the error).
    path : str, optional
        The file it was read from.

    Raises
    ------
    InputFormatError
        Empty, or holding a path separator, ``..``, a leading dot or a control
        character, or longer than 64 characters.

    Examples
    --------
    >>> plain_name("OB", what="SENSOR")
    'OB'
    """
    text = str(value).strip()
    if (not text or len(text) > 64 or "/" in text or "\\" in text or ".." in text
            or text.startswith(".") or any(ord(c) < 32 or c == "\x7f" for c in text)):
        raise InputFormatError(
            f"{text[:80]!r} cannot be part of a file name (a plain name of letters, digits, "
            "'-', '_' is expected); fix the input file", path=path, field=what)
    return text


def pointer_target(folder: Path, name: str, label_path: Path, pointer: str) -> Path:
    """Check a file name a label points to: a plain name in the label's folder (rule 1).

    Parameters
    ----------
    folder : Path
        The label's folder.
    name : str
        The file name the pointer holds.
    label_path : Path
        The label (named in the error).
    pointer : str
        The pointer keyword (``^TABLE``...).

    Returns
    -------
    Path
        ``folder / name`` (which may not exist).

    Raises
    ------
    InputFormatError
        The name holds a folder part (``../x.TAB``, ``/abs/x.TAB``), or the file is a
        link that leads out of the label's folder.
    """
    if not name or "/" in name or "\\" in name or name in (".", ".."):
        raise InputFormatError(
            f"{pointer} = {name!r} leads out of the label's folder; a PDS3 pointer names a "
            "file beside its label: copy the data file there and name it alone",
            path=str(label_path), field=pointer)
    target = Path(folder) / name
    if os.path.lexists(target) and not inside(Path(os.path.realpath(target)), folder):
        raise InputFormatError(
            f"{pointer} = {name!r} is a link that leads out of the label's folder; copy the "
            "data file beside its label", path=str(label_path), field=pointer)
    return target


def check_pointers(label: Mapping[str, Any], label_path: Path) -> None:
    """Check every file pointer of a label (``^TABLE = "X.TAB"``, ``("X.TAB", 3)``).

    Each must name a file in the label's folder (`pointer_target`), whether or not it is
    read: a reader of the label alone (``fluxcal provenance``) refuses the same labels
    as a reader of its table.

    Raises
    ------
    InputFormatError
        A pointer that leads out of the label's folder.
    """
    for key, value in label.items():
        if not str(key).startswith("^"):
            continue
        name = value if isinstance(value, str) else \
            value[0] if isinstance(value, (list, tuple)) and value and isinstance(value[0], str) \
            else None
        if name is not None:
            pointer_target(Path(label_path).parent, name, label_path, str(key))


def temporary_affixes(final: Path) -> tuple[str, str]:
    """Prefix and suffix (`tempfile.mkstemp`) of a temporary for ``final`` (rule 4).

    The name is ``.<name>.<pid>.<8 random>.fluxcal-tmp<suffix>``: the suffix is kept
    (some writers, e.g. cdflib, insist on it), the pid lets a clean-up spare the
    temporaries of a process still running.
    """
    final = Path(final)
    return f".{final.name}.{os.getpid()}.", f".{TEMP_MARK}{final.suffix}"


def old_copy(final: Path) -> Path:
    """Name of a directory product's previous copy during its swap (rule 4)."""
    final = Path(final)
    return final.with_name(f".{final.name}.{os.getpid()}.{OLD_MARK}")


def own_leftover(name: str) -> tuple[str, int, str] | None:
    """``(kind, pid, final name)`` of a name fluxcal gives its temporaries, else None.

    ``kind`` is ``"tmp"`` (a temporary) or ``"old"`` (a directory product's previous
    copy).

    Examples
    --------
    >>> own_leftover(".P.TAB.4242.k3j2ab_9.fluxcal-tmp.TAB")
    ('tmp', 4242, 'P.TAB')
    >>> own_leftover(".draft.tmp") is None and own_leftover(".bashrc.old") is None
    True
    """
    for kind, pattern in (("tmp", _TEMP), ("old", _OLD)):
        m = pattern.match(name)
        if m:
            return kind, int(m.group("pid")), m.group("name")
    return None


def temporary_owner(path: Path) -> int | None:
    """Process id in a temporary name fluxcal made (``None`` for any other name)."""
    found = own_leftover(Path(path).name)
    return None if found is None else found[1]


def open_lock_file(path: Path) -> int:
    """Open (creating it) the lock file ``path`` without following a link (rule 2).

    Returns
    -------
    int
        A read-write file descriptor of a regular file that has no other name.

    Raises
    ------
    FluxcalError
        ``path`` is a link, a folder or anything but a regular file, a hard link of
        another file (the holder's pid would overwrite that file), or a file holding
        anything but a process id (a user's file of that name): it is left as it is,
        and so is what it points to.
    """
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        if exc.errno not in (errno.ELOOP, errno.EISDIR, errno.ENXIO, errno.EMLINK):
            raise
        fd = None
    st = os.fstat(fd) if fd is not None else None
    regular = st is not None and stat.S_ISREG(st.st_mode)
    held = os.pread(fd, 64, 0) if regular and st.st_nlink == 1 else b""
    if regular and st.st_nlink == 1 and _LOCK_TEXT.match(held):
        return fd
    if fd is not None:
        os.close(fd)
    what = ("not a regular file (a link, a folder or a device)" if not regular
            else "a hard link of another file" if st.st_nlink != 1
            else "a file fluxcal did not write (it holds no process id)")
    raise FluxcalError(
        f"--out {Path(path).parent}: {Path(path).name} is {what}; fluxcal does not write "
        "through it: remove it, or choose another --out")
