"""Every Rosetta RPC-MAG route on the generic driver (`fluxcal.runs.driver`).

`RosettaRun` is the mission's `~fluxcal.runs.driver.Pipeline`: read the raw science of
each sensor (a CSV file or the archive's EDITED products), its calibration tables and,
for a batch day, the previous day's records that cross midnight; calibrate LEVEL_A..G
(sec. 4.2-4.8); declare every level, the HK product and the quicklooks of the run (the
driver writes them, all or nothing).  ``fluxcal rosetta calibrate`` (`run_files`), the one-call API
(`calibrate_levels`) and ``fluxcal batch rosetta`` (`make_day_task`) are the same
pipeline with another source.

No state is hidden: the midnight-stitching state a sensor starts from, and the previous
day's file with the state that day starts from, are fields of its `SensorSource`; the
end-of-day state and the first and last good vectors are fields of its
`SensorLevels`, declared by `RosettaRun.products` (the ``--stitch-state`` file of a
single run, the ``<out>/stitch`` files of a batch day, docs/decisions/rosetta.md
decision 27): run state beside the products, not a product.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1-4.8.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.days import day_bounds
from fluxcal.geometry.time import SclkKernel, leapseconds, tt2000_to_utc
from fluxcal.missions.rosetta import (
    archive,
    averaged,
    batch_task,
    calib,
    hk,
    io,
    level_a,
    level_b,
    level_c,
)
from fluxcal.missions.rosetta.day_edges import (
    check_day_records,
    check_shifts_nonnegative,
    merge_tail,
    previous_day_records,
    previous_day_tail,
    read_stitch_state,
    stitch_state_text,
)
from fluxcal.missions.rosetta.identity import FRAME_KERNELS
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.products import (
    LEVELS,
    parse_levels,
    sensor_products,
    thermistor_temperatures,
)
from fluxcal.products.declared import Declared, File
from fluxcal.runs import driver
from fluxcal.runs.batch import DayWithoutData

log = logging.getLogger(__name__)

#: Levels of a single run when ``--levels`` is not given.
FILE_LEVELS = ("A", "B")


@dataclass(frozen=True)
class PreviousDay:
    """The previous day's raw science of a sensor and the stitching state it starts from."""

    science: Any
    state: level_a.StitchState | None = None


@dataclass(frozen=True)
class SensorSource:
    """Raw science of one sensor and the stitching state its first day starts from.

    ``science`` is a CSV file or EDITED products (`archive.read_science`); ``previous``
    the state at the end of the day before (sec. 4.2.3.3), ``None`` for no stitching;
    ``carry`` (a batch day) the previous day's file whose vectors shifted past midnight
    belong to this day (decision 30).
    """

    sensor: str
    science: Any
    previous: level_a.StitchState | None = None
    carry: PreviousDay | None = None


@dataclass(frozen=True)
class RosettaSource:
    """What one run reads: each sensor's science, the HK, and the UTC day of a batch day.

    ``hk`` goes with the first sensor (its HK LEVEL_A is written with that sensor's
    provenance); ``day`` makes the products of that UTC day only (docs/formats/rosetta.md,
    "Day edges"); ``state_file`` receives the end-of-day stitching state of a single
    run (``--stitch-state``).
    """

    sensors: tuple[SensorSource, ...]
    hk: Any = None
    day: _dt.date | None = None
    state_file: Path | None = None


@dataclass
class Tables:
    """The calibration tables of one sensor (sec. 4.1)."""

    ground: calib.GroundCalibration
    shifts: calib.TimeShiftTable
    nominal: dict
    models: dict
    #: Both sensors' ground calibrations (the quicklook's temperatures), else None.
    both: dict | None = None


@dataclass
class SensorRaw:
    """One sensor's raw records as read, with its tables and the explicit inputs."""

    source: SensorSource
    science: xr.Dataset
    tables: Tables
    hk: xr.Dataset | None = None
    hk_source: Any = None
    #: Records of the previous day's file near midnight (`previous_day_records`).
    carry: xr.Dataset | None = None
    carry_note: str = ""


