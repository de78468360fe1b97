"""Second hostile round (issue 31, "Done when"): the reproducers of the cases it found.

Each test is a case that failed at the start of the round (docs/decisions/products.md,
decision 66, "second hostile round"); the expected outcomes are the issue's: exit 2
with one line ``fluxcal: error: ...``, the bytes of every file outside ``--out``
unchanged (compared with what the test itself wrote before the run), and a link the
user made as ``--out`` written into as the folder it names.
"""

from __future__ import annotations

import os

import pytest

from fluxcal.cli import main
from fluxcal.errors import FluxcalError
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.paths import LOCK_NAME, PathOutsideFolder, inside, write_scope
from fluxcal.products.staging import owned_run


def _one_error_line(capsys) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("fluxcal: error: "), lines[0]
    return lines[0]


def test_a_lock_that_is_a_hard_link_of_a_users_file_is_refused(tmp_path, capsys):
    """Before: a regular file with a second name passed as the lock: the pid overwrote it."""
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    out = tmp_path / "out"
    out.mkdir()
    os.link(victim, out / LOCK_NAME)
    assert main(["simulate", "rosetta", "--rate", "0", "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert LOCK_NAME in line and "hard link" in line
    assert victim.read_text() == "the user's own file\n"
    assert (out / LOCK_NAME).exists()  # left as it is


def test_a_users_file_named_like_the_lock_is_left_alone(tmp_path, capsys):
    """Before: a user's ``.fluxcal.lock`` (notes) was truncated to a pid, then removed."""
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).write_text("my notes on this folder\n")
    assert main(["simulate", "rosetta", "--rate", "0", "--out", str(out)]) == 2
    assert "holds no process id" in _one_error_line(capsys)
    assert (out / LOCK_NAME).read_text() == "my notes on this folder\n"


@pytest.mark.parametrize("text", ["", "4242\n", "4242"])
def test_a_stale_lock_of_a_killed_run_is_taken(tmp_path, text):
    """What a killed run leaves (its pid, or nothing) is fluxcal's: it is reused."""
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).write_text(text)
    with owned_run(out):
        atomic_write_bytes(out / "P.TAB", b"x")
    assert (out / "P.TAB").read_bytes() == b"x" and not (out / LOCK_NAME).exists()


def test_a_batch_refuses_a_hard_linked_lock_too(tmp_path):
    from fluxcal.runs.batch import run_batch

    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    out = tmp_path / "out"
    out.mkdir()
    os.link(victim, out / LOCK_NAME)
    with pytest.raises(FluxcalError, match="hard link"):
        run_batch([], lambda day: None, out, scheduler="serial")
    assert victim.read_text() == "the user's own file\n"


def test_an_out_that_is_a_link_the_user_made_is_written_into(tmp_path):
    """Before: --out out -> /scratch/x was refused as 'outside this folder' (exit 2)."""
    target = tmp_path / "scratch"
    target.mkdir()
    (tmp_path / "out").symlink_to(target)
    out = tmp_path / "out"
    assert inside(out, out)
    with owned_run(out):
        atomic_write_bytes(out / "day" / "P.TAB", b"x")
    assert (target / "day" / "P.TAB").read_bytes() == b"x"
    assert (tmp_path / "out").is_symlink()


def test_a_batchs_own_files_stay_inside_its_out(tmp_path):
    """Before: a link ``out/manifests -> elsewhere`` had every day's manifest written there.

    The manifests, the report and index.html are written by the batch itself (outside a
    day's scope); they are now inside the batch's `write_scope` too: the days fail with
    one line naming the file, nothing lands in ``elsewhere``.
    """
    import datetime as dt

    from fluxcal.runs.batch import DayResult, run_batch

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifests").symlink_to(elsewhere)

    def task(day):
        return DayResult(day, [atomic_write_bytes(out / f"{day}.TAB", b"x")], n_vectors=1)

    report = run_batch([dt.date(2014, 8, 1)], task, out, scheduler="serial")
    assert [d.status for d in report.days] == ["failed"]
    assert "outside this folder" in report.days[0].error
    assert list(elsewhere.iterdir()) == []


def test_the_refusal_names_a_link_in_the_folder_as_a_cause(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "up").symlink_to(tmp_path)
    with write_scope(out), pytest.raises(PathOutsideFolder, match="or a link in the folder"):
        atomic_write_bytes(out / "up" / "x.TAB", b"x", now=True)
    assert not (tmp_path / "x.TAB").exists()


