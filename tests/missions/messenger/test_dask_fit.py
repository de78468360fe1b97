"""Issue 21, item 6: the fit's map-reduce on Dask gives the serial fit, bit for bit.

`fit_passes.fit_days` on a real 2-worker LocalCluster merges the days' statistics on the
workers (`fit_passes._merge_tree`), the serial path in this process
(`fit_passes._merge_all`), both in groups of `fit_passes.MERGE_FAN_IN` (2 here), level by
level: the same sums in the same order, so every fitted table, the statistics and the pass
history must be equal.
"""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np
import pytest

pytest.importorskip("distributed")

from fluxcal.errors import InputFormatError  # noqa: E402
from fluxcal.missions.messenger import fit_passes  # noqa: E402
from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.fit import FitResult  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402
from fluxcal.runs.batch import make_local_cluster  # noqa: E402

START = dt.date(2010, 3, 1)
#: Three days merged in pairs: a pair and a lone day, then the root (two tree levels).
DAYS = 3


@pytest.fixture(autouse=True)
def pairs(monkeypatch):
    monkeypatch.setattr(fit_passes, "MERGE_FAN_IN", 2)


@pytest.fixture(scope="module")
def cluster():
    c = make_local_cluster(2)
    yield c
    c.close()


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    return simulate_flight(tmp_path_factory.mktemp("flight"),
                           FlightConfig(start=str(START), days=DAYS), truth=False)


def _assert_same(a: FitResult, b: FitResult) -> None:
    ca, cb = a.calibration, b.calibration
    for name in ("temperature_coefficients", "breakpoint_temperature_c", "duty_cycle_c0",
                 "duty_cycle_d0", "heater_signal"):
        np.testing.assert_array_equal(getattr(cb, name), getattr(ca, name), err_msg=name)
    assert cb.constants == ca.constants  # tau, dt, look-back
    assert b.passes == a.passes
    assert b.stats.days == a.stats.days  # day order kept by the tree
    assert b.stats.inputs == a.stats.inputs and b.stats.n_samples == a.stats.n_samples
    for name in ("temperature", "duty", "epoch", "epoch_weight", "temperature_fine"):
        ma, mb = getattr(a.stats, name), getattr(b.stats, name)
        np.testing.assert_array_equal(mb.count, ma.count, err_msg=name)
        np.testing.assert_array_equal(mb.mean(), ma.mean(), err_msg=name)


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["variance", "zero-mean"])
def test_dask_fit_equals_serial_fit(cluster, flight, estimator):
    chunks = fit_passes.day_chunks(flight.input_dir, flight.days)
    assert len(chunks) == DAYS
    base = load_calibration(str(START))
    kw = {"passes": 2, "estimator": estimator, "guard": False}
    serial = fit_passes.fit_days(chunks, base, scheduler="serial", **kw)
    dask = fit_passes.fit_days(chunks, base, scheduler=cluster.scheduler_address, **kw)
    _assert_same(serial, dask)
    if estimator == "variance":
        va, vb = serial.variance, dask.variance
        np.testing.assert_array_equal(vb.block_start, va.block_start)
        np.testing.assert_array_equal(vb.reason, va.reason)
        np.testing.assert_array_equal(vb.normal, va.normal)
        np.testing.assert_array_equal(vb.rhs, va.rhs)


@pytest.mark.slow
def test_dask_fit_raises_the_bad_days_own_error(cluster, flight, tmp_path):
    chunks = fit_passes.day_chunks(flight.input_dir, flight.days)
    bad = tmp_path / chunks[1].science[0].name
    lines = chunks[1].science[0].read_text().splitlines()
    lines[5] = lines[5].replace(",", ",1e", 1)  # '1e' is no number
    bad.write_text("\n".join(lines) + "\n")
    chunks[1] = dataclasses.replace(chunks[1], science=(bad,))
    with pytest.raises(InputFormatError, match=bad.name):
        fit_passes.fit_days(chunks, load_calibration(str(START)), passes=1,
                     scheduler=cluster.scheduler_address, estimator="variance", guard=False)
