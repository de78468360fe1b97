"""IMAP MAG runs: inputs -> L1A or L1B datasets per (mode, sensor) -> products.

`process` reads packet files (``.pkts``/``.bin``/any non-CSV) and team L1A CSV files
(``MAGScience-...csv``), makes L1A datasets through the SCLK kernel and, for L1B, applies
the calibration; `write_products` writes one product per mode, sensor and UTC day named
``imap_mag_<level>_<mode>-<sensor>_<yyyymmdd>_v<nnn>`` with fluxcal's product writers.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.days import split_days
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap import l1a, l1b
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.packets import data_file, read_packets
from fluxcal.products import write_product
from fluxcal.products.atomic import atomic_group
from fluxcal.products.cdf import istp_file_stem
from fluxcal.products.timeindex import default_lsk

#: The SCLK kernel shipped with fluxcal.
DEFAULT_SCLK = "imap_sclk_0036.tsc"
LEVELS = ("l1a", "l1b")
DATA_VERSION = "001"


def logical_source(level: str, mode: str, sensor: str) -> str:
    """IMAP logical source, e.g. ``imap_mag_l1b_norm-mago``."""
    return f"imap_mag_{level}_{mode}-{sensor}"


def _merge(parts: list[dict[tuple[str, str], xr.Dataset]]) -> dict[tuple[str, str], xr.Dataset]:
    keys = sorted({k for p in parts for k in p})
    out = {}
    for key in keys:
        pieces = [p[key] for p in parts if key in p]
        ds = pieces[0] if len(pieces) == 1 else xr.concat(pieces, dim="time",
                                                           combine_attrs="override")
        order = np.argsort(ds["epoch"].values, kind="stable")
        out[key] = ds.isel(time=order)
    return out


def read_l1a(inputs: Sequence[Path], clock: SclkKernel) -> dict[tuple[str, str], xr.Dataset]:
    """L1A datasets of packet and L1A CSV files, keyed by (mode, sensor), sorted in time.

    ``clock`` is the IMAP SCLK (`SclkKernel.from_pool` with the kernels loaded).
    """
    parts = []
    for path in map(Path, inputs):
        if path.suffix.lower() == ".csv":
            parts.append(l1a.read_l1a_csv(path, clock))
        else:
            parts.append(l1a.from_packets(read_packets(path), clock))
    return _merge(parts)


def to_level(l1a_sets: dict[tuple[str, str], xr.Dataset], level: str,
             calib: Path | None = None) -> dict[tuple[str, str], xr.Dataset]:
    """Return the L1A datasets as they are (``level="l1a"``) or calibrated to L1B in nT."""
    if level not in LEVELS:
        raise InputFormatError(f"level {level!r}: expected one of {', '.join(LEVELS)}",
                               field="--level")
    if level == "l1a":
        return l1a_sets
    cal = load_calibration(calib)
    return {key: l1b.calibrate(ds, cal) for key, ds in l1a_sets.items()}


def process(inputs: Sequence[Path], *, level: str = "l1b", calib: Path | None = None,
            kernels: Path | Sequence[Path] | None = None) -> dict[tuple[str, str], xr.Dataset]:
    """L1A or L1B datasets of packet and L1A CSV files, keyed by (mode, sensor).

    `read_l1a` with the SCLK kernel loaded, then `to_level`.

    Parameters
    ----------
    inputs : sequence of Path
        Packet files, or files in the team's L1A CSV layout (suffix ``.csv``).
    level : {"l1a", "l1b"}
    calib : Path, optional
        Calibration CDF (default: the shipped one).
    kernels : Path or sequence of Path, optional
        SCLK kernel (or meta-kernel) with the IMAP clock -43 (default: the shipped one).

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
    with KernelPool(kernels if kernels is not None else [data_file(DEFAULT_SCLK)],
                    fluxcal_frames=False):
        merged = read_l1a(inputs, SclkKernel.from_pool(l1a.IMAP_SCLK_ID))
    return to_level(merged, level, calib)


def write_products(datasets: dict[tuple[str, str], xr.Dataset], out: Path,
                   formats: Sequence[str] = ("cdf",), provenance: dict | None = None,
                   version: str = DATA_VERSION, quicklook: bool = False,
                   only_day: np.datetime64 | None = None) -> list[Path]:
    """Write one product per (mode, sensor) and UTC day; return the paths written.

    ``only_day`` (a batch day) writes that UTC day's products only.

    With ``quicklook``, L1B datasets also get ``imap_mag_ql_<mode>-<sensor>_<yyyymmdd>.png``
    (`fluxcal.products.quicklook.write_quicklooks`).  All files of the call are written as
    one group (`atomic_group`): on an error no file of the call appears.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    yaml = {"global_yaml": data_file("istp_global.yaml")}
    with atomic_group():
        for (mode, sensor), ds in datasets.items():
            level = ds.attrs["level"]
            source = logical_source(level, mode, sensor)
            for day, part in split_days(ds, lsk=default_lsk()):
                if only_day is not None and day != np.datetime64(only_day, "D"):
                    continue
                part.attrs = {**ds.attrs, **(provenance or {}), "Logical_source": source,
                              "Data_version": version,
                              "Data_type": f"{level.upper()}>{level.upper()} {mode}"}
                stem = out / istp_file_stem(source, day, version)
                written += write_product(part, stem, formats=formats, **yaml)
            if quicklook and level == "l1b":
                from fluxcal.products.quicklook import write_quicklooks

                written += write_quicklooks(ds, out, f"imap_mag_ql_{mode}-{sensor}", field="b",
                                            frame="sensor unit frame")
    return written