@dataclass
class RosettaRaw:
    """The raw inputs of a run (`RosettaRun.read`)."""

    sensors: list[SensorRaw]
    day: _dt.date | None = None
    state_file: Path | None = None


@dataclass
class SensorLevels:
    """One sensor's levels and what its run hands on (`RosettaRun.calibrate`)."""

    sensor: str
    science: Any
    levels: dict[str, xr.Dataset]
    #: What the products' provenance names: input files, calibration name -> file/version.
    inputs: list[Path]
    used: dict[str, Any]
    #: First and last good vector (`level_a.stitch_edges`) and the end-of-day stitching
    #: state (the ``stitch_*`` attributes of LEVEL_A, None without extended model).
    edges: tuple | None = None
    end_state: dict | None = None
    n_records: int = 0
    n_to_next_day: int = 0
    temperatures: Any = None


@dataclass
class RosettaLevels:
    """The calibrated run: each sensor's levels, the levels asked for, the day."""

    sensors: list[SensorLevels]
    wanted: tuple[str, ...]
    day: _dt.date | None = None
    state_file: Path | None = None


def needed_levels(wanted: Sequence[str]) -> set[str]:
    """Levels computed to make ``wanted``: G needs C, C and F need B, all need A."""
    need = set(wanted)
    if "G" in need:
        need.add("C")
    if "C" in need or "F" in need:
        need.add("B")
    need.add("A")
    return need


def load_tables(sensor: str, calib_dir: Path | None, quicklook: bool = False) -> Tables:
    """Load one sensor's calibration tables (both ground calibrations with ``quicklook``)."""
    ground = calib.load_ground_calibration(sensor, calib_dir)
    tables = Tables(ground, calib.load_time_shift_table(calib_dir),
                    calib.load_nominal_conversion(calib_dir),
                    calib.find_daily_offset_models(calib_dir, sensor))
    if quicklook:
        tables.both = {s: ground if s == sensor else calib.load_ground_calibration(s, calib_dir)
                       for s in ("OB", "IB")}
    return tables


