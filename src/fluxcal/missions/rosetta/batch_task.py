"""The days of ``fluxcal batch rosetta``: input layout, day edges, stitching chain, simulation.

A batch day runs through the generic driver (`fluxcal.runs.driver.DayTask` over
`fluxcal.missions.rosetta.routes.RosettaRun`); this module finds a day's inputs and the
state it starts from (`DayChain`).

Input folder layout (decision, see ``docs/decisions/rosetta.md``)::

    <input>/kernels.tm                  meta-kernel (optional; or ``--kernels``)
    <input>/calib/                      calibration overrides (optional; or ``--calib``):
                                        RPCMAG_SC_ALIGN.TXT, daily
                                        RPCMAG_<yymmdd>_006_CALIB_<OB|IB>.TXT, ...
    <input>/<yyyymmdd>/science_OB.csv   raw science of the outboard sensor (sec. 4.1.2)
    <input>/<yyyymmdd>/science_IB.csv   raw science of the inboard sensor
    <input>/<yyyymmdd>/hk.csv           raw housekeeping (sec. 4.1.1, optional)

A day folder holds the records whose telemetry time stamp (before the filter time shift)
is in that UTC day; a record stamped on another day is an input error naming file and
line.  A day's products hold the vectors whose shifted time is in that day (decision 30,
docs/formats/rosetta.md "Day edges"): the vectors of the previous day's raw file shifted
past midnight (filter shifts up to 1023.95 s, sec. 4.2.3.5) are taken from that file, and
this day's own such vectors are left to the next day (logged, and counted in the products'
``vectors_to_next_day`` attribute).  A day folder without science file is a day without
data.  Either sensor may be missing (e.g. IB switched off).

Levels: A, B, E, F always; C and G too when kernels are given (LEVEL_C needs the
SPICE attitude and ephemeris, sec. 4.4).  Without kernels the record times come from
``time_utc`` instead of ``obt`` (`fluxcal.missions.rosetta.io`).

Midnight stitching of the extended temperature model (sec. 4.2.3.3) across days that run
in parallel (docs/decisions/rosetta.md, decision 27): a day's shift depends on the whole
chain of contiguous earlier days, but only through each day's first and last good vector
(`extended_model.stitch_day`).  Each day therefore leaves a small state file
``<out>/stitch/RPCMAG_<yyyymmdd>_STITCH_<sensor>.json`` (those two vectors, keyed by the
raw file and meta-kernel they came from, plus the end-of-day offset: the seed's "separate
file"); a day walks back over the earlier days that have a science file and a daily model,
reads their state files (or, when one is missing or stale, reads that day's raw file for
its two vectors and writes the file), and resolves the chain forward.  Order of execution
does not matter, and the incoming state is part of the day's manifest inputs, so a change
in an earlier day redoes the later days of its campaign.

Every file of a day (both sensors, every level and format, HK, quicklooks, its stitch
files) is renamed into place only when the whole day succeeded (`RosettaRun.products`,
written by the driver).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1-4.8.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fluxcal.errors import FluxcalError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import copy_meta_kernel
from fluxcal.geometry.time import SclkKernel, leapseconds
from fluxcal.missions.rosetta import calib, io, level_a
from fluxcal.missions.rosetta.archive import find_products, read_science, source_files
from fluxcal.missions.rosetta.extended_model import stitch_day
from fluxcal.missions.rosetta.identity import FRAME_KERNELS
from fluxcal.missions.rosetta.level_a import stitch_edges
from fluxcal.missions.rosetta.simulate import (
    simulate,
    synthetic_alignment,
    synthetic_daily_models,
    write_truth_csv,
)
from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.paths import make_folder
from fluxcal.runs.batch import worker_kernel_pool

log = logging.getLogger(__name__)

SENSORS = ("OB", "IB")
BASE_LEVELS = ("A", "B", "E", "F")
KERNEL_LEVELS = ("A", "B", "C", "E", "F", "G")
_DAILY_CALIB = re.compile(r"^RPCMAG_(\d{6})_\d{3}_CALIB_(OB|IB)\.(TXT|ASC)$", re.IGNORECASE)


STITCH_DIR = "stitch"
_STITCH_GAP_S = 3 * 3600.0  # extended_model.STITCH_GAP_S (no import at module load)


def stitch_name(day: _dt.date, sensor: str) -> str:
    """Return ``RPCMAG_<yyyymmdd>_STITCH_<sensor>.json``."""
    return f"RPCMAG_{day:%Y%m%d}_STITCH_{sensor}.json"


def stitch_file(out_dir: Path, day: _dt.date, sensor: str) -> Path:
    """Return ``<out>/stitch/RPCMAG_<yyyymmdd>_STITCH_<sensor>.json``."""
    return Path(out_dir) / STITCH_DIR / stitch_name(day, sensor)


def _file_key(path: Path | None) -> list | None:
    if path is None:
        return None
    st = Path(path).stat()
    return [str(Path(path).resolve()), st.st_size, st.st_mtime_ns]


def day_folder(input_dir: Path, day: _dt.date) -> Path:
    """Return ``<input>/<yyyymmdd>``."""
    return Path(input_dir) / f"{day:%Y%m%d}"


def science_file(input_dir: Path, day: _dt.date, sensor: str) -> Path:
    """Return ``<input>/<yyyymmdd>/science_<sensor>.csv``."""
    return day_folder(input_dir, day) / f"science_{sensor}.csv"


def hk_file(input_dir: Path, day: _dt.date) -> Path:
    """Return ``<input>/<yyyymmdd>/hk.csv``."""
    return day_folder(input_dir, day) / "hk.csv"


def _source(csv: Path, input_dir: Path, day: _dt.date, kind: str):
    """Return the day's CSV, else its EDITED archive products (labels), else ``None``.

    Archive products (issue 14) are found anywhere below ``input_dir`` by the date in
    their names (`fluxcal.missions.rosetta.archive.find_products`); the CSV day folder
    is looked at first (docs/decisions/rosetta_archive.md).
    """
    if csv.is_file():
        return csv
    labels = tuple(p.label for p in find_products(input_dir, kind=kind, day=day))
    return labels or None


def science_source(input_dir: Path, day: _dt.date, sensor: str):
    """Return the day's raw science of ``sensor``: ``science_<S>.csv`` or EDITED labels."""
    return _source(science_file(input_dir, day, sensor), input_dir, day, sensor)


