"""A broken or misspelled mission plugin does not stop the others (issue 32).

Before: one entry point of ``fluxcal.missions`` whose module did not import stopped every
command, ``fluxcal --help`` included, with a traceback at start-up, and the entry points
were scanned again on every lookup.  Now the broken plugin is a warning naming it and is
skipped; asking for it is one error naming the group, the name and what failed.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

import fluxcal.cli
from fluxcal.cli import build_app, main
from fluxcal.errors import FluxcalError
from fluxcal.runs import registry

BROKEN = EntryPoint("brokenmission", "fluxcal_no_such_plugin.mission:MISSION",
                    registry.GROUP)


@pytest.fixture
def fake_entry_points(monkeypatch):
    """Add entry points to the installed ones; count the scans."""
    real = registry.entry_points
    calls = []

    def install(*extra: EntryPoint) -> list:
        def fake(group: str):
            calls.append(group)
            return [*real(group=group), *extra]

        monkeypatch.setattr(registry, "entry_points", fake)
        registry.rescan()
        return calls

    yield install
    monkeypatch.undo()
    registry.rescan()


def test_broken_plugin_is_a_warning_and_skipped(fake_entry_points) -> None:
    fake_entry_points(BROKEN)
    with pytest.warns(registry.PluginWarning, match="brokenmission") as record:
        found = registry.missions()
    assert {"messenger", "rosetta", "imap", "synthetic"} <= set(found)
    assert "brokenmission" not in found
    (message,) = {str(w.message) for w in record}
    assert "fluxcal.missions" in message and "fluxcal_no_such_plugin" in message
    assert "module fluxcal_no_such_plugin.mission not found" in message


def test_asking_for_a_broken_plugin_names_group_and_name(fake_entry_points) -> None:
    fake_entry_points(BROKEN)
    with pytest.raises(FluxcalError, match=r"brokenmission = fluxcal_no_such_plugin"
                                           r".*group fluxcal\.missions.*failed to load"):
        registry.get("brokenmission")
    with pytest.raises(FluxcalError, match="no mission 'other'.*failed to load: brokenmission"):
        registry.get("other")
    assert registry.get("messenger").name == "messenger"


def test_entry_points_are_scanned_once_per_process(fake_entry_points) -> None:
    calls = fake_entry_points()
    for _ in range(3):
        registry.missions()
        registry.get("rosetta")
    registry.frame_kernels()
    registry.archived_readers()
    assert calls == [registry.GROUP]


def test_misnamed_and_duplicate_plugins_are_refused_not_guessed(fake_entry_points) -> None:
    wrong = EntryPoint("toyish", "tests.runs.toy_mission:MISSION", registry.GROUP)
    twin = EntryPoint("rosetta", "fluxcal.runs.synthetic:MISSION", registry.GROUP)
    fake_entry_points(wrong, twin)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", registry.PluginWarning)
        found = registry.missions()
    assert "toyish" not in found and "toy" not in found
    assert "synthetic" in found and "rosetta" in found
    with pytest.raises(FluxcalError, match="calls itself 'toy'"):
        registry.get("toyish")


def test_cli_works_and_refuses_the_broken_plugin(fake_entry_points, monkeypatch,
                                                 capsys) -> None:
    fake_entry_points(BROKEN)
    monkeypatch.setattr(fluxcal.cli, "app", build_app())
    assert main(["version"]) == 0
    err = capsys.readouterr().err
    assert err.count("fluxcal: warning:") == 1 and "brokenmission" in err
    assert main(["-q", "version"]) == 0
    assert "warning" not in capsys.readouterr().err
    for args in (["brokenmission", "calibrate", "--input", "x"],
                 ["batch", "brokenmission", "--start", "2024-01-01"]):
        assert main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith("fluxcal: error: mission plugin entry point brokenmission")
        assert "group fluxcal.missions" in err


def test_help_with_a_broken_plugin_installed(tmp_path: Path) -> None:
    """A real installed distribution (a dist-info on the path) whose module is misspelled."""
    dist = tmp_path / "broken_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\n"
                                   "Version: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[fluxcal.missions]\nbrokenmission = broken_plugin.misssion:MISSION\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(tmp_path), *[p for p in sys.path if p.endswith("src")]])}
    done = subprocess.run([sys.executable, "-c", "import sys, fluxcal.cli; "
                           "sys.exit(fluxcal.cli.main(['--help']))"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "Commands:" in done.stdout and "brokenmission" not in done.stdout
    assert "Traceback" not in done.stderr
    (line,) = [x for x in done.stderr.splitlines() if x.strip()]
    assert line.startswith("fluxcal: warning: mission plugin entry point brokenmission = "
                           "broken_plugin.misssion:MISSION (group fluxcal.missions) failed")


def test_plugin_module_that_raises_on_import(fake_entry_points, monkeypatch,
                                             tmp_path: Path) -> None:
    (tmp_path / "fluxcal_raising_plugin.py").write_text("raise RuntimeError('boom')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    fake_entry_points(EntryPoint("raising", "fluxcal_raising_plugin:MISSION", registry.GROUP))
    with pytest.warns(registry.PluginWarning, match="raising.*RuntimeError: boom"):
        assert "raising" not in registry.missions()
    with pytest.raises(FluxcalError, match="RuntimeError: boom"):
        registry.get("raising")
