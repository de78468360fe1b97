"""Issue 34 on forward models: a written table meets its stated errors, or the fit refuses.

The worlds are `flight_sim` streams driven by the independent test wind
(`tests/missions/messenger/_realistic_wind.py`, numpy only, written from the issue's
description), with true tables that differ from the shipped ones; the truth is read
with `forward.read_tables` and the unseen day recalibrated through the pipeline
(`_unseen_day.recalibrate_rms`).  Small on purpose (2 days at 1 Hz; the issue's 16-day,
20-realisation verification runs on a bigger machine:
``benchmarks/messenger_fit_pulls.py``, docs/decisions/messenger_fit.md entry 19).
"""

from __future__ import annotations

import functools
import re
import tomllib

import numpy as np
import pytest

from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_guards import check_fit
from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
from tests.missions.messenger._realistic_wind import realistic_wind
from tests.missions.messenger._unseen_day import recalibrate_rms

START = "2010-03-01"
#: The unseen day may exceed the predicted rms by this factor: one day is one draw, and
#: the prediction is itself estimated (bootstrap, four folds of the waveforms).
UNSEEN_OVER_PREDICTED = 1.5

pytestmark = pytest.mark.slow


def _world(path, seed, days, **wind):
    run = simulate_flight(path, FlightConfig(start=START, days=days, seed=seed),
                          wind=functools.partial(realistic_wind, **wind), truth=True)
    true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
    return run, true


@pytest.fixture(scope="module")
def calm(tmp_path_factory):
    """2 fitted days and an unseen one of the issue-21 wind (3 % compressive, f^-2)."""
    return _world(tmp_path_factory.mktemp("calm") / "sim", 7000, 3, compressive=0.03)


def _true_breaks(true):
    return (true.a0 - true.a1) / (true.b1 - true.b0)


def test_a_pass_limit_below_convergence_is_refused_with_the_last_changes(calm):
    run, _ = calm
    with pytest.raises(FitRefusedError, match=r"^not converged after 1 passes: the last "
                                              r"changed .*\(allowed .*\); not written "
                                              r"\(converged: every parameter .*--passes 20: "
                                              r"the fit stops as soon as it converges"):
        fit_days(day_chunks(run.input_dir, run.days[:2]), load_calibration(START), passes=1,
                 estimator="variance")


def test_a_convergence_refusal_names_the_last_pass_s_other_cause(calm):
    """1 pass on 2 calm days: not converged, and beyond a 5 % goal as well (after one pass
    tau's, entry 43; converged, D0 z's, entry 38), so the refusal says more passes alone
    will not write it and names the cause `check_fit` gives its last pass."""
    run, _ = calm
    chunks = day_chunks(run.input_dir, run.days[:2])
    last = fit_days(chunks, load_calibration(START), passes=1, estimator="variance",
                    guard=False)
    assert not last.convergence["converged"]
    with pytest.raises(FitRefusedError, match=r"a relative error above the 5% goal") as judged:
        check_fit(last)
    cause = str(judged.value).split("; not written", 1)[0]
    with pytest.raises(FitRefusedError) as refused:
        fit_days(chunks, load_calibration(START), passes=1, estimator="variance")
    text = str(refused.value)
    assert text.startswith("not converged after 1 passes") and "\n" not in text
    assert text.endswith("more passes alone will not write it: " + cause + ")"), text


