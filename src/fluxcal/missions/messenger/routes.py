"""Every MESSENGER route on the generic driver (`fluxcal.runs.driver`).

`MessengerRun` is MESSENGER's `~fluxcal.runs.driver.Pipeline`: check the options, read
a source (`CsvSource`: the three CSV streams; `EdrSource`: a folder of archived EDRs
through a mapping), calibrate (`fluxcal.missions.messenger.run.calibrate_run`) and
declare every day's products (`~fluxcal.missions.messenger.run.run_products`), which the
driver writes.  ``edr2cdr`` (`run_source`: CSV files, `run_edr2cdr`, or an EDR folder,
`run_edr_archive`) and the batch day task (`fluxcal.missions.messenger.batch_task`) are
the same driver with another source.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fluxcal.archive.pds3 import read_label, table_names
from fluxcal.missions.messenger.batch_day import day_file, read_day_science
from fluxcal.missions.messenger.calibration_data import data_dir
from fluxcal.missions.messenger.edr import DAY_OFFSETS, load_mapping, read_edr, select_files
from fluxcal.missions.messenger.identity import FRAME_KERNELS
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.missions.messenger.products import Progress, istp_files
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.run import (
    calibrate_run,
    prepare_formats,
    quicklook_frame_of,
    run_products,
)
from fluxcal.missions.messenger.validation_report import read_defect_spans
from fluxcal.products.declared import Declared
from fluxcal.runs import driver
from fluxcal.runs.batch import DayWithoutData

#: Name of the mapping file that makes an input folder an EDR folder (issue 14).
EDR_MAPPING = "edr_mapping.toml"


@dataclass(frozen=True)
class CsvSource:
    """The three CSV streams of a run (docs/formats/messenger.md).

    ``day``: a batch day, whose science files are those of the day before, the day and
    the day after; only the samples of that day are kept (`run.batch_day_rows`).
    """

    science: tuple[Path, ...]
    heater: tuple[Path, ...]
    temperature: tuple[Path, ...]
    day: _dt.date | None = None


@dataclass(frozen=True)
class EdrSource:
    """A folder of archived MAG EDRs read through a column mapping.

    ``days`` limits the science EDRs read (a batch day); ``inputs`` lists the files the
    products' provenance names (default: every label read, its tables and the mapping).
    """

    folder: Path
    mapping: Path
    days: tuple[_dt.date, ...] | None = None
    inputs: tuple[Path, ...] | None = None


def edr_day_files(folder: Path, mapping: Path, day: _dt.date) -> dict[str, list[Path]]:
    """Return the EDR labels and tables day ``day`` reads, per kind (highest versions)."""
    m = load_mapping(mapping)
    out: dict[str, list[Path]] = {}
    for kind, offsets in DAY_OFFSETS.items():
        days = [day + _dt.timedelta(days=k) for k in offsets]
        labels = [f.path for f in select_files(folder, m, kind, days)]
        out[kind] = labels + [p.with_suffix(".TAB") for p in labels
                              if p.with_suffix(".TAB").is_file()]
    out["mapping"] = [m.path]
    return out


def csv_day_files(folder: Path, day: _dt.date) -> dict[str, list[Path]]:
    """Return a batch day's CSV streams: its science file, heater D-1..D, temperature D-1..D+1.

    The previous day's heater file serves the 5-change look-back of sec. 7.  Besides
    (``science_around``, ``heater_after``): the science files of D-1 and D+1 and the
    heater file of D+1 that exist, which a batch day reads too, for its samples that a
    file of the day beside holds (a stream across midnight given as one day's files;
    `run.batch_day_rows`).
    """
    one = _dt.timedelta(days=1)
    heat = [p for p in (day_file(folder, "HTR", day - one), day_file(folder, "HTR", day))
            if p.exists()]
    temp = [p for p in (day_file(folder, "TMP", day - one), day_file(folder, "TMP", day),
                        day_file(folder, "TMP", day + one)) if p.exists()]
    around = [p for p in (day_file(folder, "SCI", day - one), day_file(folder, "SCI", day + one))
              if p.exists()]
    after = [p for p in (day_file(folder, "HTR", day + one),) if p.exists()]
    return {"science": [day_file(folder, "SCI", day)], "heater": heat, "temperature": temp,
            "science_around": around, "heater_after": after}


def day_file_groups(input_dir: Path, day: _dt.date) -> dict[str, list[Path]]:
    """Return a batch day's files per stream: its EDRs (a folder with `EDR_MAPPING`) or CSVs.

    `edr_day_files` when the folder holds the mapping, else `csv_day_files`.
    """
    mapping = Path(input_dir) / EDR_MAPPING
    if mapping.is_file():
        return edr_day_files(input_dir, mapping, day)
    return csv_day_files(input_dir, day)


def _edr_tables(labels: Sequence[Path]) -> list[Path]:
    """Return the data files the labels point to (checksummed with them in provenance)."""
    tables = []
    for p in labels:
        label = read_label(p)
        for name in table_names(label):
            ptr = label[f"^{name}"]
            data = p.parent / str(ptr[0] if isinstance(ptr, (list, tuple)) else ptr)
            if data != p and data.exists():
                tables.append(data)
    return tables


@dataclass(frozen=True)
class MessengerRun:
    """MESSENGER MAG EDR -> CDR as a `fluxcal.runs.driver.Pipeline` (picklable)."""

    frame_kernels: Mapping[str, Path] | None = field(default_factory=lambda: FRAME_KERNELS)

    def check(self, options: MessengerOptions) -> None:
        """Check the formats and load the figure's support before any data is read."""
        prepare_formats(options.formats)

    def read(self, source: CsvSource | EdrSource,
             options: MessengerOptions) -> tuple[tuple[Any, Any, Any], list[Path]]:
        """Read the science, heater and temperature streams; return them and the inputs."""
        if isinstance(source, EdrSource):
            m = load_mapping(source.mapping)
            days = list(source.days) if source.days is not None else None
            streams = read_edr(source.folder, m, days=days, calibration_folder=options.calib)
            if source.inputs is not None:
                return streams, list(source.inputs)
            labels = [Path(p) for ds in streams for p in ds.attrs["inputs"].split(";")]
            return streams, [*labels, *_edr_tables(labels), m.path]
        if source.day is None:
            science, read = read_science(source.science), list(map(Path, source.science))
        else:  # a batch day: its samples, from its file or the files beside it
            science, read = read_day_science(source.science,
                                             day_file(Path(source.science[0]).parent, "SCI",
                                                      source.day), source.day, options.calib)
        streams = (science, read_heater(source.heater), read_temperature(source.temperature))
        return streams, [*read, *map(Path, source.heater), *map(Path, source.temperature)]

    def size(self, raw: tuple[Any, Any, Any]) -> int:
        """Return the number of science vectors."""
        return int(raw[0].sizes["time"])

    def calibrate(self, raw: tuple[Any, Any, Any], options: MessengerOptions,
                  progress: Progress | None) -> tuple[Any, Any]:
        """`calibrate_run` for the products and quicklook the options ask for."""
        sci, heat, temp = raw
        return calibrate_run(sci, heat, temp, frames=options.frames,
                             quicklook_frame=quicklook_frame_of(
                                 options.frames, options.quicklook, options.quicklook_frame),
                             calibration_folder=options.calib, progress=progress)

    def products(self, calibrated: tuple[Any, Any],
                 options: MessengerOptions) -> Iterator[Declared]:
        """`run_products`: every day's products, offset report and quicklook, day after day."""
        return run_products(*calibrated, options)

    def calibration(self, calibrated: tuple[Any, Any],
                    options: MessengerOptions) -> dict[str, Path]:
        """Return the calibration tables the run used (name -> path), for the provenance."""
        return {path.name: path for path in calibrated[1].paths}

    def day_files(self, input_dir: Path, day: _dt.date,
                  options: MessengerOptions) -> list[Path]:
        """Return the EDRs or CSV streams a batch day reads (those that exist)."""
        files = day_file_groups(input_dir, day)
        return [p for group in files.values() for p in group if p.exists()]

    def day_calibration(self, input_dir: Path, day: _dt.date,
                        options: MessengerOptions) -> dict[str, Path]:
        """Return the calibration tables and product-metadata files a batch day uses.

        The tables in force (``--calib`` or the shipped ones) and the ISTP attribute
        files: a changed one redoes the day (its manifest checksums them).
        """
        folder = Path(options.calib) if options.calib else data_dir()
        files = {p.name: p for p in sorted(folder.glob("*_v*.*"))}
        files.update({p.name: p for p in (*istp_files(), data_dir() / "istp_products.yaml")})
        return files

    def day_defects(self, products: Sequence[Path]) -> list[dict]:
        """Return the defect spans the day's offsets reports list (for the batch report)."""
        return [span for p in products
                if Path(p).name.startswith("MAGOFFSETS") and Path(p).suffix == ".txt"
                for span in read_defect_spans(p)]

    def day_source(self, input_dir: Path, day: _dt.date,
                   options: MessengerOptions) -> CsvSource | EdrSource:
        """Return the batch day's EDRs (a folder with `EDR_MAPPING`) or CSV streams.

        Raises
        ------
        DayWithoutData
            When the day has no science file.
        """
        files = day_file_groups(input_dir, day)
        if "mapping" in files:
            if not files["science"]:
                raise DayWithoutData(f"no science EDR of {day} in {input_dir}")
            return EdrSource(input_dir, files["mapping"][0], days=(day,),
                             inputs=tuple(p for group in files.values() for p in group))
        science = [p for p in files["science"] if p.exists()] + files["science_around"]
        if not science:
            raise DayWithoutData(f"no science file {files['science'][0]}, nor of the days "
                                 "beside it")
        return CsvSource(tuple(science), (*files["heater"], *files["heater_after"]),
                         tuple(files["temperature"]), day=day)


