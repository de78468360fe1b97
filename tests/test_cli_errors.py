"""Every user-facing CLI error: one line on stderr, exit code 2, nothing left behind.

A table of bad inputs walks the commands through `fluxcal.cli.main`.  For each case the
test checks the exit code, that stderr holds exactly one line starting
``fluxcal: error:`` (no traceback), that the line names the offending path or option,
and that the output folder holds exactly what it held before (a ``keep.txt``).
"""

from __future__ import annotations

import errno
import gzip
import socket
from pathlib import Path

import pytest

from fluxcal.cli import main
from fluxcal.errors import FluxcalError

ROSETTA_CSV = ("time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality\n"
               "2014-08-01T00:00:00.000000,365471901.094381,2,12267,-3093,21919,10193,10818,0\n")
MESSENGER_SCI_HEADER = "partition,met,rate,range,cx,cy,cz\n"


def _free_port() -> int:
    with socket.socket() as s:  # bound then closed: nothing listens there afterwards
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture()
def world(tmp_path: Path) -> dict[str, Path]:
    """Small bad and good inputs, an output folder with one file, a file as 'folder'."""
    w = {"tmp": tmp_path}
    w["out"] = tmp_path / "out"
    w["out"].mkdir()
    (w["out"] / "keep.txt").write_text("kept\n")
    w["file"] = tmp_path / "a_file"
    w["file"].write_text("not a folder\n")
    w["blocked"] = w["file"] / "out"  # a file where a folder is needed
    w["csv"] = tmp_path / "RPCMAG_20140801_RAW_OB.csv"
    w["csv"].write_text(ROSETTA_CSV)
    w["gz"] = tmp_path / "RPCMAG_20140801_RAW_OB.csv.gz"
    w["gz"].write_bytes(gzip.compress(ROSETTA_CSV.encode()))
    w["header_only"] = tmp_path / "RPCMAG_20140801_RAW_IB.csv"
    w["header_only"].write_text(ROSETTA_CSV.splitlines()[0] + "\n")
    w["empty_cdf"] = tmp_path / "empty.cdf"
    w["empty_cdf"].write_bytes(b"")
    w["corrupt_cdf"] = tmp_path / "corrupt.cdf"
    w["corrupt_cdf"].write_bytes(b"\xcd\xf3\x00\x01\x00\x00\xff\xff" + b"\x07" * 300)
    w["inputs"] = tmp_path / "inputs"
    w["inputs"].mkdir()
    w["mess_hdr"] = tmp_path / "MAG_science.csv"
    w["mess_hdr"].write_text(MESSENGER_SCI_HEADER)
    return w


def _batch(w, *extra: str) -> list[str]:
    return ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-01",
            "--input", str(w["inputs"]), "--scheduler", "serial", "--quiet", *extra]


def _calibrate(w, science: str = "csv", *extra: str) -> list[str]:
    return ["rosetta", "calibrate", "--science", str(w[science]), "--sensor", "OB", *extra]


