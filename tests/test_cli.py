"""The top-level ``fluxcal`` command: exit codes and messages."""

from __future__ import annotations

from pathlib import Path

from fluxcal import __version__
from fluxcal.cli import main


def test_version(capsys):
    assert main(["version"]) == 0
    assert capsys.readouterr().out.strip() == __version__


def test_unknown_command_is_a_usage_error(capsys):
    assert main(["no-such-command"]) == 2
    assert "no-such-command" in capsys.readouterr().err


def test_bad_option_value_is_a_usage_error(capsys):
    # a non-numeric hour count is rejected by the option parser, not by a traceback
    assert main(["simulate", "rosetta", "--hours", "many", "--out", "x"]) == 2


def test_fluxcal_error_is_reported_with_exit_code_2(capsys, tmp_path):
    missing = tmp_path / "nope.csv"
    code = main(["messenger", "edr2cdr", "--sci", str(missing), "--heater", str(missing),
                 "--temperature", str(missing), "--kernels", str(missing),
                 "--out", str(tmp_path / "out")])
    assert code != 0
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_every_command_has_help(capsys):
    for cmd in (["messenger", "edr2cdr"], ["rosetta", "calibrate"], ["rosetta", "clean"],
                ["simulate", "messenger"], ["simulate", "rosetta"], ["plot"], ["provenance"],
                ["batch"], ["demo"]):
        assert main([*cmd, "--help"]) == 0, cmd


def _small_science(tmp_path):
    from tests.missions.rosetta._raw import write_raw_csv

    return write_raw_csv(tmp_path / "RPCMAG_20140801_RAW_OB.csv", "2014-08-01T10:00:00", 400,
                         0.05)


def test_rosetta_calib_folder_missing_is_an_error_not_a_fallback(capsys, tmp_path):
    """Before: exit 0 with the shipped files (placeholder alignment) used silently."""
    sci, out = _small_science(tmp_path), tmp_path / "out"
    code = main(["rosetta", "calibrate", "--science", str(sci), "--sensor", "OB",
                 "--levels", "A,B", "--calib", str(tmp_path / "no" / "such" / "dir"),
                 "--out", str(out)])
    assert code == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "--calib" in line and "does not exist" in line
    assert not out.exists()


def test_rosetta_placeholder_alignment_warns_and_is_recorded(capsys, tmp_path):
    """The shipped alignment is marked PLACEHOLDER: terminal, CDF attribute and label say so."""
    import cdflib

    sci, out = _small_science(tmp_path), tmp_path / "out"
    args = ["rosetta", "calibrate", "--science", str(sci), "--sensor", "OB",
            "--levels", "A,B", "--formats", "tab,cdf", "--out", str(out)]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "PLACEHOLDER" in err and "RPCMAG_SC_ALIGN.TXT" in err
    (cdf,) = out.glob("*clb-ob*.cdf")
    attrs = cdflib.CDF(str(cdf)).globalattsget()
    assert "PLACEHOLDER" in " ".join(attrs["alignment"])
    assert any("PLACEHOLDER" in p.read_text() for p in out.glob("*_CLB_OB_*.LBL"))
    # every run, not once
    assert main(args) == 0
    assert "PLACEHOLDER" in capsys.readouterr().err


def test_rosetta_measured_alignment_does_not_warn(capsys, tmp_path):
    from fluxcal.missions.rosetta import calib
    from fluxcal.missions.rosetta.simulate import synthetic_alignment

    sci, out, cal = _small_science(tmp_path), tmp_path / "out", tmp_path / "calib"
    cal.mkdir()
    calib.write_alignment(synthetic_alignment(), cal / calib.ALIGN_FILE)
    assert not calib.load_alignment(cal).placeholder
    assert main(["rosetta", "calibrate", "--science", str(sci), "--sensor", "OB",
                 "--levels", "A,B", "--calib", str(cal), "--out", str(out)]) == 0
    assert "PLACEHOLDER" not in capsys.readouterr().err


