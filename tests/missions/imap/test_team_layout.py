"""The team's product layout (issue 33 item 4): fluxcal's L1B/L1C as the team's tools read.

Expected names, dimensions and attributes are those of the team's real L1B CDF in
../shared (read here with cdflib); the decisive check is the team's own L1C reading
fluxcal's L1B (the team's package, skipped when it is not installed).
"""

from __future__ import annotations

from pathlib import Path

import cdflib
import numpy as np
import pytest
from typer.testing import CliRunner

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap.cli import app
from fluxcal.missions.imap.team_layout import (
    from_team,
    read_l1b,
    read_l1b_csv,
    vectors_per_second,
)
from fluxcal.products.compare import compare, load_product
from tests.missions.imap._levels import run_team, team_dir


def _calibrate(imap_data: Path, out: Path, *extra: str) -> None:
    result = CliRunner().invoke(app, [
        "calibrate", "--input", str(imap_data / "mag_l1_test_data.pkts"), "--out", str(out),
        "--kernels", str(imap_data / "imap_sclk_0036.tsc"),
        "--calib", str(imap_data / "imap_calibration_mag_20240229_v01.cdf"),
        "--xtce", str(imap_data / "MAG_SCI_COMBINED.xml"), *extra])
    assert result.exit_code == 0, result.output


def test_team_layout_has_the_team_names(imap_data: Path, tmp_path: Path) -> None:
    _calibrate(imap_data, tmp_path / "team", "--layout", "team")
    _calibrate(imap_data, tmp_path / "own")
    name = "imap_mag_l1b_norm-mago_20231130_v001.cdf"
    ours = cdflib.CDF(str(tmp_path / "team" / name))
    real = cdflib.CDF(str(team_dir() / "L2" / "imap_mag_l1b_norm-mago_20251017_v002.cdf"))
    for cdf in (ours, real):  # what user code written for the team's file looks up
        names = cdf.cdf_info().zVariables
        assert {"epoch", "vectors", "compression_flags"} <= set(names)
        assert cdf.varinq("epoch").Data_Type_Description == "CDF_TIME_TT2000"
        assert cdf.varinq("vectors").Dim_Sizes == [4]
        assert cdf.varinq("compression_flags").Dim_Sizes == [2]
        assert cdf.varattsget("vectors")["DEPEND_0"] == "epoch"
        g = cdf.globalattsget()
        for key in ("Logical_source", "is_mago", "is_active", "vectors_per_second",
                    "missing_sequences", "Data_level"):
            assert key in g, key
    assert ours.globalattsget()["Logical_source"] == ["imap_mag_l1b_norm-mago"]
    # the same vectors as fluxcal's own layout, to the bit and the ns
    c = compare(load_product(tmp_path / "team" / name), load_product(tmp_path / "own" / name), 0)
    assert c.matched == 96 and all(s.max_abs == 0.0 for s in c.overall)
    back = from_team(tmp_path / "team" / name)
    assert back.attrs["sensor"] == "mago" and back.attrs["mode"] == "norm"


def test_vectors_per_second_attribute() -> None:
    t0 = 794966559703707008
    t = np.concatenate([t0 + np.arange(10) * 500_000_000,
                        t0 + 5_000_000_000 + np.arange(10) * 250_000_000])
    assert vectors_per_second(t) == f"{t0}:2,{t0 + 5_000_000_000}:4"


def test_inputs_recognised_by_content(tmp_path: Path) -> None:
    team = team_dir()
    csv = read_l1b(team / "L1c" / "T013" / "mag-l1b-l1c-t013-magi-normal-in.csv")
    assert csv.attrs["sensor"] == "magi" and csv.sizes["time"] == 1216
    cdf = read_l1b(team / "L2" / "imap_mag_l1b_norm-mago_20251017_v002.cdf")
    assert cdf.attrs["sensor"] == "mago" and cdf.sizes["time"] == 3504
    bad = tmp_path / "x.csv"
    bad.write_text("t,x,y\n2025-01-01T00:00:00,1,2\n")
    with pytest.raises(InputFormatError, match=r"x\.csv.*column\(s\) \['z', 'range'\]"):
        read_l1b_csv(bad)
    with pytest.raises(InputFormatError, match="not a CDF file"):
        from_team(bad)