def hk_source(input_dir: Path, day: _dt.date):
    """Return the day's raw HK: ``hk.csv`` or EDITED HK labels, or ``None``."""
    return _source(hk_file(input_dir, day), input_dir, day, "HK")


def _source_files(source, sensor: str | None = None) -> list[Path]:
    """Return `fluxcal.missions.rosetta.archive.source_files`."""
    return source_files(source, sensor)


def day_science(input_dir: Path, day: _dt.date) -> dict[str, Any]:
    """Return the day's raw science per sensor that has one (`science_source`)."""
    files = {s: science_source(input_dir, day, s) for s in SENSORS}
    return {s: p for s, p in files.items() if p is not None}


def edge_key(science: Any, sensor: str, kernels: Path | None) -> list:
    """Key of a stitch file: the raw files (path, size, mtime) and meta-kernel it came from."""
    files = [] if science is None else _source_files(science, sensor)
    return [[_file_key(p) for p in files], _file_key(kernels)]


def stitch_text(key: list, edges, end_state: dict | None) -> str:
    """Return a day's stitch file: its key, first and last good vectors, end-of-day state."""
    return json.dumps({"key": key,
                       "first": list(edges[0]) if edges else None,
                       "last": list(edges[1]) if edges else None,
                       "end_state": end_state}, indent=1)


