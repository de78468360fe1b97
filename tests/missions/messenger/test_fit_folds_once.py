"""Issue 34, item 7: the waveform columns' fold errors are fitted once, after the passes.

No pass reads ``FitResult.waveform_error`` (only the figure of merit after the passes
does, `fit_merit.predicted_error`), so `fit.fit_days` skips the four folds' splines in
every pass and states the errors once, from the last pass's statistics and starting
table (docs/decisions/messenger_fit.md, entry 3x-folds).  The expected values are the
fit's own, stated the way every pass stated them before: the same `fit_days` with the
per-pass errors forced back on.  Everything must agree bit for bit (the same
arithmetic on the same inputs), and the folds must be fitted once instead of once per
pass.  The data are a forward model that shares no code with the fit
(`flight_sim`, 2 days of the realistic wind).
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from fluxcal.missions.messenger import fit
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_reduce import WAVEFORM_FOLDS
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight

START = dt.date(2010, 3, 1)
PASSES = 3


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    return simulate_flight(tmp_path_factory.mktemp("flight"),
                           FlightConfig(start=str(START), days=2, seed=2121), truth=False)


def _fit(flight, monkeypatch, estimator: str, per_pass: bool):
    """`fit_days` as it runs (``per_pass`` False) or with every pass stating its errors."""
    stated: list[np.ndarray | None] = []
    fold_unmixes = []
    unmix = fit.unmix_waveforms

    def counting_unmix(stats, waveform=None):
        if waveform is not None:  # one fold's statistics
            fold_unmixes.append(1)
        return unmix(stats, waveform)

    monkeypatch.setattr(fit, "unmix_waveforms", counting_unmix)
    if per_pass:
        name = "fit_variance_calibration" if estimator == "variance" else "fit_calibration"
        original = getattr(fit, name)

        def stating(*args, **kwargs):
            out = original(*args, **{**kwargs, "waveform_errors": True})
            stated.append(out.waveform_error)
            return out

        monkeypatch.setattr(fit, name, stating)
    res = fit.fit_days(fit.day_chunks(flight.input_dir, flight.days),
                       load_calibration(str(START)), passes=PASSES, estimator=estimator,
                       guard=False)
    monkeypatch.undo()
    return res, stated, len(fold_unmixes)


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["variance", "zero-mean"])
def test_fold_errors_once_equal_the_last_pass_errors_and_change_nothing_else(
        flight, monkeypatch, estimator):
    now, _, folds_now = _fit(flight, monkeypatch, estimator, per_pass=False)
    before, stated, folds_before = _fit(flight, monkeypatch, estimator, per_pass=True)
    runs = len(before.passes)
    assert len(now.passes) == runs
    # the folds' spread fitted once (the four folds unmixed once), not once per pass
    assert folds_now == WAVEFORM_FOLDS
    assert folds_before >= WAVEFORM_FOLDS * runs
    # the stated column errors: those the last pass's own fit stated, bit for bit
    assert stated[-1] is not None and np.all(np.isfinite(stated[-1]))
    np.testing.assert_array_equal(now.waveform_error, stated[-1])
    np.testing.assert_array_equal(now.waveform_error, before.waveform_error)
    # and nothing else moved: the tables, every pass's history, the stated errors of
    # the other terms and the figure of merit built from all of them
    for name in ("temperature_coefficients", "breakpoint_temperature_c", "duty_cycle_c0",
                 "duty_cycle_d0", "heater_signal"):
        np.testing.assert_array_equal(getattr(now.calibration, name),
                                      getattr(before.calibration, name), err_msg=name)
    assert now.calibration.constants == before.calibration.constants
    assert now.passes == before.passes and now.convergence == before.convergence
    law = ("a0", "b0", "a1", "b1", "x_m", "a0_err", "b0_err", "a1_err", "b1_err", "x_m_err")
    assert [[getattr(f, k) for k in law] for f in now.temperature] == [
        [getattr(f, k) for k in law] for f in before.temperature]
    assert [f.slope_err for f in now.duty] == [f.slope_err for f in before.duty]
    assert now.merit == before.merit
    if estimator == "variance":
        assert now.merit["waveform_nt"] == before.merit["waveform_nt"]
