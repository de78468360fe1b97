"""A synthetic-mission kit: spacecraft clock, frames, ephemeris and attitude kernels.

The demos and the forward-model tests run without mission archives: these writers make
a self-consistent kernel set with spiceypy's own writers (``spkw13``, ``ckw03``) and
text kernels, on top of the generic kernels from PyPI (LSK, DE421).

* MESSENGER-like (`write_messenger_like_kernels`): SCLK -236 (fields seconds and
  microseconds, TDT parallel time, two partitions with the clock reset of 2013-01-08 as
  in the real kernel), frames MSGR_SPACECRAFT (CK -236000), MSGR_MAG (fixed, a 4.9 degree
  rotation about Y as in the real msgr_v231.tf), MSGR_MAG_STOWED, a 12-hour eccentric
  Mercury orbit (periapsis altitude 200 km, apoapsis altitude 15,200 km, inclination 82.5
  deg) and a Sun-keeping attitude (sunshade, -Y, to the Sun) with a slow roll and,
  optionally, intervals with +Y to the Sun.
* Rosetta-like (`write_rosetta_like_kernels`): SCLK -226 (65536 ticks/s, OBT seconds
  since 2003-01-01), ROS_SPACECRAFT (CK -226000), comet 67P (1000012) on a heliocentric
  orbit and the spacecraft escorting it at ~30 km, attitude pointing +Z at the comet.

Each writer returns the path of a meta-kernel listing the files it wrote; load it with
`fluxcal.geometry.kernels.KernelPool`.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import spiceypy

from fluxcal.errors import KernelError
from fluxcal.geometry.kernels import KernelPool

_GM_MERCURY = 22031.78  # km^3/s^2 (DE421 / pck00010)
_GM_SUN = 1.32712440018e11
_AU = 149597870.7


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
    import os

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
    path.write_text("\n".join(lines))
    return path


def copy_meta_kernel(source: Path, dest: Path) -> Path:
    """Write at ``dest`` a meta-kernel loading the same files as ``source``.

    A meta-kernel's paths are relative to its own folder (`write_meta_kernel`), so a
    text copy elsewhere would point at the wrong place: this one is rewritten for
    ``dest``'s folder.
    """
    from fluxcal.geometry.kernels import relative_meta_kernel_files

    files = relative_meta_kernel_files(Path(source))
    if files is None:
        raise KernelError(f"{source}: not a meta-kernel with relative PATH_VALUES")
    return write_meta_kernel(Path(dest), files)


def _sclk_text(
    sc_id: int,
    moduli: tuple[int, int],
    partitions: list[tuple[float, float]],
    triplets: list[tuple[float, float, float]],
    comment: str,
) -> str:
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


def _prepare(out_dir: str | Path, prefix: str) -> tuple[Path, Path, Path, Path, Path]:
    """Create ``out_dir``; return it and the SCLK, FK, SPK, CK paths (old binaries removed)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sclk, fk = out / f"{prefix}.tsc", out / f"{prefix}.tf"
    spk, ck = out / f"{prefix}.bsp", out / f"{prefix}_sc.bc"
    for path in (spk, ck):  # the SPICE writers refuse to overwrite
        path.unlink(missing_ok=True)
    return out, sclk, fk, spk, ck


@contextlib.contextmanager
def _furnished(*paths: Path) -> Iterator[None]:
    """Load text kernels just written, for the writers that need them; unload after."""
    for path in paths:
        spiceypy.furnsh(str(path))
    try:
        yield
    finally:
        for path in paths:
            spiceypy.unload(str(path))


def _tdt(utc: str) -> float:
    et = spiceypy.str2et(utc)
    return spiceypy.unitim(et, "TDB", "TDT")


def _kepler_states(elements: list[float], epochs: np.ndarray) -> np.ndarray:
    return np.array([spiceypy.conics(elements, float(t)) for t in epochs])


def _write_spk(
    path: Path,
    body: int,
    center: int,
    epochs: np.ndarray,
    states: np.ndarray,
    segid: str,
    *,
    append: bool = False,
) -> None:
    """Write (or append) a type 13 (Hermite) SPK segment of ``states`` relative to J2000."""
    if append:
        handle = spiceypy.spkopa(str(path))
    else:
        handle = spiceypy.spkopn(str(path), "fluxcal synthetic SPK", 0)
    try:
        spiceypy.spkw13(
            handle, body, center, "J2000", float(epochs[0]), float(epochs[-1]), segid, 7,
            len(epochs), states.tolist(), epochs.tolist(),
        )
    finally:
        spiceypy.spkcls(handle)


