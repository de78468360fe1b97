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
import datetime as _dt
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

from fluxcal.geometry.kernels import KernelPool
from fluxcal.runs.batch import DayResult, worker_kernel_pool

#: Progress callback: (description, steps done, steps in total).
Progress = Callable[[str, int, int], None]


class Pipeline(Protocol):
    """What a mission hands the driver for one run (a picklable object for batch days)."""

    def check(self, options: Any) -> None:
        """Refuse bad options before any input is read (one line, `FluxcalError`)."""

    def read(self, source: Any, options: Any) -> tuple[Any, list[Path]]:
        """Read a source; return the raw telemetry and the input files (provenance)."""

    def size(self, raw: Any) -> int:
        """Return the number of field vectors in ``raw`` (the batch's vectors/s)."""

    def calibrate(self, raw: Any, options: Any, progress: Progress | None) -> Any:
        """Calibrate raw telemetry (kernels loaded)."""

    def write(self, calibrated: Any, out_dir: Path, options: Any, *, inputs: Sequence[Path],
              kernel_list: Sequence[str], only_day: _dt.date | None,
              progress: Progress | None) -> list[Path]:
        """Write the products of every day (or of ``only_day``) atomically; return them."""

    def day_source(self, input_dir: Path, day: _dt.date, options: Any) -> Any:
        """Return one batch day's source; raise `~fluxcal.runs.batch.DayWithoutData` if none."""


def run(
    pipeline: Pipeline,
    source: Any,
    kernels: Path | Sequence[Path] | KernelPool | None,
    out_dir: Path,
    options: Any,
    *,
    only_day: _dt.date | None = None,
    progress: Progress | None = None,
) -> tuple[list[Path], int]:
    """Check, read, calibrate (kernels loaded) and write one run; return (files, vectors).

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
    """
    pipeline.check(options)
    if progress is not None:
        progress("reading inputs", 0, 1)
    raw, inputs = pipeline.read(source, options)
    n_vectors = pipeline.size(raw)
    loaded = (contextlib.nullcontext(kernels) if isinstance(kernels, KernelPool)
              else KernelPool(kernels if kernels is not None else []))
    with loaded as pool:
        calibrated = pipeline.calibrate(raw, options, progress)
        del raw  # what the products need is in ``calibrated``: the telemetry is freed
        written = pipeline.write(calibrated, Path(out_dir), options, inputs=inputs,
                                 kernel_list=pool.kernel_list(), only_day=only_day,
                                 progress=progress)
    return written, n_vectors


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
    source = pipeline.day_source(Path(input_dir), day, options)
    pool = worker_kernel_pool(kernels)
    paths, n_vectors = run(pipeline, source, pool, out_dir, options, only_day=day)
    return DayResult(day, paths, n_vectors=n_vectors)
