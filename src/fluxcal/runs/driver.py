"""The generic run driver: one path from inputs to products for every mission and route.

A mission hands the driver a `Pipeline` (what to check, how to read a source, how to
calibrate it with the kernels loaded, how to write the products); the driver does the
rest once: the order of the steps, the kernel pool, progress, releasing the raw
telemetry once calibrated, and, for a batch day, finding the day's source, the worker's
kernel pool and the `~fluxcal.runs.batch.DayResult`.  A single run (`run`) and a batch
day (`run_day`) are the same path, so they give the same products for the same data.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import logging
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from fluxcal.extras import require_for_options
from fluxcal.geometry.kernels import KernelPool
from fluxcal.products.declared import Declared, Product, write_declared
from fluxcal.products.provenance import provenance_attrs
from fluxcal.runs.batch import DayInputs, DayResult, DayWithoutData, worker_kernel_pool

log = logging.getLogger(__name__)

#: Progress callback: (description, steps done, steps in total).
Progress = Callable[[str, int, int], None]


class Pipeline(Protocol):
    """What a mission hands the driver for one run (a picklable object for batch days).

    Optional attribute ``frame_kernels`` (frame name -> frames kernel; absent, None or
    empty: none): the frames the kernel pool defines when the user's kernels do not (the
    mission's own).
    """

    def check(self, options: Any) -> None:
        """Refuse bad options before any input is read (one line, `FluxcalError`)."""

    def read(self, source: Any, options: Any) -> tuple[Any, list[Path]]:
        """Read a source (kernels loaded); return the raw telemetry and the input files."""

    def size(self, raw: Any) -> int:
        """Return the number of field vectors in ``raw`` (the batch's vectors/s)."""

    def calibrate(self, raw: Any, options: Any, progress: Progress | None) -> Any:
        """Calibrate raw telemetry (kernels loaded)."""

    def products(self, calibrated: Any, options: Any) -> Iterable[Declared]:
        """Declare the run's products (`fluxcal.products.declared`); the driver writes them.

        A generator is consumed one product at a time (memory-bound products).
        """

    def calibration(self, calibrated: Any, options: Any) -> Mapping[str, Any]:
        """Return the calibration used (name -> file or version) for the provenance."""

    def day_files(self, input_dir: Path, day: _dt.date, options: Any) -> list[Path]:
        """Return the files one batch day reads (its manifest checksums them)."""

    # Optional: ``day_source(input_dir, day, options)``, one batch day's source (raising
    # `~fluxcal.runs.batch.DayWithoutData` if none); default: the ``day_files`` list.

    # Optional: ``day_calibration(input_dir, day, options) -> {name: path or version}``,
    # what else a day depends on (checksummed in its manifest beside `day_files`);
    # default: ``calibration(None, options)``.
    # Optional: ``day_defects(products) -> [span, ...]``, the telemetry-defect spans the
    # day's products record (cause, start, end, samples), listed in the batch report.


def _pool(pipeline: Pipeline, kernels: Path | Sequence[Path] | KernelPool | None) -> Any:
    """Return the kernel pool of a run: ``kernels`` if already loaded, else a new scoped pool."""
    if isinstance(kernels, KernelPool):
        return contextlib.nullcontext(kernels)
    return KernelPool(kernels if kernels is not None else [], frames=_frames(pipeline))


def _frames(pipeline: Pipeline) -> Mapping[str, Path] | None:
    return getattr(pipeline, "frame_kernels", None)


def day_source(pipeline: Pipeline, input_dir: Path, day: _dt.date, options: Any) -> Any:
    """Return a batch day's source: ``pipeline.day_source``, else its ``day_files``.

    Raises
    ------
    fluxcal.runs.batch.DayWithoutData
        When the day has no input file.
    """
    own = getattr(pipeline, "day_source", None)
    if own is not None:
        return own(Path(input_dir), day, options)
    files = pipeline.day_files(Path(input_dir), day, options)
    if not files:
        raise DayWithoutData(f"no input file of {day} in {input_dir}")
    return files


def run(
    pipeline: Pipeline,
    source: Any,
    kernels: Path | Sequence[Path] | KernelPool | None,
    out_dir: Path,
    options: Any,
    *,
    only_day: _dt.date | None = None,
    progress: Progress | None = None,
    on_calibrated: Callable[[Any], None] | None = None,
) -> tuple[list[Path], int]:
    """Check, then (kernels loaded) read, calibrate and write one run; return (files, vectors).

    Parameters
    ----------
    pipeline : Pipeline
        The mission's steps.
    source : object
        What ``pipeline.read`` reads (files, a folder, ...).
    kernels : path, sequence of paths or KernelPool
        Kernels to load for the run, or a pool already loaded (a batch worker's).
    out_dir : Path
        Product folder.
    options : object
        The mission's run options (its options dataclass).
    only_day : datetime.date, optional
        Write that UTC day only (a batch day; inputs may reach into the days around it).
    progress : callable, optional
        ``progress(description, done, total)``.
    on_calibrated : callable, optional
        Called with the calibrated data before it is written (a command's summary, a
        demo's comparison with the truth).
    """
    require_for_options(options)  # a missing plot/zarr extra: one line, nothing read
    pipeline.check(options)
    t0 = time.perf_counter()
    with _pool(pipeline, kernels) as pool:
        loaded = pool.kernel_list()
        log.info("kernels loaded: %d file(s)%s", len(loaded),
                 f" ({', '.join(Path(k).name for k in loaded)})" if loaded else "")
        if progress is not None:
            progress("reading inputs", 0, 1)
        raw, inputs = pipeline.read(source, options)
        n_vectors = pipeline.size(raw)
        t1 = time.perf_counter()
        log.info("read %d input file(s): %s vectors", len(inputs), f"{n_vectors:,}")
        if progress is not None:  # a mission may say more (its own steps, each product)
            progress(f"calibrating {n_vectors:,} vectors", 0, 1)
        calibrated = pipeline.calibrate(raw, options, progress)
        del raw  # what the products need is in ``calibrated``: the telemetry is freed
        t2 = time.perf_counter()
        log.info("calibrated in %.1f s (read in %.1f s)", t2 - t1, t1 - t0)
        if on_calibrated is not None:
            on_calibrated(calibrated)
        if progress is not None:
            progress("writing products", 0, 1)
        written = write(pipeline, calibrated, Path(out_dir), options, inputs=inputs,
                        kernel_list=pool.kernel_list(), only_day=only_day,
                        progress=progress)
        if progress is not None:
            progress(f"wrote {len(written)} files", 1, 1)
        log.info("written in %.1f s", time.perf_counter() - t2)
    log.info("wrote %d product file(s) to %s", len(written), out_dir)
    return written, n_vectors


def write(
    pipeline: Pipeline,
    calibrated: Any,
    out_dir: Path,
    options: Any,
    *,
    inputs: Sequence[Path],
    kernel_list: Sequence[str],
    only_day: _dt.date | None = None,
    progress: Progress | None = None,
) -> list[Path]:
    """Write the products ``pipeline.products`` declares, all or nothing; return them.

    Each product's provenance (`fluxcal.products.provenance.provenance_attrs`) records
    the run's inputs, ``pipeline.calibration`` and the kernels loaded, or the inputs and
    calibration the product names itself (one sensor of several); each distinct record
    is made once (checksums of large inputs are not recomputed per product).

    Raises
    ------
    fluxcal.runs.batch.DayWithoutData
        When ``only_day`` is given and no product of that day was declared.
    """
    run_calibration = dict(pipeline.calibration(calibrated, options))
    records: dict[tuple, Mapping[str, Any]] = {}

    def provenance(product: Product) -> Mapping[str, Any]:
        used_inputs = tuple(inputs if product.inputs is None else product.inputs)
        used = dict(run_calibration if product.calibration is None else product.calibration)
        key = (tuple(map(str, used_inputs)), tuple((k, str(v)) for k, v in used.items()))
        if key not in records:
            records[key] = provenance_attrs(list(used_inputs), used, list(kernel_list))
        return records[key]

    def step(name: str, done: int, total: int) -> None:
        log.debug("%s written", name)  # INFO: one line per step, not per product
        if progress is not None:  # an unknown total (0): still the one step of writing
            progress(f"wrote {name}", *((done, total) if total else (0, 1)))

    written = write_declared(pipeline.products(calibrated, options), out_dir, provenance,
                             only_day=only_day, progress=step)
    if only_day is not None and not written:
        raise DayWithoutData(f"no samples of {only_day} in "
                             f"{', '.join(Path(p).name for p in inputs) or 'the inputs'}")
    return written


def calibrate(
    pipeline: Pipeline,
    source: Any,
    kernels: Path | Sequence[Path] | KernelPool | None,
    options: Any,
) -> Any:
    """Check, then (kernels loaded) read and calibrate one source; write nothing.

    The calibrated data of `run` without products (the library's one-call API).
    """
    pipeline.check(options)
    with _pool(pipeline, kernels):
        raw, _inputs = pipeline.read(source, options)
        return pipeline.calibrate(raw, options, None)


def run_day(
    pipeline: Pipeline,
    input_dir: Path,
    out_dir: Path,
    day: _dt.date,
    options: Any,
    kernels: Path | Sequence[Path] | None,
) -> DayResult:
    """Run one batch day: its source, the worker's kernel pool, `run` for that day only.

    Raises
    ------
    fluxcal.runs.batch.DayWithoutData
        When the day has no input (status ``no_data``).
    """
    pipeline.check(options)  # before looking for the day's files
    source = day_source(pipeline, input_dir, day, options)
    pool = worker_kernel_pool(kernels, _frames(pipeline))
    paths, n_vectors = run(pipeline, source, pool, out_dir, options, only_day=day)
    result = DayResult(day, paths, n_vectors=n_vectors)
    day_defects = getattr(pipeline, "day_defects", None)
    if day_defects is not None:
        result.defects = list(day_defects(paths))
    return result


@dataclass(frozen=True)
class DayTask:
    """A batch day task made of a `Pipeline` (picklable; `fluxcal.runs.batch.run_batch`).

    A mission whose day needs nothing but its pipeline returns one of these from its
    ``make_day_task``; ``inputs(day)`` lists the day's files (``pipeline.day_files``)
    and, when the pipeline has one, ``pipeline.day_calibration``, and ``settings()``
    the run options, so that an unchanged day is skipped and a day whose inputs,
    calibration or options changed is redone (`fluxcal.runs.manifest.stale_reason`).
    """

    pipeline: Pipeline
    input_dir: Path
    out_dir: Path
    options: Any
    kernels: Path | Sequence[Path] | None = None
    name: str = "day"

    def inputs(self, day: _dt.date) -> DayInputs:
        """Return the day's input files and kernels (checksummed in the manifest)."""
        files = self.pipeline.day_files(Path(self.input_dir), day, self.options)
        kernels = [] if self.kernels is None else (
            [self.kernels] if isinstance(self.kernels, (str, Path)) else list(self.kernels))
        day_calibration = getattr(self.pipeline, "day_calibration", None)
        if day_calibration is not None:
            calibration = day_calibration(Path(self.input_dir), day, self.options)
        elif hasattr(self.pipeline, "calibration"):
            calibration = self.pipeline.calibration(None, self.options)
        else:
            calibration = {}
        return DayInputs(tuple(Path(p) for p in [*files, *kernels]), calibration)

    def settings(self) -> dict[str, Any]:
        """Return the run options that change a product (the manifest key's options).

        Every field of the options dataclass but those whose metadata says
        ``"changes_products": False`` (a progress or test option).
        """
        if not dataclasses.is_dataclass(self.options):
            return {}
        return {f.name: getattr(self.options, f.name)
                for f in dataclasses.fields(self.options)
                if f.metadata.get("changes_products", True)}

    def __call__(self, day: _dt.date) -> DayResult:
        """Process ``day`` (`run_day`)."""
        return run_day(self.pipeline, Path(self.input_dir), Path(self.out_dir), day,
                       self.options, self.kernels)
