"""Hostile option values and inputs (issue 31 item 4): refused in one line, exit 2.

Every run option is checked where it is declared (`fluxcal.runs.options.check_fields`),
so the command line, a ``--config`` TOML file and the Python API refuse the same values
with the same message.  The expected refusals are the issue's reproducers and the ranges
documented in docs/guide/run_config.md: numbers finite, averaging intervals 1 s to one
day (86,400 s), at least one frame, product version 1-99.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.missions.rosetta.options import RosettaOptions
from tests.conftest import SHARED_DATA

NAN, INF = float("nan"), float("inf")

# (options class, command-line flag, CLI text, TOML text, API keyword and value)
BAD = [
    (MessengerOptions, "--max-offset-step", "nan", "nan", {"max_offset_step": NAN}),
    (MessengerOptions, "--max-offset-step", "inf", "inf", {"max_offset_step": INF}),
    (MessengerOptions, "--max-offset-step", "-inf", "-inf", {"max_offset_step": -INF}),
    (MessengerOptions, "--frames", "", "[]", {"frames": ()}),
    (MessengerOptions, "--frames", "mso,xyz", '["mso", "xyz"]', {"frames": ("mso", "xyz")}),
    (MessengerOptions, "--average", "100000", "[100000]", {"averages": (100000,)}),
    (MessengerOptions, "--average", "0", "[0]", {"averages": (0,)}),
    (MessengerOptions, "--average", "5,5", "[5, 5]", {"averages": (5, 5)}),
    (MessengerOptions, "--product-version", "0", "0", {"version": 0}),
    (MessengerOptions, "--formats", "xls", '["xls"]', {"formats": ("xls",)}),
    (RosettaOptions, "--average", "nan", "nan", {"average_s": NAN}),
    (RosettaOptions, "--average", "100000", "100000", {"average_s": 100000.0}),
    (RosettaOptions, "--stitch-gap-hours", "inf", "inf", {"stitch_gap_hours": INF}),
    (RosettaOptions, "--stitch-gap-hours", "-1", "-1", {"stitch_gap_hours": -1.0}),
]
IDS = [f"{c[0].__name__[:-7]}{c[1]}={c[2] or 'empty'}" for c in BAD]


def _argv(cls: type, tmp: Path, *extra: str) -> list[str]:
    """A command of ``cls``'s mission whose inputs do not exist (options are checked first)."""
    out = str(tmp / "out")
    if cls is MessengerOptions:
        return ["messenger", "edr2cdr", "--input", str(tmp / "none.csv"), "--kernels",
                str(tmp / "none.tm"), "--out", out, *extra]
    return ["rosetta", "calibrate", "--input", str(tmp / "none.csv"), "--sensor", "OB",
            "--out", out, *extra]


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("fluxcal: error: "), err
    assert "Traceback" not in err and "(" + "'" not in lines[0]  # no Python tuple repr
    return lines[0]


def _reason(line: str) -> str:
    """The message after ``field '<name>': `` (the same wherever the value came from)."""
    return line.split("': ", 1)[1]


@pytest.mark.parametrize(("cls", "flag", "cli", "toml", "api"), BAD, ids=IDS)
def test_cli_config_and_api_refuse_alike(tmp_path: Path, capsys, cls, flag, cli, toml,
                                         api) -> None:
    assert main(_argv(cls, tmp_path, f"{flag}={cli}")) == 2
    on_cli = _one_line(capsys)
    assert f"'{flag}'" in on_cli

    config = tmp_path / "run.toml"
    key = flag.lstrip("-")
    config.write_text(f"{key} = {toml}\n")
    assert main(_argv(cls, tmp_path, "--config", str(config))) == 2
    in_file = _one_line(capsys)
    assert str(config) in in_file and "line 1" in in_file and f"'{key}'" in in_file

    with pytest.raises(InputFormatError) as exc:
        cls(**api)
    assert f"'{flag}'" in str(exc.value)
    assert _reason(on_cli) == _reason(in_file) == _reason(str(exc.value))
    assert not (tmp_path / "out").exists()


