"""A mission registered from the test folder runs through the CLI, batch and demo.

The toy mission (``tests/runs/toy_mission.py``) is added with ``FLUXCAL_MISSIONS``;
no generic file of fluxcal is edited.  Expected values: counts (2, 4, 6) at a gain of
0.5 nT/count are (1, 2, 3) nT (at 0.25: half that), computed by hand.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import cdflib
import numpy as np
import pytest

import fluxcal.cli
from fluxcal.cli import build_app, main
from fluxcal.runs import demo, registry

TOY = "tests.runs.toy_mission:MISSION"


@pytest.fixture
def toy_cli(monkeypatch):
    monkeypatch.setenv(registry.ENV, TOY)
    monkeypatch.setattr(fluxcal.cli, "app", build_app())
    return registry.get("toy")


def _field(path: Path) -> np.ndarray:
    return np.asarray(cdflib.CDF(str(path)).varget("B"))


def test_toy_is_registered_beside_the_builtin_missions(toy_cli) -> None:
    names = set(registry.missions())
    assert {"toy", "messenger", "rosetta", "synthetic"} <= names


def test_toy_single_run_takes_its_options_dataclass(toy_cli, tmp_path: Path) -> None:
    from tests.runs.toy_mission import simulate_days

    simulate_days(tmp_path / "in", [dt.date(2024, 1, 1)])
    src = tmp_path / "in" / "TOY_20240101.csv"
    assert main(["toy", "calibrate", "--input", str(src), "--out", str(tmp_path / "o"),
                 "--gain", "0.25"]) == 0
    np.testing.assert_array_equal(_field(tmp_path / "o" / "TOY_20240101.cdf")[0],
                                  [0.5, 1.0, 1.5])


def test_toy_batch_takes_the_same_options(toy_cli, tmp_path: Path, capsys) -> None:
    from tests.runs.toy_mission import simulate_days

    days = [dt.date(2024, 1, 1), dt.date(2024, 1, 2)]
    simulate_days(tmp_path / "in", days)
    args = ["batch", "toy", "--start", "2024-01-01", "--end", "2024-01-03", "--input",
            str(tmp_path / "in"), "--out", str(tmp_path / "o"), "--scheduler", "serial",
            "--quiet"]
    assert main([*args, "--formats", "cdf,nc"]) == 0
    report = json.loads((tmp_path / "o" / "batch_report_toy.json").read_text())
    assert report["counts"] == {"done": 2, "skipped": 0, "no_data": 1, "failed": 0}
    np.testing.assert_array_equal(_field(tmp_path / "o" / "TOY_20240102.cdf")[-1], [1, 2, 3])
    assert (tmp_path / "o" / "TOY_20240102.nc").exists()
    # an option value outside the dataclass's choices: one line, exit 2, before any day
    assert main([*args, "--formats", "tab", "--force"]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("fluxcal: error:") and "--formats" in line \
        and "unknown value tab" in line


def test_toy_demo_part_is_in_the_tour(toy_cli, tmp_path: Path, monkeypatch) -> None:
    assert "Toy mission" in [p.title for p in demo.parts()]
    toy = registry.get("toy")
    monkeypatch.setattr(registry, "missions", lambda: {"toy": toy})  # a tour of toy alone
    assert main(["demo", "--full", "--out", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "toy" / "products" / "TOY_20240101.cdf").exists()
    report = tmp_path / "d" / "batch" / "toy" / "products" / "batch_report_toy.json"
    assert json.loads(report.read_text())["counts"]["skipped"] == 2  # the demo's rerun
    assert len(list(report.parent.glob("TOY_*.cdf"))) == 2


def test_quick_demo_runs_the_quick_parts_only(toy_cli, tmp_path: Path, monkeypatch) -> None:
    """``fluxcal demo``: the quick parts, each run's report and an overview linking them."""
    assert [p.title for p in demo.parts(full=False) if "Toy" in p.title] == ["Toy first run"]
    toy = registry.get("toy")
    monkeypatch.setattr(registry, "missions", lambda: {"toy": toy})
    assert main(["demo", "--out", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "toy" / "products" / "TOY_20240101.cdf").exists()
    assert (tmp_path / "d" / "toy" / "products" / "index.html").exists()
    assert not (tmp_path / "d" / "batch").exists()  # the batch part is the full tour's
    overview = (tmp_path / "d" / "index.html").read_text()
    assert 'href="toy/products/index.html"' in overview


def test_unknown_mission_names_the_registry(tmp_path: Path) -> None:
    from fluxcal.errors import FluxcalError

    with pytest.raises(FluxcalError, match="fluxcal.missions.*known: .*messenger"):
        registry.get("voyager")