def test_l1c_command_in_the_team_layout(tmp_path: Path) -> None:
    d = team_dir() / "L1c" / "T015"
    result = CliRunner().invoke(app, [
        "l1c", "--input", str(d / "mag-l1b-l1c-t015-magi-normal-in.csv"),
        "--input", str(d / "mag-l1b-l1c-t015-magi-burst-in.csv"),
        "--out", str(tmp_path), "--layout", "team"])
    assert result.exit_code == 0, result.output
    cdf = cdflib.CDF(str(tmp_path / "imap_mag_l1c_norm-magi_20250311_v001.cdf"))
    flags = cdf.varget("generated_flag")
    # the team's L1C holds no missing row: 960 normal + 577 interpolated
    assert flags.size == 1537 and (flags == 1).sum() == 577


def test_team_l1c_reads_fluxcal_l1b(imap_data: Path, tmp_path: Path) -> None:
    """Before: the team's L1C refused fluxcal's L1B (KeyError 'epoch')."""
    _calibrate(imap_data, tmp_path, "--layout", "team")
    path = tmp_path / "imap_mag_l1b_norm-mago_20231130_v001.cdf"
    team = run_team(
        "import sys, numpy as np\n"
        "from imap_processing.cdf.utils import load_cdf\n"
        "from imap_processing.mag.l1c.mag_l1c import mag_l1c\n"
        "out = mag_l1c(load_cdf(sys.argv[1]), np.datetime64('2023-11-30'))\n"
        "np.savez(sys.argv[2], epoch=out['epoch'].values, vectors=out['vectors'].values, "
        "gen=out['generated_flag'].values)\n", path, tmp_path / "team.npz")
    ours = from_team(path)
    assert team["vectors"].shape == (96, 4) and (team["gen"] == 0).all()
    np.testing.assert_array_equal(team["vectors"][:, :3], ours["b"].values)
    assert np.abs(team["epoch"] - ours["epoch"].values).max() <= 64  # their float64 epoch


def test_team_layout_is_cdf_only(imap_data: Path, tmp_path: Path) -> None:
    for command in (["calibrate", "--input", str(imap_data / "mag_l1_test_data.pkts"),
                     "--kernels", str(imap_data / "imap_sclk_0036.tsc"),
                     "--calib", str(imap_data / "imap_calibration_mag_20240229_v01.cdf"),
                     "--xtce", str(imap_data / "MAG_SCI_COMBINED.xml")],
                    ["l1c", "--input", str(team_dir() / "L1c" / "T013" /
                                           "mag-l1b-l1c-t013-magi-normal-in.csv")]):
        result = CliRunner().invoke(app, [*command, "--out", str(tmp_path / "x"),
                                          "--layout", "team", "--formats", "cdf,nc"])
        assert isinstance(result.exception, InputFormatError)
        assert "CDFs only" in str(result.exception) and not (tmp_path / "x").exists()


def test_team_layout_is_reproducible_and_names_its_parents(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    """Two runs with SOURCE_DATE_EPOCH fixed write the same bytes (issue 32).

    Before, ``Generation_date`` was the wall clock of each run.  1700000000 s after
    1970-01-01 is 2023-11-14T22:13:20 UTC (19675 days and 80000 s).  The team's
    ``Parents`` are the input files, by name.
    """
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    d = team_dir() / "L1c" / "T015"
    names = ["mag-l1b-l1c-t015-magi-normal-in.csv", "mag-l1b-l1c-t015-magi-burst-in.csv"]
    written = []
    for run in ("a", "b"):
        args = ["l1c", *(a for n in names for a in ("--input", str(d / n))),
                "--out", str(tmp_path / run / "out"), "--layout", "team"]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, result.output
        written.append(tmp_path / run / "out" / "imap_mag_l1c_norm-magi_20250311_v001.cdf")
    assert written[0].read_bytes() == written[1].read_bytes()
    attrs = cdflib.CDF(str(written[0])).globalattsget()
    assert attrs["Generation_date"] == ["2023-11-14T22:13:20"]
    assert attrs["Parents"] == names


def test_imap_declares_its_products() -> None:
    """The runner writes IMAP's products: its pipelines declare them (issue 32)."""
    from fluxcal.missions.imap.routes import ImapRun, LevelRun

    for pipeline in (ImapRun(), LevelRun()):
        assert not hasattr(pipeline, "write")
        assert callable(pipeline.products) and callable(pipeline.calibration)