def _write_ck(
    path: Path, instrument: int, sclk_id: int, epochs: np.ndarray, cmat: np.ndarray, segid: str
) -> None:
    from fluxcal.geometry.time import SclkKernel

    sclk = SclkKernel.from_pool(sclk_id)
    ticks = sclk.et_to_encoded(epochs)
    quats = np.array([spiceypy.m2q(m) for m in cmat])
    # keep consecutive quaternions in the same hemisphere (shortest-arc interpolation)
    for i in range(1, len(quats)):
        if np.dot(quats[i], quats[i - 1]) < 0:
            quats[i] = -quats[i]
    handle = spiceypy.ckopn(str(path), "fluxcal synthetic CK", 0)
    try:
        spiceypy.ckw03(
            handle, float(ticks[0]), float(ticks[-1]), instrument, "J2000", False, segid,
            len(ticks), ticks.tolist(), quats.tolist(), np.zeros((len(ticks), 3)).tolist(),
            1, [float(ticks[0])],
        )
    finally:
        spiceypy.ckcls(handle)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


MESSENGER_FK = """KPL/FK

fluxcal synthetic MESSENGER-like frames kernel (ids and names as in msgr_v231.tf)

\\begindata

   NAIF_BODY_NAME              += ( 'MESSENGER' )
   NAIF_BODY_CODE              += ( -236 )

   FRAME_MSGR_SPACECRAFT       = -236000
   FRAME_-236000_NAME          = 'MSGR_SPACECRAFT'
   FRAME_-236000_CLASS         = 3
   FRAME_-236000_CLASS_ID      = -236000
   FRAME_-236000_CENTER        = -236
   CK_-236000_SCLK             = -236
   CK_-236000_SPK              = -236

   FRAME_MSGR_MAG              = -236400
   FRAME_-236400_NAME          = 'MSGR_MAG'
   FRAME_-236400_CLASS         = 4
   FRAME_-236400_CLASS_ID      = -236400
   FRAME_-236400_CENTER        = -236
   TKFRAME_-236400_RELATIVE    = 'MSGR_SPACECRAFT'
   TKFRAME_-236400_SPEC        = 'ANGLES'
   TKFRAME_-236400_UNITS       = 'DEGREES'
   TKFRAME_-236400_AXES        = ( 2, 1, 3 )
   TKFRAME_-236400_ANGLES      = ( 4.9, 0.0, 0.0 )

   FRAME_MSGR_MAG_STOWED       = -236410
   FRAME_-236410_NAME          = 'MSGR_MAG_STOWED'
   FRAME_-236410_CLASS         = 4
   FRAME_-236410_CLASS_ID      = -236410
   FRAME_-236410_CENTER        = -236
   TKFRAME_-236410_RELATIVE    = 'MSGR_SPACECRAFT'
   TKFRAME_-236410_SPEC        = 'ANGLES'
   TKFRAME_-236410_UNITS       = 'DEGREES'
   TKFRAME_-236410_AXES        = ( 3, 2, 1 )
   TKFRAME_-236410_ANGLES      = ( 180.0, 4.9, 0.0 )

\\begintext
"""


