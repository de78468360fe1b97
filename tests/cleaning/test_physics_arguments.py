"""Arguments checked against the physics of the data: one line, exit 2 (issue 23, item 2).

Before: ``rosetta clean --bandwidth 50`` on 20-Hz data (Nyquist 10 Hz) replaced the whole
spectrum by noise (3.2 nT of change), LAP lines above the Nyquist frequency or negative were
taken, and a negative filter time shift calibrated a single run.
"""

import pytest

from fluxcal.cli import main
from fluxcal.errors import CalibrationError, InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import leapseconds
from fluxcal.missions.rosetta import calib
from fluxcal.missions.rosetta import cleaning_levels as cl
from tests.cleaning.test_rosetta_cleaning import _wheel_case, _write


@pytest.fixture(scope="module")
def lsk():
    with KernelPool():
        yield leapseconds()


@pytest.mark.parametrize("bandwidth", [10.0, 50.0, 0.0, -0.1])
def test_band_width_must_be_below_nyquist(lsk, bandwidth):
    ds, *_ = _wheel_case(lsk, n=3000)
    with pytest.raises(InputFormatError, match="Nyquist") as err:
        cl.level_h(ds, None, [2.5], bandwidth_hz=bandwidth)
    assert "sid 2 at 20 Hz" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("line", [10.5, 27.3, -2.5, 0.0])
def test_lap_lines_must_be_in_the_spectrum(lsk, line):
    ds, *_ = _wheel_case(lsk, n=3000)
    with pytest.raises(InputFormatError, match="LAP line"):
        cl.level_h(ds, None, [2.5, line])


def test_band_width_just_below_nyquist_and_line_at_nyquist_are_taken(lsk):
    ds, *_ = _wheel_case(lsk, n=3000)
    out = cl.level_h(ds, None, [10.0], bandwidth_hz=0.5)
    assert out.attrs["level"] == "H"


@pytest.mark.parametrize("extra, words", [
    (["--bandwidth", "50"], "Nyquist"),
    (["--bandwidth", "-1"], "--bandwidth"),
    (["--lap-lines", "2.5,12"], "LAP line 12 Hz"),
    (["--lap-lines", "2.5,-3"], "--lap-lines"),
])
def test_clean_command_refuses_in_one_line(tmp_path, capsys, lsk, extra, words):
    ds, *_ = _wheel_case(lsk, n=2000)
    ds = ds.isel(time=slice(0, 2000))
    files = _write(ds, tmp_path / "in", lsk)
    out = tmp_path / "out"
    args = ["rosetta", "clean", "--level", "H", "--input", str(files[".cdf"]), "--out", str(out)]
    if "--lap-lines" not in extra:
        args += ["--lap-lines", "2.5"]
    capsys.readouterr()
    code = main(args + extra)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("fluxcal: error:") and words in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_negative_filter_shift_is_refused_naming_line_and_field(tmp_path):
    text = (calib.default_dir() / calib.TIMESHIFT_FILE).read_text().splitlines()
    header = next(i for i, line in enumerate(text) if line.startswith("sid"))
    row = text[header + 2].split(",")
    row[3] = "-0.5"  # primary_shift_s
    text[header + 2] = ",".join(row)
    path = tmp_path / calib.TIMESHIFT_FILE
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(CalibrationError) as err:
        calib.read_time_shift_table(path)
    msg = str(err.value)
    assert f"line {header + 3}" in msg and "primary_shift_s" in msg and "negative" in msg
