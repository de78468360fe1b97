"""Hostile paths: nothing written or removed outside ``--out`` or the user's own files.

Issue 31, "Security and data loss", each reproducer as a test (docs/decisions/products.md,
decision 66; `fluxcal.products.paths`).  The expected outcomes are the issue's: exit 2
with one line ``fluxcal: error: ...``, and the bytes of every file outside the run's own
products unchanged (compared with what the test itself wrote before the run).  Most
tests call the CLI in-process (`fluxcal.cli.main`); the signal tests start a process.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from fluxcal.cli import main
from fluxcal.errors import InputFormatError
from fluxcal.products.atomic import atomic_path, atomic_write_bytes, ungrouped
from fluxcal.products.paths import (
    LOCK_NAME,
    PathOutsideFolder,
    inside,
    own_leftover,
    plain_name,
    write_scope,
)
from fluxcal.products.staging import clean_stale_temporaries, owned_run

SRC = str(Path(__file__).resolve().parents[1] / "src")
#: Above Linux's largest pid_max (2**22): a process that cannot be running.
DEAD_PID = 2**22 + 1


def _one_error_line(capsys) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("fluxcal: error: "), lines[0]
    return lines[0]


def _tree(folder: Path) -> dict[str, bytes | str]:
    """Every entry below ``folder``: file bytes, link targets, folders (links not followed)."""
    out: dict[str, bytes | str] = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            out[rel] = (f"-> {os.readlink(p)}" if p.is_symlink() else
                        "<dir>" if p.is_dir() else p.read_bytes())
    return out


# -- the lock --------------------------------------------------------------------------

def test_a_planted_lock_link_is_refused_and_its_target_untouched(tmp_path, capsys):
    """Before: the lock was opened through the link: the victim got the pid, the link went."""
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to("../victim.txt")
    before = _tree(tmp_path)
    assert main(["simulate", "rosetta", "--rate", "0", "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert LOCK_NAME in line and "not a regular file" in line
    assert _tree(tmp_path) == before  # victim's bytes, and the link itself, unchanged


def test_a_default_out_is_owned_too(tmp_path, capsys, monkeypatch):
    """``simulate`` without --out writes into ./rosetta-sim: the same lock, the same rule."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "victim.txt").write_text("the user's own file\n")
    (tmp_path / "rosetta-sim").mkdir()
    (tmp_path / "rosetta-sim" / LOCK_NAME).symlink_to("../victim.txt")
    before = _tree(tmp_path)
    assert main(["simulate", "rosetta", "--rate", "0"]) == 2
    assert "not a regular file" in _one_error_line(capsys)
    assert _tree(tmp_path) == before


def test_a_lock_that_is_a_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    (out / LOCK_NAME).mkdir(parents=True)
    (out / LOCK_NAME / "keep.txt").write_text("x")
    before = _tree(tmp_path)
    assert main(["simulate", "rosetta", "--rate", "0", "--out", str(out)]) == 2
    assert LOCK_NAME in _one_error_line(capsys)
    assert _tree(tmp_path) == before


def test_a_batch_refuses_a_planted_lock_link_too(tmp_path):
    from fluxcal.errors import FluxcalError
    from fluxcal.runs.batch import run_batch

    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(victim)
    before = _tree(tmp_path)
    with pytest.raises(FluxcalError, match="not a regular file"):
        run_batch([], lambda day: None, out, scheduler="serial")
    assert _tree(tmp_path) == before


def test_out_given_twice_is_refused_before_anything_is_made(tmp_path, capsys):
    """Before: ``--out A --out B`` locked A and wrote into B beside another run."""
    a, b = tmp_path / "A", tmp_path / "B"
    assert main(["simulate", "rosetta", "--hours", "0.01", "--out", str(a),
                 "--out", str(b)]) == 2
    assert "--out given 2 times" in _one_error_line(capsys)
    assert not a.exists() and not b.exists()
    assert main(["batch", "rosetta", "--out", str(a), f"--out={b}"]) == 2
    assert "--out given 2 times" in _one_error_line(capsys)


# -- --out checked before any input is read --------------------------------------------

