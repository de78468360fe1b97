"""A synthetic day task: exercises the batch machinery without a mission pipeline.

Input per day: ``<input_dir>/SYNTH_<yyyymmdd>.csv`` with header ``epoch_ns,cx,cy,cz``
(sensor counts), and one calibration file ``<input_dir>/synthetic_calib.txt``
(``offset = ox oy oz`` in counts, ``gain = g`` in nT/count).  Output per day:
``<out_dir>/SYNTH_<yyyymmdd>.TAB/.LBL`` and the ISTP-named ``SYNTH_<yyyymmdd>_v01.cdf``
(`fluxcal.products.cdf.istp_file_stem` of the ``Logical_source`` ``SYNTH``) with
``B = gain * (counts - offset)``.

Used by the batch tests, ``benchmarks/batch.py`` and ``fluxcal batch synthetic``.
The ``crash_once_on`` option kills the worker process once, mid-write, on one day;
``delay`` makes every day slower and ``hog_mb_on`` makes one day hold a lot of memory
(fault injection for the tests).
"""

from __future__ import annotations

import datetime as _dt
import os
import re
import signal
import time
from dataclasses import dataclass
from pathlib import Path

import cdflib
import numpy as np
import xarray as xr

from fluxcal.errors import CalibrationError, InputFormatError
from fluxcal.products.atomic import atomic_path, atomic_write_bytes
from fluxcal.products.cdf import istp_file_stem
from fluxcal.products.columns import Column
from fluxcal.products.paths import make_folder
from fluxcal.products.provenance import provenance_attrs
from fluxcal.products.writer import write_product
from fluxcal.runs.batch import DayInputs, DayResult, DayWithoutData

CALIB_NAME = "synthetic_calib.txt"
#: ISTP ``Logical_source`` of the synthetic product (its CDF is ``SYNTH_<yyyymmdd>_v01.cdf``).
LOGICAL_SOURCE = "SYNTH"
_DAY_NS = 86_400 * 1_000_000_000


def input_path(input_dir: Path, day: _dt.date) -> Path:
    """Input CSV of a day."""
    return Path(input_dir) / f"SYNTH_{day:%Y%m%d}.csv"


def day_epoch0(day: _dt.date) -> int:
    """TT2000 ns of 00:00 UTC of ``day`` (cdflib's leap-second table)."""
    return int(cdflib.cdfepoch.compute_tt2000([day.year, day.month, day.day, 0, 0, 0, 0, 0, 0]))