@dataclass(frozen=True)
class RosettaRun:
    """Rosetta RPC-MAG raw telemetry -> LEVEL_A..G as a `~fluxcal.runs.driver.Pipeline`.

    Parameters
    ----------
    kernels : Path, optional
        The user's meta-kernel: with it, times come from the OBT through the SCLK kernel
        and levels C and G can be made; without, from ``time_utc``
        (`fluxcal.missions.rosetta.io`).
    stitch_dir : Path, optional
        A batch's folder of stitch files (``<out>/stitch``): the days' first and last
        vectors and end-of-day states (`fluxcal.missions.rosetta.batch_task.DayChain`).
    frame_kernels : mapping, optional
        Frames the kernel pool defines when the user's kernels do not: Rosetta's own
        (`identity.FRAME_KERNELS`, the comet's CSEQ), not every mission's.
    """

    kernels: Path | None = None
    stitch_dir: Path | None = None
    frame_kernels: Mapping[str, Path] | None = field(default_factory=lambda: FRAME_KERNELS)

    # --- the driver's steps ----------------------------------------------------------
    def check(self, options: RosettaOptions) -> None:
        """Refuse unknown levels, and kernels-only options without kernels, before reading."""
        wanted = set(parse_levels(",".join(options.levels or FILE_LEVELS)))
        if options.alignment_from_kernels and self.kernels is None:
            raise FluxcalError("--alignment-from-kernels needs --kernels (frames kernel + "
                               "boom CK)")
        if wanted & {"C", "G"} and self.kernels is None:
            raise FluxcalError("levels C and G need SPICE kernels: pass --kernels META "
                               "(SCLK, CK, SPK)")

    def read(self, source: RosettaSource,
             options: RosettaOptions) -> tuple[RosettaRaw, list[Path]]:
        """Read each sensor's tables and raw science (kernels loaded), and the HK.

        A batch day's records must be stamped in its UTC day (`check_day_records`); the
        previous day's records near midnight are read too (an unreadable file leaves its
        tail out, with a note: that day fails on its own and is reported).
        """
        lsk = leapseconds()
        sclk = SclkKernel.from_pool(io.SCLK_ID) if self.kernels is not None else None
        bounds = None if source.day is None else day_bounds(np.datetime64(source.day), lsk)
        sensors, inputs = [], []
        for k, s in enumerate(source.sensors):
            calib.check_sensor(s.sensor)
            tables = load_tables(s.sensor, options.calib, options.quicklook)
            log.info("%s calibration: %r; %r; %d daily offset model(s)", s.sensor,
                     tables.ground, tables.shifts, len(tables.models))
            raw = archive.read_science(s.science, s.sensor, sclk=sclk, lsk=lsk)
            log.info("%s science: %s records from %s", s.sensor,
                     f"{raw.sizes['time']:,}", _name(s.science))
            if bounds is not None:
                check_day_records(raw, bounds, s.science, lsk)
                check_shifts_nonnegative(tables.shifts)
            first, last = (np.datetime64(str(t)[:19]) for t in
                           _utc(raw["epoch"].values[[0, -1]], lsk))
            tables.ground.validity.check(first, last)
            item = SensorRaw(s, raw, tables)
            if k == 0 and source.hk is not None:
                item.hk = archive.read_hk(source.hk, sclk=sclk, lsk=lsk)
                item.hk_source = source.hk
                if bounds is not None:
                    check_day_records(item.hk, bounds, source.hk, lsk)
            if s.carry is not None and bounds is not None:
                try:
                    item.carry = previous_day_records(
                        s.carry.science, s.sensor,
                        day_bounds(np.datetime64(source.day, "D") - 1, lsk), tables.shifts,
                        primary=options.primary, sclk=sclk, lsk=lsk)
                except FluxcalError as exc:
                    item.carry_note = _unreadable(s, exc)
            sensors.append(item)
            inputs += archive.source_files(s.science, s.sensor)
        return RosettaRaw(sensors, source.day, source.state_file), inputs

    def size(self, raw: RosettaRaw) -> int:
        """Return the number of science records read (both sensors, good and bad)."""
        return int(sum(s.science.sizes["time"] for s in raw.sensors))

    def calibrate(self, raw: RosettaRaw, options: RosettaOptions,
                  progress: driver.Progress | None) -> RosettaLevels:
        """Make the levels asked for (and those they need) of every sensor (kernels loaded)."""
        wanted = tuple(lev for lev in LEVELS
                       if lev in parse_levels(",".join(options.levels or FILE_LEVELS)))
        lsk = leapseconds()
        sensors = []
        for k, s in enumerate(raw.sensors):
            if progress is not None:
                progress(f"{s.source.sensor}: calibrating LEVEL_{','.join(wanted)}", k,
                         len(raw.sensors))
            levels = self._sensor_levels(s, wanted, raw.day, options, lsk)
            for name, ds in levels.levels.items():
                log.info("%s %s done: %s %s", levels.sensor,
                         "HK LEVEL_A" if name == "HK" else f"LEVEL_{name}",
                         f"{ds.sizes['time']:,}", "records" if name == "HK" else "vectors")
            sensors.append(levels)
        if progress is not None:
            progress("calibrated", len(raw.sensors), len(raw.sensors))
        return RosettaLevels(sensors, wanted, raw.day, raw.state_file)

    def products(self, calibrated: RosettaLevels,
                 options: RosettaOptions) -> Iterator[Declared]:
        """Declare every sensor's products, then the stitching states (run state, no product).

        Each sensor's products name its own input files and calibration.  The states go
        to the single run's ``state_file`` and the batch's stitch files with the
        products, all or nothing (`fluxcal.products.declared.File`).

        Raises
        ------
        InputFormatError
            A batch day's product of another day (a safeguard: LEVEL_A is trimmed).
        """
        lsk = leapseconds()
        day = calibrated.day
        for s in calibrated.sensors:
            for item in sensor_products(s.levels, calibrated.wanted, formats=options.formats,
                                        quicklook=options.quicklook,
                                        temperatures=s.temperatures, lsk=lsk,
                                        inputs=tuple(s.inputs), calibration=s.used):
                if day is not None and item.day not in (None, day):
                    raise InputFormatError(f"records outside the day {day} (would write "
                                           f"{item.name})", path=str(s.science),
                                           field="time_utc")
                yield item
        if calibrated.state_file is not None:
            for s in calibrated.sensors:
                yield File(calibrated.state_file, stitch_state_text(s.end_state), listed=False)
        if self.stitch_dir is not None and day is not None:
            for s in calibrated.sensors:
                key = batch_task.edge_key(s.science, s.sensor, self.kernels)
                yield File(Path(self.stitch_dir) / batch_task.stitch_name(day, s.sensor),
                           batch_task.stitch_text(key, s.edges, s.end_state), listed=False)

    def calibration(self, calibrated: RosettaLevels | None,
                    options: RosettaOptions) -> dict[str, Any]:
        """Return no run-wide calibration: each product names its own sensor's (`products`)."""
        return {}

    def day_files(self, input_dir: Path, day: _dt.date, options: RosettaOptions) -> list[Path]:
        """Return the day's raw files and the previous day's science (its tail)."""
        return self.chain(input_dir, options).files(day)

    def day_calibration(self, input_dir: Path, day: _dt.date,
                        options: RosettaOptions) -> dict[str, Any]:
        """Return the calibration files and incoming stitching states the day depends on."""
        return self.chain(input_dir, options).calibration(day)

    def day_source(self, input_dir: Path, day: _dt.date,
                   options: RosettaOptions) -> RosettaSource:
        """Return the day's sources with the states they start from (decisions 27, 30).

        Raises
        ------
        DayWithoutData
            When the day has neither sensor's science.
        """
        science = batch_task.day_science(input_dir, day)
        if not science:
            raise DayWithoutData(
                f"no science_OB.csv or science_IB.csv in "
                f"{batch_task.day_folder(input_dir, day)} and no EDITED products "
                f"RPCMAG{day:%y%m%d}T<hhmm>_RAW_<OB|IB>_M<mode> in {input_dir}")
        chain = self.chain(input_dir, options)
        sensors = []
        for sensor, path in science.items():
            carry = chain.previous_day(day, sensor)
            sensors.append(SensorSource(sensor, path, chain.incoming_state(day, sensor),
                                        None if carry is None else PreviousDay(*carry)))
        return RosettaSource(tuple(sensors), batch_task.hk_source(input_dir, day), day)

    def chain(self, input_dir: Path, options: RosettaOptions) -> batch_task.DayChain:
        """Return the batch days of ``input_dir`` with the stitching chain across them."""
        stitch_dir = self.stitch_dir if self.stitch_dir is not None else Path(input_dir)
        return batch_task.DayChain(Path(input_dir), stitch_dir, self.kernels,
                                   self.frame_kernels, options.calib,
                                   options.stitch_gap_hours * 3600.0)

    # --- one sensor ------------------------------------------------------------------
    def _sensor_levels(self, s: SensorRaw, wanted: tuple[str, ...], day: _dt.date | None,
                       options: RosettaOptions, lsk: Any) -> SensorLevels:
        sensor, t = s.source.sensor, s.tables
        gap = options.stitch_gap_hours * 3600.0
        a = level_a.level_a(s.science, t.ground, t.shifts, t.nominal, daily_models=t.models,
                            primary=options.primary, stitch_gap_s=gap,
                            previous=s.source.previous, lsk=lsk)
        state = {k: v for k, v in a.attrs.items() if k.startswith("stitch_")}
        out = SensorLevels(sensor, s.source.science, {}, [], {},
                           edges=level_a.stitch_edges(s.science, sensor),
                           end_state=state or None, n_records=int(s.science.sizes["time"]))
        if day is not None:
            a = self._day_edges(a, s, out, day, gap, options, lsk)
        out.levels["A"] = a
        out.used = {"ground": t.ground.source, "time_shift": t.shifts.source}
        out.used.update({f"daily_{m.day}": m.source for m in t.models.values()})
        need = needed_levels(wanted)
        if "B" in need:
            alignment = None if options.alignment_from_kernels else calib.load_alignment(
                options.calib)
            table = None if options.no_jumps else calib.load_offset_jump_table(options.calib)
            if alignment is not None:
                out.used["alignment"] = alignment.source
            if table is not None:
                out.used["offset_jumps"] = table.source
            out.levels["B"] = level_b.level_b(a, alignment, table, boom=options.boom, lsk=lsk,
                                              daily_models=t.models)
        if "C" in need:
            out.levels["C"] = level_c.level_c(out.levels["B"], frame=options.frame,
                                              centre=options.centre, lsk=lsk)
        for src, dst in (("A", "E"), ("B", "F"), ("C", "G")):
            if dst in need:
                out.levels[dst] = averaged.average(out.levels[src], options.average_s, lsk=lsk)
        if s.hk is not None:
            out.levels["HK"] = hk.hk_level_a(s.hk, t.ground.thermistor, t.nominal)
        out.inputs = [*archive.source_files(s.source.science, sensor),
                      *([] if s.hk_source is None else archive.source_files(s.hk_source)),
                      *out.inputs]  # the previous day's file when its tail is in (_day_edges)
        if t.both is not None:
            out.temperatures = thermistor_temperatures(s.science, t.both, t.nominal)
        return out

    def _day_edges(self, a: xr.Dataset, s: SensorRaw, out: SensorLevels, day: _dt.date,
                   gap: float, options: RosettaOptions, lsk: Any) -> xr.Dataset:
        """Keep the day's vectors of LEVEL_A and put the previous day's tail in front."""
        t = s.tables
        bounds = day_bounds(np.datetime64(day), lsk)
        after = a["epoch"].values >= bounds[1]
        out.n_to_next_day = int(after.sum())
        if out.n_to_next_day:
            log.info("%s %s: %d vectors shifted past midnight belong to the product of %s",
                     day, out.sensor, out.n_to_next_day, day + _dt.timedelta(days=1))
            a = a.isel(time=np.flatnonzero(~after))
        tail, note = None, s.carry_note
        if s.carry is not None:
            try:
                tail = previous_day_tail(s.carry, bounds[0], t.ground, t.shifts, t.nominal,
                                         t.models, primary=options.primary, stitch_gap_s=gap,
                                         previous=s.source.carry.state, lsk=lsk)
            except FluxcalError as exc:  # that day fails on its own and is reported
                note = _unreadable(s.source, exc)
        n_from_previous = 0 if tail is None else int(tail.sizes["time"])
        if tail is not None:
            a = merge_tail(tail, a)
            out.inputs = archive.source_files(s.source.carry.science, out.sensor)
        a.attrs.update(vectors_to_next_day=out.n_to_next_day,
                       vectors_from_previous_day=note or n_from_previous)
        return a


