"""IMAP MAG on the generic driver (`fluxcal.runs.driver`): single runs and batch days.

`ImapRun` is the mission's `~fluxcal.runs.driver.Pipeline`: read packet files (or the
team's L1A CSV layout) into L1A datasets through the SCLK kernel, calibrate them to L1B,
write one product per mode, sensor and UTC day.  ``fluxcal imap calibrate`` and
``fluxcal batch imap`` are the same driver with another source.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap import l1a
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.options import ImapOptions
from fluxcal.missions.imap.packets import packet_definition
from fluxcal.missions.imap.pipeline import (
    LEVELS,
    read_l1a,
    to_level,
    write_products,
)
from fluxcal.missions.imap.sources import BATCH_FILES, sclk_kernels
from fluxcal.products.provenance import provenance_attrs
from fluxcal.runs import driver
from fluxcal.runs.batch import DayWithoutData

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
            raise InputFormatError(f"level {options.level!r}: expected one of {LEVELS}",
                                   field="--level")
        if options.level == "l1b":
            load_calibration(options.calib)
        if options.xtce is not None:
            packet_definition(options.xtce)

    def read(self, source: Sequence[Path], options: ImapOptions) -> tuple[Datasets, list[Path]]:
        """Decode the packets (or read the L1A CSVs) into L1A datasets (kernels loaded)."""
        clock = SclkKernel.from_pool(l1a.IMAP_SCLK_ID)
        return (read_l1a(source, clock, xtce=options.xtce, csv_layout=options.csv_layout),
                list(map(Path, source)))

    def size(self, raw: Datasets) -> int:
        """Return the number of vectors of both sensors."""
        return int(sum(ds.sizes["time"] for ds in raw.values()))

    def calibrate(self, raw: Datasets, options: ImapOptions, progress: Any) -> Datasets:
        """L1A as read, or L1B in nT (`fluxcal.missions.imap.pipeline.to_level`)."""
        return to_level(raw, options.level, options.calib)

    def write(self, calibrated: Datasets, out_dir: Path, options: ImapOptions, *,
              inputs: Sequence[Path], kernel_list: Sequence[str],
              only_day: _dt.date | None, progress: Any) -> list[Path]:
        """One product per mode, sensor and UTC day (or ``only_day``), all or nothing."""
        calibration = {"imap_mag_l1b": options.calib} if options.level == "l1b" else {}
        prov = provenance_attrs(list(inputs), calibration, list(kernel_list))
        day = None if only_day is None else np.datetime64(only_day.isoformat(), "D")
        return write_products(calibrated, out_dir, options.formats, prov,
                              quicklook=options.quicklook, only_day=day)

    def day_files(self, input_dir: Path, day: _dt.date, options: ImapOptions) -> list[Path]:
        """Return the packet and L1A CSV files named for ``day`` (`DAY_PATTERNS`)."""
        return sorted({p for pattern in DAY_PATTERNS
                       for p in Path(input_dir).glob(pattern.format(day=day))})

    def day_source(self, input_dir: Path, day: _dt.date, options: ImapOptions) -> list[Path]:
        """Return the day's files.

        Raises
        ------
        DayWithoutData
            When no file is named for the day.
        """
        files = self.day_files(input_dir, day, options)
        if not files:
            raise DayWithoutData(f"no IMAP MAG file named for {day:%Y%m%d} in {input_dir}")
        return files


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