def test_plot_rosetta_tab_product(capsys, tmp_path):
    """Before: KeyError 'epoch' (archive tables carry time_utc text, not TT2000)."""
    sci, out = _small_science(tmp_path), tmp_path / "out"
    assert main(["rosetta", "calibrate", "--science", str(sci), "--sensor", "OB",
                 "--levels", "A", "--formats", "tab", "--out", str(out)]) == 0
    (tab,) = out.glob("*_CLA_OB_*.TAB")
    capsys.readouterr()
    assert main(["plot", str(tab), "--out", str(tmp_path / "ql"), "--spectrogram"]) == 0
    names = sorted(p.name for p in (tmp_path / "ql").iterdir())
    assert names == [f"{tab.stem}_20140801.png", f"{tab.stem}_spec.png"]


def test_moved_simulation_folder_still_loads(capsys, tmp_path, monkeypatch):
    """Before: the meta-kernel listed absolute paths, so a moved folder failed to load."""
    import shutil

    import spiceypy

    first, moved = tmp_path / "first", tmp_path / "elsewhere" / "sim"
    assert main(["simulate", "rosetta", "--out", str(first), "--hours", "0.02"]) == 0
    meta = first / "kernels" / "rosetta_synthetic.tm"
    assert str(tmp_path) not in meta.read_text()  # nothing absolute
    moved.parent.mkdir()
    shutil.move(str(first), str(moved))
    out = tmp_path / "out"
    assert main(["rosetta", "calibrate", "--science",
                 str(moved / "RPCMAG_20140801_RAW_OB.csv"), "--sensor", "OB",
                 "--levels", "A,B,C", "--calib", str(moved / "calib"),
                 "--kernels", str(moved / "kernels" / "rosetta_synthetic.tm"),
                 "--frame", "ECLIPJ2000", "--out", str(out)]) == 0
    assert list(out.glob("*_CLC_OB_*.TAB"))
    # plain SPICE reads it the NAIF way: relative to the working directory
    monkeypatch.chdir(moved / "kernels")
    before = spiceypy.ktotal("ALL")
    spiceypy.furnsh("rosetta_synthetic.tm")
    try:
        # the meta-kernel and its 5 files (SCLK, FK, SPK, CK, the CSEQ frame: issue 32)
        assert spiceypy.ktotal("ALL") == before + 6
    finally:
        spiceypy.unload("rosetta_synthetic.tm")


def test_meta_kernel_paths_with_symbols_and_continuations(tmp_path):
    from fluxcal.geometry.kernels import relative_meta_kernel_files

    meta = tmp_path / "mk" / "set.tm"
    meta.parent.mkdir()
    meta.write_text("KPL/MK\n\\begindata\nPATH_VALUES = ( '../data' 'sub' )\n"
                    "PATH_SYMBOLS = ( 'D' 'DS' )\nKERNELS_TO_LOAD = ( '$D/a.tsc'\n"
                    "  '$DS/very/long/na+'\n  'me.bc' '/abs/c.bsp' )\n\\begintext\n"
                    "KERNELS_TO_LOAD = ( 'ignored.txt' )\n")
    assert relative_meta_kernel_files(meta) == [
        (tmp_path / "data" / "a.tsc").resolve(),  # '$DS' is not '$D' followed by 'S'
        (tmp_path / "mk" / "sub" / "very" / "long" / "name.bc").resolve(),
        Path("/abs/c.bsp")]
    absolute = tmp_path / "abs.tm"
    absolute.write_text("\\begindata\nPATH_VALUES = ( '/x' )\nPATH_SYMBOLS = ( 'X' )\n"
                        "KERNELS_TO_LOAD = ( '$X/a.tsc' )\n")
    assert relative_meta_kernel_files(absolute) is None  # SPICE loads it as it is