@dataclass(frozen=True)
class DayChain:
    """The days of a batch input folder and the midnight-stitching chain across them.

    Everything the chain depends on is a field: the input folder, the folder of the
    stitch files (``<out>/stitch``), the meta-kernel and frames the raw files are read
    with, the calibration folder and the stitching gap (sec. 4.2.3.3, decision 27).
    """

    input_dir: Path
    stitch_dir: Path
    kernels: Path | None = None
    frame_kernels: Mapping[str, Path] | None = None
    calib: Path | None = None
    stitch_gap_s: float = _STITCH_GAP_S

    def _read_stitch(self, day: _dt.date, sensor: str) -> dict | None:
        path = Path(self.stitch_dir) / stitch_name(day, sensor)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        key = edge_key(science_source(self.input_dir, day, sensor), sensor, self.kernels)
        return data if data.get("key") == key else None

    def _edges(self, day: _dt.date, sensor: str):
        """First and last good vector ``((epoch, word), (epoch, word))`` of a day, cached."""
        cached = self._read_stitch(day, sensor)
        if cached is not None:
            return None if cached["first"] is None else (tuple(cached["first"]),
                                                         tuple(cached["last"]))
        worker_kernel_pool(self.kernels, self.frame_kernels)  # the day's own pool
        sclk = SclkKernel.from_pool(io.SCLK_ID) if self.kernels is not None else None
        source = science_source(self.input_dir, day, sensor)
        raw = read_science(source, sensor, sclk=sclk, lsk=leapseconds())
        edges = stitch_edges(raw, sensor)
        # the chain's cache of an earlier day (no product of this day): written at once
        atomic_write_bytes(Path(self.stitch_dir) / stitch_name(day, sensor),
                           stitch_text(edge_key(source, sensor, self.kernels), edges, None))
        return edges

    def incoming_state(self, day: _dt.date, sensor: str):
        """Stitching state at the end of the day before ``day`` (``None``: no stitching).

        Walks back over the contiguous earlier days that have a science file of
        ``sensor`` and a daily model, then resolves the chain forward from their first and
        last vectors (`extended_model.stitch_day`), exactly as one run over all the days
        would.  A day whose raw file cannot be read has no products (its own task fails
        and is reported) and breaks the chain like a day without data; the break is in
        this day's manifest inputs (`calibration`), so repairing that day redoes this one.
        """
        return self._chain(day, sensor)[0]

    def _chain(self, day: _dt.date, sensor: str):
        models = calib.find_daily_offset_models(self.calib, sensor)
        chain = []
        d = day - _dt.timedelta(days=1)
        while (science_source(self.input_dir, d, sensor) is not None
               and models.get(np.datetime64(d.isoformat(), "D")) is not None):
            chain.append(d)
            d -= _dt.timedelta(days=1)
        if not chain:
            return None, ""
        cal = calib.load_ground_calibration(sensor, self.calib)
        nominal = calib.load_nominal_conversion(self.calib)
        state, note = None, ""
        for d in reversed(chain):
            try:
                edges = self._edges(d, sensor)
            except FluxcalError as exc:
                edges, note = None, f"chain broken at {d}: {exc}"
            if edges is None:
                state = None
                continue
            (e0, w0), (e1, w1) = edges
            t = cal.extended_model_temperature(
                level_a.sensor_temperature(np.array([w0, w1]), cal, nominal)
            )
            model = models[np.datetime64(d.isoformat(), "D")]
            _, state = stitch_day(model, (e0, float(t[0])), (e1, float(t[1])), state,
                                  self.stitch_gap_s)
            note = ""
        return state, note

    def previous_day(self, day: _dt.date, sensor: str):
        """``(previous day's science source, its incoming state)`` or ``None`` (decision 30)."""
        prev_day = day - _dt.timedelta(days=1)
        prev = science_source(self.input_dir, prev_day, sensor)
        if prev is None:
            return None
        return prev, self.incoming_state(prev_day, sensor)

    def _incoming_text(self, day: _dt.date, sensor: str) -> str:
        state, note = self._chain(day, sensor)
        if state is None:
            return f"none {note}".strip()
        return json.dumps(state.to_attrs(), sort_keys=True)

    def files(self, day: _dt.date) -> list[Path]:
        """Return the day's raw files (both sensors, HK) and the previous day's science."""
        files = [p for sensor, source in day_science(self.input_dir, day).items()
                 for p in _source_files(source, sensor)]
        hk = hk_source(self.input_dir, day)
        if hk is not None:
            files += _source_files(hk)
        for sensor in day_science(self.input_dir, day):  # its tail is in this day
            prev = science_source(self.input_dir, day - _dt.timedelta(days=1), sensor)
            if prev is not None:
                files += _source_files(prev, sensor)
        return files

    def calibration(self, day: _dt.date) -> dict[str, Any]:
        """Return what else the day depends on: calibration files and incoming states.

        Calibration: every file of fluxcal's Rosetta data folder and of the override
        folder, except other days' daily offset models (adding a day's model must not
        invalidate the other days); the stitching state the day starts from and the one
        its previous day's tail starts from (decisions 27, 30).
        """
        stamp = f"{day:%y%m%d}"
        cal: dict[str, Any] = {}
        folders = {"fluxcal": Path(__file__).resolve().parent / "data"}
        if self.calib is not None:
            folders["calib"] = Path(self.calib)
        for key, folder in folders.items():
            for p in sorted(folder.glob("*")):
                m = _DAILY_CALIB.match(p.name)
                if p.is_file() and (m is None or m.group(1) == stamp):
                    cal[f"{key}/{p.name}"] = p
        for sensor in day_science(self.input_dir, day):  # the chain of earlier days
            cal[f"stitch_in/{sensor}"] = self._incoming_text(day, sensor)
            prev = science_source(self.input_dir, day - _dt.timedelta(days=1), sensor)
            if prev is not None:  # its tail shifted past midnight is in this day
                cal[f"tail_in/{sensor}"] = self._incoming_text(
                    day - _dt.timedelta(days=1), sensor)
        return cal


