"""A batch day is redone when anything its products were made with changed (issue 32).

The manifest key: the inputs' and the calibration's SHA-256, the options that change a
product and the software version.  Before this test was written, a rerun with another
``--formats``, ``--calib`` or averaging interval marked every day "up to date" and kept
the stale products.  Each case changes one part of the key and expects the day redone
(with the reason naming what changed); an identical rerun skips it.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
from pathlib import Path

import pytest

from fluxcal.cli import main
from fluxcal.runs import batch, manifest
from fluxcal.runs.batch import run_batch, stale_reason, task_settings
from fluxcal.runs.synthetic_task import SyntheticDayTask, write_synthetic_inputs

DAY = dt.date(2024, 3, 1)


def _day(out: Path, name: str) -> dict:
    (day,) = json.loads((out / f"batch_report_{name}.json").read_text())["days"]
    return day


def _synthetic(inp: Path, out: Path, *extra: str) -> dict:
    assert main(["batch", "synthetic", "--start", DAY.isoformat(), "--end", DAY.isoformat(),
                 "--input", str(inp), "--out", str(out), "--scheduler", "serial", "--quiet",
                 *extra]) == 0
    return _day(out, "synthetic")


def test_synthetic_rerun_with_changed_formats_redoes_the_day(tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, [DAY], n_per_day=20)
    first = _synthetic(inp, out, "--formats", "tab,cdf")
    assert first["status"] == "done" and first["reason"].startswith("no manifest")
    same = _synthetic(inp, out, "--formats", "tab,cdf")
    assert (same["status"], same["reason"]) == ("skipped", "up to date")
    changed = _synthetic(inp, out, "--formats", "cdf,nc")
    assert changed["status"] == "done"
    assert changed["reason"] == 'option formats ["tab", "cdf"] -> ["cdf", "nc"]'
    assert (out / "SYNTH_20240301.nc").is_file()  # the product the new option asks for
    assert "option formats" in (out / "index.html").read_text()  # the folder's report says why
    # an option that changes no product (a test delay) keeps the day
    assert _synthetic(inp, out, "--formats", "cdf,nc", "--delay", "0.01")["status"] == "skipped"
    # the calibration's content is part of the key
    (inp / "synthetic_calib.txt").write_text("offset = 0 0 0\ngain = 0.05\n")
    recal = _synthetic(inp, out, "--formats", "cdf,nc")
    assert recal["status"] == "done"
    assert recal["reason"] == "input calibration:synthetic_calib changed"


def test_software_version_and_missing_product_redo(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, [DAY], n_per_day=20)
    task = SyntheticDayTask(inp, out, formats=("cdf",))
    assert run_batch([DAY], task, out, scheduler="serial").days[0].status == "done"
    assert stale_reason(task, DAY, out, "synthetic") is None
    monkeypatch.setattr(manifest, "software_version", lambda: "99.0")
    assert stale_reason(task, DAY, out, "synthetic").endswith("-> 99.0")
    monkeypatch.undo()
    (out / "SYNTH_20240301_v01.cdf").unlink()
    assert stale_reason(task, DAY, out, "synthetic") == "product SYNTH_20240301_v01.cdf missing"


def test_manifest_of_an_older_fluxcal_without_options_is_redone(tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "out"
    write_synthetic_inputs(inp, [DAY], n_per_day=20)
    task = SyntheticDayTask(inp, out, formats=("cdf",))
    run_batch([DAY], task, out, scheduler="serial")
    path = batch.manifest_path(out, "synthetic", DAY)
    man = json.loads(path.read_text())
    assert man["settings"] == {"formats": ["cdf"], "quicklook": False}
    del man["settings"]
    path.write_text(json.dumps(man))
    assert "older fluxcal" in stale_reason(task, DAY, out, "synthetic")


def test_path_options_are_keyed_by_content_not_by_folder(tmp_path: Path) -> None:
    """A calibration folder is recorded by its files' checksums: no path of this machine."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    (a / "cal_v1.txt").write_text("1\n")
    shutil.copytree(a, b)

    class Task:
        def __init__(self, calib: Path) -> None:
            self.calib = calib

        def settings(self) -> dict:
            return {"calib": self.calib}

    key_a, key_b = task_settings(Task(a)), task_settings(Task(b))
    assert key_a == key_b and str(tmp_path) not in json.dumps(key_a)
    (b / "cal_v1.txt").write_text("2\n")
    assert task_settings(Task(b)) != key_a


