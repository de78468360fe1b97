"""A synthetic-mission kit: helpers to write spacecraft clock, ephemeris and attitude kernels.

The demos and the forward-model tests run without mission archives: a mission's
synthetic kernel writer (the mission package's ``synthetic_kernels``) makes a
self-consistent kernel set with these helpers -- spiceypy's own writers (``spkw13``,
``ckw03``), a type 1 SCLK text kernel, meta-kernels with relative paths -- on top of
the generic kernels from PyPI (LSK, DE421).

Each mission writer returns the path of a meta-kernel listing the files it wrote
(`write_meta_kernel`); load it with `fluxcal.geometry.kernels.KernelPool`.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.errors import KernelError
from fluxcal.geometry.kernels import relative_meta_kernel_files
from fluxcal.geometry.time import SclkKernel
from fluxcal.products.atomic import atomic_path, atomic_write_bytes
from fluxcal.products.paths import make_folder

GM_MERCURY = 22031.78  # km^3/s^2 (DE421 / pck00010)
GM_SUN = 1.32712440018e11
AU = 149597870.7


def _split_path(path: str, width: int = 70) -> list[str]:
    return [path[i : i + width] for i in range(0, len(path), width)] or [""]


def write_meta_kernel(path: Path, files: list[Path]) -> Path:
    """Write a meta-kernel listing ``files`` relative to the meta-kernel's folder.

    As NAIF recommends, the folder is named once, in ``PATH_VALUES`` (symbol
    ``KERNELS``, value ``'.'`` or a relative path such as ``'kernels'``), and every file
    as ``$KERNELS/<name>``: moving the folder with its meta-kernel keeps it valid.
    `fluxcal.geometry.kernels.KernelPool` resolves the relative value against the
    meta-kernel's folder (`relative_meta_kernel_files`); plain SPICE tools resolve it
    against their working directory, so run them from the meta-kernel's folder.  Long
    names are split to SPICE's 80 characters with ``+``.

    References
    ----------
    .. [1] NAIF, Kernel Required Reading, "Path Symbols in Meta-kernels".
    """
    path = Path(path)
    base = path.parent.resolve()
    rel = [os.path.relpath(Path(f).resolve(), base) for f in files]
    common = os.path.commonpath([os.path.dirname(r) or "." for r in rel]) if rel else "."
    lines = ["KPL/MK", "", "fluxcal synthetic kernel set; paths relative to this file's folder",
             "", "\\begindata", ""]
    lines += [f"PATH_VALUES  = ( '{common or '.'}' )", "PATH_SYMBOLS = ( 'KERNELS' )", ""]
    lines.append("KERNELS_TO_LOAD = (")
    for r in rel:
        tail = os.path.relpath(r, common or ".")
        pieces = _split_path(f"$KERNELS/{Path(tail).as_posix()}")
        for j, piece in enumerate(pieces):
            continued = "+" if j < len(pieces) - 1 else ""
            lines.append(f"   '{piece}{continued}'")
    lines += [")", "", "\\begintext", ""]
    atomic_write_bytes(path, "\n".join(lines), now=True)
    return path


def copy_meta_kernel(source: Path, dest: Path) -> Path:
    """Write at ``dest`` a meta-kernel loading the same files as ``source``.

    A meta-kernel's paths are relative to its own folder (`write_meta_kernel`), so a
    text copy elsewhere would point at the wrong place: this one is rewritten for
    ``dest``'s folder.
    """
    files = relative_meta_kernel_files(Path(source))
    if files is None:
        raise KernelError(f"{source}: not a meta-kernel with relative PATH_VALUES")
    return write_meta_kernel(Path(dest), files)


def sclk_text(
    sc_id: int,
    moduli: tuple[int, int],
    partitions: list[tuple[float, float]],
    triplets: list[tuple[float, float, float]],
    comment: str,
) -> str:
    """Return a type 1 SCLK kernel (two fields, TDT parallel time) for clock ``sc_id``."""
    cid = abs(sc_id)
    start = " ".join(f"{a:.13E}" for a, _ in partitions)
    end = " ".join(f"{b:.13E}" for _, b in partitions)
    coeff = "\n".join(f"    {t:.13E}  {p:.13E}  {r:.13E}" for t, p, r in triplets)
    return f"""KPL/SCLK

{comment}

\\begindata