def default_kernels(input_dir: Path, kernels: Path | None) -> Path | None:
    """Return the meta-kernel of a batch: ``kernels``, else ``<input>/kernels.tm`` if present."""
    if kernels is not None:
        return Path(kernels)
    default = Path(input_dir) / "kernels.tm"
    return default if default.is_file() else None


def default_calib(input_dir: Path, calib: Path | None) -> Path | None:
    """Return the calibration folder of a batch: ``calib``, else ``<input>/calib`` if present."""
    if calib is not None:
        return Path(calib)
    for name in ("calib", "CALIB"):  # CALIB: the archive's folder name
        default = Path(input_dir) / name
        if default.is_dir():
            return default
    return None


def simulate_days(
    input_dir: Path,
    days: Sequence[_dt.date],
    *,
    start_time: str = "10:00:00",
    minutes: float = 15.0,
    rate_hz: float = 20.0,
    seed: int = 0,
    kernels: bool = True,
    truth: bool = False,
    field: str = "realistic",
) -> list[Path]:
    """Write simulated raw inputs of ``days`` in the batch layout; return the day folders.

    Each day gets ``minutes`` of both sensors from ``start_time`` UTC (the forward model
    `fluxcal.missions.rosetta.simulate.simulate`), plus its HK file; ``<input>/calib``
    gets a synthetic alignment and each day's extended temperature models, and (with
    ``kernels``) ``<input>/kernels/`` one Rosetta-like kernel set covering every day,
    referenced by ``<input>/kernels.tm``.  ``truth`` also writes ``truth_<sensor>.csv``.
    ``field``: the truth field of `simulate` (``realistic`` or ``quiet``).
    """
    input_dir = Path(input_dir)
    days = sorted(days)
    duration = float(minutes) * 60.0
    calib_dir = input_dir / "calib"
    make_folder(calib_dir)
    alignment = synthetic_alignment()
    calib.write_alignment(alignment, calib_dir / calib.ALIGN_FILE)
    models = synthetic_daily_models([np.datetime64(d.isoformat(), "D") for d in days])
    for sensor in SENSORS:
        for model in models[sensor].values():
            calib.write_daily_offset_model(model, calib_dir)
    meta = None
    if kernels:
        first = f"{days[0].isoformat()}T{start_time}"
        span = (days[-1] - days[0]).total_seconds() + duration
        meta = write_rosetta_like_kernels(input_dir / "kernels", first, span, margin_s=3600.0)
        copy_meta_kernel(meta, input_dir / "kernels.tm")  # paths relative to its folder
    cals = {s: calib.load_ground_calibration(s) for s in SENSORS}
    shifts = calib.load_time_shift_table()
    nominal = calib.load_nominal_conversion()
    jumps = calib.load_offset_jump_table()
    folders = []
    with KernelPool(meta, frames=FRAME_KERNELS):
        lsk = leapseconds()
        for k, day in enumerate(days):
            folder = day_folder(input_dir, day)
            make_folder(folder)
            sim = simulate(
                f"{day.isoformat()}T{start_time}", duration, calibrations=cals,
                time_shifts=shifts, nominal=nominal, alignment=alignment, jumps=jumps,
                daily_models=models, rate_hz=rate_hz, with_kernels=kernels,
                seed=seed + k, lsk=lsk, field=field,
            )
            for sensor in SENSORS:
                io.write_science_csv(sim.science[sensor], folder / f"science_{sensor}.csv",
                                     lsk=lsk)
                if truth:
                    write_truth_csv(sim.truth[sensor], folder / f"truth_{sensor}.csv", lsk=lsk)
            io.write_hk_csv(sim.hk, folder / "hk.csv", lsk=lsk)
            folders.append(folder)
    return folders
