"""``--config FILE.toml``: run options from a file, merged under the command line (issue 25).

Expected values by hand: the toy mission multiplies counts (2, 4, 6) by the gain, so a
gain of 0.25 nT/count gives (0.5, 1, 1.5) nT and 1.0 gives (2, 4, 6).
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cdflib
import numpy as np
import pytest

import fluxcal.cli
from fluxcal.cli import build_app, main
from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.runs import registry
from fluxcal.runs.options import read_config

TOY = "tests.runs.toy_mission:MISSION"


@pytest.fixture
def toy(monkeypatch, tmp_path: Path) -> Path:
    """Register the toy mission; return one simulated day's input file."""
    from tests.runs.toy_mission import simulate_days

    monkeypatch.setenv(registry.ENV, TOY)
    monkeypatch.setattr(fluxcal.cli, "app", build_app())
    simulate_days(tmp_path / "in", [dt.date(2024, 1, 1)])
    return tmp_path / "in" / "TOY_20240101.csv"


def _field(path: Path) -> np.ndarray:
    return np.asarray(cdflib.CDF(str(path)).varget("B"))[0]


def _run(src: Path, out: Path, config: Path, *extra: str) -> int:
    return main(["toy", "calibrate", "--input", str(src), "--out", str(out),
                 "--config", str(config), *extra])


def test_file_values_apply_and_the_command_line_wins(toy: Path, tmp_path: Path) -> None:
    config = tmp_path / "run.toml"
    config.write_text('gain = 0.25\nformats = ["cdf", "nc"]\n')
    # formats from the command line, gain from the file
    assert _run(toy, tmp_path / "a", config, "--formats", "cdf") == 0
    np.testing.assert_array_equal(_field(tmp_path / "a" / "TOY_20240101.cdf"), [0.5, 1, 1.5])
    assert not (tmp_path / "a" / "TOY_20240101.nc").exists()
    # both from the file
    assert _run(toy, tmp_path / "b", config) == 0
    assert (tmp_path / "b" / "TOY_20240101.nc").exists()
    # the command line's gain over the file's, even when it equals the default's form
    assert _run(toy, tmp_path / "c", config, "--gain", "1.0") == 0
    np.testing.assert_array_equal(_field(tmp_path / "c" / "TOY_20240101.cdf"), [2, 4, 6])
    assert _run(toy, tmp_path / "d", config, "--gain", "0.5") == 0  # the default value
    np.testing.assert_array_equal(_field(tmp_path / "d" / "TOY_20240101.cdf"), [1, 2, 3])


def test_batch_takes_the_file_too(toy: Path, tmp_path: Path) -> None:
    config = tmp_path / "run.toml"
    config.write_text('formats = "cdf,nc"\ngain = 1\n')
    assert main(["batch", "toy", "--start", "2024-01-01", "--end", "2024-01-01", "--input",
                 str(toy.parent), "--out", str(tmp_path / "o"), "--scheduler", "serial",
                 "--quiet", "--config", str(config)]) == 0
    assert (tmp_path / "o" / "TOY_20240101.nc").exists()
    np.testing.assert_array_equal(_field(tmp_path / "o" / "TOY_20240101.cdf"), [2, 4, 6])


@pytest.mark.parametrize(("text", "expected"), [
    ("gian = 0.25\n", ["run.toml", "line 1", "'gian'", "unknown key", "gain"]),
    ('formats = ["cdf"]\ngain = "big"\n', ["run.toml", "line 2", "'gain'", "expected a number"]),
    ("gain = true\n", ["line 1", "'gain'", "expected a number"]),
    ('formats = ["tab"]\n', ["line 1", "'formats'", "unknown value tab; choose from"]),
    ("formats = [1, 2]\n", ["line 1", "'formats'", "array of strings"]),
    ("gain = 0.25\n\ngain = 1\n", ["run.toml", "line 3", "not valid TOML"]),
    ("gain = \n", ["run.toml", "line 1", "not valid TOML"]),
    ("[formats]\ncdf = 1\n", ["line 1", "'formats'", "(dict)"]),
])
def test_bad_file_is_one_line_exit_2_and_nothing_written(
        toy: Path, tmp_path: Path, capsys, text: str, expected: list[str]) -> None:
    config = tmp_path / "run.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert _run(toy, out, config) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("fluxcal: error: "), err
    assert str(config) in err[0]
    for part in expected:
        assert part in err[0], (part, err[0])
    assert not out.exists()


@pytest.mark.parametrize("kind", ["missing", "folder", "binary"])
def test_unreadable_file_is_one_line_exit_2(toy: Path, tmp_path: Path, capsys,
                                            kind: str) -> None:
    config = tmp_path / "run.toml"
    if kind == "folder":
        config.mkdir()
    elif kind == "binary":
        config.write_bytes(b"\xff\xfe\x00gain")
    assert _run(toy, tmp_path / "out", config) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fluxcal: error: ") and str(config) in err and "--config" in err
    assert "cannot read the run-configuration file" in err
    assert not (tmp_path / "out").exists()


def test_keys_are_fields_or_long_options_and_paths_are_relative_to_the_file(
        tmp_path: Path) -> None:
    config = tmp_path / "conf" / "messenger.toml"
    config.parent.mkdir()
    config.write_text('frames = ["mso", "rtn"]\naverage = [1, 5]\nmax-offset-step = 0\n'
                      'product-version = 3\ncalib = "fitted"\nquicklook = true\n')
    got = read_config(config, MessengerOptions)
    assert got == {"frames": ("mso", "rtn"), "averages": (1, 5), "max_offset_step": None,
                   "version": 3, "calib": tmp_path / "conf" / "fitted", "quicklook": True}
    ros = tmp_path / "rosetta.toml"
    ros.write_text('average = 60\nlevels = ["A", "B", "C"]\nprimary = "ib"\n')
    assert read_config(ros, RosettaOptions) == {"average_s": 60.0, "levels": ("A", "B", "C"),
                                                "primary": "IB"}


def test_a_field_given_twice_and_checks_of_the_option_name_the_file(tmp_path: Path) -> None:
    config = tmp_path / "m.toml"
    config.write_text("averages = [1]\naverage = [5]\n")
    with pytest.raises(InputFormatError, match=r"line 2, field 'average'.*again"):
        read_config(config, MessengerOptions)
    config.write_text("\nversion = 100\n")
    with pytest.raises(InputFormatError,
                       match=r"m\.toml, line 2, field 'version': .*1-99"):
        read_config(config, MessengerOptions)


def test_every_options_command_offers_config(capsys) -> None:
    for cmd in (["messenger", "edr2cdr"], ["rosetta", "calibrate"], ["imap", "calibrate"],
                ["batch", "messenger"], ["batch", "rosetta"], ["batch", "imap"]):
        assert main([*cmd, "--help"]) == 0
        assert "--config" in capsys.readouterr().out, cmd


def test_the_documented_examples_read() -> None:
    docs = Path(__file__).resolve().parents[2] / "docs" / "examples"
    msgr = read_config(docs / "edr2cdr.toml", MessengerOptions)
    assert msgr["frames"] == ("mso", "rtn") and msgr["averages"] == (1, 60)
    assert msgr["version"] == 2 and msgr["max_offset_step"] == 2.0
    ros = read_config(docs / "rosetta.toml", RosettaOptions)
    assert ros["levels"] == ("A", "B", "C", "F", "G") and ros["average_s"] == 60.0