def test_nan_never_switches_the_offset_check_off() -> None:
    """``<= 0 disables`` is a decision of the command line; nan is not <= 0 nor > 0."""
    assert MessengerOptions(max_offset_step=None).max_offset_step is None
    for value in (NAN, INF, 0.0, -1.0):
        with pytest.raises(InputFormatError, match="--max-offset-step"):
            MessengerOptions(max_offset_step=value)
    assert math.isclose(MessengerOptions(max_offset_step=3).max_offset_step, 3.0)


def test_api_forms_are_normalised() -> None:
    """A list, a comma-separated string or an upper-case name mean what the CLI means."""
    opts = MessengerOptions(frames=["MSO", "rtn"], averages=[1, 60], calib="cal")
    assert opts.frames == ("mso", "rtn") and opts.averages == (1, 60)
    assert opts.calib == Path("cal")
    assert MessengerOptions(frames="mso,rtn").frames == ("mso", "rtn")
    assert RosettaOptions(average_s=2).average_s == 2.0


@pytest.mark.parametrize("kwargs", [{"averages": (NAN,)}, {"averages": (1.5,)},
                                    {"version": True}, {"version": 2.0},
                                    {"frames": (1,)}, {"quicklook": "yes"},
                                    {"averages": 5}, {"frames": 3}])
def test_api_wrong_types_are_input_errors(kwargs) -> None:
    """Not ``cannot convert float NaN to integer`` deep in the run: refused up front."""
    with pytest.raises(InputFormatError, match="field '--"):
        MessengerOptions(**kwargs)


def test_messenger_api_nan_option(tmp_path: Path) -> None:
    """The function route with a NaN option refuses before anything is read."""
    from fluxcal.missions.messenger.routes import run_edr2cdr

    with pytest.raises(InputFormatError, match="--average"):
        run_edr2cdr([tmp_path / "s.csv"], [], [], tmp_path / "k.tm", tmp_path / "out",
                    averages=[NAN])
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["1", "86400", "1,5,10,60"])
def test_average_range_accepts_its_ends(value: str) -> None:
    from fluxcal.runs.options import from_command_line

    opts = from_command_line(MessengerOptions, {"averages": value})
    assert opts.averages == tuple(int(v) for v in value.split(","))


def _cdf(path: Path, attrs: dict[str, str]) -> Path:
    from cdflib.cdfwrite import CDF

    cdf = CDF(str(path), cdf_spec={"Compressed": False})
    cdf.write_globalattrs({k: {0: v} for k, v in attrs.items()})
    cdf.close()
    return path


@pytest.mark.parametrize(("attrs", "expect"), [
    ({"Project": "another tool"}, "not a product written by fluxcal"),
    ({"software": "fluxcal", "inputs": 'json:[{"name": '}, "field 'inputs': broken JSON"),
    ({"software": "fluxcal", "kernels": "json:5"}, "field 'kernels': expected a JSON list"),
    ({"software": "fluxcal", "calibration": 'json:{"a": 1}'},
     "field 'calibration': expected a JSON dict"),
])
def test_provenance_of_a_foreign_or_broken_file(tmp_path: Path, capsys, attrs, expect) -> None:
    """Not empty lists and exit 0, not a JSONDecodeError: one line naming file and field."""
    path = _cdf(tmp_path / "x.cdf", attrs)
    assert main(["provenance", str(path)]) == 2
    line = _one_line(capsys)
    assert "x.cdf" in line and expect in line, line


def test_provenance_of_a_foreign_netcdf(tmp_path: Path, capsys) -> None:
    import xarray as xr

    path = tmp_path / "x.nc"
    xr.Dataset({"a": ("t", np.arange(3.0))}, attrs={"title": "x"}).to_netcdf(path)
    assert main(["provenance", str(path)]) == 2
    assert "not a product written by fluxcal" in _one_line(capsys)