# (case id, argv builder, text the error line must contain)
CASES = [
    ("calibrate-out-is-a-file", lambda w: [*_calibrate(w), "--out", str(w["blocked"])],
     "--out"),
    ("calibrate-calib-missing", lambda w: [*_calibrate(w), "--out", str(w["out"]),
                                           "--calib", str(w["tmp"] / "no_such_dir")],
     "--calib"),
    ("calibrate-kernels-missing", lambda w: [*_calibrate(w), "--out", str(w["out"]),
                                             "--kernels", str(w["tmp"] / "none.tm")],
     "--kernels"),
    ("calibrate-gzip-input", lambda w: [*_calibrate(w, "gz"), "--out", str(w["out"])],
     "gunzip"),
    ("calibrate-header-only", lambda w: [*_calibrate(w, "header_only"), "--out",
                                         str(w["out"])], "RPCMAG_20140801_RAW_IB.csv"),
    ("simulate-rosetta-out-is-a-file",
     lambda w: ["simulate", "rosetta", "--out", str(w["blocked"])], "--out"),
    ("simulate-rosetta-negative-hours",
     lambda w: ["simulate", "rosetta", "--out", str(w["out"]), "--hours", "-1"], "--hours"),
    ("simulate-rosetta-zero-rate",
     lambda w: ["simulate", "rosetta", "--out", str(w["out"]), "--rate", "0"], "--rate"),
    ("simulate-rosetta-bad-start",
     lambda w: ["simulate", "rosetta", "--out", str(w["out"]), "--start", "yesterday"],
     "--start"),
    ("simulate-rosetta-bad-primary",
     lambda w: ["simulate", "rosetta", "--out", str(w["out"]), "--primary", "XB"],
     "--primary"),
    ("simulate-messenger-out-is-a-file",
     lambda w: ["simulate", "messenger", "--out", str(w["blocked"])], "a_file"),
    ("plot-empty-cdf", lambda w: ["plot", str(w["empty_cdf"]), "--out", str(w["out"])],
     "empty.cdf"),
    ("plot-corrupt-cdf", lambda w: ["plot", str(w["corrupt_cdf"]), "--out", str(w["out"])],
     "corrupt.cdf"),
    ("plot-out-is-a-file", lambda w: ["plot", str(w["corrupt_cdf"]), "--out",
                                      str(w["blocked"])], "--out"),
    ("clean-empty-cdf", lambda w: ["rosetta", "clean", "--level", "K", "--input",
                                   str(w["empty_cdf"]), "--out", str(w["out"])], "empty.cdf"),
    ("clean-corrupt-cdf", lambda w: ["rosetta", "clean", "--level", "K", "--input",
                                     str(w["corrupt_cdf"]), "--out", str(w["out"])],
     "corrupt.cdf"),
    ("demo-out-is-a-file", lambda w: ["demo", "--out", str(w["blocked"])], "a_file"),
    ("batch-out-is-a-file", lambda w: [*_batch(w), "--out", str(w["blocked"])], "--out"),
    ("batch-kernels-missing", lambda w: [*_batch(w), "--out", str(w["out"]), "--kernels",
                                         str(w["tmp"] / "none.tm")], "--kernels"),
    ("batch-calib-missing", lambda w: [*_batch(w), "--out", str(w["out"]), "--calib",
                                       str(w["tmp"] / "no_such_dir")], "--calib"),
    ("batch-bad-format", lambda w: [*_batch(w), "--out", str(w["out"]), "--formats",
                                    "tab,pdf"], "--formats"),
    ("batch-unreachable-scheduler",
     lambda w: ["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-01",
                "--input", str(w["inputs"]), "--out", str(w["out"]), "--quiet",
                "--scheduler", f"tcp://127.0.0.1:{_free_port()}"], "--scheduler"),
]


def _snapshot(w) -> set[str]:
    return {str(p.relative_to(w["tmp"])) for p in w["tmp"].rglob("*")}