SCLK_KERNEL_ID            = ( @2026-01-01/00:00:00 )
SCLK_DATA_TYPE_{cid}       = ( 1 )
SCLK01_TIME_SYSTEM_{cid}   = ( 2 )
SCLK01_N_FIELDS_{cid}      = ( 2 )
SCLK01_MODULI_{cid}        = ( {moduli[0]} {moduli[1]} )
SCLK01_OFFSETS_{cid}       = ( 0 0 )
SCLK01_OUTPUT_DELIM_{cid}  = ( 2 )
SCLK_PARTITION_START_{cid} = ( {start} )
SCLK_PARTITION_END_{cid}   = ( {end} )
SCLK01_COEFFICIENTS_{cid}  = (
{coeff}
)

\\begintext
"""


def prepare_kernel_folder(out_dir: str | Path, prefix: str) -> tuple[Path, Path, Path, Path, Path]:
    """Create ``out_dir``; return it and the SCLK, FK, SPK, CK paths.

    An earlier set's kernels stay until the new ones are complete: `write_spk` and
    `write_ck` write into a temporary and rename it over them.
    """
    out = Path(out_dir)
    make_folder(out)
    sclk, fk = out / f"{prefix}.tsc", out / f"{prefix}.tf"
    spk, ck = out / f"{prefix}.bsp", out / f"{prefix}_sc.bc"
    return out, sclk, fk, spk, ck


@contextlib.contextmanager
def furnished(*paths: Path) -> Iterator[None]:
    """Load text kernels just written, for the writers that need them; unload after."""
    for path in paths:
        spiceypy.furnsh(str(path))
    try:
        yield
    finally:
        for path in paths:
            spiceypy.unload(str(path))


def tdt(utc: str) -> float:
    """Return TDT seconds past J2000 of a UTC string (a leapseconds kernel loaded)."""
    et = spiceypy.str2et(utc)
    return spiceypy.unitim(et, "TDB", "TDT")


def kepler_states(elements: list[float], epochs: np.ndarray) -> np.ndarray:
    """Return the states (km, km/s) of conic ``elements`` at ``epochs`` (``spiceypy.conics``)."""
    return np.array([spiceypy.conics(elements, float(t)) for t in epochs])


def write_spk(
    path: Path,
    body: int,
    center: int,
    epochs: np.ndarray,
    states: np.ndarray,
    segid: str,
    *,
    append: bool = False,
) -> None:
    """Write (or append) a type 13 (Hermite) SPK segment of ``states`` relative to J2000.

    Atomically (`fluxcal.products.atomic.atomic_path`): SPICE writes a temporary (a copy
    of ``path`` to append to), renamed over ``path`` once the file is closed, so a
    failed write leaves the earlier file as it was and a link at ``path`` is replaced,
    never written through.
    """
    with atomic_path(path, now=True) as tmp:
        if append:
            shutil.copyfile(path, tmp)
            handle = spiceypy.spkopa(str(tmp))
        else:
            handle = spiceypy.spkopn(str(tmp), "fluxcal synthetic SPK", 0)
        try:
            spiceypy.spkw13(
                handle, body, center, "J2000", float(epochs[0]), float(epochs[-1]), segid,
                7, len(epochs), states.tolist(), epochs.tolist(),
            )
        finally:
            spiceypy.spkcls(handle)


def write_ck(
    path: Path, instrument: int, sclk_id: int, epochs: np.ndarray, cmat: np.ndarray, segid: str
) -> None:
    """Write a type 3 CK segment of the C-matrices ``cmat`` (J2000 -> ``instrument``).

    Atomically, as `write_spk`.
    """
    sclk = SclkKernel.from_pool(sclk_id)
    ticks = sclk.et_to_encoded(epochs)
    quats = np.array([spiceypy.m2q(m) for m in cmat])
    # keep consecutive quaternions in the same hemisphere (shortest-arc interpolation)
    for i in range(1, len(quats)):
        if np.dot(quats[i], quats[i - 1]) < 0:
            quats[i] = -quats[i]
    with atomic_path(path, now=True) as tmp:  # as `write_spk`
        handle = spiceypy.ckopn(str(tmp), "fluxcal synthetic CK", 0)
        try:
            spiceypy.ckw03(
                handle, float(ticks[0]), float(ticks[-1]), instrument, "J2000", False, segid,
                len(ticks), ticks.tolist(), quats.tolist(),
                np.zeros((len(ticks), 3)).tolist(), 1, [float(ticks[0])],
            )
        finally:
            spiceypy.ckcls(handle)


def unit(v: np.ndarray) -> np.ndarray:
    """Return ``v`` divided by its norm along the last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def smoothstep(x: np.ndarray) -> np.ndarray:
    """Return the cubic smoothstep ``3x^2 - 2x^3`` of ``x`` clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def conics_pos(elements: list[float], et: float) -> np.ndarray:
    """Position (km) from conic elements at ``et`` (``spiceypy.conics``)."""
    return np.asarray(spiceypy.conics(elements, float(et))[:3])