def _quoted(lines: list[str]) -> str:
    """The lines as a spreadsheet exports them: every field quoted, CRLF (RFC 4180)."""
    return "".join(",".join(f'"{v}"' for v in ln.split(",")) + "\r\n" for ln in lines)


def test_messenger_csv_with_quoted_header_reads_as_plain(tmp_path: Path) -> None:
    """The same numbers from ``"partition","met",...`` as from the unquoted file."""
    from fluxcal.missions.messenger.readers import SCIENCE_COLUMNS, _read_table

    lines = [",".join(SCIENCE_COLUMNS), "1,246993728.5,3,0,12,-7,30000",
             "1,246993729,3,1,-32768,0,5"]
    plain, quoted = tmp_path / "plain.csv", tmp_path / "quoted.csv"
    plain.write_text("\n".join(lines) + "\n")
    quoted.write_bytes(_quoted(lines).encode())
    expected = np.array([[1, 1], [246993728.5, 246993729], [3, 3], [0, 1], [12, -32768],
                         [-7, 0], [30000, 5]], dtype=float)  # the numbers written above
    np.testing.assert_array_equal(_read_table(plain, SCIENCE_COLUMNS), expected)
    np.testing.assert_array_equal(_read_table(quoted, SCIENCE_COLUMNS), expected)


def test_rosetta_csv_with_quoted_header_reads_as_plain(tmp_path: Path) -> None:
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.missions.rosetta import io

    lines = ["time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality",
             "2014-08-01T00:00:00.000000,366076800.000000,2,1000,-2000,300,16000,17000,0",
             "2014-08-01T00:00:00.050000,366076800.050000,2,1001,-2001,301,16000,17000,0"]
    quoted = tmp_path / "quoted.csv"
    quoted.write_bytes(_quoted(lines).encode())
    with KernelPool():
        ds = io.read_science_csv(quoted, "OB")
    assert ds["b_counts"].values.tolist() == [[1000, -2000, 300], [1001, -2001, 301]]
    assert ds["epoch"].values[1] - ds["epoch"].values[0] == 50_000_000  # 0.05 s apart


def test_rosetta_wrong_header_message_has_no_tuple_repr(tmp_path: Path) -> None:
    from fluxcal.missions.rosetta import io

    path = tmp_path / "bad.csv"
    path.write_text("a,b\n1,2\n")
    with pytest.raises(InputFormatError) as exc:
        io.read_science_csv(path, "OB")
    assert "header a,b differs from the expected time_utc,obt," in str(exc.value)


@pytest.mark.slow
def test_messenger_files_across_a_long_gap_calibrate(tmp_path: Path) -> None:
    """2012-06-01 and 2013-01-09 (after the clock reset) in one run, kernels over each.

    Was: exit 2 with a SPICE error at a time in neither input (positions looked up over
    the months between).  Now each day is written, and its field equals the field of
    the same file calibrated alone to 1e-6 nT (interpolation grids differ only in their
    verified nodes: 1e-4 km, 5e-10 rad).
    """
    import fluxcal
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

    inputs, kernels = [], []
    for i, start in enumerate(("2012-06-01T00:00:00", "2013-01-09T02:00:00")):
        mk = write_messenger_like_kernels(tmp_path / f"k{i}", start, 600.0, margin_s=600.0)
        with KernelPool(mk):
            sim = simulate(SimulationConfig(start_utc=start, duration_s=600.0,
                                            solar_wind="quiet"),
                           load_calibration(start), SclkKernel.from_pool(-236))
        inputs.append(write_inputs(sim, tmp_path / f"in{i}"))
        kernels.append(mk)

    def run(out: Path, which: list[int], kernel_files: list[Path]) -> int:
        argv = ["messenger", "edr2cdr", "--out", str(out), "--formats", "cdf",
                "--average", "", "--frames", "mso"]
        for i in which:
            argv += ["--sci", str(inputs[i]["science"]), "--heater",
                     str(inputs[i]["heater"]), "--temperature",
                     str(inputs[i]["temperature"])]
        return main(argv + [a for k in kernel_files for a in ("--kernels", str(k))])

    both = [kernels[0].parent / n for n in ("msgr_synthetic.tsc", "msgr_synthetic.tf")]
    both += [k.parent / n for k in kernels for n in ("msgr_synthetic.bsp",
                                                     "msgr_synthetic_sc.bc")]
    assert run(tmp_path / "both", [0, 1], both) == 0
    for i, day in enumerate(("20120601", "20130109")):
        assert run(tmp_path / f"alone{i}", [i], [kernels[i]]) == 0
        name = f"messenger_mag_mso-sci_{day}_v01.cdf"
        joint = fluxcal.read_product(tmp_path / "both" / name)
        alone = fluxcal.read_product(tmp_path / f"alone{i}" / name)
        assert joint.sizes["time"] == alone.sizes["time"] > 0
        assert np.abs(joint["b"].values - alone["b"].values).max() < 1e-6


