"""Running batch days on Dask: the ``batch`` extra (dask, distributed) behind one guard.

Imported only where days run on a cluster: `fluxcal.runs.batch.run_batch` without
``scheduler="serial"`` (``fluxcal batch``) and the in-flight fits that reduce days on a
local cluster or an existing scheduler.  A core install (no Dask) gets
`~fluxcal.errors.MissingExtraError` from the import, one line naming
``fluxcal[batch]``; ``--scheduler serial`` runs the same days without Dask.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import logging
import signal
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from fluxcal.extras import guard

try:  # the batch extra: a core install stops here, in one line
    import dask
    from distributed import Client, LocalCluster, as_completed
except ImportError as _exc:
    raise guard("batch", "running days on Dask (a local cluster or --scheduler ADDRESS; "
                "--scheduler serial needs no Dask)", _exc) from _exc

from fluxcal.products.staging import Interrupted


def make_local_cluster(n_workers: int = 2) -> Any:
    """Return a `LocalCluster` of single-threaded worker processes (SPICE-safe).

    Notes
    -----
    Dask starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which also freezes
    glibc's dynamic mmap threshold: every large numpy temporary is then a fresh mmap
    and page-faults on first touch.  A 20 Hz day task (seed 000) ran ~15-25 % slower so; the
    local cluster here starts its workers without it (the one-thread BLAS/OpenMP
    limits are kept).
    """
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                            dashboard_address=":0", silence_logs=logging.ERROR,
                            preload=[__name__])  # dask_setup: workers leave Ctrl-C to us


#: What a nanny logs when its worker process takes longer than the close's grace period
#: (4 s in distributed) to exit, before it kills the process.
_STILL_ALIVE = "Worker process still alive after"

log = logging.getLogger(__name__)


class _StillAlive(logging.Filter):
    """Drop (and count) the nannies' "worker still alive ... killing" records."""

    def __init__(self) -> None:
        super().__init__()
        self.killed = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage().startswith(_STILL_ALIVE):
            self.killed += 1
            return False
        return True


#: What the Dask client logs when a result it gathers is lost with its worker (the day is
#: computed again; an interrupted batch's workers stop before they are gathered).
_LOST_RESULT = "Couldn't gather"


class _LostResults(logging.Filter):
    """Drop (and count) the client's "Couldn't gather ... rescheduling" records."""

    def __init__(self) -> None:
        super().__init__()
        self.lost = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage().startswith(_LOST_RESULT):
            self.lost += 1
            return False
        return True


def close_local_cluster(cluster: Any) -> None:
    """Close a `make_local_cluster` cluster once its work is done (its client closed).

    Every result is in by then: a worker process that takes longer than distributed's
    grace period to exit (a loaded machine, a large interpreter to tear down) is killed
    by its nanny, which logs a "Worker process still alive after 4.0 seconds, killing"
    warning per worker (16 in ``fluxcal demo --full``).  Those warnings say nothing a
    user can act on: they are counted here during the close only (other warnings of the
    nannies still show) and summed up in one INFO line.
    """
    nanny = logging.getLogger("distributed.nanny")
    quiet = _StillAlive()
    nanny.addFilter(quiet)
    try:
        cluster.close()
    finally:
        nanny.removeFilter(quiet)
    log.info("local Dask cluster closed%s", f" ({quiet.killed} worker process(es) stopped "
             "after the grace period)" if quiet.killed else "")


def _quiet_shutdown(client: Any, cluster: Any) -> int | None:
    """Silence the cluster's logs before an interrupted batch closes it.

    Workers busy with a day cannot answer the closing scheduler: each would log its
    lost heartbeat with a traceback, and the nanny its kill.  The interruption and the
    days it stopped are in the summary and the report instead.  Returns this process's
    former ``distributed`` level, for `run_days_on_dask` to give back once the cluster is
    closed (``None``: nothing changed).
    """
    if cluster is None:
        return None  # an external cluster: its logs are its owner's
    before = logging.getLogger("distributed").level
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    with contextlib.suppress(Exception):
        client.run(_silence_distributed_logs)
    return before


def _silence_distributed_logs() -> None:
    """On a worker: log nothing below CRITICAL from ``distributed``."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def dask_setup(worker: Any) -> None:
    """Dask preload hook of `make_local_cluster`'s workers: ignore SIGINT.

    Ctrl-C in a terminal signals the whole process group: the workers of a local cluster
    would each stop with a traceback.  Ignoring it there leaves the interruption to the
    batch process, which cancels the days, closes the cluster and writes the report.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)



def run_days_on_dask(days: Iterable[_dt.date], func: Callable[..., Any],
                     args: Callable[[_dt.date], tuple], name: str, scheduler: str | None,
                     n_workers: int, record: Callable[[Any], None],
                     failed: Callable[[_dt.date, Exception], Any]) -> tuple[str, int]:
    """Run ``func(*args(day))`` for every day on Dask; return (scheduler address, workers).

    `fluxcal.runs.batch.run_batch`'s Dask path: on a new local cluster of ``n_workers``
    (``scheduler`` None) or at the address ``scheduler``.  Each result goes to ``record``
    as it arrives; a task that raised (e.g. ``KilledWorker``) is recorded as
    ``failed(day, exc)``.  Ctrl-C or SIGTERM cancels the days and re-raises.
    """
    cluster = make_local_cluster(n_workers) if scheduler is None else None
    restore: int | None = None
    try:
        with Client(cluster if cluster is not None else scheduler) as client:
            used = str(client.scheduler.address)
            workers = len(client.scheduler_info().get("workers", {}))
            futures = {
                client.submit(func, *args(day), pure=False,
                              key=f"{name}-{day.isoformat()}-{time.time_ns()}"): day
                for day in days
            }
            lost = _LostResults()  # a rescheduled day is no news; Ctrl-C's race is none
            logging.getLogger("distributed.client").addFilter(lost)
            try:
                for fut in as_completed(futures):
                    day = futures[fut]
                    try:
                        st = fut.result()
                    except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                        st = failed(day, exc)
                    record(st)
            except (KeyboardInterrupt, Interrupted):
                client.cancel(list(futures))  # an external scheduler stops the days too
                restore = _quiet_shutdown(client, cluster)
                raise
            finally:
                logging.getLogger("distributed.client").removeFilter(lost)
            if lost.lost:
                log.info("Dask computed %d day(s) again after their worker lost the result",
                         lost.lost)
    finally:
        if cluster is not None:
            close_local_cluster(cluster)
        if restore is not None:  # the calling process's logging as it was
            logging.getLogger("distributed").setLevel(restore)
    return used, workers