def write_messenger_like_kernels(
    out_dir: str | Path,
    start_utc: str = "2012-06-01T00:00:00",
    duration_s: float = 86400.0,
    *,
    plus_y_sunward: list[tuple[float, float]] | None = None,
    attitude_step: float = 5.0,
    margin_s: float = 3600.0,
) -> Path:
    """Write a MESSENGER-like kernel set and return its meta-kernel.

    Parameters
    ----------
    out_dir : path
        Folder for the kernels (created).
    start_utc : str
        Start of the covered interval (UTC, ISO).
    duration_s : float
        Length of the covered interval (s); the kernels cover ``margin_s`` more each side.
    plus_y_sunward : list of (start, end) seconds after ``start_utc``, optional
        Intervals in which the spacecraft turns +Y to the Sun (sensor in sunlight),
        with 10-minute slews; otherwise -Y (the sunshade side) faces the Sun.
    attitude_step : float
        Spacing of the CK pointing records (s).
    margin_s : float
        Extra coverage before and after the interval (s).

    Returns
    -------
    Path
        The meta-kernel ``messenger_synthetic.tm``.
    """
    out, sclk_path, fk_path, spk_path, ck_path = _prepare(out_dir, "msgr_synthetic")
    with KernelPool([], fluxcal_frames=False):
        launch = _tdt("2004-08-03T06:15:56.5")
        reset = _tdt("2013-01-08T20:00:00")
        # partition 1: MET 0 at launch, drifting clock (rate changes once); partition 2
        # starts again near MET 1e3 s after the reset (as the real MESSENGER clock).
        p1_end = (reset - launch) * 1e6
        mid = 0.5 * p1_end
        rate1, rate2 = 1.0000001, 0.99999995
        t_mid = launch + mid / 1e6 * rate1
        p1_end_parallel = t_mid + (p1_end - mid) / 1e6 * rate2
        p2_start = 1.0e9
        triplets = [
            (0.0, launch, rate1),
            (mid, t_mid, rate2),
            (p1_end, p1_end_parallel, 1.00000002),
        ]
        sclk_path.write_text(
            _sclk_text(
                -236,
                (268435456, 1000000),
                [(0.0, p1_end), (p2_start, 2.68435456e14)],
                triplets,
                "fluxcal synthetic MESSENGER-like SCLK (id -236): seconds and microseconds.",
            )
        )
        fk_path.write_text(MESSENGER_FK)
        with _furnished(sclk_path, fk_path):
            et0 = spiceypy.str2et(start_utc) - margin_s
            et1 = spiceypy.str2et(start_utc) + duration_s + margin_s
            epochs = np.arange(et0, et1 + 60.0, 60.0)
            rp, ra = 2440.0 + 200.0, 2440.0 + 15200.0
            ecc = (ra - rp) / (ra + rp)
            elements = [rp, ecc, math.radians(82.5), math.radians(30.0), math.radians(120.0),
                        0.0, et0, _GM_MERCURY]
            states = _kepler_states(elements, epochs)
            _write_spk(spk_path, -236, 199, epochs, states, "MESSENGER-LIKE ORBIT")
            att_epochs = np.arange(et0, et1 + attitude_step, attitude_step)
            sun = np.array(
                [spiceypy.spkpos("SUN", float(t), "J2000", "NONE", "MERCURY")[0]
                 for t in att_epochs]
            )
            cmat = _sun_keeping_attitude(att_epochs - (et0 + margin_s), _unit(sun), plus_y_sunward)
            _write_ck(ck_path, -236000, -236, att_epochs, cmat, "MESSENGER-LIKE ATTITUDE")
    files = [sclk_path, fk_path, spk_path, ck_path]
    return write_meta_kernel(out / "messenger_synthetic.tm", files)


def _sun_keeping_attitude(
    t: np.ndarray, sun_dir: np.ndarray, plus_y: list[tuple[float, float]] | None
) -> np.ndarray:
    """C-matrices (J2000 -> spacecraft) with -Y (or +Y in ``plus_y``) to the Sun."""
    north = np.array([0.0, 0.0, 1.0])
    y_axis = -sun_dir
    x_axis = _unit(np.cross(y_axis, north))
    z_axis = np.cross(x_axis, y_axis)
    roll = 2 * np.pi * t / (6 * 3600.0) + 0.05 * np.sin(2 * np.pi * t / 900.0)
    flip = np.zeros_like(t)
    for start, end in plus_y or []:
        flip = np.maximum(flip, _smoothstep((t - start) / 600.0) * _smoothstep((end - t) / 600.0))
    angle = np.pi * flip
    # roll about the Sun line, then turn about the rolled X axis by `angle`
    c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
    x_r = c * x_axis + s * z_axis
    z_r = -s * x_axis + c * z_axis
    ca, sa = np.cos(angle)[:, None], np.sin(angle)[:, None]
    y_f = ca * y_axis + sa * z_r
    z_f = -sa * y_axis + ca * z_r
    return np.stack([x_r, y_f, z_f], axis=1)  # rows: spacecraft axes in J2000


