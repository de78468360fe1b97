"""IMAP MAG inputs -> L1A or L1B datasets per (mode, sensor).

`process` reads packet files and the team's L1A CSV files (told apart by content, not by
name: `fluxcal.missions.imap.l1a.csv_header`), makes L1A datasets through the SCLK
kernel, drops duplicated packets (counted and warned) and, for L1B, applies the
calibration; the products of those datasets are declared by
`fluxcal.missions.imap.products` (the run on the driver: `fluxcal.missions.imap.routes`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap import l1a, l1b
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.packets import read_packets
from fluxcal.missions.imap.sources import sclk_kernels

log = logging.getLogger(__name__)

LEVELS = ("l1a", "l1b")


#: Variables that make a vector the same vector (with ``epoch``).
_IDENTITY = ("sequence", "vector_index", "coarse", "fine", "range", "compression",
             "compression_width")


def drop_duplicates(ds: xr.Dataset) -> tuple[xr.Dataset, int, int]:
    """Drop vectors identical to an earlier one; return (dataset, vectors, packets) dropped.

    Identical: same ``epoch``, counts and every variable of `_IDENTITY`, as when one
    packet (or one L1A CSV row) is read twice (a file given twice, a file holding
    packets twice).  The first is kept; the order is otherwise unchanged.  Packets
    dropped count distinct (sequence, coarse, fine) among the dropped vectors.
    """
    n = ds.sizes["time"]
    epoch = ds["epoch"].values
    if n < 2 or np.all(epoch[1:] > epoch[:-1]):  # no two vectors at one time: none identical
        return ds, 0, 0
    keys = [ds[v].values for v in reversed(_IDENTITY)]
    keys += [ds["counts"].values[:, j] for j in (2, 1, 0)] + [ds["epoch"].values]
    order = np.lexsort(keys)
    same = np.ones(n - 1, dtype=bool)
    for k in keys:
        same &= k[order[1:]] == k[order[:-1]]
    drop = np.zeros(n, dtype=bool)
    drop[np.maximum(order[1:], order[:-1])[same]] = True
    n_drop = int(drop.sum())
    if n_drop == 0:
        return ds, 0, 0
    packets = np.unique(np.stack([ds[v].values[drop] for v in ("sequence", "coarse", "fine")],
                                 axis=1), axis=0).shape[0]
    return ds.isel(time=np.flatnonzero(~drop)), n_drop, int(packets)


def _merge(parts: list[dict[tuple[str, str], xr.Dataset]]) -> dict[tuple[str, str], xr.Dataset]:
    keys = sorted({k for p in parts for k in p})
    out = {}
    for key in keys:
        pieces = [p[key] for p in parts if key in p]
        ds = pieces[0] if len(pieces) == 1 else xr.concat(pieces, dim="time",
                                                           combine_attrs="override")
        ds, n_vectors, n_packets = drop_duplicates(ds)
        if n_vectors:
            log.warning("IMAP MAG %s-%s: %d duplicated packet(s) dropped (%d vectors read "
                        "twice)", *key, n_packets, n_vectors)
        epoch = ds["epoch"].values
        if np.any(epoch[1:] < epoch[:-1]):  # a copy only when the order changes
            ds = ds.isel(time=np.argsort(epoch, kind="stable"))
        out[key] = ds.assign_attrs(FLUXCAL_DUPLICATES_DROPPED=n_vectors)
    return out


def read_l1a(inputs: Sequence[Path], clock: SclkKernel, *, xtce: Path | None = None,
             csv_layout: str | None = None) -> dict[tuple[str, str], xr.Dataset]:
    """L1A datasets of packet and L1A CSV files, keyed by (mode, sensor), sorted in time.

    Each file is told apart by content (`fluxcal.missions.imap.l1a.csv_header`), not by
    its name; vectors read twice are dropped (`drop_duplicates`).  ``clock`` is the IMAP
    SCLK (`SclkKernel.from_pool` with the kernels loaded); ``xtce`` the packet definition
    (`fluxcal.missions.imap.packets.xtce_path`); ``csv_layout`` as in
    `fluxcal.missions.imap.l1a.csv_layout`.
    """
    parts = []
    for path in map(Path, inputs):
        if l1a.csv_header(path) is not None:
            parts.append(l1a.read_l1a_csv(path, clock, layout=csv_layout))
        else:
            parts.append(l1a.from_packets(read_packets(path, xtce=xtce), clock))
        log.info("read %s: %s", path.name, _counts(parts[-1]) or "no vectors")
    return _merge(parts)


def _counts(datasets: dict[tuple[str, str], xr.Dataset]) -> str:
    """``norm-mago 96, norm-magi 96`` vectors of each (mode, sensor), for a log line."""
    return ", ".join(f"{m}-{s} {ds.sizes['time']:,}" for (m, s), ds in datasets.items())


def to_level(l1a_sets: dict[tuple[str, str], xr.Dataset], level: str,
             calib: Path | None = None,
             progress: Callable[[str, int, int], None] | None = None,
             ) -> dict[tuple[str, str], xr.Dataset]:
    """Return the L1A datasets as they are (``level="l1a"``) or calibrated to L1B in nT.

    ``progress(description, done, total)`` is called per (mode, sensor) calibrated.
    """
    if level not in LEVELS:
        raise InputFormatError(f"level {level!r}: expected one of {', '.join(LEVELS)}",
                               field="--level")
    if level == "l1a":
        log.info("L1A: %s vectors", _counts(l1a_sets) or "no")
        return l1a_sets
    cal = load_calibration(calib)
    log.info("calibration: %s", cal.path.name)
    out = {}
    for k, ((mode, sensor), ds) in enumerate(l1a_sets.items()):
        if progress is not None:
            progress(f"L1B {mode}-{sensor}", k, len(l1a_sets))
        out[mode, sensor] = l1b.calibrate(ds, cal)
        log.info("L1B %s-%s done: %s vectors; calibration_valid: %s", mode, sensor,
                 f"{ds.sizes['time']:,}", out[mode, sensor].attrs["calibration_valid"])
    if progress is not None:
        progress("L1B calibrated", len(l1a_sets), len(l1a_sets))
    return out


def process(inputs: Sequence[Path], *, level: str = "l1b", calib: Path | None = None,
            kernels: Path | Sequence[Path] | None = None, xtce: Path | None = None,
            csv_layout: str | None = None) -> dict[tuple[str, str], xr.Dataset]:
    """L1A or L1B datasets of packet and L1A CSV files, keyed by (mode, sensor).

    `read_l1a` with the SCLK kernel loaded, then `to_level`.

    Parameters
    ----------
    inputs : sequence of Path
        Packet files, or files in the team's L1A CSV layout (by content).
    level : {"l1a", "l1b"}
    calib : Path, optional
        The team's calibration CDF (needed for L1B).
    kernels : Path or sequence of Path
        SCLK kernel (or meta-kernel) with the IMAP clock -43 (needed).
    xtce : Path, optional
        The team's XTCE packet definition (default: the installed team package's).
    csv_layout : str, optional
        Mode and rates of L1A CSVs whose names do not give them.

    Raises
    ------
    InputFormatError
        An unknown level, or an input error naming file, packet or line, and field.
    """
    if level not in LEVELS:
        raise InputFormatError(f"level {level!r}: expected one of {', '.join(LEVELS)}",
                               field="--level")
    if level == "l1b":
        load_calibration(calib)  # a bad calibration file fails before any packet is read
    with KernelPool(sclk_kernels(kernels), fluxcal_frames=False):
        merged = read_l1a(inputs, SclkKernel.from_pool(l1a.IMAP_SCLK_ID), xtce=xtce,
                          csv_layout=csv_layout)
    return to_level(merged, level, calib)