@pytest.mark.parametrize("build,expect", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_nothing_left(world, capsys, build, expect) -> None:
    before = _snapshot(world)
    code = main(build(world))
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("fluxcal: error: "), err
    assert expect in lines[0], lines[0]
    assert "Traceback" not in err
    assert _snapshot(world) == before  # nothing new anywhere, keep.txt untouched
    assert (world["out"] / "keep.txt").read_text() == "kept\n"


@pytest.mark.parametrize("kind", ["header-only", "gzip"])
def test_messenger_bad_science_file(world, capsys, kind) -> None:
    sci = world["mess_hdr"]
    if kind == "gzip":
        sci = world["tmp"] / "MAG_science.csv.gz"
        sci.write_bytes(gzip.compress(b"partition,met,rate,range,cx,cy,cz\n1,2,3,0,1,2,3\n"))
    heater, temp = world["tmp"] / "MAG_heater.csv", world["tmp"] / "MAG_temperature.csv"
    heater.write_text("partition,met,heater\n1,246993728,0\n")
    temp.write_text("partition,met,temperature_c\n1,246993728,20.0\n")
    before = _snapshot(world)
    code = main(["messenger", "edr2cdr", "--sci", str(sci), "--heater", str(heater),
                 "--temperature", str(temp), "--kernels", str(world["file"]),
                 "--out", str(world["out"])])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and sci.name in err, err
    assert _snapshot(world) == before


def test_full_disk_during_simulate_leaves_nothing(world, capsys, monkeypatch) -> None:
    """ENOSPC half-way through ``simulate rosetta``: one line, exit 2, no partial set."""
    from fluxcal.missions.rosetta import calib

    def full(model, folder, *args, **kwargs):  # after the kernels and alignment are written
        raise OSError(errno.ENOSPC, "No space left on device", str(Path(folder) / "x.TXT"))

    monkeypatch.setattr(calib, "write_daily_offset_model", full)
    target = world["out"] / "sim"
    before = _snapshot(world)
    code = main(["simulate", "rosetta", "--out", str(target), "--hours", "0.01"])
    err = capsys.readouterr().err
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "No space left on device" in line and "free space" in line and "x.TXT" in line
    assert _snapshot(world) == before


def test_debug_shows_the_traceback(world, monkeypatch) -> None:
    # the --out check (before the command runs) raises; --debug lets it through
    with pytest.raises(FluxcalError, match="is a file, not a folder"):
        main(["--debug", "demo", "--out", str(world["blocked"])])
    monkeypatch.setenv("FLUXCAL_DEBUG", "1")
    with pytest.raises(FluxcalError, match="is a file, not a folder"):
        main(["demo", "--out", str(world["blocked"])])


def test_internal_error_is_one_line_exit_1(world, capsys, monkeypatch) -> None:
    """A bug (not a user error) is one line pointing to --debug, exit 1."""
    import fluxcal.runs.demo

    def bug(out):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(fluxcal.runs.demo, "run_demo", bug)
    assert main(["demo", "--out", str(world["out"])]) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "internal error" in line and "--debug" in line


@pytest.mark.parametrize("argv,expect", [
    (["no-such-command"], "no-such-command"),
    (["simulate", "rosetta", "--hours", "many"], "--hours"),
    (["batch", "synthetic", "--start", "2024-03-01", "--end", "2024-03-01",
      "--input", "/no/such/input", "--out", "x"], "--input"),
    (["batch"], "mission"),
])
def test_usage_errors_are_one_line_too(capsys, argv, expect) -> None:
    """Before: click's three-line 'Usage: ... Try ... Error: ...' block."""
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("fluxcal: error: ") and expect in line and "--help" in line


# --- issue 22: hostile inputs (binary files, huge or fractional counts, BOM, bad options) ---

#: Bytes of a binary file (a NUL, then every byte value): what a user gives by mistake.
BINARY = bytes(range(256)) * 8
MESSENGER_ROWS = ("1,246995038.000000,10,0,-197,-507,527\n"
                  "1,246995038.050000,10,0,-219,-508,532\n"
                  "1,246995038.100000,10,0,-212,-501,530\n")


@pytest.fixture()
def hostile(world) -> dict[str, Path]:
    """Inputs a hostile tester gives: binary files, out-of-range numbers, a BOM header."""
    import shutil

    from fluxcal.missions.messenger.calibration_data import data_dir

    w = dict(world)
    tmp = w["tmp"]

    def put(name: str, content: str | bytes) -> Path:
        p = tmp / name
        (p.write_bytes if isinstance(content, bytes) else p.write_text)(content)
        return p

    w["bin_csv"] = put("RPCMAG_20140801_RAW_OB_bin.csv", BINARY)
    w["bin_body_csv"] = put("RPCMAG_20140801_RAW_OB_body.csv",
                            ROSETTA_CSV.encode() + BINARY)
    row = ROSETTA_CSV.splitlines()[1].split(",")
    w["r_20digit"] = put("RAW_OB_20digit.csv", ROSETTA_CSV.splitlines()[0] + "\n" + ",".join(
        [*row[:3], "12345678901234567890", *row[4:]]) + "\n")
    w["r_fraction"] = put("RAW_OB_fraction.csv", ROSETTA_CSV.splitlines()[0] + "\n" + ",".join(
        [*row[:3], "12267.5", *row[4:]]) + "\n")
    w["r_bom_fraction"] = put("RAW_OB_bom.csv", "\ufeff" + w["r_fraction"].read_text())
    w["m_bin"] = put("MAG_science_bin.csv", BINARY)
    w["m_bin_body"] = put("MAG_science_body.csv", (MESSENGER_SCI_HEADER + MESSENGER_ROWS)
                          .encode() + BINARY)
    w["m_20digit"] = put("MAG_science_20digit.csv", MESSENGER_SCI_HEADER + MESSENGER_ROWS
                         + "1,246995038.150000,10,0,12345678901234567890,-501,530\n")
    w["m_fraction"] = put("MAG_science_fraction.csv", MESSENGER_SCI_HEADER + MESSENGER_ROWS
                          + "1,246995038.150000,10,0,-212.5,-501,530\n")
    w["m_bom_fraction"] = put("MAG_science_bom.csv", "\ufeff" + w["m_fraction"].read_text())
    w["m_sci"] = put("MAG_science_good.csv", MESSENGER_SCI_HEADER + MESSENGER_ROWS)
    w["m_heater"] = put("MAG_heater.csv", "partition,met,heater\n1,246993728,0\n")
    w["m_temp"] = put("MAG_temperature.csv", "partition,met,temperature_c\n1,246993728,20.0\n")
    w["bin_intervals"] = put("intervals.csv", BINARY)
    # a calibration folder of every shipped MESSENGER table, its TOML replaced by binary bytes
    w["m_calib"] = tmp / "messenger_calib"
    shutil.copytree(data_dir(), w["m_calib"], ignore=shutil.ignore_patterns("*.py", "*.yaml",
                                                                            "edr_*"))
    (w["m_calib"] / "processing_v1.toml").write_bytes(BINARY)
    # a Rosetta calibration folder whose daily CALIB file is binary
    w["r_calib"] = tmp / "rosetta_calib"
    w["r_calib"].mkdir()
    (w["r_calib"] / "RPCMAG_140801_006_CALIB_OB.TXT").write_bytes(BINARY)
    return w


def _edr2cdr(w, sci: str = "m_sci", *extra: str) -> list[str]:
    return ["messenger", "edr2cdr", "--sci", str(w[sci]), "--heater", str(w["m_heater"]),
            "--temperature", str(w["m_temp"]), "--kernels", str(w["file"]),
            "--out", str(w["out"]), *extra]


def _sim_messenger(w, *extra: str) -> list[str]:
    return ["simulate", "messenger", "--out", str(w["out"] / "sim"), *extra]


# (case id, argv builder, texts the error line must contain)
HOSTILE = [
    # binary bytes where text is expected
    ("rosetta-csv-binary", lambda w: [*_calibrate(w, "bin_csv"), "--out", str(w["out"])],
     ["RPCMAG_20140801_RAW_OB_bin.csv", "line 1", "binary"]),
    ("rosetta-csv-binary-body", lambda w: [*_calibrate(w, "bin_body_csv"), "--out",
                                           str(w["out"])],
     ["RPCMAG_20140801_RAW_OB_body.csv", "line 3", "binary"]),
    ("messenger-csv-binary", lambda w: _edr2cdr(w, "m_bin"),
     ["MAG_science_bin.csv", "line 1", "binary"]),
    ("messenger-csv-binary-body", lambda w: _edr2cdr(w, "m_bin_body"),
     ["MAG_science_body.csv", "line 5", "binary"]),
    ("messenger-calib-toml-binary", lambda w: _edr2cdr(w, "m_sci", "--calib",
                                                       str(w["m_calib"])),
     ["processing_v1.toml", "line 1", "binary"]),
    ("rosetta-daily-calib-binary", lambda w: [*_calibrate(w), "--out", str(w["out"]),
                                              "--calib", str(w["r_calib"])],
     ["RPCMAG_140801_006_CALIB_OB.TXT", "line 1", "binary"]),
    ("messenger-fit-intervals-binary",
     lambda w: ["messenger", "fit", "--sci", str(w["m_sci"]), "--heater", str(w["m_heater"]),
                "--temperature", str(w["m_temp"]), "--kernels", str(w["file"]),
                "--intervals", str(w["bin_intervals"]), "--out", str(w["out"] / "fit")],
     ["intervals.csv", "line 1", "binary"]),
    ("rosetta-clean-intervals-binary",
     lambda w: ["rosetta", "clean", "--level", "K", "--input", str(w["empty_cdf"]),
                "--intervals", str(w["bin_intervals"]), "--out", str(w["out"])],
     ["intervals.csv", "line 1", "binary"]),
    # numbers: a 20-digit count, a fractional count (plain numbers, no np.float64(...))
    ("rosetta-20-digit-count", lambda w: [*_calibrate(w, "r_20digit"), "--out",
                                          str(w["out"])],
     ["RAW_OB_20digit.csv", "line 2", "field 'bx'", "12345678901234567890", "outside"]),
    ("messenger-20-digit-count", lambda w: _edr2cdr(w, "m_20digit"),
     ["MAG_science_20digit.csv", "line 5", "field 'cx'", "outside the signed 16-bit"]),
    ("rosetta-fractional-count", lambda w: [*_calibrate(w, "r_fraction"), "--out",
                                            str(w["out"])],
     ["RAW_OB_fraction.csv", "line 2", "field 'bx'", "not an integer"]),
    ("messenger-fractional-count", lambda w: _edr2cdr(w, "m_fraction"),
     ["MAG_science_fraction.csv", "line 5", "field 'cx'", "-212.5 is not an integer"]),
    # a UTF-8 BOM is not part of the first column's name: the next defect is reported
    ("rosetta-bom-header", lambda w: [*_calibrate(w, "r_bom_fraction"), "--out",
                                      str(w["out"])],
     ["RAW_OB_bom.csv", "line 2", "field 'bx'", "not an integer"]),
    ("messenger-bom-header", lambda w: _edr2cdr(w, "m_bom_fraction"),
     ["MAG_science_bom.csv", "line 5", "field 'cx'", "not an integer"]),
    # options
    ("messenger-average-0", lambda w: _edr2cdr(w, "m_sci", "--average", "0"), ["--average"]),
    ("messenger-average-negative", lambda w: _edr2cdr(w, "m_sci", "--average", "-5"),
     ["--average"]),
    ("rosetta-average-0", lambda w: [*_calibrate(w), "--out", str(w["out"]), "--levels",
                                     "A,B,E", "--average", "0"], ["--average", "above 0"]),
    ("rosetta-average-negative", lambda w: [*_calibrate(w), "--out", str(w["out"]),
                                            "--average", "-5"], ["--average", "above 0"]),
    ("rosetta-clean-average-0", lambda w: ["rosetta", "clean", "--level", "I", "--input",
                                           str(w["empty_cdf"]), "--average", "0", "--out",
                                           str(w["out"])], ["--average", "above 0"]),
    ("simulate-messenger-duration-0", lambda w: _sim_messenger(w, "--duration", "0"),
     ["--duration", "86400"]),
    ("simulate-messenger-duration-negative", lambda w: _sim_messenger(w, "--duration", "-5"),
     ["--duration", "86400"]),
    ("simulate-messenger-duration-huge", lambda w: _sim_messenger(w, "--duration", "1e9"),
     ["--duration", "at most 86400 s"]),
    ("simulate-messenger-bad-start", lambda w: _sim_messenger(w, "--start", "garbage"),
     ["--start", "garbage"]),
    ("simulate-rosetta-hours-huge",
     lambda w: ["simulate", "rosetta", "--out", str(w["out"] / "sim"), "--hours", "1e9"],
     ["--hours", "at most 744 h"]),
]


@pytest.mark.parametrize("build,expect", [c[1:] for c in HOSTILE], ids=[c[0] for c in HOSTILE])
def test_hostile_input_is_one_line_exit_2(hostile, capsys, build, expect) -> None:
    """Before: 'internal error ... a bug' (exit 1), np.float64(...), '\\ufeffpartition'."""
    before = _snapshot(hostile)
    code = main(build(hostile))
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines()
             if ln.strip() and not ln.startswith("fluxcal: compiling")]  # first-run notice
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("fluxcal: error: "), err
    for text in expect:
        assert text in lines[0], lines[0]
    for wrong in ("np.float64", "np.int64", "\\ufeff", "\ufeff", "internal error", "Error:"):
        assert wrong not in lines[0], lines[0]
    assert _snapshot(hostile) == before  # nothing new in --out (or anywhere)