def test_cli_fit_writes_a_table_that_meets_its_stated_errors_or_refuses(calm, tmp_path,
                                                                       capsys):
    from fluxcal.cli import main

    run, true = calm
    out = tmp_path / "fitted"
    command = ["messenger", "fit", "--input-dir", str(run.input_dir), "--days",
               f"{run.days[0]}:{run.days[1]}", "--out", str(out)]
    rc = main(command)
    cap = capsys.readouterr()
    # 2 days do not pin D0 z to its 5 % goal (entry 38: +- 10.6 % on seed 7000): the
    # refusal advises this fit's own value and error as a hold; followed exactly, the
    # table states D0 z held with that width and must meet its stated errors like any
    hold = re.search(r"D0 z = .* above the 5% goal.* --hold-d0 (z=\S+) \(this fit's", cap.err)
    if rc == 2 and hold:
        assert not out.exists() or not any(out.iterdir())
        rc = main([*command, "--hold-d0", hold.group(1)])
        cap = capsys.readouterr()
    if rc != 0:  # a refusal names its cause in one line
        assert rc == 2 and len(cap.err.strip().splitlines()) == 1, cap.err
        assert not out.exists() or not any(out.iterdir())
        pytest.skip(f"refused: {cap.err.strip()}")
    if hold:  # the held z's width covers the truth (and is this fit's own error)
        value, width = (float(v) for v in hold.group(1)[2:].split("+-"))
        assert abs(value - true.d0[2]) <= 3.0 * width, (value, width, true.d0[2])
    report = tomllib.loads((out / "fit_report.toml").read_text())
    conv = report["convergence"]
    assert conv["converged"] and conv["passes_run"] <= 12, conv
    assert conv["stop"].startswith(f"converged after {conv['passes_run']} passes")
    assert "converged after" in cap.out and "predicted error of a recalibrated day" in cap.out
    header = next(out.glob("offsets_temperature_v*.csv")).read_text()
    assert "# fit predicted error of a recalibrated day:" in header
    assert "# fit law error band (counts, 1 sigma" in header
    predicted = np.asarray(report["merit"]["total_nt"])
    assert np.all(predicted <= 0.1), predicted
    # the prediction holds inside the range the table states (T_RANGE, entry 21)
    unseen = recalibrate_rms(run.input_dir, run.days[2], out,
                             report["temperature"]["T_RANGE"])
    print(f"{'held ' + hold.group(1) + ': ' if hold else ''}predicted "
          f"{predicted.round(3)} nT, unseen {unseen.round(3)} nT")
    assert np.all(unseen <= UNSEEN_OVER_PREDICTED * predicted), (unseen, predicted)
    # T_m: its stated error (re-chosen in every resample) covers the truth at 3 sigma
    t = report["temperature"]
    pulls = [(t[a]["Tm"] - tm) / t[a]["Tm_err"] for a, tm in zip("xyz", _true_breaks(true),
                                                                 strict=True)]
    assert all(t[a]["Tm_err"] > 0 for a in "xyz")
    assert np.all(np.abs(pulls) < 3.0), pulls


def test_holding_d0_is_refused_or_meets_its_width(calm):
    """The refusal's advice (``--hold-d0 z``) writes nothing that fails its own errors.

    Held at the shipped value (the truth differs) with the default width (half the
    value), the width enters every stated error and the predicted one: either the fit
    is refused on it, or the recalibrated day is within the predicted error.
    """
    run, true = calm
    chunks = day_chunks(run.input_dir, run.days[:2])
    res = fit_days(chunks, load_calibration(START), estimator="variance", hold_d0=("z",),
                   guard=False)
    shipped = load_calibration(START).duty_cycle_d0[2]
    assert res.duty[2].slope == shipped
    assert res.duty[2].slope_err == pytest.approx(0.5 * shipped, rel=0.2)
    from fluxcal.missions.messenger import fit_merit

    try:
        if not res.convergence["converged"]:
            raise FitRefusedError(res.convergence["stop"])
        fit_merit.check_merit(res)
    except FitRefusedError as exc:
        print(f"refused: {exc}")
        return
    from fluxcal.missions.messenger.fit_write import write_calibration_folder

    out = run.input_dir.parent / "held"
    write_calibration_folder(res, out, None, {"inputs": {}, "intervals": "all data",
                                              "days": "2", "command": "test"})
    unseen = recalibrate_rms(run.input_dir, run.days[2], out, res.stated_ranges)
    predicted = np.asarray(res.merit["total_nt"])
    assert np.all(unseen <= UNSEEN_OVER_PREDICTED * predicted), (unseen, predicted)


def test_hard_world_is_refused_naming_the_compressive_wind(tmp_path):
    # 15 % of |B| compressive down to 2 s (the hard cruise wind): most
    # intervals are rejected as compressive; the fit refuses and says so
    run, _ = _world(tmp_path / "sim", 7100, 2, compressive=0.15, broadband=True)
    with pytest.raises(FitRefusedError, match=r"rejected as compressive \(limit 50%\)"):
        fit_days(day_chunks(run.input_dir, run.days), load_calibration(START),
                 estimator="variance")
