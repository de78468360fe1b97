"""``fluxcal messenger edr2cdr`` end to end on simulated input files."""

import numpy as np

from fluxcal.cli import main
from fluxcal.products import read_fluxcal_product


def _args(files, kernels, out, *extra):
    return ["messenger", "edr2cdr", "--sci", str(files["science"]), "--heater",
            str(files["heater"]), "--temperature", str(files["temperature"]), "--kernels",
            str(kernels), "--out", str(out), *extra]


def test_edr2cdr_writes_archive_named_products(tmp_path, simulated_files, messenger_kernels):
    out = tmp_path / "out"
    code = main(_args(simulated_files, messenger_kernels, out, "--frames", "mso,rtn",
                      "--average", "60", "--formats", "tab,cdf,png"))
    assert code == 0
    names = sorted(p.name for p in out.iterdir())
    # the first corrected times fall before midnight but stay in their EDR day (12153)
    assert not any("12152" in n for n in names)
    assert "MAGMSOSCI12153_V01.TAB" in names and "MAGMSOSCI12153_V01.LBL" in names
    assert "messenger_mag_mso-sci_20120601_v01.cdf" in names
    assert "MAGRTNSCIAVG12153_60_V01.TAB" in names
    assert "MAGOFFSETS12153.png" in names and "MAGOFFSETS12153.txt" in names
    assert not any(n.startswith(".tmp") for n in names)
    tab = read_fluxcal_product(out / "MAGMSOSCI12153_V01.TAB")
    cdf = read_fluxcal_product(out / "messenger_mag_mso-sci_20120601_v01.cdf")
    np.testing.assert_allclose(np.asarray(tab["b"].values, float), cdf["b"].values, atol=5e-4)
    label = (out / "MAGMSOSCI12153_V01.LBL").read_text()
    assert "offsets_temperature" in label and "msgr_synthetic" in label


def test_formats_without_png_write_the_report_text_only(tmp_path, simulated_files,
                                                        messenger_kernels):
    out = tmp_path / "out"
    code = main(_args(simulated_files, messenger_kernels, out, "--frames", "mso",
                      "--average", "", "--formats", "cdf"))
    assert code == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["MAGOFFSETS12153.txt", "index.html",  # index.html: the run's report
                     "messenger_mag_mso-sci_20120601_v01.cdf"]


def test_an_unknown_format_fails_before_any_work(tmp_path, simulated_files, messenger_kernels,
                                                 capsys):
    out = tmp_path / "out"
    code = main(_args(simulated_files, messenger_kernels, out, "--formats", "cdf,pgn"))
    assert code == 2
    err = capsys.readouterr().err
    assert "pgn" in err and "png" in err and err.count("\n") == 1
    assert not out.exists() or not any(out.iterdir())


def test_an_unknown_format_fails_before_the_edrs_are_read(tmp_path, messenger_kernels, capsys):
    """The EDR route too: an empty EDR folder would fail later, at reading, naming no format."""
    (tmp_path / "edr").mkdir()
    mapping = tmp_path / "mapping.toml"
    mapping.write_text("")
    code = main(["messenger", "edr2cdr", "--edr", str(tmp_path / "edr"), "--mapping",
                 str(mapping), "--kernels", str(messenger_kernels), "--out",
                 str(tmp_path / "out"), "--formats", "cdf,pgn"])
    assert code == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "pgn" in line and "formats" in line


def test_failed_day_writes_nothing(tmp_path, simulated_files, messenger_kernels):
    out = tmp_path / "out"
    # a threshold below the real (smooth) steps fails every day
    code = main(_args(simulated_files, messenger_kernels, out, "--frames", "mso",
                      "--max-offset-step", "0.001", "--average", ""))
    assert code == 2
    assert not out.exists() or not any(out.iterdir())


def test_bad_input_is_an_error_not_a_crash(tmp_path, simulated_files, messenger_kernels, capsys):
    bad = tmp_path / "bad.csv"
    lines = simulated_files["science"].read_text().splitlines()
    lines[5] = lines[5].replace(",10,0,", ",12,0,")
    bad.write_text("\n".join(lines) + "\n")
    files = dict(simulated_files, science=bad)
    code = main(_args(files, messenger_kernels, tmp_path / "out"))
    assert code == 2
    err = capsys.readouterr().err
    assert "bad.csv" in err and "line 6" in err and "rate" in err


def test_bad_options_are_errors(tmp_path, simulated_files, messenger_kernels, capsys):
    out = tmp_path / "out"
    assert main(_args(simulated_files, messenger_kernels, out, "--frames", "gse")) == 2
    assert "frames" in capsys.readouterr().err
    assert main(_args(simulated_files, messenger_kernels, out, "--average", "1,x")) == 2
    assert "--average" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_a_cdf_only_run_does_not_load_matplotlib(tmp_path, simulated_files, messenger_kernels):
    # the start-up it costs is paid only when a figure is asked for (docs/decisions/
    # products.md, decision 49; dask.array is xarray's to import: docs/decisions/runs.md, R5)
    import json
    import subprocess
    import sys

    args = _args(simulated_files, messenger_kernels, tmp_path / "out", "--frames", "mso,rtn",
                 "--formats", "cdf")
    code = ("import json, sys\nfrom fluxcal.cli import main\n"
            f"assert main({args!r}) == 0\n"
            "print(json.dumps([m for m in ('matplotlib', 'xarray') "
            "if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert json.loads(out.splitlines()[-1]) == ["xarray"]
