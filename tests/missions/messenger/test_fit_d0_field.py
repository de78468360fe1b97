"""D0's error along the field's mean direction (issue 34 item 2; messenger_fit.md entry 28).

The variance estimator determines an offset along the mean field only through the
rotations; fitted on a field that keeps one sense (polarity) while the heater regulates,
D0's projection on that direction comes out biased by about 2 of its bootstrap errors
(the heater waveforms are fitted once, from the same data, so no resample sees it).
The fit states the measured part: `fit_variance.widen_d0_along_field`, scaled by the
field's one-sidedness `fit_variance.d0_field_balance`.
"""

from __future__ import annotations

import numpy as np
import pytest

from fluxcal.missions.messenger import fit_breaks as fb
from fluxcal.missions.messenger import fit_variance as fv

#: Eq. 8's fine-range matrix, seed Table 4 gains with small cross terms (nT per count).
MATRIX = np.array([[0.046769, 0.0, 0.0], [0.0002, 0.046673, 0.0], [-0.0001, 0.0003, 0.047997]])
PARKER = np.array([0.55, -0.6, 0.58]) / np.linalg.norm([0.55, -0.6, 0.58])


def _stats(blocks: list[tuple[np.ndarray, float]], first: int = 0) -> fv.VarianceStatistics:
    """Statistics whose blocks hold only ``field_sum`` ``(sum w^2 R^2 u, sum w^2 R^2)``."""
    nb, p = len(blocks), fb.N_PARAMETERS
    return fv.VarianceStatistics(
        normal=np.zeros((nb, p, p)), rhs=np.zeros((nb, p)), yy=np.zeros(nb),
        samples=np.zeros(nb), block_start=(first + np.arange(nb)) * 7200.0,
        field_sum=np.array([[*(np.asarray(u) * wt), wt] for u, wt in blocks]))


@pytest.mark.parametrize("share", [1.0, 0.75, 0.5, 0.2, 0.0])
def test_balance_is_the_weighted_mean_of_the_field_direction(share):
    # closed form: a share s of the information with the field along +p, 1 - s along -p:
    # the mean direction is (2 s - 1) p, its length |2 s - 1|
    stats = _stats([(PARKER, 3.0 * share), (-PARKER, 3.0 * (1 - share)),
                    (PARKER, 1.0 * share), (-PARKER, 1.0 * (1 - share))])
    direction, balance = fv.d0_field_balance(stats)
    assert balance == pytest.approx(abs(2 * share - 1), abs=1e-12)
    if balance > 0:
        assert direction == pytest.approx(np.sign(2 * share - 1) * PARKER, abs=1e-12)


def test_balance_merges_per_block_and_is_zero_without_information():
    # two days' reductions: a block of each day, and one block both days touch (summed)
    a = _stats([(PARKER, 2.0), (-PARKER, 1.0)])
    b = _stats([(-PARKER, 1.0), (PARKER, 4.0)], first=1)
    merged = a.merge(b)
    assert merged.field_sum.shape == (3, 4)
    assert merged.field_sum[1] == pytest.approx([*(-2.0 * PARKER), 2.0])
    direction, balance = fv.d0_field_balance(merged)
    assert balance == pytest.approx(4.0 / 8.0)  # (2 - 1 - 1 + 4) p / 8
    assert direction == pytest.approx(PARKER)
    assert fv.d0_field_balance(fv.VarianceStatistics()) == (pytest.approx(np.zeros(3)), 0.0)
    # statistics reduced without the sums (older pickles, constructed tests): zeros
    bare = _stats([(PARKER, 1.0)], first=5)
    bare.field_sum = np.zeros((0, 4))
    assert fv.d0_field_balance(a.merge(bare))[1] == pytest.approx(1.0 / 3.0)