def _name(source: Any) -> str:
    """Return a source's file or folder name for a log line (not the whole path)."""
    if isinstance(source, (str, Path)):
        return Path(source).name
    return f"{len(source)} files" if isinstance(source, Sequence) else str(source)


def _utc(epoch: np.ndarray, lsk: Any) -> np.ndarray:
    return tt2000_to_utc(epoch, digits=0, lsk=lsk)


def _unreadable(source: SensorSource, exc: Exception) -> str:
    """Return the note of a previous day's file whose tail is missing (logged once)."""
    note = f"previous day's file unreadable, its tail is missing: {exc}"
    log.warning("%s: %s", source.science, note)
    return note


def file_source(science: Any, sensor: str, *, hk: Any = None,
                previous: level_a.StitchState | None = None,
                state_file: Path | None = None) -> RosettaSource:
    """Return the source of a single run on one sensor's file(s).

    ``state_file`` (``--stitch-state``): the JSON stitching state the run starts from
    when it exists (sec. 4.2.3.3: "the offset values at the end of a day are stored in a
    separate file"), rewritten with the run's end state; ``previous`` gives that state
    directly instead (giving both is an error).
    """
    if previous is not None and state_file is not None:
        raise FluxcalError("give the stitching state either as a file or as a state, not both")
    if previous is None and state_file is not None:
        previous = read_stitch_state(state_file)
    return RosettaSource((SensorSource(calib.check_sensor(sensor), science, previous),),
                         hk=hk, state_file=None if state_file is None else Path(state_file))


