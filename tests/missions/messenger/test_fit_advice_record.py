"""The advice harness's chain record and its tally read the own-value hold as advised.

`benchmarks/messenger_fit_advice.py --record` parses the own-value hold out of
`fit_guards.d0_goal_refusal`'s message, and `benchmarks/messenger_fit_advice_tally.py`
re-makes its width at another ``lambda`` (verification section 66).  Expected values
come from the refusal's own message built here (no fit) and the closed form
``error x sqrt(1 + (lambda rho)^2)`` rounded up to two digits (entry 60).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from fluxcal.missions.messenger import fit_guards
from tests.missions.messenger._benchmarks import load_benchmark

advice = load_benchmark("messenger_fit_advice")
tally = load_benchmark("messenger_fit_advice_tally")


def _fit(error: float, split: dict | None = None) -> SimpleNamespace:
    """A stand-in for the refused fit: D0 z's stated error and entry 52's split."""
    duty = [SimpleNamespace(slope_err=1.0), SimpleNamespace(slope_err=1.0),
            SimpleNamespace(slope_err=error)]
    return SimpleNamespace(duty=duty, d0_field={"law_d0_split": split} if split else {})


@pytest.mark.parametrize(("compressive", "rho", "factor"), [
    ((80, 384), -0.8, np.sqrt(1 + 0.8 ** 2)),   # below 25 %: entry 60's widening
    ((0, 384), 0.0, 1.0)])                       # a calm wind: the error as stated
def test_the_record_reads_the_own_value_hold_below_a_quarter(compressive, rho, factor):
    error = 0.004
    msg = fit_guards.d0_goal_refusal("z", 0.02, error, compressive=compressive,
                                     split_rho=rho)
    hold = advice.own_hold_record(msg, _fit(error))
    want = error * factor
    # the message rounds the width up to two digits: at most one step of the second
    assert hold["axis"] == "z" and hold["value"] == pytest.approx(0.02)
    assert want <= hold["width"] <= want + 1e-4 + 1e-15
    assert hold["factor"] == pytest.approx(factor, abs=5e-3)
    assert hold["rho_named"] == pytest.approx(rho, abs=5e-3)
    assert hold["fit_error"] == error and hold["split_added"] is None
    chain = {"own_hold": hold}
    # the tally's width at lambda 1 is the advised one; at lambda 0 the error rounded up
    assert tally.widths_at([chain], 1.0)[0] == pytest.approx(hold["width"])
    assert tally.widths_at([chain], 0.0)[0] == pytest.approx(error)


def test_the_record_reads_the_split_a_fit_states_above_a_quarter():
    # 100 of 384 (26 %): the own value advised unwidened, its error carrying entry 52's
    # draws (sd 0.003 added to 0.004: 0.005 stated); lambda 2 doubles the draws
    split = {"rho": [0.0, 0.0, -0.75], "added_counts_per_ppt": [0.0, 0.0, 0.003]}
    msg = fit_guards.d0_goal_refusal("z", 0.02, 0.005, compressive=(100, 384),
                                     split_stated=True)
    hold = advice.own_hold_record(msg, _fit(0.005, split))
    assert hold["width"] == pytest.approx(0.005) and hold["factor"] == 1.0
    assert hold["split_rho"] == -0.75 and hold["split_added"] == 0.003
    want = np.hypot(0.004, 0.006)  # rounded up to two digits, as the advice is
    assert want <= tally.widths_at([{"own_hold": hold}], 2.0)[0] <= want + 1e-4


def test_no_hold_is_recorded_where_the_own_value_is_not_advised():
    # above 25 % with no split stated (entry 49): only the start table's hold
    msg = fit_guards.d0_goal_refusal("z", 0.02, 0.004, compressive=(120, 384))
    assert "this fit's value" not in msg
    assert advice.own_hold_record(msg, _fit(0.004)) == {}


@pytest.mark.parametrize("x", [0.00512, 0.0049, 0.011, 0.0999, 0.1, 1.234e-5])
def test_the_tally_rounds_as_the_refusal_does(x):
    assert tally.up_to_two_digits(x) == pytest.approx(fit_guards._up_to_two_digits(x))
