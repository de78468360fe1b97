"""Third hostile round (issue 31 follow-up): the WEAK outcomes of the second round, fixed.

docs/decisions/products.md, decision 74.  Expected outcomes are the issue's: a folder
another run is writing into is one line ``fluxcal: error: ...`` and exit 2 with nothing
written; every writer takes the lock of the folder it writes into, named or not; the
bytes of every file outside the run's own products unchanged (compared with what the
test itself wrote before the run).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fluxcal.cli import main
from fluxcal.products import write_product
from fluxcal.products.paths import LOCK_NAME
from fluxcal.products.staging import clean_stale_temporaries, output_lock
from tests.products.conftest import make_dataset
from tests.test_hostile_paths import DEAD_PID, _one_error_line


def _tree(folder: Path) -> dict[str, bytes]:
    """Every entry below ``folder`` (links as their target text), to compare before/after."""
    out: dict[str, bytes] = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        out[rel] = (b"->" + os.readlink(p).encode()) if p.is_symlink() else \
            b"<dir>" if p.is_dir() else p.read_bytes()
    return out


@pytest.fixture()
def product(tmp_path: Path) -> Path:
    """A small netCDF product (600 vectors at 20 Hz on 2024-01-01) in ``tmp_path / "data"``."""
    folder = tmp_path / "data"
    folder.mkdir()
    write_product(make_dataset(600), folder / "P", formats=("nc",))
    return folder / "P.nc"


# --- 1. ``fluxcal plot`` without --out locks the product's folder ----------------------------

def test_plot_beside_its_product_refuses_a_folder_another_run_is_writing(product, capsys):
    """Before: no lock was taken in the product's folder; the PNG was written beside a
    run that held it (exit 0)."""
    before = _tree(product.parent)
    with output_lock(product.parent):  # another run, writing into that folder now
        before = _tree(product.parent)
        assert main(["plot", str(product)]) == 2
        line = _one_error_line(capsys)
        assert "another fluxcal run" in line and str(product.parent) in line
        assert _tree(product.parent) == before  # no PNG, no temporary, the lock kept
    assert not (product.parent / LOCK_NAME).exists()


def test_plot_beside_its_product_still_writes_its_pngs(product, capsys):
    assert main(["plot", str(product), "--spectrogram"]) == 0
    names = sorted(p.name for p in product.parent.iterdir())
    assert names == ["P.nc", "P_20240101.png", "P_spec.png"]  # no lock or probe left
    assert capsys.readouterr().out.split() == [str(product.parent / "P_20240101.png"),
                                               str(product.parent / "P_spec.png")]


def test_plot_with_out_refuses_a_busy_out_too(product, tmp_path, capsys):
    out = tmp_path / "ql"
    out.mkdir()
    with output_lock(out):
        assert main(["plot", str(product), "--out", str(out)]) == 2
        assert "another fluxcal run" in _one_error_line(capsys)
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]


def test_a_failing_plot_beside_its_product_leaves_nothing(tmp_path, capsys):
    """Before: the day's PNG stayed when the spectrogram then failed (too few samples for
    ``nperseg=256``), exit 2 with partial output.  Now staged: nothing is left."""
    write_product(make_dataset(200), tmp_path / "P", formats=("nc",))
    before = _tree(tmp_path)
    assert main(["plot", str(tmp_path / "P.nc"), "--spectrogram"]) == 2
    assert "spectrogram" in _one_error_line(capsys)
    assert _tree(tmp_path) == before


def test_plot_beside_its_product_enters_no_subfolder(product, capsys):
    """The product's folder is not one the user named: its own stale temporaries are
    removed (as with --out), nothing in its subfolders is looked at or removed."""
    sub = product.parent / "someone_elses"
    sub.mkdir()
    deep = sub / f".x.TAB.{DEAD_PID}.abcdefgh.fluxcal-tmp.TAB"
    deep.write_text("in a folder the user did not name")
    top = product.parent / f".y.TAB.{DEAD_PID}.abcdefgh.fluxcal-tmp.TAB"
    top.write_text("a killed run's temporary where plot writes")
    assert main(["plot", str(product)]) == 0
    assert deep.exists() and not top.exists()


def test_clean_stale_temporaries_below_false_stays_in_the_folder(tmp_path):
    name = f".x.TAB.{DEAD_PID}.abcdefgh.fluxcal-tmp.TAB"
    (tmp_path / "sub").mkdir()
    for p in (tmp_path / name, tmp_path / "sub" / name):
        p.write_text("stale")
    assert clean_stale_temporaries(tmp_path, below=False) == [tmp_path / name]
    assert (tmp_path / "sub" / name).exists()
    assert clean_stale_temporaries(tmp_path) == [tmp_path / "sub" / name]


# --- ``fluxcal compare`` without --out locks the current folder ------------------------------

def test_compare_into_the_current_folder_refuses_a_busy_folder(product, tmp_path, capsys,
                                                               monkeypatch):
    """Before: the difference plot went into the current folder with no lock taken."""
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    with output_lock(here):
        assert main(["compare", str(product), str(product)]) == 2
        assert "another fluxcal run" in _one_error_line(capsys)
        assert sorted(p.name for p in here.iterdir()) == [LOCK_NAME]
    assert main(["compare", str(product), str(product)]) == 0
    assert sorted(p.name for p in here.iterdir()) == ["compare_P_vs_P.png"]


# --- a batch's --out that is a dangling link ------------------------------------------------

def test_a_batch_out_that_is_a_dangling_link_is_named_as_such(tmp_path, capsys):
    """Before: the batch started, then "out: File exists (a file stands where a folder is
    expected)"; a single run said "a link to ..., which does not exist" (second round)."""
    import datetime as dt

    from fluxcal.runs.synthetic_task import write_synthetic_inputs

    write_synthetic_inputs(tmp_path / "in", [dt.date(2024, 1, 1)], n_per_day=50)
    (tmp_path / "out").symlink_to(tmp_path / "gone")
    assert main(["batch", "synthetic", "--input", str(tmp_path / "in"), "--start",
                 "2024-01-01", "--end", "2024-01-01", "--out", str(tmp_path / "out"),
                 "--scheduler", "serial", "--quiet"]) == 2
    line = _one_error_line(capsys)
    assert f"{tmp_path / 'out'} is a link to {tmp_path / 'gone'}, which does not exist" in line
    assert not (tmp_path / "gone").exists()