def run_files(
    science: Any,
    sensor: str,
    out: Path,
    *,
    hk: Any = None,
    kernels: Path | None = None,
    options: RosettaOptions | None = None,
    state_file: Path | None = None,
    on_calibrated: Callable[[RosettaLevels], None] | None = None,
    progress: driver.Progress | None = None,
) -> list[Path]:
    """``fluxcal rosetta calibrate``: one sensor's raw science (and HK) to its products.

    ``options`` default `RosettaOptions` (levels A, B); ``on_calibrated`` receives the
    levels before they are written, ``progress(description, done, total)`` each step
    (`fluxcal.runs.driver.run`).  Returns the files.
    """
    options = options or RosettaOptions()
    source = file_source(science, sensor, hk=hk, state_file=state_file)
    run = RosettaRun(kernels=None if kernels is None else Path(kernels))
    return driver.run(run, source, kernels, Path(out), options,
                      on_calibrated=on_calibrated, progress=progress)[0]


def calibrate_levels(
    science: Any,
    sensor: str,
    *,
    hk: Any = None,
    kernels: Path | None = None,
    options: RosettaOptions | None = None,
    previous: level_a.StitchState | None = None,
) -> dict[str, xr.Dataset]:
    """Calibrate one sensor's raw science in memory; return its levels (and ``HK``)."""
    options = options or RosettaOptions()
    source = file_source(science, sensor, hk=hk, previous=previous)
    run = RosettaRun(kernels=None if kernels is None else Path(kernels))
    return driver.calibrate(run, source, kernels, options).sensors[0].levels