@pytest.mark.parametrize("mission", ["synthetic", "rosetta", "messenger", "imap"])
def test_batch_over_a_folder_without_the_missions_files(tmp_path: Path, capsys,
                                                        mission: str) -> None:
    """Every day without data is not success: exit 2 naming the folder, nothing written."""
    folder = tmp_path / "inputs"
    folder.mkdir()
    (folder / "notes.txt").write_text("not telemetry\n")
    (folder / "MAG_science.csv").write_text("partition,met,rate,range,cx,cy,cz\n")
    out = tmp_path / "out"
    extra: list[str] = []
    if mission == "imap":  # IMAP asks for its clock kernel first (no default is shipped)
        sclk = SHARED_DATA / "imap" / "imap_sclk_0036.tsc"
        if not sclk.is_file():
            pytest.skip(f"IMAP SCLK kernel not found at {sclk}")
        extra = ["--kernels", str(sclk)]
    code = main(["batch", mission, "--start", "2014-08-01", "--end", "2014-08-03",
                 "--input", str(folder), "--out", str(out), "--scheduler", "serial",
                 "--quiet", *extra])
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert code == 2 and len(err) == 1, err
    assert "--input" in err[0] and str(folder) in err[0] and mission in err[0]
    assert "2014-08-01 to 2014-08-03" in err[0]
    assert not out.exists()


def test_verbose_shows_fluxcal_steps_not_other_libraries(tmp_path: Path, capsys) -> None:
    """``-v``: fluxcal's INFO lines (the driver's steps), other libraries' at WARNING."""
    import logging

    try:
        assert main(["-v", "simulate", "rosetta", "--out", str(tmp_path / "sim"), "--hours",
                     "0.005"]) == 0
        assert logging.getLogger("fluxcal.runs.driver").isEnabledFor(logging.INFO)
        for other in ("numba", "distributed", "matplotlib", "fsspec"):
            assert not logging.getLogger(other).isEnabledFor(logging.INFO), other
    finally:
        logging.getLogger("fluxcal").setLevel(logging.NOTSET)
    assert main(["version"]) == 0
    assert not logging.getLogger("fluxcal.runs.driver").isEnabledFor(logging.INFO)


@pytest.mark.parametrize(("argv", "shown", "hidden"), [
    (["messenger", "edr2cdr"], ["--input", "--product-version"], ["--sci", "--version"]),
    (["messenger", "fit"], ["--input"], ["--sci"]),
    (["rosetta", "calibrate"], ["--input"], ["--science"]),
    (["rosetta", "fit"], ["--input"], ["--science"]),
    (["batch", "messenger"], ["--input", "--product-version"], ["--version"]),
])
def test_one_input_name_old_names_hidden_but_working(capsys, argv, shown, hidden) -> None:
    """The main input is ``--input`` everywhere; ``--sci``/``--science``/``--version`` parse."""
    assert main([*argv, "--help"]) == 0
    words = set(capsys.readouterr().out.replace(",", " ").split())
    assert set(shown) <= words and not set(hidden) & words, words & set(hidden)


