"""Command-line conventions (issue 25): --version, help never cut, no <bool>, -q/--quiet."""

from __future__ import annotations

import logging
import re
import sys

import pytest
import typer

from fluxcal import __version__
from fluxcal.cli import app, main


def _command_paths(cmd, path: tuple[str, ...] = ()):
    yield path
    for name, sub in getattr(cmd, "commands", {}).items():
        yield from _command_paths(sub, (*path, name))


PATHS = list(_command_paths(typer.main.get_command(app)))


def test_root_version_option_prints_the_version_and_exits_0(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == __version__
    assert main(["version"]) == 0  # the subcommand stays
    assert capsys.readouterr().out.strip() == __version__


def test_version_inside_edr2cdr_is_still_the_product_version(capsys):
    # --product-version; the old --version still parses but is not shown (issue 31)
    assert main(["messenger", "edr2cdr", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--product-version <int>" in out and "_V<nn>" in out and "--version" not in out


def test_the_tree_has_every_command():
    assert len(PATHS) >= 14, PATHS
    for p in [(), ("messenger", "edr2cdr"), ("messenger", "fit"), ("rosetta", "calibrate"),
              ("rosetta", "fit"), ("rosetta", "clean"), ("simulate", "messenger"),
              ("batch",), ("compare",), ("plot",), ("demo",)]:
        assert p in PATHS


#: "..." is allowed only in click's usage line ("COMMAND [ARGS]...") and for arguments
#: that take several values ("FILES...")
CUT = re.compile(r"\w\.\.\.(?!\S)|…")


@pytest.mark.parametrize("columns", [60, 80])
def test_no_help_text_is_cut_and_flags_show_no_metavar(columns, monkeypatch, capsys):
    """Before: 9 option help texts ended in "…" at 80 columns; flags showed <bool>."""
    monkeypatch.setenv("COLUMNS", str(columns))
    for path in PATHS:
        assert main([*path, "--help"]) == 0, path
        out = capsys.readouterr().out
        assert "<bool>" not in out, path
        for line in out.splitlines():
            if line.startswith("Usage:"):
                continue
            assert not CUT.search(line), (path, line)


def test_every_command_summary_is_whole_in_its_group(capsys):
    """A group's list shows each command's whole first paragraph (click cut it at ...)."""
    assert main(["rosetta", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Derive calibration files from flight data (RO-IGEP-TR0028 sec. 4.2.3.3, 4.2.3.4)." \
        in text
    assert main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "with its quicklook and HTML report (seconds)." in text  # the demo's summary


def test_help_uses_wide_terminals_up_to_120_columns(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "200")
    assert main(["messenger", "edr2cdr", "--help"]) == 0
    widths = [len(line) for line in capsys.readouterr().out.splitlines()]
    assert 100 < max(widths) <= 120


def test_quiet_logs_errors_only_and_hides_progress(monkeypatch, capsys):
    from fluxcal.cli_help import progress_wanted, quiet_requested
    from fluxcal.missions.messenger.cli import progress_display, status_display

    levels, seen = [], []
    monkeypatch.setattr(logging, "basicConfig", lambda **kw: levels.append(kw["level"]))
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)

    def echo(*args, **kwargs):  # what the running `version` command sees
        seen.append((quiet_requested(), progress_wanted()))
        if quiet_requested():
            with progress_display() as progress, status_display("simulating"):
                seen.append(progress is None)

    monkeypatch.setattr(typer, "echo", echo)
    assert main(["version"]) == 0
    assert levels[-1] == logging.WARNING and seen[-1] == (False, True)
    assert logging.getLogger("fluxcal").level == logging.NOTSET
    assert main(["-v", "version"]) == 0  # fluxcal's own steps; other libraries: warnings
    assert levels[-1] == logging.WARNING and logging.getLogger("fluxcal").level == logging.INFO
    assert main(["-q", "version"]) == 0
    assert levels[-1] == logging.ERROR and seen[-2:] == [(True, False), True]
    assert main(["--quiet", "version"]) == 0 and seen[-2] == (True, False)
    assert not quiet_requested()  # no process-wide flag outlives the command
    assert capsys.readouterr().err == ""


def test_quiet_and_verbose_exclude_each_other(capsys):
    assert main(["-q", "-v", "version"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("fluxcal: error:") and "--quiet" in line