def make_day_task(input_dir: Path, out_dir: Path, **options: Any) -> driver.DayTask:
    """Build the task of ``fluxcal batch rosetta`` (`fluxcal.runs.driver.DayTask`).

    ``options``: ``kernels`` (default ``<input>/kernels.tm`` when it exists) and the
    fields of `RosettaOptions` (``calib`` default ``<input>/calib``; ``levels`` default
    A, B, C, E, F, G with kernels, else A, B, E, F; ``stitch_gap_s`` as seconds); others
    are ignored.
    """
    input_dir, out_dir = Path(input_dir), Path(out_dir)
    kernels = batch_task.default_kernels(input_dir, options.pop("kernels", None))
    if "stitch_gap_s" in options:
        options["stitch_gap_hours"] = float(options.pop("stitch_gap_s")) / 3600.0
    names = {f.name for f in dataclasses.fields(RosettaOptions)}
    opts = {k: v for k, v in options.items() if k in names and v is not None}
    for key in ("formats", "levels"):
        if key in opts:
            value = opts[key]
            opts[key] = tuple(value.split(",")) if isinstance(value, str) else tuple(value)
    levels = opts.get("levels") or (batch_task.KERNEL_LEVELS if kernels is not None
                                    else batch_task.BASE_LEVELS)
    opts["levels"] = tuple(levels)
    opts["calib"] = batch_task.default_calib(input_dir, opts.get("calib"))
    run = RosettaRun(kernels=kernels, stitch_dir=out_dir / batch_task.STITCH_DIR)
    return driver.DayTask(run, input_dir, out_dir, RosettaOptions(**opts), kernels,
                          name="rosetta")
