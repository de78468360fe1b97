"""Issue 34: a table fitted on cold data predicts the error of a warmer unseen day honestly.

The world: `flight_sim` streams (true tables differing from the shipped ones,
`flight_sim.CalibrationChanges`: breaks moved by -6 / +5 / +4 C, upper slopes x1.3 /
0.8 / 1.35) driven by the independent test wind (`_realistic_wind`, 3 % compressive).
Two training days whose heater-off excursions peak at -45..-30 C only (the breaks, at
-16 / -8 / -11 C in the truth, lie above the data), one unseen day with the flight
model's default excursions (peaks up to +55 C).  The fitted table's prediction for the
unseen day (`fit_merit.predicted_error` with that day's sample distribution) must cover
the unseen day's true rms error: the law's part against the law's error computed from
the world's true tables (eq. 3a, 3b, 4 and eq. 8 with Table 4, written here from the
seed), the total against the unseen day recalibrated through the pipeline.

Before docs/decisions/messenger_fit.md entry 21 the resamples could not move the upper
segments beyond the data, the prediction's law part was ~0.01 nT there, and the
prediction (0.17 nT, the waveforms) did not cover the day (0.44 / 0.68 / 0.21 nT, seed
9100).  Now the fit holds them (`fit_holds.held_upper_segments`) and every resample draws
their widths, so the prediction's law part carries them once.  Slow: about 3 passes of
2 days at 1 Hz.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger import fit_merit, forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_passes import FitSettings, day_chunks, fit_days, reduce_chunk
from fluxcal.missions.messenger.fit_write import write_calibration_folder
from fluxcal.missions.messenger.flight_sim import (
    FlightConfig,
    HeaterModel,
    read_flight_truth,
    simulate_flight,
)
from tests.missions.messenger._realistic_wind import realistic_wind
from tests.missions.messenger._unseen_day import recalibrate_rms

pytestmark = pytest.mark.slow

#: One unseen day is one draw of the error the prediction states as an rms: it may
#: exceed the prediction by this factor (as `test_fit_honest.UNSEEN_OVER_PREDICTED`).
UNSEEN_OVER_PREDICTED = 1.5
#: Table 4 (seed sec. 8), fine range: gains (nT/count) and alignment.
K = np.array([0.046769, 0.046673, 0.047997])
ALPHA, BETA, GAMMA = -0.00462, 0.00053, -0.00736


def _fine_matrix() -> np.ndarray:
    """Eq. 8 as a matrix (sensor nT from offset-corrected counts)."""
    return np.array([[K[0], 0.0, 0.0], [ALPHA * K[0], K[1], 0.0],
                     [BETA * K[0], GAMMA * K[1], K[2]]])


def _law(a0, b0, a1, b1, t: np.ndarray) -> np.ndarray:
    """Eq. 3a, 3b with T_m from eq. 4, per axis: shape (t.size, 3)."""
    a0, b0, a1, b1 = (np.asarray(x, dtype=float)[None, :] for x in (a0, b0, a1, b1))
    tm = (a0 - a1) / (b1 - b0)
    return np.where(t[:, None] <= tm, a0 + b0 * t[:, None], a1 + b1 * t[:, None])


def test_cold_table_predicts_the_error_of_a_warmer_unseen_day(tmp_path):
    wind = functools.partial(realistic_wind, compressive=0.03)
    train = simulate_flight(tmp_path / "train",
                            FlightConfig(start="2010-03-01", days=2, seed=9100,
                                         heater=HeaterModel(peak_c=(-45.0, -30.0))),
                            wind=wind, truth=False)
    unseen = simulate_flight(tmp_path / "unseen",
                             FlightConfig(start="2010-03-10", days=1, seed=9101),
                             wind=wind, truth=True)
    true = forward.read_tables(sorted(train.calibration_dir.glob("*_v*.*")))
    # guards off: the break check would refuse this table (its breaks lie beyond the
    # data); the prediction must be honest on its own
    res = fit_days(day_chunks(train.input_dir, train.days), load_calibration("2010-03-01"),
                   passes=3, estimator="variance", guard=False)
    lo, hi = res.variance.fitted_range()
    assert hi <= -25.0, (lo, hi)
    assert sorted(res.held_upper) == ["x", "y", "z"]
    day = unseen.days[0]
    reduced = reduce_chunk(day_chunks(unseen.input_dir, [day])[0], res.calibration, None,
                           FitSettings(), estimator="variance")
    pred = fit_merit.predicted_error(res, day=fit_merit.DaySamples.of(*reduced))
    # the law's true error over the unseen day's fine-range samples, from the truth
    tr = read_flight_truth(unseen.input_dir, day)
    t = tr["temperature_c"][tr["range"] == 0]
    assert t.max() > 0.0  # the unseen day is warmer than the data
    fitted = np.asarray(res.calibration.offset_coefficients(), dtype=float).T
    d_law = _law(*fitted, t) - _law(true.a0, true.b0, true.a1, true.b1, t)
    true_law = np.sqrt(((d_law @ _fine_matrix().T) ** 2).mean(axis=0))
    law = np.asarray(pred["law_nt"])
    print(f"law true {true_law.round(3)} predicted {law.round(3)}")
    assert np.all(true_law <= UNSEEN_OVER_PREDICTED * law), (true_law, law)
    # the fault fixed: before, the law's part was ~0.01 nT (the resamples could not move
    # the segments beyond the data); the held widths are not negligible now
    assert np.all(law > 0.1), law
    # the whole day through the pipeline against the total prediction
    folder = tmp_path / "fitted"
    write_calibration_folder(res, folder, None, {"inputs": {}, "intervals": "all data",
                                                 "days": "2 simulated cold days"},
                             study=not res.convergence["converged"])
    header = next(folder.glob("offsets_temperature_v*.csv")).read_text()
    assert "x: upper segment (eq. 3b) held: no accepted interval determines it" in header
    unseen_rms = recalibrate_rms(unseen.input_dir, day, folder)
    total = np.asarray(pred["total_nt"])
    print(f"unseen day {unseen_rms.round(3)} predicted {total.round(3)}")
    assert np.all(unseen_rms <= UNSEEN_OVER_PREDICTED * total), (unseen_rms, total)
    # and a goal of 0.1 nT refuses it, naming the held segments
    res.merit = {**res.merit, **pred}
    with pytest.raises(FitRefusedError, match=r"the temperature law [\d.]+ nT \(upper "
                                              r"segment x, y, z held at the table"):
        fit_merit.check_merit(res)
