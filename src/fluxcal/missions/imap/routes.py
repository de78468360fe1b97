"""IMAP MAG on the generic driver (`fluxcal.runs.driver`): single runs and batch days.

`ImapRun` is the mission's `~fluxcal.runs.driver.Pipeline`: read packet files (or the
team's L1A CSV layout) into L1A datasets through the SCLK kernel, calibrate them to L1B,
declare one product per mode, sensor and UTC day (the driver writes them).  `LevelRun`
declares the products of ``fluxcal imap l1c`` and ``imap l2``.  ``fluxcal imap calibrate`` and
``fluxcal batch imap`` are the same driver with another source.
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.days import utc_day
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap import l1a
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.chain import LEVELS, read_l1a, to_level
from fluxcal.missions.imap.options import ImapOptions
from fluxcal.missions.imap.packets import packet_definition
from fluxcal.missions.imap.products import products
from fluxcal.missions.imap.sources import BATCH_FILES, sclk_kernels
from fluxcal.products.declared import Declared
from fluxcal.products.timeindex import default_lsk
from fluxcal.runs import driver
from fluxcal.runs.batch import DayWithoutData

log = logging.getLogger(__name__)

Datasets = dict[tuple[str, str], xr.Dataset]
#: Input files of a batch day: names holding the day as ``yyyymmdd`` (IMAP's convention,
#: e.g. ``imap_mag_l0_raw_20240101_v001.pkts``).
DAY_PATTERNS = ("*{day:%Y%m%d}*.pkts", "*{day:%Y%m%d}*.bin", "MAGScience-*{day:%Y%m%d}*.csv")


@dataclass(frozen=True)
class ImapRun:
    """IMAP MAG L0 -> L1A -> L1B as a `fluxcal.runs.driver.Pipeline` (picklable)."""

    frame_kernels: Mapping[str, Path] | None = field(default_factory=dict)

    def check(self, options: ImapOptions) -> None:
        """Refuse a bad level, calibration file or named packet definition before any input.

        Without ``--xtce`` the packet definition is looked for when a packet file is
        read (`fluxcal.missions.imap.packets.xtce_path`): L1A CSV inputs need none.
        """
        if options.level not in LEVELS:
            raise InputFormatError(f"level {options.level!r}: expected one of {', '.join(LEVELS)}",
                                   field="--level")
        if options.level == "l1b":
            load_calibration(options.calib)
        if options.xtce is not None:
            packet_definition(options.xtce)
        if options.layout == "team" and tuple(options.formats) != ("cdf",):
            raise InputFormatError("--layout team writes the team's CDFs only: leave out "
                                   "--formats or give --formats cdf", field="--formats")

    def read(self, source: Sequence[Path] | DaySource,
             options: ImapOptions) -> tuple[Datasets, list[Path]]:
        """Decode the packets (or read the L1A CSVs) into L1A datasets (kernels loaded).

        A `DaySource` (a batch day) keeps the vectors of its UTC day only (`day_vectors`).
        """
        files = list(map(Path, source.files if isinstance(source, DaySource) else source))
        clock = SclkKernel.from_pool(l1a.IMAP_SCLK_ID)
        raw = read_l1a(files, clock, xtce=options.xtce, csv_layout=options.csv_layout)
        if isinstance(source, DaySource):
            raw = day_vectors(raw, source)
        return raw, files

    def size(self, raw: Datasets) -> int:
        """Return the number of vectors of both sensors."""
        return int(sum(ds.sizes["time"] for ds in raw.values()))

    def calibrate(self, raw: Datasets, options: ImapOptions, progress: Any) -> Datasets:
        """L1A as read, or L1B in nT (`fluxcal.missions.imap.chain.to_level`)."""
        return to_level(raw, options.level, options.calib, progress)

    def products(self, calibrated: Datasets, options: ImapOptions) -> Iterator[Declared]:
        """One product per mode, sensor and UTC day (`fluxcal.missions.imap.products.products`)."""
        return products(calibrated, options.formats, quicklook=options.quicklook,
                        layout=options.layout)

    def calibration(self, calibrated: Datasets | None, options: ImapOptions) -> dict:
        """Return the L1B calibration file (none for L1A): provenance, batch manifest."""
        return {"imap_mag_l1b": options.calib} if options.level == "l1b" else {}

    def day_files(self, input_dir: Path, day: _dt.date, options: ImapOptions) -> list[Path]:
        """Return the packet and L1A CSV files named for ``day`` and the days beside it.

        A file named for a day may hold vectors of the days beside it (a stream across
        midnight given as one day's file): the day's vectors are taken from all three
        (`day_vectors`), as a single run of every file would put them in its product.
        """
        one = _dt.timedelta(days=1)
        return sorted({p for d in (day - one, day, day + one) for p in named_for(input_dir, d)})

    def day_source(self, input_dir: Path, day: _dt.date, options: ImapOptions) -> DaySource:
        """Return the files of the day and the days beside it, and the day.

        Raises
        ------
        DayWithoutData
            When no file is named for the day or the days beside it.
        """
        files = self.day_files(input_dir, day, options)
        if not files:
            raise DayWithoutData(f"no IMAP MAG file named for {day:%Y%m%d} or the days beside "
                                 f"it in {input_dir}")
        return DaySource(tuple(files), day)


@dataclass(frozen=True)
class LevelRun:
    """The products of ``imap l1c`` and ``imap l2`` for `fluxcal.runs.driver.write`.

    ``calibration_files``: the calibration (name -> file) the level was made with.
    """

    calibration_files: Mapping[str, Path] = field(default_factory=dict)

    def products(self, calibrated: Datasets, options: Any) -> Iterator[Declared]:
        """One product per mode, sensor (or frame) and UTC day (`products`)."""
        return products(calibrated, options.formats, layout=options.layout)

    def calibration(self, calibrated: Datasets | None, options: Any) -> dict:
        """Return the calibration files (provenance)."""
        return dict(self.calibration_files)


@dataclass(frozen=True)
class DaySource:
    """A batch day's files (its own and those of the days beside it) and the day."""

    files: tuple[Path, ...]
    day: _dt.date


def named_for(input_dir: Path, day: _dt.date) -> list[Path]:
    """Return the packet and L1A CSV files named for ``day`` (`DAY_PATTERNS`)."""
    return sorted({p for pattern in DAY_PATTERNS
                   for p in Path(input_dir).glob(pattern.format(day=day))})


def day_vectors(raw: Datasets, source: DaySource) -> Datasets:
    """Keep the vectors of the UTC day ``source.day`` (the product day of `products`).

    Vectors of a day beside it that has no file of its own are named in a warning (only
    a batch that runs that day writes them).

    Raises
    ------
    DayWithoutData
        When no vector read is of the day.
    """
    day = np.datetime64(source.day.isoformat(), "D")
    out: Datasets = {}
    others: dict[str, int] = {}
    for key, ds in raw.items():
        days = utc_day(ds["epoch"].values, default_lsk())
        keep = days == day
        for other in (day - 1, day + 1):
            others[str(other)] = others.get(str(other), 0) + int((days == other).sum())
        if keep.any():
            out[key] = ds.isel(time=np.flatnonzero(keep))
    names = ", ".join(p.name for p in source.files)
    for other, n in others.items():
        if n and not named_for(source.files[0].parent, _dt.date.fromisoformat(other)):
            log.warning("%d IMAP MAG vector(s) of %s in %s: that day has no file, its "
                        "products hold them only when the batch runs %s too",
                        n, other, names, other)
    if not out:
        raise DayWithoutData(f"no IMAP MAG vector of {source.day} in {names}")
    return out


def make_day_task(input_dir: Path, out_dir: Path, **options: Any) -> driver.DayTask:
    """Build the task for ``fluxcal batch imap`` (options: kernels and `ImapOptions`).

    Kernels, calibration and packet definition not named by an option are the input
    folder's ``kernels.tm``, ``calibration.cdf``, ``packet_definition.xml`` when there
    (`fluxcal.missions.imap.sources.BATCH_FILES`).
    """
    fields = {f for f in ImapOptions.__dataclass_fields__}
    values = {k: v for k, v in options.items() if k in fields or k == "kernels"}
    for role, name in BATCH_FILES.items():  # the input folder's own, when none is named
        if values.get(role) is None and (Path(input_dir) / name).is_file():
            values[role] = Path(input_dir) / name
    kernels = values.pop("kernels", None)
    return driver.DayTask(ImapRun(), Path(input_dir), Path(out_dir), ImapOptions(**values),
                          sclk_kernels(kernels), name="imap")
