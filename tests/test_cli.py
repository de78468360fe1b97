"""The top-level ``fluxcal`` command: exit codes and messages."""

from __future__ import annotations

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
                ["simulate", "messenger"], ["simulate", "rosetta"], ["plot"], ["batch"],
                ["demo"]):
        assert main([*cmd, "--help"]) == 0, cmd