@pytest.mark.parametrize(("old", "new"), [("--sci", "--input"), ("--version", "--product-version")])
def test_old_names_refuse_like_the_new(tmp_path: Path, capsys, old: str, new: str) -> None:
    value = ["0"] if "version" in old else [str(tmp_path / "none.csv")]
    base = ["messenger", "edr2cdr", "--kernels", str(tmp_path / "k.tm"), "--out",
            str(tmp_path / "out")]
    extra = ["--heater", str(tmp_path / "h.csv"), "--temperature", str(tmp_path / "t.csv")]
    extra += [] if "version" not in old else ["--input", str(tmp_path / "none.csv")]
    assert main([*base, *extra, old, *value]) == 2
    line_old = _one_line(capsys)
    assert main([*base, *extra, new, *value]) == 2
    assert _one_line(capsys) == line_old and new in line_old


@pytest.mark.parametrize(("argv", "text", "expect"), [
    (["rosetta", "clean", "--level", "K", "--input", "x.cdf"], 'input = "y.cdf"\n',
     ["line 1", "'input'", "unknown key", "lap-lines", "inputs and --out"]),
    (["rosetta", "clean", "--level", "K", "--input", "x.cdf"], 'seed = 1.5\n',
     ["line 1", "'seed'", "--seed"]),
    (["rosetta", "fit", "--input", "x.csv", "--sensor", "OB"], 'degree = 2\nblok = 3\n',
     ["line 2", "'blok'", "unknown key", "block-seconds"]),
    (["messenger", "fit", "--input", "x.csv"], 'passes = "many"\n',
     ["line 1", "'passes'", "--passes"]),
    (["messenger", "fit", "--input", "x.csv"], 'estimator = ["a", "b"]\n',
     ["line 1", "'estimator'", "expected one value"]),
])
def test_fit_and_clean_take_config_and_refuse_bad_keys(tmp_path: Path, capsys, argv, text,
                                                      expect) -> None:
    config = tmp_path / "run.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out), "--config", str(config)]) == 2
    line = _one_line(capsys)
    assert str(config) in line and all(e in line for e in expect), line
    assert not out.exists()


def test_clean_config_merged_under_the_command_line(tmp_path: Path) -> None:
    """The file's values are defaults; an option given on the command line wins."""
    sim, cal = tmp_path / "sim", tmp_path / "cal"
    assert main(["simulate", "rosetta", "--out", str(sim), "--hours", "0.005"]) == 0
    assert main(["rosetta", "calibrate", "--input", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
                 "--sensor", "OB", "--calib", str(sim / "calib"), "--out", str(cal),
                 "--formats", "cdf"]) == 0
    (level_b,) = cal.glob("rosetta_rpcmag_clb-ob_*.cdf")
    config = tmp_path / "clean.toml"
    config.write_text('no-plot = true\nformats = "cdf"\n')
    base = ["rosetta", "clean", "--level", "K", "--input", str(level_b), "--config",
            str(config)]
    assert main([*base, "--out", str(tmp_path / "a")]) == 0
    assert sorted(p.suffix for p in (tmp_path / "a").iterdir() if p.name != "index.html") \
        == [".cdf"]  # formats and no-plot from the file
    assert main([*base, "--out", str(tmp_path / "b"), "--formats", "tab"]) == 0
    assert sorted(p.suffix for p in (tmp_path / "b").iterdir() if p.name != "index.html") \
        == [".LBL", ".TAB"]  # the command line wins


@pytest.mark.parametrize(("option", "value"), [
    ("--step", "nan"), ("--step", "inf"), ("--max-gap", "inf"), ("--max-gap", "nan"),
    ("--bandwidth", "inf"), ("--lap-lines", "inf"), ("--lap-lines", "nan")])