def test_an_unusable_out_is_named_before_any_input_is_read(tmp_path, capsys):
    """Before: a file in --out's path was reported after the whole day was calibrated."""
    (tmp_path / "afile").write_text("x")
    out = tmp_path / "afile" / "sub"
    missing = tmp_path / "never-read.csv"  # the input check would name this file
    assert main(["rosetta", "calibrate", "--science", str(missing), "--sensor", "OB",
                 "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert f"--out {out}" in line and "is a file, not a folder" in line
    assert str(missing) not in line


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder")
def test_a_read_only_out_is_named_before_any_input_is_read(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["rosetta", "calibrate", "--science", str(tmp_path / "x.csv"),
                     "--sensor", "OB", "--out", str(ro / "out")]) == 2
        assert "--out" in _one_error_line(capsys)
    finally:
        ro.chmod(0o755)


# -- names from metadata ---------------------------------------------------------------

def _level_h_product(folder: Path, sensor: str) -> Path:
    """A small LEVEL_H product (CDF) whose SENSOR attribute is ``sensor``."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import leapseconds, utc_to_tt2000
    from fluxcal.products import write_product

    with KernelPool([]):
        t0 = int(utc_to_tt2000(np.array(["2014-08-01T10:00:00"]), leapseconds())[0])
    n = 200
    ds = xr.Dataset({"b": (("time", "component"), np.tile([10.0, -5.0, 3.0], (n, 1)),
                           {"units": "nT"})},
                    coords={"epoch": ("time", t0 + np.arange(n, dtype=np.int64) * 50_000_000),
                            "component": ["x", "y", "z"]},
                    attrs={"level": "H", "sensor": sensor})
    with ungrouped():
        return write_product(ds, folder / "P", formats=("cdf",))[0]


def test_a_sensor_name_that_is_a_path_is_refused(tmp_path, capsys):
    """Before: SENSOR = 'X/../../../escaped' put 4 products three folders up, exit 0."""
    product = _level_h_product(tmp_path / "in", "X/../../../escaped")
    work = tmp_path / "w" / "a" / "b"
    work.mkdir(parents=True)
    before = _tree(tmp_path)
    assert main(["rosetta", "clean", "--level", "I", "--input", str(product),
                 "--out", str(work / "out")]) == 2
    line = _one_error_line(capsys)
    assert str(product) in line and "SENSOR" in line and "X/../../../escaped" in line
    assert _tree(tmp_path) == before  # nothing written anywhere, --out not left behind


@pytest.mark.parametrize("name", ["X/../../e", "..", "../e", "/etc/e", ".hidden", "a\\b",
                                  "a\x00b", "a\nb", "", "x" * 65])
def test_plain_name_refuses_paths_and_control_characters(name):
    with pytest.raises(InputFormatError, match="cannot be part of a file name"):
        plain_name(name, what="SENSOR", path="in.cdf")


@pytest.mark.parametrize("name", ["OB", "IB", "FM-2", "sensor_1", "a.b"])
def test_plain_name_keeps_plain_names(name):
    assert plain_name(name, what="SENSOR") == name


def test_every_write_of_a_run_stays_inside_its_out(tmp_path):
    """The second fence: a writer handed a path out of --out refuses it, writes nothing."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "up").symlink_to(tmp_path)  # a link in --out that leads out of it
    with write_scope(out):
        for bad in (out / ".." / "x.TAB", out / "a" / ".." / ".." / "x.TAB",
                    out / "up" / "x.TAB", Path("/tmp") / "x.TAB"):
            with pytest.raises(PathOutsideFolder, match="outside this folder"):
                atomic_write_bytes(bad, b"x", now=True)
        atomic_write_bytes(out / "sub" / "ok.TAB", b"x", now=True)
    assert sorted(p.name for p in tmp_path.rglob("*.TAB")) == ["ok.TAB"]
    assert inside(out / "sub" / "link-itself", out)


@pytest.mark.parametrize("directory", [False, True], ids=["file", "store"])
def test_a_link_at_a_products_name_is_replaced_never_written_through(tmp_path, directory):
    target = tmp_path / "target"
    target.mkdir()
    (target / "keep").write_text("the user's own file\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "P.zarr").symlink_to(target)
    (out / "P.TAB").symlink_to(target / "keep")
    before = _tree(target)
    with write_scope(out), atomic_path(out / ("P.zarr" if directory else "P.TAB"),
                                       directory=directory, now=True) as tmp:
        if directory:
            tmp.mkdir()
            (tmp / "x").write_text("new")
        else:
            tmp.write_text("new")
    assert _tree(target) == before
    name = "P.zarr/x" if directory else "P.TAB"
    assert (out / name).read_text() == "new" and not (out / name).is_symlink()
    assert [p.name for p in out.iterdir() if own_leftover(p.name)] == []


# -- removal: only fluxcal's own temporaries -------------------------------------------

def test_a_users_hidden_files_survive_every_command(tmp_path, capsys):
    """Before: .draft.tmp, .analysis.tmpl, .bashrc.old were removed as 'stale temporaries'."""
    out = tmp_path / "out"
    user = {"notes/.draft.tmp": b"draft", ".analysis.tmpl": b"tmpl", ".bashrc.old": b"old",
            "bashrc": b"rc", ".x.TAB.123.abcd1234.tmp.TAB": b"not fluxcal's pattern",
            "deep/er/.y.zarr.old/keep": b"k", f".z.TAB.{DEAD_PID}.fluxcal-tmp": b"no random"}
    for rel, data in user.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    stale = out / "deep" / f".P.TAB.{DEAD_PID}.k3j2ab12.fluxcal-tmp.TAB"  # a killed run's
    stale.write_bytes(b"partial")
    before = _tree(out)
    assert main(["simulate", "rosetta", "--rate", "0", "--out", str(out)]) == 2
    capsys.readouterr()
    after = _tree(out)
    assert not stale.exists()
    del before[str(stale.relative_to(out))]
    assert after == before


def test_own_leftover_matches_only_fluxcals_names(tmp_path):
    with atomic_path(tmp_path / "P.cdf") as tmp:
        assert own_leftover(tmp.name) == ("tmp", os.getpid(), "P.cdf")
        tmp.write_bytes(b"x")
    for name in (".draft.tmp", ".analysis.tmpl", ".bashrc.old", ".P.TAB.12.ab.tmp.TAB",
                 "P.TAB.12.abcd1234.fluxcal-tmp.TAB", ".P.fluxcal-old", ".P.x.fluxcal-old"):
        assert own_leftover(name) is None, name


def test_clean_up_follows_no_link_and_spares_a_running_runs_folder(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    theirs = elsewhere / f".Q.TAB.{DEAD_PID}.k3j2ab12.fluxcal-tmp.TAB"
    theirs.write_bytes(b"x")
    out = tmp_path / "out"
    out.mkdir()
    (out / "link").symlink_to(elsewhere)
    (out / f".L.TAB.{DEAD_PID}.k3j2ab12.fluxcal-tmp.TAB").symlink_to(theirs)
    nested = out / "nested"
    nested.mkdir()
    (nested / LOCK_NAME).write_text("4242\n")  # another run is writing here
    held = nested / f".R.TAB.{DEAD_PID}.k3j2ab12.fluxcal-tmp.TAB"
    held.write_bytes(b"x")
    assert clean_stale_temporaries(out) == []
    assert theirs.exists() and held.exists()
    assert (out / f".L.TAB.{DEAD_PID}.k3j2ab12.fluxcal-tmp.TAB").is_symlink()


def test_a_failing_run_keeps_another_runs_products_nested_below_its_out(tmp_path):
    """Before: a failing run deleted every file that appeared below --out during it."""
    out = tmp_path / "out"
    nested = out / "B"
    with pytest.raises(InputFormatError), owned_run(out):
        # this run writes (a file read back at once, a staged product) ...
        atomic_write_bytes(out / "mine" / "early.csv", b"mine", now=True)
        atomic_write_bytes(out / "P.TAB", b"staged")
        # ... while another process finishes its products in a folder below (--out out/B)
        (nested / "sub").mkdir(parents=True)
        (nested / "B.TAB").write_bytes(b"theirs")
        (nested / "sub" / "B.cdf").write_bytes(b"theirs")
        raise InputFormatError("rejected", path="x.csv")
    assert _tree(out) == {"B": "<dir>", "B/B.TAB": b"theirs", "B/sub": "<dir>",
                          "B/sub/B.cdf": b"theirs"}


def test_a_failing_run_into_a_new_folder_leaves_no_folder(tmp_path):
    out = tmp_path / "new" / "out"
    with pytest.raises(InputFormatError), owned_run(out):
        atomic_write_bytes(out / "day" / "P.TAB", b"x", now=True)
        raise InputFormatError("rejected", path="x.csv")
    assert list(tmp_path.iterdir()) == []


# -- PDS3 pointers ---------------------------------------------------------------------

_LABEL = """PDS_VERSION_ID = PDS3
RECORD_TYPE = FIXED_LENGTH
RECORD_BYTES = 6
FILE_RECORDS = 1
^TABLE = {pointer}
OBJECT = TABLE
  ROWS = 1
  COLUMNS = 1
  ROW_BYTES = 6
  INTERCHANGE_FORMAT = ASCII
  OBJECT = COLUMN
    NAME = A
    DATA_TYPE = ASCII_INTEGER
    START_BYTE = 1
    BYTES = 4
  END_OBJECT = COLUMN
END_OBJECT = TABLE
END
"""


def _label(tmp_path: Path, pointer: str) -> Path:
    folder = tmp_path / "a" / "b"
    folder.mkdir(parents=True)
    (tmp_path / "x.TAB").write_bytes(b"1234\r\n")  # outside the label's folder
    (folder / "X.LBL").write_text(_LABEL.format(pointer=pointer))
    return folder / "X.LBL"


@pytest.mark.parametrize("pointer", ['"../../x.TAB"', '("../../x.TAB", 1)', '"/etc/hosts"'])
def test_a_pds3_pointer_out_of_the_labels_folder_is_refused(tmp_path, capsys, pointer):
    """Before: read_product and provenance followed ^TABLE = "../../x.TAB"."""
    import fluxcal

    label = _label(tmp_path, pointer)
    with pytest.raises(InputFormatError, match=r"\^TABLE .*leads out of the label's folder"):
        fluxcal.read_product(label)
    assert main(["provenance", str(label)]) == 2
    line = _one_error_line(capsys)
    assert str(label) in line and "leads out of the label's folder" in line


def test_a_pds3_pointer_through_a_link_out_of_the_folder_is_refused(tmp_path):
    import fluxcal

    label = _label(tmp_path, '"X.TAB"')
    (label.parent / "X.TAB").symlink_to(tmp_path / "x.TAB")
    with pytest.raises(InputFormatError, match="link that leads out"):
        fluxcal.read_product(label)


def test_a_pds3_format_file_out_of_the_labels_folder_is_refused(tmp_path):
    import fluxcal

    label = _label(tmp_path, '"X.TAB"')
    (label.parent / "X.TAB").write_bytes(b"4321\r\n")
    (tmp_path / "X.FMT").write_text("OBJECT = COLUMN\nEND_OBJECT = COLUMN\n")
    text = label.read_text().replace("  ROW_BYTES = 6\n",
                                     '  ROW_BYTES = 6\n  ^STRUCTURE = "../../X.FMT"\n')
    label.write_text(text)
    with pytest.raises(InputFormatError, match=r"\^STRUCTURE .*leads out of the label's"):
        fluxcal.read_product(label)


def test_a_pds3_pointer_beside_its_label_is_read(tmp_path):
    from fluxcal.archive.pds3 import read_table

    label = _label(tmp_path, '"x.tab"')  # matched case-insensitively, as before
    (label.parent / "X.TAB").write_bytes(b"4321\r\n")
    assert read_table(label)["A"].values.tolist() == [4321]


# -- signals ---------------------------------------------------------------------------

def test_a_signal_whose_exception_a_library_swallowed_still_exits_143(monkeypatch, capsys):
    """Python runs a handler inside any code: one that swallows its exception lost SIGTERM."""
    from fluxcal import cli

    def app(**_kwargs):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)  # the handler runs here and raises ...
        except BaseException:  # noqa: BLE001, S110 - ... into a library that swallows it
            pass
        return 0

    monkeypatch.setattr(cli, "app", app)
    assert main(["version"]) == 128 + signal.SIGTERM
    assert "interrupted: SIGTERM" in capsys.readouterr().err


@pytest.mark.parametrize("delay", [0.0, 0.3, 1.0, 2.5])
def test_sigterm_just_after_start_is_never_ignored(tmp_path, delay):
    """Before: a SIGTERM sent just after start was ignored once in 3 tries (exit 0)."""
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from fluxcal.cli import main; "
                             "sys.exit(main(sys.argv[1:]))", "simulate", "rosetta",
                             "--hours", "0.01", "--out", str(out)],
                            env={**os.environ, "PYTHONPATH": SRC},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    if proc.poll() is not None:  # a machine fast enough to finish first: not this case
        pytest.skip(f"the command ended within {delay} s")
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    # killed before the handlers were installed (-15), or cleaned up and exited 143
    assert proc.returncode in (-signal.SIGTERM, 128 + signal.SIGTERM), (proc.returncode, err)
    leftovers = [p for p in out.rglob("*") if own_leftover(p.name)] if out.exists() else []
    assert not leftovers and not (out / LOCK_NAME).exists()
