"""Mission-scale batch processing: one task per day on Dask distributed.

`run_batch` sends one task per day to a Dask cluster (by default a `LocalCluster` of
single-threaded worker *processes*, because SPICE keeps one global, non-thread-safe
kernel pool per process) or to an existing scheduler (``scheduler="tcp://host:8786"``),
or runs the days in this process (``scheduler="serial"``).  The Dask half lives in
`fluxcal.runs.cluster` (the ``batch`` extra), imported only when days go to Dask; this
module (day types, manifests, the serial runner) needs no Dask.

A *day task* is a picklable callable ``task(day) -> DayResult`` that writes the day's
products atomically (`fluxcal.products.write_product`).  It may also define
``task.inputs(day) -> DayInputs`` (its input files and calibration), which lets the
runner decide *before* running whether a day is up to date.  Missions expose a
factory ``make_day_task(input_dir, out_dir, **options)`` in
the mission's contract (`fluxcal.runs.contract.Mission.day_task`, see `task_factory`).

Idempotence: after a day succeeds, a JSON manifest ``<out>/manifests/<name>_<day>.json``
records the products (size, SHA-256) and the day's *key*: the inputs and calibration with
their SHA-256 (or version), the options that change a product (``task.settings()``,
`task_settings`) and the software version.  A later run skips the day when its products
still exist with the recorded sizes and every part of the key is unchanged; a day whose
key changed is redone, and the report says why each day was done or skipped
(`DayStatus.reason`, `fluxcal.runs.manifest`); ``force=True`` redoes it.  A killed worker loses at
most the day it was running: the task is resubmitted by Dask, its products appear only
by atomic rename, and its manifest is written after them.

A failing day does not stop the others: its exception is caught on the worker and
reported (`DayStatus.error`).  The report of every day is written as JSON.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import time
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

from fluxcal.errors import FluxcalError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.preflight import writable_folder
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.html_report import run_products, write_run_report
from fluxcal.products.paths import write_scope
from fluxcal.products.provenance import file_checksums, portable_value, sha256_file
from fluxcal.products.staging import (  # noqa: F401 - LOCK_NAME, OutputFolderBusy: re-exported
    LOCK_NAME,
    Interrupted,
    OutputFolderBusy,
    clean_stale_temporaries,
    output_lock,
    report_stale,
)
from fluxcal.runs import registry
from fluxcal.runs.manifest import (  # noqa: F401 - manifest_path, is_up_to_date: re-exported
    MANIFEST_DIR,
    current_inputs,
    is_up_to_date,
    manifest_path,
    stale_reason,
    task_settings,
    write_manifest,
)
from fluxcal.version import software_version

log = logging.getLogger(__name__)

REPORT_NAME = "batch_report_{name}.json"


class DayWithoutData(FluxcalError):  # noqa: N818 - reads as a status, not a failure
    """Raised by a day task when there is no input for the day (status ``"no_data"``)."""


@dataclass(frozen=True)
class DayInputs:
    """Files and calibration a day's processing depends on.

    Parameters
    ----------
    files : sequence of Path
        Input telemetry files (and kernels, if their change must trigger a redo).
    calibration : mapping
        Calibration name -> file path (checksummed) or version string.
    """

    files: tuple[Path, ...] = ()
    calibration: Mapping[str, str | Path] = field(default_factory=dict)

    def checksums(self) -> dict[str, str]:
        """Map ``"input:<file name>"``/``"calibration:<name>"`` to SHA-256 (or version).

        Files are keyed by name (a repeated name numbered ``#2``...), never by folder:
        the manifest, like the products, holds no path of this machine.
        """
        out = file_checksums(self.files)
        for name, v in self.calibration.items():
            p = Path(str(v))
            out[f"calibration:{name}"] = sha256_file(p) if p.is_file() else str(v)
        return out


@dataclass
class DayResult:
    """What a day task returns.

    Parameters
    ----------
    day : datetime.date
        The day processed.
    products : list of Path
        Every file written for the day.
    n_vectors : int
        Number of field vectors processed (for the vectors/s rate).
    inputs : DayInputs, optional
        The inputs used (recorded in the manifest); default ``task.inputs(day)``.
    defects : list of dict
        The day's local defect spans (cause, size), for the batch report (issue 23).
    """

    day: _dt.date
    products: list[Path]
    n_vectors: int = 0
    inputs: DayInputs | None = None
    defects: list[dict] = field(default_factory=list)


class DayTask(Protocol):
    """A picklable per-day job.

    Optional: ``inputs(day) -> DayInputs`` (files and calibration, checksummed) and
    ``settings() -> {option: value}`` (the options that change a product); both are
    part of the day's manifest key (`stale_reason`).
    """

    def __call__(self, day: _dt.date) -> DayResult:  # noqa: D102
        ...


#: Every status a day can have in a report.
STATUSES = ("done", "skipped", "no_data", "failed", "interrupted")


@dataclass
class DayStatus:
    """Outcome of one day: ``done``, ``skipped``, ``no_data``, ``failed`` or ``interrupted``.

    ``interrupted``: the batch was stopped (Ctrl-C, SIGTERM) before the day finished.
    ``reason``: why the day was run or skipped (`stale_reason`: the part of its manifest
    key that changed, ``"--force"``, or ``"up to date"``).
    """

    day: str
    status: str
    products: list[str] = field(default_factory=list)
    n_vectors: int = 0
    seconds: float = 0.0
    error: str | None = None
    traceback: str | None = None
    worker: str | None = None
    defects: list[dict] = field(default_factory=list)
    reason: str | None = None

    def __repr__(self) -> str:
        """One line: day, status, vectors, seconds, and the error's first 120 characters."""
        error = f": {' '.join(self.error.split())[:120]}" if self.error else ""
        return (f"DayStatus({self.day} {self.status}, {self.n_vectors} vectors, "
                f"{len(self.products)} products, {self.seconds:.1f} s{error})")


@dataclass
class BatchReport:
    """Every day's status plus run totals."""

    name: str
    days: list[DayStatus]
    wall_seconds: float
    scheduler: str
    n_workers: int
    report_path: str | None = None

    def __repr__(self) -> str:
        """Two lines: the counts (failed days named), then vectors, time, cluster, report."""
        counts = ", ".join(f"{self.count(s)} {s}" for s in ("done", "skipped", "no_data",
                                                            "failed"))
        failed = [d.day for d in self.failed]
        named = f" ({', '.join(failed[:3])}{', ...' if len(failed) > 3 else ''})" if failed else ""
        report = (f"; report {Path(self.report_path).parent.name}/"
                  f"{Path(self.report_path).name}" if self.report_path else "")
        return (f"BatchReport({self.name}: {len(self.days)} days: {counts}{named}\n"
                f"  {self.n_vectors} vectors in {self.wall_seconds:.1f} s on {self.scheduler}, "
                f"{self.n_workers} workers{report})")

    def count(self, status: str) -> int:
        """Return the number of days with ``status``."""
        return sum(d.status == status for d in self.days)

    @property
    def failed(self) -> list[DayStatus]:
        """Days that failed."""
        return [d for d in self.days if d.status == "failed"]

    @property
    def n_vectors(self) -> int:
        """Vectors processed in this run (skipped days not counted)."""
        return sum(d.n_vectors for d in self.days if d.status == "done")

    @property
    def ok(self) -> bool:
        """True when no day failed."""
        return not self.failed

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        done = [d for d in self.days if d.status == "done"]
        return {
            "name": self.name,
            "software_version": software_version(),
            "scheduler": self.scheduler,
            "n_workers": self.n_workers,
            "wall_seconds": round(self.wall_seconds, 3),
            # "interrupted" only when a day has it: uninterrupted reports keep their form
            "counts": {s: self.count(s) for s in STATUSES
                       if s != INTERRUPTED or self.count(s)},
            "vectors": self.n_vectors,
            "vectors_per_second": (self.n_vectors / self.wall_seconds
                                   if self.wall_seconds > 0 else 0.0),
            "days_per_second": len(done) / self.wall_seconds if self.wall_seconds > 0 else 0.0,
            # errors and tracebacks name files by name: the report holds no folder
            "days": [portable_value(asdict(d)) for d in self.days],
        }


# --- one day (runs on a worker) ------------------------------------------------------------


def run_day(task: Any, day: _dt.date, out_dir: Path, name: str, force: bool) -> DayStatus:
    """Run one day: skip if up to date, else run the task and write its manifest.

    Never raises for a failing day: the error is returned in the `DayStatus`.
    """
    t0 = time.perf_counter()
    worker = f"pid {os.getpid()}"
    reason: str | None = "--force"
    try:
        if not force:
            reason = stale_reason(task, day, out_dir, name)
            if reason is None:
                return DayStatus(day.isoformat(), "skipped", worker=worker,
                                 seconds=time.perf_counter() - t0, reason="up to date")
        inputs = current_inputs(task, day)
        settings = task_settings(task)
        with write_scope(out_dir):  # every write of the day inside --out (decision 66)
            result = task(day)
        write_manifest(out_dir, name, day, result, result.inputs or inputs, settings)
        return DayStatus(day.isoformat(), "done",
                         products=[os.path.relpath(p, out_dir) for p in result.products],
                         n_vectors=int(result.n_vectors), worker=worker,
                         seconds=time.perf_counter() - t0,
                         defects=list(getattr(result, "defects", None) or []), reason=reason)
    except DayWithoutData as exc:
        return DayStatus(day.isoformat(), "no_data", error=str(exc), worker=worker,
                         seconds=time.perf_counter() - t0, reason=reason)
    except Exception as exc:  # noqa: BLE001 - one failing day must not stop the others
        log.warning("day %s failed: %s", day, exc)
        return DayStatus(day.isoformat(), "failed", error=f"{type(exc).__name__}: {exc}",
                         traceback="".join(traceback.format_exception(exc)[-6:]),
                         worker=worker, seconds=time.perf_counter() - t0, reason=reason)


# --- worker-side kernel cache --------------------------------------------------------------

_KERNEL_CACHE: dict[str, Any] = {}


def worker_kernel_pool(kernels: str | Path | Sequence[str | Path] | None,
                       frames: Mapping[str, str | Path] | None = None) -> Any:
    """Load ``kernels`` once per worker process and keep them loaded.

    Day tasks call this instead of ``with KernelPool(...)``: the first call in a process
    furnishes the kernels; later calls with the same list return the same pool; a
    different list unloads the previous one first (SPICE has one pool per process).
    ``frames``: the mission's frame kernels (`fluxcal.geometry.kernels.KernelPool`;
    None: none).

    Returns
    -------
    fluxcal.geometry.kernels.KernelPool
        The entered pool (its ``kernel_list()`` serves provenance).
    """
    if kernels is None:
        key_items: list[str] = []
    elif isinstance(kernels, (str, Path)):
        key_items = [str(kernels)]
    else:
        key_items = [str(k) for k in kernels]
    key = "\n".join(key_items + [f"{n}={p}" for n, p in sorted((frames or {}).items())])
    pool = _KERNEL_CACHE.get("pool")
    if pool is not None and _KERNEL_CACHE.get("key") == key:
        return pool
    if pool is not None:
        release_worker_kernel_pool()
    pool = KernelPool(key_items, frames=frames).__enter__()
    _KERNEL_CACHE.update(pool=pool, key=key)
    return pool


def release_worker_kernel_pool() -> None:
    """Unload the kernels `worker_kernel_pool` keeps loaded in this process (if any)."""
    pool = _KERNEL_CACHE.pop("pool", None)
    _KERNEL_CACHE.clear()
    if pool is not None:
        pool.__exit__(None, None, None)


# --- the runner --------------------------------------------------------------------------


def day_range(start: _dt.date, end: _dt.date) -> list[_dt.date]:
    """Every day from ``start`` to ``end`` inclusive."""
    if end < start:
        raise ValueError(f"end {end} is before start {start}")
    return [start + _dt.timedelta(days=i) for i in range((end - start).days + 1)]


def run_batch(
    days: Iterable[_dt.date],
    task: Callable[[_dt.date], DayResult],
    out_dir: Path,
    scheduler: str | None = None,
    n_workers: int = 2,
    force: bool = False,
    *,
    name: str | None = None,
    on_day_done: Callable[[DayStatus], None] | None = None,
    report_path: Path | None = None,
) -> BatchReport:
    """Run ``task`` for every day, in parallel, resumably; write a JSON report.

    Parameters
    ----------
    days : iterable of datetime.date
        Days to process (one task each).
    task : callable
        Picklable ``task(day) -> DayResult``; optional ``task.inputs(day) -> DayInputs``.
    out_dir : Path
        Product folder; holds ``manifests/`` and the report.
    scheduler : str, optional
        ``None``: a new LocalCluster of ``n_workers`` processes, one thread each;
        ``"serial"``: run in this process (kernels a task loads through
        `worker_kernel_pool` are unloaded at the end, so the caller's SPICE pool is left
        as it was); otherwise the address of an existing Dask scheduler.
    n_workers : int
        Workers of the LocalCluster.
    force : bool
        Redo days even when they are up to date.
    name : str, optional
        Product-set name for manifests and report (default ``task.name`` or
        the task's class name).
    on_day_done : callable, optional
        Called in this process with each `DayStatus` as it arrives (progress bars).
    report_path : Path, optional
        Default ``out_dir / "batch_report_<name>.json"``.

    Returns
    -------
    BatchReport
        Status of every day, in day order.

    Raises
    ------
    OutputFolderBusy
        If another batch is writing into ``out_dir`` (`output_lock`).
    FluxcalError
        ``out_dir`` cannot be a folder (a file, or a dangling link, in its path;
        `fluxcal.preflight.writable_folder`).
    """
    out_dir = writable_folder(Path(out_dir), "--out")  # a dangling link named, not mkdir'd
    out_dir.mkdir(parents=True, exist_ok=True)
    # every write of the batch (manifests, report, index.html) inside --out (decision 66)
    with output_lock(out_dir), write_scope(out_dir):
        return _run_batch_locked(days, task, out_dir, scheduler, n_workers, force, name,
                                 on_day_done, report_path)


def _run_batch_locked(days, task, out_dir, scheduler, n_workers, force, name, on_day_done,
                      report_path) -> BatchReport:
    days = sorted(set(days))
    name = name or str(getattr(task, "name", type(task).__name__))
    report_stale(clean_stale_temporaries(out_dir), out_dir)
    t0 = time.perf_counter()
    statuses: dict[str, DayStatus] = {}

    def record(st: DayStatus) -> None:
        statuses[st.day] = st
        if on_day_done is not None:
            on_day_done(st)

    used, workers = str(scheduler or "local cluster"), 1 if scheduler == "serial" else n_workers
    interrupted: BaseException | None = None
    try:
        used, workers = _run_days(days, task, out_dir, scheduler, n_workers, force, name,
                                  record)
    except (KeyboardInterrupt, Interrupted) as exc:  # Ctrl-C, SIGTERM (products.staging)
        interrupted = exc
    for p in clean_stale_temporaries(out_dir):  # left by a worker killed during this run
        log.info("removed stale temporary %s", p)
    report = BatchReport(
        name,
        [statuses.get(d.isoformat()) or DayStatus(d.isoformat(), INTERRUPTED) for d in days],
        time.perf_counter() - t0, used, workers)
    rpath = Path(report_path) if report_path else out_dir / REPORT_NAME.format(name=name)
    report.report_path = str(rpath)
    atomic_write_bytes(rpath, json.dumps(report.to_dict(), indent=1).encode())
    if interrupted is None:  # the folder's HTML report: every day's products, the report
        write_run_report(out_dir, title=f"fluxcal batch {name}",
                         products=[p for p in run_products(out_dir)
                                   if not p.rel.startswith("manifests/")])
    if interrupted is not None:
        interrupted.batch_report = report  # type: ignore[attr-defined]
        raise interrupted
    return report


#: Status of a day a batch did not finish because the run was interrupted.
INTERRUPTED = "interrupted"


def _run_days(days, task, out_dir, scheduler, n_workers, force, name,
              record) -> tuple[str, int]:
    """Run the days serially or on Dask, recording each status; return (scheduler, workers)."""
    if scheduler == "serial":
        had_pool = "pool" in _KERNEL_CACHE
        try:
            for day in days:
                record(run_day(task, day, out_dir, name, force))
        finally:
            if not had_pool:  # this process is not a worker: leave its SPICE pool as found
                release_worker_kernel_pool()
        return "serial", 1
    from fluxcal.runs.cluster import run_days_on_dask  # the batch extra's module

    return run_days_on_dask(
        days, run_day, lambda day: (task, day, out_dir, name, force), name, scheduler,
        n_workers, record,
        lambda day, exc: DayStatus(day.isoformat(), "failed",
                                   error=f"{type(exc).__name__}: {exc}"))


#: Dask helpers that live in `fluxcal.runs.cluster` (the ``batch`` extra), still importable
#: from here: ``from fluxcal.runs.batch import make_local_cluster``.
_CLUSTER_NAMES = ("make_local_cluster", "dask_setup")


def __getattr__(name: str) -> Any:
    if name in _CLUSTER_NAMES:
        from fluxcal.runs import cluster  # raises MissingExtraError without fluxcal[batch]

        return getattr(cluster, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# --- missions ----------------------------------------------------------------------------


def accepted_formats(mission: str) -> tuple[str, ...]:
    """Return the ``--formats`` the registered ``mission``'s runs accept."""
    return registry.get(mission).accepted_formats()


def task_factory(mission: str) -> Callable[..., Any]:
    """Return ``make_day_task(input_dir, out_dir, **options)`` of a registered mission.

    Raises
    ------
    FluxcalError
        If no such mission is registered or it has no day task.
    """
    return registry.get(mission).load("day_task")
