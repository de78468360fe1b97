"""Closing the local Dask cluster: no "worker still alive" warning per worker (issue 31).

``fluxcal demo --full`` printed 16 "Worker process still alive after 4.0 seconds,
killing" warnings: distributed's nannies log one for each worker process that takes
longer than the close's grace period to exit, after every result is in.  They are
counted and summed up in one INFO line during the close only; any other warning of the
nannies, and the same warning outside a close, still shows.
"""

from __future__ import annotations

import logging

import pytest

pytest.importorskip("distributed")

from fluxcal.runs.cluster import close_local_cluster  # noqa: E402 - after the skip

NANNY = logging.getLogger("distributed.nanny")


class SlowWorkersCluster:
    """A stand-in cluster whose close logs what distributed's nannies log on a busy machine."""

    closed = False

    def close(self) -> None:
        for _ in range(2):
            NANNY.warning("Worker process still alive after 4.0 seconds, killing")
        NANNY.warning("some other nanny warning")
        self.closed = True


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


def test_close_counts_the_still_alive_warnings_in_one_info_line(caplog) -> None:
    cluster = SlowWorkersCluster()
    # the nanny's own level: a Dask cluster started earlier in this process (its
    # silence_logs, a quiet batch) may have left "distributed" at ERROR
    with caplog.at_level(logging.INFO), caplog.at_level(logging.INFO, logger=NANNY.name):
        close_local_cluster(cluster)
    assert cluster.closed
    assert _warnings(caplog) == ["some other nanny warning"]
    assert ("local Dask cluster closed (2 worker process(es) stopped after the grace "
            "period)") in [r.getMessage() for r in caplog.records]


def test_the_warning_shows_outside_a_close(caplog) -> None:
    caplog.set_level(logging.INFO, logger=NANNY.name)  # as above
    close_local_cluster(SlowWorkersCluster())
    caplog.clear()
    NANNY.warning("Worker process still alive after 4.0 seconds, killing")
    assert _warnings(caplog) == ["Worker process still alive after 4.0 seconds, killing"]


def test_a_failing_close_leaves_no_filter_behind() -> None:
    class Broken:
        def close(self) -> None:
            raise OSError("boom")

    before = list(NANNY.filters)
    with pytest.raises(OSError):
        close_local_cluster(Broken())
    assert NANNY.filters == before


def test_an_interrupted_run_gives_the_distributed_level_back() -> None:
    """Ctrl-C during `run_days_on_dask` silences ``distributed`` (CRITICAL) for the close;
    a process that goes on afterwards (a notebook, a test run) gets its level back."""
    import datetime as dt

    from fluxcal.runs.cluster import run_days_on_dask

    dist = logging.getLogger("distributed")
    before = dist.level
    dist.setLevel(logging.INFO)

    def interrupt(_result) -> None:
        raise KeyboardInterrupt  # as Ctrl-C would, while the results arrive

    try:
        with pytest.raises(KeyboardInterrupt):
            run_days_on_dask([dt.date(2024, 3, 1), dt.date(2024, 3, 2)], abs, lambda d: (-1,),
                             "interrupted", None, 1, interrupt, lambda day, exc: None)
        assert dist.level == logging.INFO
    finally:
        dist.setLevel(before)