def test_run_batch_from_python_names_a_dangling_out_link_too(tmp_path):
    """Before: ``out_dir.mkdir`` raised a bare ``FileExistsError`` ("File exists")."""
    from fluxcal.errors import FluxcalError
    from fluxcal.runs.batch import run_batch

    (tmp_path / "out").symlink_to(tmp_path / "gone")
    with pytest.raises(FluxcalError, match="which does not exist"):
        run_batch([], lambda day: None, tmp_path / "out", scheduler="serial")
    assert not (tmp_path / "gone").exists()


# --- writers that bypassed the path rule (item 3) -------------------------------------------

def test_synthetic_inputs_replace_a_link_never_write_through_it(tmp_path):
    """Before: ``np.savetxt`` opened the day's CSV by name, so a link planted there (in a
    demo's --out) had its target outside --out overwritten.  Now `atomic_path`: the link
    is replaced by the file, its target keeps its bytes."""
    import datetime as dt

    from fluxcal.products.paths import write_scope
    from fluxcal.runs.synthetic_task import input_path, write_synthetic_inputs

    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    out = tmp_path / "out"
    (out / "in").mkdir(parents=True)
    day = dt.date(2024, 1, 1)
    input_path(out / "in", day).symlink_to(victim)
    with write_scope(out):
        write_synthetic_inputs(out / "in", [day], n_per_day=10)
    assert victim.read_text() == "the user's own file\n"
    csv = input_path(out / "in", day)
    assert not csv.is_symlink()
    lines = csv.read_text().splitlines()
    assert lines[0] == "epoch_ns,cx,cy,cz" and len(lines) == 11  # header + 10 records


def _states(epochs):
    """A straight line at 1 km/s along x from (7000, 0, 0) km: a closed form to read back."""
    import numpy as np

    t = epochs - epochs[0]
    return np.column_stack([7000.0 + t, 0 * t, 0 * t, 1.0 + 0 * t, 0 * t, 0 * t])


def test_synthetic_kernels_replace_an_earlier_set_only_when_complete(tmp_path):
    """Before: `prepare_kernel_folder` removed the earlier .bsp/.bc at once and SPICE wrote
    the new ones in place, so a simulation that then failed left the set without them.
    Now each is written into a temporary and renamed over the old one when closed."""
    import numpy as np
    import spiceypy

    from fluxcal.geometry.synthetic import prepare_kernel_folder, write_spk
    from fluxcal.products.paths import write_scope

    out = tmp_path / "kernels"
    out.mkdir()
    (out / "x.bsp").write_bytes(b"an earlier set's SPK")
    (out / "x_sc.bc").write_bytes(b"an earlier set's CK")
    victim = tmp_path / "victim.bsp"
    victim.write_bytes(b"the user's own file")
    epochs = np.arange(0.0, 3600.0, 600.0)
    with write_scope(out):
        *_, spk, ck = prepare_kernel_folder(out, "x")
        assert spk.read_bytes() == b"an earlier set's SPK"  # kept until replaced
        assert ck.read_bytes() == b"an earlier set's CK"
        with pytest.raises(spiceypy.utils.exceptions.SpiceyError):  # epochs not increasing
            write_spk(spk, -99, 399, epochs[::-1].copy(), _states(epochs), "BAD")
        assert spk.read_bytes() == b"an earlier set's SPK"
        assert [p.name for p in out.iterdir() if "fluxcal-tmp" in p.name] == []
        spk.unlink()
        spk.symlink_to(victim)  # a link planted at the name: replaced, not written through
        write_spk(spk, -99, 399, epochs, _states(epochs), "LINE")
        write_spk(spk, -98, 399, epochs, _states(epochs) * 2, "LINE2", append=True)
    assert victim.read_bytes() == b"the user's own file" and not spk.is_symlink()
    spiceypy.furnsh(str(spk))
    try:
        for body, scale in ((-99, 1.0), (-98, 2.0)):
            state, _ = spiceypy.spkgeo(body, 1234.0, "J2000", 399)
            # the closed form at t = 1234 s: Hermite through the exact line is exact (1e-9 km)
            np.testing.assert_allclose(state, scale * np.array([8234.0, 0, 0, 1, 0, 0]),
                                       atol=1e-9)
    finally:
        spiceypy.unload(str(spk))