def _changed_value(f, value, tmp_path: Path):
    """A different valid value of option field ``f`` (from its type and choices)."""
    choices = f.metadata.get("choices")
    if isinstance(value, bool):
        return not value
    if isinstance(value, tuple):
        pool = [c for c in (choices or ()) if c not in value]
        if pool:
            return (*value[:1], pool[0])
        return (*value, value[-1] + 1) if isinstance(value[-1], int) else value[:-1]
    if isinstance(value, (int, float)):
        return value + 1
    if choices:
        return next(c for c in choices if c != value)
    if value is None or isinstance(value, Path):
        folder = tmp_path / f"opt_{f.name}"
        folder.mkdir(exist_ok=True)
        (folder / "x.txt").write_text(f.name)
        return folder
    return f"{value}X"


def _every_option_is_in_the_key(task, day: dt.date, out: Path, name: str,
                                tmp_path: Path) -> None:
    """Each field of the task's options, changed alone, makes the day stale, by name."""
    import dataclasses

    assert stale_reason(task, day, out, name) is None
    for f in dataclasses.fields(task.options):
        value = _changed_value(f, getattr(task.options, f.name), tmp_path)
        other = dataclasses.replace(task, options=dataclasses.replace(task.options,
                                                                      **{f.name: value}))
        reason = stale_reason(other, day, out, name)
        # a calibration folder's files are also the day's inputs: they may say it first
        named = reason is not None and (reason.startswith(f"option {f.name} ") or (
            f.name == "calib" and "calibration:" in reason))
        assert named, (f.name, reason)


# --- Rosetta (short simulated day: the forward model, 2 minutes per sensor) ---------------

ROSETTA_DAY = dt.date(2014, 11, 1)


@pytest.fixture(scope="module")
def rosetta_sim(tmp_path_factory):
    from fluxcal.missions.rosetta.batch_task import simulate_days

    root = tmp_path_factory.mktemp("rosetta_key_in")
    simulate_days(root, [ROSETTA_DAY], minutes=2.0, seed=5)
    return root


def _rosetta(inp: Path, out: Path, *extra: str) -> dict:
    assert main(["batch", "rosetta", "--start", ROSETTA_DAY.isoformat(), "--end",
                 ROSETTA_DAY.isoformat(), "--input", str(inp), "--out", str(out),
                 "--scheduler", "serial", "--quiet", *extra]) == 0
    return _day(out, "rosetta")