ROSETTA_FK = """KPL/FK

fluxcal synthetic Rosetta-like frames kernel (ids and names as in ROS_V38.TF)

\\begindata

   NAIF_BODY_NAME              += ( 'ROSETTA', '67P/C-G' )
   NAIF_BODY_CODE              += ( -226, 1000012 )

   FRAME_ROS_SPACECRAFT        = -226000
   FRAME_-226000_NAME          = 'ROS_SPACECRAFT'
   FRAME_-226000_CLASS         = 3
   FRAME_-226000_CLASS_ID      = -226000
   FRAME_-226000_CENTER        = -226
   CK_-226000_SCLK             = -226
   CK_-226000_SPK              = -226

\\begintext
"""


def write_rosetta_like_kernels(
    out_dir: str | Path,
    start_utc: str = "2014-09-01T00:00:00",
    duration_s: float = 86400.0,
    *,
    attitude_step: float = 10.0,
    margin_s: float = 3600.0,
) -> Path:
    """Write a Rosetta-like kernel set (comet escort) and return its meta-kernel.

    Parameters
    ----------
    out_dir : path
        Folder for the kernels (created).
    start_utc : str
        Start of the covered interval (UTC, ISO).
    duration_s : float
        Length of the interval (s).
    attitude_step : float
        Spacing of the CK records (s).
    margin_s : float
        Extra coverage each side (s).

    Returns
    -------
    Path
        The meta-kernel ``rosetta_synthetic.tm``.
    """
    out, sclk_path, fk_path, spk_path, ck_path = _prepare(out_dir, "ros_synthetic")
    with KernelPool([], fluxcal_frames=False):
        epoch0 = _tdt("2003-01-01T00:00:00")
        sclk_path.write_text(
            _sclk_text(
                -226,
                (4294967296, 65536),
                [(0.0, 2.81474976710655e14)],
                [
                    (0.0, epoch0, 1.0000003),
                    (65536.0 * 3.5e8, epoch0 + 3.5e8 * 1.0000003, 0.9999998),
                ],
                "fluxcal synthetic Rosetta-like SCLK (id -226): OBT seconds since 2003-01-01.",
            )
        )
        fk_path.write_text(ROSETTA_FK)
        with _furnished(sclk_path, fk_path):
            et0 = spiceypy.str2et(start_utc) - margin_s
            et1 = spiceypy.str2et(start_utc) + duration_s + margin_s
            epochs = np.arange(et0, et1 + 600.0, 600.0)
            comet_elements = [1.243 * _AU, 0.641, math.radians(7.04), math.radians(50.1),
                              math.radians(12.8), math.radians(-20.0), et0, _GM_SUN]
            comet = _kepler_states(comet_elements, epochs)
            _write_spk(spk_path, 1000012, 10, epochs, comet, "67P-LIKE ORBIT")
            # spacecraft on a slow 30 km circular orbit about the comet (mass ~1e13 kg)
            gm_comet = 6.674e-20 * 1.0e13
            sc_elements = [30.0, 0.0, math.radians(70.0), 0.0, 0.0, 0.0, et0, gm_comet]
            sc = _kepler_states(sc_elements, epochs)
            _write_spk(spk_path, -226, 1000012, epochs, sc, "ROSETTA-LIKE ESCORT", append=True)
            att_epochs = np.arange(et0, et1 + attitude_step, attitude_step)
            to_comet = _unit(-np.array([conics_pos(sc_elements, t) for t in att_epochs]))
            sun = _unit(-np.array([conics_pos(comet_elements, t) for t in att_epochs]))
            z_axis = to_comet
            y_axis = _unit(np.cross(z_axis, sun))
            x_axis = np.cross(y_axis, z_axis)
            cmat = np.stack([x_axis, y_axis, z_axis], axis=1)
            _write_ck(ck_path, -226000, -226, att_epochs, cmat, "ROSETTA-LIKE ATTITUDE")
    return write_meta_kernel(out / "rosetta_synthetic.tm", [sclk_path, fk_path, spk_path, ck_path])


def conics_pos(elements: list[float], et: float) -> np.ndarray:
    """Position (km) from conic elements at ``et`` (``spiceypy.conics``)."""
    return np.asarray(spiceypy.conics(elements, float(et))[:3])
