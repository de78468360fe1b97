"""The pull harness's command-line verdict judges the refusal's advice as `fit_days` does.

``benchmarks/messenger_fit_pulls.py``'s `command_line_verdict` names what the command line
would print for a fit; the command line re-judges an advised ``--error-goal`` with
`fit_passes.judged_at` (the T_RANGE and the law's convergence at that goal), so the harness
must too, or it prints a goal the command line does not advise (verification section 55).
"""

from __future__ import annotations

import types

from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger.fit_passes import judged_at
from tests.missions.messenger._benchmarks import load_benchmark


def test_command_line_verdict_rejudges_the_advice_as_fit_days_does(monkeypatch):
    harness = load_benchmark("messenger_fit_pulls")
    seen = {}

    def check_merit(result, rejudge=None):
        seen["rejudge"] = rejudge
        raise FitRefusedError("predicted error above the goal")

    monkeypatch.setattr(harness.fit_merit, "check_merit", check_merit)
    monkeypatch.setattr(harness, "check_fit", lambda res: None)
    res = types.SimpleNamespace(
        variance=types.SimpleNamespace(reason={}), convergence={"converged": True})
    monkeypatch.setattr(harness.fit_merit, "compressive_refusal", lambda reason: "")
    assert harness.command_line_verdict(res) == "refused: predicted error above the goal"
    assert seen["rejudge"] is judged_at