def test_rosetta_rerun_with_changed_options_or_calib_redoes_the_day(rosetta_sim,
                                                                   tmp_path: Path) -> None:
    out = tmp_path / "out"
    base = ("--levels", "A,B", "--formats", "cdf")
    assert _rosetta(rosetta_sim, out, *base)["status"] == "done"
    assert _rosetta(rosetta_sim, out, *base)["reason"] == "up to date"
    # formats
    redo = _rosetta(rosetta_sim, out, "--levels", "A,B", "--formats", "tab")
    assert (redo["status"], redo["reason"]) == ("done", 'option formats ["cdf"] -> ["tab"]')
    assert list(out.rglob("*.TAB"))
    # a --calib folder with the same files as the default one is the same key ...
    calib = tmp_path / "calib"
    shutil.copytree(rosetta_sim / "calib", calib)
    same = _rosetta(rosetta_sim, out, "--levels", "A,B", "--formats", "tab", "--calib",
                    str(calib))
    assert same["status"] == "skipped"
    # ... one with a changed file is not
    align = calib / "RPCMAG_SC_ALIGN.TXT"
    align.write_text(align.read_text() + "\n")
    changed = _rosetta(rosetta_sim, out, "--levels", "A,B", "--formats", "tab", "--calib",
                       str(calib))
    assert changed["status"] == "done" and "RPCMAG_SC_ALIGN.TXT" in changed["reason"]
    # the averaging interval (a product option of levels E, F, G)
    avg = _rosetta(rosetta_sim, out, "--levels", "A,B", "--formats", "tab", "--calib",
                   str(calib), "--average", "2")
    assert (avg["status"], avg["reason"]) == ("done", "option average_s 1.0 -> 2.0")
    # and every other option of RosettaOptions, one at a time (no rerun needed to see it)
    from fluxcal.missions.rosetta.routes import make_day_task

    task = make_day_task(rosetta_sim, out, levels="A,B", formats=("tab",), calib=calib,
                         average_s=2.0)
    _every_option_is_in_the_key(task, ROSETTA_DAY, out, "rosetta", tmp_path)


# --- MESSENGER (one short simulated day at 1 vector/s) ------------------------------------

def test_messenger_rerun_with_changed_options_redoes_the_day(tmp_path: Path) -> None:
    from fluxcal.missions.messenger.batch_task import make_day_task, simulate_days

    day = dt.date(2012, 6, 1)
    inp, out = tmp_path / "in", tmp_path / "out"
    simulate_days(inp, [day], seconds_per_day=300.0, rate_setting=6)
    opts = {"formats": ("tab",), "frames": ("mso",), "averages": (60,)}

    def run(**changes) -> batch.DayStatus:
        task = make_day_task(inp, out, **{**opts, **changes})
        (status,) = run_batch([day], task, out, scheduler="serial").days
        return status

    assert run().status == "done"
    again = run()
    assert (again.status, again.reason) == ("skipped", "up to date")
    frames = run(frames=("mso", "sc"))
    assert (frames.status, frames.reason) == ("done", 'option frames ["mso"] -> ["mso", "sc"]')
    assert (out / "MAGSCSCI12153_V01.TAB").is_file()
    step = run(frames=("mso", "sc"), max_offset_step=3.0)
    assert (step.status, step.reason) == ("done", "option max_offset_step 2.0 -> 3.0")
    # and every other option of MessengerOptions, one at a time
    task = make_day_task(inp, out, **{**opts, "frames": ("mso", "sc"), "max_offset_step": 3.0})
    _every_option_is_in_the_key(task, day, out, "messenger", tmp_path)


# --- a plugin's own task (the toy mission: a dataclass task, no settings()) ------------------

def test_plugin_dataclass_task_rerun_with_changed_gain_redoes_the_day(tmp_path: Path) -> None:
    """A dataclass task without ``settings()`` is keyed on its fields (gain, formats)."""
    import cdflib
    import numpy as np

    from tests.runs.toy_mission import make_day_task, simulate_days

    day = dt.date(2024, 1, 1)
    inp, out = tmp_path / "in", tmp_path / "out"
    simulate_days(inp, [day])

    def run(gain: float) -> batch.DayStatus:
        (status,) = run_batch([day], make_day_task(inp, out, gain=gain), out,
                              scheduler="serial", name="toy").days
        return status

    assert run(0.5).status == "done"
    assert run(0.5).reason == "up to date"
    redo = run(0.25)
    assert (redo.status, redo.reason) == ("done", "option gain 0.5 -> 0.25")
    # counts 2, 4, 6 (simulate_days) at 0.25 nT/count
    b = cdflib.CDF(str(out / "TOY_20240101.cdf")).varget("B")
    np.testing.assert_array_equal(b[0], [0.5, 1.0, 1.5])