def test_clean_refuses_nonfinite_numbers_before_reading(tmp_path: Path, capsys, option: str,
                                                       value: str) -> None:
    level = "J" if option in ("--step", "--max-gap") else "H"
    argv = ["rosetta", "clean", "--level", level, "--input", str(tmp_path / "ob.cdf"),
            "--out", str(tmp_path / "out"), "--no-plot", option, value]
    argv += ["--input-ib", str(tmp_path / "ib.cdf")] if level == "J" else []
    argv += ["--lap-lines", "2.5"] if option == "--bandwidth" else []
    assert main(argv) == 2
    line = _one_line(capsys)
    assert option in line and "finite" in line, line


@pytest.mark.parametrize(("option", "value"), [
    ("--block-seconds", "inf"), ("--block-seconds", "nan"), ("--block-seconds", "100000"),
    ("--max-sigma", "nan"), ("--max-sigma", "inf"), ("--max-sigma", "0")])
def test_rosetta_fit_refuses_nonsense_numbers(tmp_path: Path, capsys, option: str,
                                              value: str) -> None:
    """Was: inf an internal error (OverflowError), nan/inf --max-sigma accepted."""
    science = tmp_path / "RPCMAG_20140801_RAW_OB.csv"
    science.write_text("time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality\n"
                       "2014-08-01T00:00:00.000000,365471901.094381,2,1,2,3,10193,10818,0\n")
    assert main(["rosetta", "fit", "--input", str(science), "--sensor", "OB", "--out",
                 str(tmp_path / "out"), option, value]) == 2
    assert f"'{option}'" in _one_line(capsys)
    assert not (tmp_path / "out").exists()


def test_rosetta_run_reports_progress(tmp_path: Path) -> None:
    """The driver's steps reach the progress display of every mission's run (issue 31)."""
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import run_files

    sim = tmp_path / "sim"
    assert main(["simulate", "rosetta", "--out", str(sim), "--hours", "0.005"]) == 0
    steps: list[tuple[str, int, int]] = []
    run_files(sim / "RPCMAG_20140801_RAW_OB.csv", "OB", tmp_path / "out",
              options=RosettaOptions(calib=sim / "calib", formats=("cdf",)),
              progress=lambda text, done, total: steps.append((text, done, total)))
    texts = [s[0] for s in steps]
    assert texts[0] == "reading inputs" and texts[1].startswith("calibrating ")
    assert "writing products" in texts and steps[-1][1:] == (1, 1)
    assert texts[-1].startswith("wrote ")


def test_missing_input_names_the_new_option_only(tmp_path: Path, capsys) -> None:
    assert main(["rosetta", "calibrate", "--sensor", "OB", "--out", str(tmp_path / "o")]) == 2
    line = _one_line(capsys)
    assert "Missing option '--input'" in line and "--science" not in line


def test_closing_a_local_cluster_says_nothing(caplog) -> None:
    """No "Worker process still alive ... killing" warnings after a finished batch."""
    import logging

    pytest.importorskip("distributed")
    from distributed import Client

    from fluxcal.runs.cluster import close_local_cluster, make_local_cluster

    cluster = make_local_cluster(2)
    level = logging.getLogger("distributed").level
    client = Client(cluster)
    # both workers busy in a sleep: they cannot stop within the 4 s the nanny waits, so
    # each is killed, which is what a slow machine does to a finished cluster
    busy = [client.submit(time.sleep, 30, pure=False, workers=[w], allow_other_workers=False)
            for w in client.scheduler_info()["workers"]]
    while sum(len(v) for v in client.processing().values()) < len(busy):
        time.sleep(0.1)
    time.sleep(0.5)
    client.close()
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        close_local_cluster(cluster)
    assert not [r for r in caplog.records if r.name.startswith("distributed")
                and logging.WARNING <= r.levelno < logging.ERROR]
    assert logging.getLogger("distributed").level == level  # restored