def run_source(source: CsvSource | EdrSource, kernels: Path | Sequence[Path], out_dir: Path,
               options: MessengerOptions, progress: Progress | None = None) -> list[Path]:
    """Run EDR -> CDR on one source with the generic driver; return every file written.

    A day whose offsets fail the smoothness check (sec. 13) gets no file; the other
    days are written, then `ValidationError` is raised naming the failed days.
    ``progress(description, done, total)`` is called after reading, calibrating and each
    product (the CLI draws it).
    """
    return driver.run(MessengerRun(), source, kernels, out_dir, options, progress=progress)[0]


def _options(options: dict[str, Any]) -> MessengerOptions:
    """`MessengerOptions` of the function routes' keywords (``calibration_folder``: ``calib``)."""
    if "calibration_folder" in options:
        options["calib"] = options.pop("calibration_folder")
    return MessengerOptions(**options)


def run_edr2cdr(science: Sequence[Path], heater: Sequence[Path], temperature: Sequence[Path],
                kernels: Path | Sequence[Path], out_dir: Path, *,
                progress: Progress | None = None, **options: Any) -> list[Path]:
    """`run_source` on the three CSV streams (docs/formats/messenger.md).

    ``options``: the fields of `MessengerOptions` (frames, formats, averages,
    max_offset_step, quicklook, quicklook_frame, version; ``calibration_folder`` or
    ``calib`` replaces the shipped tables).
    """
    source = CsvSource(tuple(map(Path, science)), tuple(map(Path, heater)),
                       tuple(map(Path, temperature)))
    return run_source(source, kernels, out_dir, _options(options), progress)


def run_edr_archive(edr_dir: str | Path, mapping: str | Path, kernels: Path | Sequence[Path],
                    out_dir: Path, *, progress: Progress | None = None,
                    **options: Any) -> list[Path]:
    """`run_source` on a folder of archived EDRs read through ``mapping`` (`read_edr`).

    ``options`` as `run_edr2cdr`.  The product provenance lists every EDR label and
    table read and the mapping file.
    """
    source = EdrSource(Path(edr_dir), Path(mapping))
    return run_source(source, kernels, out_dir, _options(options), progress)