@pytest.mark.parametrize("balance", [1.0, 0.5, 0.0])
def test_widening_adds_the_stated_spread_along_the_field_only(balance):
    # resamples with a known covariance (counts/ppt): along the field (nT) the spread
    # becomes sqrt(s^2 + (k b s)^2), s the resamples' own; across it nothing changes
    rng = np.random.default_rng(5)
    d0 = np.array([0.24, 0.23, 0.024])
    b_d0 = d0 + rng.standard_normal((4000, 3)) * np.array([2e-3, 3e-3, 2.5e-3])
    free = np.array([True, True, True])
    out, along, added = fv.widen_d0_along_field(b_d0, d0, MATRIX, PARKER, balance, free)
    par = lambda x: ((x - d0) @ MATRIX.T) @ PARKER  # noqa: E731
    s = np.sqrt(np.mean(par(b_d0) ** 2))
    assert along == pytest.approx(s, rel=1e-12)
    assert added == pytest.approx(fv.D0_FIELD_BIAS_SIGMA * balance * s, rel=1e-12)
    # the draws are independent of the resamples: the variances add (4000 draws: 5 %)
    assert np.sqrt(np.mean(par(out) ** 2)) == pytest.approx(np.hypot(s, added), rel=0.05)
    # exactly along the field: the perpendicular parts are the resamples' own
    perp = lambda x: ((x - d0) @ MATRIX.T) - np.outer(par(x), PARKER)  # noqa: E731
    assert perp(out) == pytest.approx(perp(b_d0), abs=1e-12)
    if balance == 0.0:
        assert np.array_equal(out, b_d0)


def test_widening_leaves_a_held_axis_alone():
    rng = np.random.default_rng(6)
    d0 = np.array([0.24, 0.23, 0.024])
    b_d0 = d0 + rng.standard_normal((500, 3)) * 2e-3
    b_d0[:, 2] = 0.02 + rng.standard_normal(500) * 0.01  # held z: its own width's draws
    out, _, added = fv.widen_d0_along_field(b_d0, d0, MATRIX, PARKER, 1.0,
                                            np.array([True, True, False]))
    assert added > 0
    assert np.array_equal(out[:, 2], b_d0[:, 2])
    assert not np.array_equal(out[:, :2], b_d0[:, :2])


@pytest.mark.slow
def test_one_sided_field_states_d0_along_it_honestly(tmp_path):
    """Forward model (issue 34's Mercury orbit, `_hard_worlds`, one wind sector): the
    field is one-sided, the widening is on, and D0's error along the field lies within
    1.5 of its stated error there.  While the regressors' direction carried the fitted
    heater waveforms' error this seed's error there was 1.89 of the bootstrap's (10
    realisations: 1.85 +- 0.19, verification section 21), 1.7 of the stated error with
    the residual widening of 0.5 x b: the test fails for that cause.  Since entry 31 it
    is 0.02 of the bootstrap's."""
    from fluxcal.missions.messenger import forward
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
    from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
    from tests.missions.messenger._hard_worlds import MercuryOrbit

    orbit = MercuryOrbit(3400)
    run = simulate_flight(tmp_path / "sim", FlightConfig(start="2010-03-01", days=2, seed=3400),
                          wind=orbit.field, schedule=orbit.schedule, truth=True)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    res = fit_days(day_chunks(run.input_dir, run.days), load_calibration("2010-03-01"),
                   estimator="variance", guard=False)
    info = res.d0_field
    direction = np.asarray(info["direction"])
    assert info["balance"] > 0.9  # one sector: the field kept its sense
    assert abs(direction @ PARKER) > 0.9  # the wind's direction (`_hard_worlds.PARKER`)
    assert info["added_nt_per_ppt"] == pytest.approx(
        fv.D0_FIELD_BIAS_SIGMA * info["balance"] * info["along_nt_per_ppt"])
    m = np.asarray(res.calibration.matrices[0], dtype=float)
    err = m @ (np.asarray(res.calibration.duty_cycle_d0) - true.d0)
    stated = np.std((res.bootstrap["d0"] @ m.T) @ direction)
    # in quadrature in expectation: 200 resamples leave a sample correlation of the draws
    # with them of about 1 / sqrt(200), 10 % on the sum
    assert stated == pytest.approx(np.hypot(info["along_nt_per_ppt"],
                                            info["added_nt_per_ppt"]), rel=0.1)
    assert abs(err @ direction) < 1.5 * stated, (err @ direction / stated)
    pulls = (np.asarray(res.calibration.duty_cycle_d0) - true.d0) / np.array(
        [f.slope_err for f in res.duty])
    assert np.all(np.abs(pulls) < 2.5), pulls
