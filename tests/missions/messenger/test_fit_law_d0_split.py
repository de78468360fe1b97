"""The law at -50 C and D0 apart in a compressive wind: the split's widening (issue 34).

docs/decisions/messenger_fit.md entry 52.  Closed form: resamples built from the
columns of a Hadamard matrix (mean zero, orthogonal, unit mean square), so every mean,
variance and covariance of the constructed resamples is exact, and the widening's draws,
orthogonal to them by construction, add exactly their stated variance.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import hadamard

from fluxcal.missions.messenger import fit_variance as fv

N = 64
T_REF = -50.0
H = hadamard(N).astype(float)


def _resamples(sigma=(2e-3, 1e-3, 3e-3), r=(250.0, 300.0, 280.0), eps=(0.5, 0.8, 0.3),
               kappa=(0.02, -0.01, 0.0)):
    """Laws and D0 per axis: D0 = d0 + sigma h1; the slope b0 + kappa h1; the intercept
    traded so that the law at T_REF moves by -R sigma h1, plus eps h2 of its own; the
    upper segment c with a trade of its own, 0.3 h1; T_m fixed."""
    law = np.zeros((N, 3, 4))
    d0 = np.array([0.24, 0.23, 0.024])
    b_d0 = np.tile(d0, (N, 1))
    for j in range(3):
        s, k = sigma[j], kappa[j]
        alpha = -r[j] * s - k * sigma[j] * T_REF
        law[:, j, 0] = 10.0 + alpha * H[:, 1] + eps[j] * H[:, 2 + j]
        law[:, j, 1] = 0.5 + k * sigma[j] * H[:, 1]
        law[:, j, 2] = 1.3 + 0.3 * H[:, 1]
        law[:, j, 3] = -10.0
        b_d0[:, j] += s * H[:, 1]
    return law, b_d0


@pytest.mark.parametrize("free", [(True, True, True), (True, False, True)])
def test_split_widening_adds_the_traded_share_and_keeps_the_sum(free):
    """D0 widens by sqrt(1 + (lambda rho)^2), the law at T_REF by the trade (beta_L = -R)
    times the same draws, the sum L + R D0 not at all; a held D0 axis is untouched."""
    sigma, r, eps, kappa = (2e-3, 1e-3, 3e-3), (250.0, 300.0, 280.0), (0.5, 0.8, 0.3), \
        (0.02, -0.01, 0.0)
    law, b_d0 = _resamples(sigma, r, eps, kappa)
    free = np.array(free)
    out_law, out_d0, info = fv.widen_law_d0_split(law, b_d0, T_REF, free,
                                                  np.array([True, True, True]))
    lam = fv.LAW_D0_SPLIT_WIDENING
    for j in range(3):
        s, big_r, e = sigma[j], r[j], eps[j]
        if not free[j]:
            assert np.array_equal(out_d0[:, j], b_d0[:, j])
            assert np.array_equal(out_law[:, j], law[:, j])
            assert info["added_counts_per_ppt"][j] == 0.0
            continue
        # closed form: var(L) = (R s)^2 + e^2, cov(L, D0) = -R s^2
        rho = -big_r * s / np.hypot(big_r * s, e)
        added = lam * abs(rho) * s
        assert info["rho"][j] == pytest.approx(rho, rel=1e-9)
        assert info["added_counts_per_ppt"][j] == pytest.approx(added, rel=1e-9)
        assert np.std(out_d0[:, j]) == pytest.approx(s * np.sqrt(1 + (lam * rho) ** 2),
                                                     rel=1e-9)
        assert out_d0[:, j].mean() == pytest.approx(b_d0[:, j].mean(), abs=1e-15)
        at = fv.law_values(out_law, np.array([T_REF]))[:, 0, j]
        assert np.std(at) == pytest.approx(
            np.sqrt((big_r * s) ** 2 + e ** 2 + (big_r * added) ** 2), rel=1e-9)
        assert np.std(at + big_r * out_d0[:, j]) == pytest.approx(e, rel=1e-9)
        # at a warmer temperature below the break the law tilts with the slope's trade:
        # it moves by (alpha + kappa sigma T) / sigma per unit of the draws
        t = -20.0
        alpha = -big_r * s - kappa[j] * s * T_REF
        move = (alpha + kappa[j] * s * t) / s
        at_t = fv.law_values(out_law, np.array([t]))[:, 0, j]
        assert np.std(at_t) == pytest.approx(
            np.sqrt((move * s) ** 2 + e ** 2 + (move * added) ** 2), rel=1e-9)
        # the upper segment's slope change follows its own trade (0.3 per sigma), T_m not
        assert np.std(out_law[:, j, 2]) == pytest.approx(0.3 * np.sqrt(1 + (added / s) ** 2),
                                                         rel=1e-9)
        assert np.array_equal(out_law[:, j, 3], law[:, j, 3])


def test_split_widening_leaves_a_held_upper_segment_and_an_untraded_axis_alone():
    """A held upper segment keeps its c draws; an axis whose law does not trade with
    D0 (rho = 0) gains nothing; without resamples' spread nothing moves."""
    law, b_d0 = _resamples()
    law[:, 1, 0] = 10.0 + 0.8 * H[:, 3]  # y's law independent of its D0
    law[:, 1, 1] = 0.5
    out_law, out_d0, info = fv.widen_law_d0_split(law, b_d0, T_REF, np.ones(3, bool),
                                                  np.array([False, True, True]))
    assert np.array_equal(out_law[:, 0, 2], law[:, 0, 2])       # x held upper: c kept
    assert not np.array_equal(out_law[:, 0, 0], law[:, 0, 0])   # its intercept traded
    assert info["rho"][1] == pytest.approx(0.0, abs=1e-12)
    assert info["added_counts_per_ppt"][1] == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(out_d0[:, 1], b_d0[:, 1], rtol=0, atol=1e-15)
    flat = np.tile(law[:1], (N, 1, 1))
    same_law, same_d0, none = fv.widen_law_d0_split(flat, np.tile(b_d0[:1], (N, 1)), T_REF,
                                                    np.ones(3, bool), np.ones(3, bool))
    assert np.array_equal(same_law, flat)
    assert none["added_counts_per_ppt"] == [0.0, 0.0, 0.0]