def write_synthetic_inputs(input_dir: Path, days: list[_dt.date], n_per_day: int = 1000,
                           seed: int = 1, offset=(12.0, -7.0, 3.0), gain: float = 0.05) -> None:
    """Write the calibration file and one CSV per day (field = a rotating 100 nT vector)."""
    input_dir = Path(input_dir)
    make_folder(input_dir)
    atomic_write_bytes(input_dir / CALIB_NAME,
                       "# synthetic calibration, version 1\n"
                       f"offset = {offset[0]} {offset[1]} {offset[2]}\ngain = {gain}\n",
                       now=True)
    rng = np.random.default_rng(seed)
    for day in days:
        t = np.arange(n_per_day) * (_DAY_NS // max(n_per_day, 1))
        phase = 2 * np.pi * t / _DAY_NS
        b = np.stack([100 * np.cos(phase), 100 * np.sin(phase), 20 + rng.normal(0, 1, n_per_day)],
                     axis=1)
        counts = np.round(b / gain + np.asarray(offset)).astype(np.int64)
        rows = np.column_stack([day_epoch0(day) + t, counts])
        with atomic_path(input_path(input_dir, day), now=True) as tmp:  # never through a link
            np.savetxt(tmp, rows, fmt="%d", delimiter=",", header="epoch_ns,cx,cy,cz",
                       comments="")


def read_calibration(path: Path) -> tuple[np.ndarray, float]:
    """Read ``offset`` and ``gain`` from the synthetic calibration file."""
    values: dict[str, list[float]] = {}
    for i, line in enumerate(Path(path).read_text().splitlines(), 1):
        line = line.split("#")[0].strip()
        if not line:
            continue
        key, sep, rest = line.partition("=")
        if not sep:
            raise CalibrationError(f"{path}, line {i}: expected 'KEY = values'")
        values[key.strip()] = [float(x) for x in rest.split()]
    try:
        return np.array(values["offset"]), values["gain"][0]
    except KeyError as exc:
        raise CalibrationError(f"{path}: missing key {exc}") from exc


def read_day_csv(path: Path) -> np.ndarray:
    """Read a day CSV into an (n, 4) int64 array; errors name file, line and field."""
    header = Path(path).open().readline().strip()
    fields = ["epoch_ns", "cx", "cy", "cz"]
    if header.split(",") != fields:
        raise InputFormatError(f"header {header!r}, expected {','.join(fields)}", path=str(path),
                               line=1)
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    except ValueError as exc:
        m = re.search(r"row (\d+), column (\d+)", str(exc))
        line = int(m.group(1)) + 2 if m else None  # 0-based data row after the header
        field = fields[int(m.group(2)) - 1] if m and int(m.group(2)) <= 4 else None
        raise InputFormatError(f"not an integer: {exc}", path=str(path), line=line,
                               field=field) from exc
    if data.shape[1] != 4:
        raise InputFormatError(f"{data.shape[1]} columns, expected 4", path=str(path))
    return data


@dataclass(frozen=True)
class SyntheticDayTask:
    """Calibrate one synthetic day and write its products (picklable)."""

    input_dir: Path
    out_dir: Path
    formats: tuple[str, ...] = ("tab", "cdf")
    delay: float = 0.0
    crash_once_on: _dt.date | None = None
    quicklook: bool = False
    hog_mb_on: tuple[str, float] | None = None
    name: str = "synthetic"

    def inputs(self, day: _dt.date) -> DayInputs:
        """Return the day's CSV and the calibration file."""
        return DayInputs((input_path(self.input_dir, day),),
                         {"synthetic_calib": Path(self.input_dir) / CALIB_NAME})

    def settings(self) -> dict[str, object]:
        """Return the options that change a product (``delay`` and fault injection do not)."""
        return {"formats": self.formats, "quicklook": self.quicklook}

    def __call__(self, day: _dt.date) -> DayResult:
        """Process ``day``."""
        src = input_path(self.input_dir, day)
        if not src.exists():
            raise DayWithoutData(f"no input {src}")
        calib = Path(self.input_dir) / CALIB_NAME
        offset, gain = read_calibration(calib)
        data = read_day_csv(src)
        if self.delay:
            time.sleep(self.delay)
        if self.hog_mb_on is not None and self.hog_mb_on[0] == day.isoformat():
            hog = np.ones(int(self.hog_mb_on[1] * 2**20 // 8))  # touched: resident memory
            time.sleep(5.0)  # long enough for a memory-limited worker's nanny to act
            del hog
        b = gain * (data[:, 1:] - offset)
        ds = xr.Dataset(
            {"B": (("time", "component"), b, {"units": "nT", "description": "Synthetic field"})},
            coords={"epoch": ("time", data[:, 0], {"units": "ns", "description": "TT2000"}),
                    "component": ["x", "y", "z"]},
            attrs=provenance_attrs(inputs=[src], calibration={"synthetic_calib": calib},
                                   command_line=f"synthetic day task {day}"),
        )
        stem = Path(self.out_dir) / f"SYNTH_{day:%Y%m%d}"
        if self.crash_once_on == day:
            self._maybe_crash(stem)
        cols = [Column("epoch", "%d"), Column("B", "%10.3f", label="B{c}")]
        paths = write_product(ds, stem, formats=self.formats, columns=cols,
                              label_extra={"Logical_source": LOGICAL_SOURCE},
                              cdf_stem=stem.parent / istp_file_stem(LOGICAL_SOURCE, day, 1))
        if self.quicklook:
            from fluxcal.products.quicklook import write_quicklooks

            paths += write_quicklooks(ds, Path(self.out_dir), stem.name)
        return DayResult(day, paths, n_vectors=len(b))

    def _maybe_crash(self, stem: Path) -> None:
        marker = Path(self.out_dir) / f".crashed-{stem.name}"
        if marker.exists():
            return
        atomic_write_bytes(marker, str(os.getpid()), now=True)
        # A half-written temporary, as a writer killed mid-file would leave it (by hand:
        # the point is a temporary no rename ever finishes).
        (stem.parent / f".{stem.name}.TAB.{os.getpid()}.x1y2z3w4.fluxcal-tmp.TAB"
         ).write_text("partial")
        os.kill(os.getpid(), signal.SIGKILL)


def make_day_task(input_dir: Path, out_dir: Path, **options) -> SyntheticDayTask:
    """Build the task for ``fluxcal batch synthetic``.

    Options: formats, delay, quicklook, and (fault injection for the tests) ``hog_mb_on``
    as ``"YYYY-MM-DD:MB"``: on that day the task holds that many MB for 5 s.
    """
    allowed = {"formats", "delay", "quicklook", "hog_mb_on"}
    opts = {k: v for k, v in options.items() if k in allowed and v not in (None, "")}
    if "formats" in opts:
        opts["formats"] = tuple(opts["formats"])
    if "hog_mb_on" in opts:
        day, _, mb = str(opts["hog_mb_on"]).partition(":")
        opts["hog_mb_on"] = (day, float(mb))
    return SyntheticDayTask(Path(input_dir), Path(out_dir), **opts)


def simulate_days(input_dir: Path, days: list[_dt.date]) -> None:
    """Write the synthetic inputs of ``days`` (a full day of 1 Hz counts each)."""
    write_synthetic_inputs(input_dir, list(days), n_per_day=86_400)