@pytest.mark.parametrize("attrs", [{"sensor": "sub/x"}, {"sensor": "magx"},
                                   {"mode": "norm/../x"}, {"mode": "survey"},
                                   {"drop": "compression"}, {"drop": "compression_width"}],
                         ids=["sensor-path", "sensor-unknown", "mode-path", "mode-unknown",
                              "no-compression", "no-compression-width"])
def test_an_imap_product_whose_sensor_or_mode_is_no_name_is_refused(tmp_path, capsys, attrs):
    """Before: a fluxcal L1B with ``sensor = 'sub/x'`` made ``out/imap_mag_l1c_norm-sub/``.

    The sensor and mode attributes of an input product name the IMAP products; only the
    instrument's own (mago, magi; norm, burst) are names (decision 66, rule 3).  A product
    without the compression flags L1C keeps per row was an internal error (KeyError).
    """
    import numpy as np
    import xarray as xr

    from fluxcal.products import write_product
    from fluxcal.products.atomic import ungrouped

    n = 50
    t0 = 788_961_669_184_000_000  # 2025-01-01T10:00 in TT2000 ns (any day will do)
    ds = xr.Dataset({"b": (("time", "component"), np.tile([10.0, -5.0, 3.0], (n, 1)),
                           {"units": "nT"}),
                     "range": ("time", np.zeros(n, np.int64)),
                     "compression": ("time", np.zeros(n, np.int64)),
                     "compression_width": ("time", np.zeros(n, np.int64))},
                    coords={"epoch": ("time", t0 + np.arange(n, dtype=np.int64) * 125_000_000),
                            "component": ["x", "y", "z"]},
                    attrs={"level": "l1b", "sensor": "mago", "mode": "norm"})
    if "drop" in attrs:
        ds = ds.drop_vars(attrs["drop"])
        key = attrs["drop"]
    else:
        ds.attrs.update(attrs)
        key = next(iter(attrs))
    with ungrouped():
        product = write_product(ds, tmp_path / "in" / "P", formats=("cdf",))[0]
    out = tmp_path / "out"
    assert main(["imap", "l1c", "--input", str(product), "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert str(product) in line and f"field '{key}'" in line
    assert not out.exists()


def test_a_file_another_program_writes_into_out_survives_a_failed_run(tmp_path):
    """Before: a run that failed (or was interrupted) removed every new plain file in --out.

    At 60cb1b8 through the command line: ``rosetta calibrate --out out``, ``echo data >
    out/download.txt`` 8 s in, SIGTERM 2 s later: exit 143 and ``download.txt`` gone.  The
    lock keeps other fluxcal runs out, not the user's other programs: a failed run removes
    what it recorded, and its own temporaries by name, nothing else.
    """
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_bytes(b"before")
    with pytest.raises(KeyboardInterrupt), owned_run(out):
        atomic_write_bytes(out / "P.TAB", b"staged")
        atomic_write_bytes(out / "early.csv", b"mine", now=True)
        (out / "download.txt").write_bytes(b"another program's")
        raise KeyboardInterrupt
    assert sorted(os.listdir(out)) == ["download.txt", "old.txt"]
    assert (out / "download.txt").read_bytes() == b"another program's"


@pytest.mark.parametrize("args", [["--out", ""], ["--out="], ["--out", "  "]],
                         ids=["space", "equals", "blank"])
def test_an_empty_out_is_refused_not_the_current_folder(tmp_path, capsys, monkeypatch, args):
    """Before: ``--out ""`` (an unset variable) wrote the 18 products into the current folder."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "rosetta", "--hours", "0.01", *args]) == 2
    assert "--out is empty" in _one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []
    assert main(["batch", "rosetta", "--input", str(tmp_path), "--start", "2014-08-01",
                 "--end", "2014-08-01", *args]) == 2
    assert "--out is empty" in _one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_an_out_that_is_a_dangling_link_is_named_as_such(tmp_path, capsys):
    """Before: ``out -> /gone`` was reported as "a file, not a folder"; nothing is created."""
    (tmp_path / "out").symlink_to(tmp_path / "gone")
    assert main(["simulate", "rosetta", "--hours", "0.01", "--out", str(tmp_path / "out")]) == 2
    assert "which does not exist" in _one_error_line(capsys)
    assert not (tmp_path / "gone").exists()