@pytest.mark.slow
def test_compressive_cruise_states_the_law_and_d0_apart_honestly(tmp_path):
    """Forward model (issue 34's hard cruise wind, 5 % compressive, `_hard_worlds`; 4
    days, seed 3603, 28 % of the intervals compressive): the split is widened, the
    header says so, and the law at -50 C and D0 each lie within 2.7 of their stated
    errors on every axis (with it: law y 2.44, D0 y 1.75).  Without the widening
    (`LAW_D0_SPLIT_WIDENING` = 0) this seed's law y is 2.98 of its band off at -50 C
    (verification section 46): the test fails for that cause (checked); 2.7 sits
    between the two.  The truth is the forward
    model's Table 2 and 3, the law at -50 C in closed form (eq. 3a, below every break)."""
    import functools

    from fluxcal.missions.messenger import forward
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
    from fluxcal.missions.messenger.fit_write import d0_field_lines
    from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
    from tests.missions.messenger._hard_worlds import cruise_hard_wind

    # five days simulated, four fitted: the pulls harness's world (`--unseen`)
    run = simulate_flight(tmp_path / "sim", FlightConfig(start="2010-03-01", days=5, seed=3603),
                          wind=functools.partial(cruise_hard_wind, compressive=0.05),
                          truth=True)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    res = fit_days(day_chunks(run.input_dir, run.days[:4]), load_calibration("2010-03-01"),
                   passes=12, estimator="variance", guard=False)
    split = res.d0_field["law_d0_split"]
    assert all(r < -0.5 for r in split["rho"]), split  # the heater pins the sum
    assert any("traded with the law at -50 C" in line for line in d0_field_lines(res))
    coeff = np.asarray(res.calibration.temperature_coefficients, dtype=float)
    law_err = (coeff[:, 0] + coeff[:, 1] * T_REF) - (np.asarray(true.a0) + np.asarray(true.b0)
                                                     * T_REF)
    law_pull = law_err / res.law_error(np.array([T_REF]))[0]
    d0_pull = (np.asarray(res.calibration.duty_cycle_d0) - true.d0) / np.array(
        [f.slope_err for f in res.duty])
    assert np.all(np.abs(law_pull) < 2.7), law_pull
    assert np.all(np.abs(d0_pull) < 2.7), d0_pull
