"""A daily model fitted by ``fluxcal rosetta fit`` and the Appendix B jumps: not together.

The daily fit takes LEVEL_A from the ground calibration alone (docs/decisions/rosetta_fit.md
entry 3), so on a day inside an Appendix B interval the jump goes into its ``P_0``;
``rosetta calibrate`` subtracting the jump again in LEVEL_B left the field off by the whole
jump, silently (entry 62: 1.44 / 0.19 / 0.70 nT on a simulated 2014-08-01 whose file
stated 0.03 nT).  Entry 5: the two are alternatives.
"""

from __future__ import annotations

import numpy as np

from fluxcal.cli import main
from fluxcal.missions.rosetta import calib


def test_calibrate_refuses_the_jumps_on_a_day_whose_daily_model_fluxcal_fitted(tmp_path, capsys):
    sim = tmp_path / "sim"
    assert main(["-q", "simulate", "rosetta", "--hours", "1", "--rate", "1", "--out",
                 str(sim)]) == 0
    raw = sim / "RPCMAG_20140801_RAW_OB.csv"
    daily = sim / "calib" / "RPCMAG_140801_006_CALIB_OB.TXT"
    # the simulator's own daily file (the seed's form, no T_RANGE) goes with the jumps
    assert main(["-q", "rosetta", "calibrate", "--input", str(raw), "--sensor", "OB",
                 "--calib", str(sim / "calib"), "--levels", "A,B", "--formats", "cdf",
                 "--out", str(tmp_path / "seed_form")]) == 0
    # the same polynomial as `rosetta fit` writes it: with its fitted range and error
    daily.write_text(daily.read_text() + "T_RANGE = -300.0 300.0\n"
                     "SIGMA_CURVE = 0.01 0.01 0.01\n")
    assert calib.read_daily_offset_model(daily).temperature_range == (-300.0, 300.0)
    table = calib.load_offset_jump_table(sim / "calib")
    row = int(np.flatnonzero((table.start_utc <= "2014-08-01") & (table.end_utc > "2014-08-02"))[0])
    jump = table.jumps["OB"][row]
    assert np.all(np.abs(jump) > 0.1)  # Appendix B: a jump of tenths of nT to 1.4 nT
    capsys.readouterr()
    out = tmp_path / "fitted_with_jumps"
    assert main(["rosetta", "calibrate", "--input", str(raw), "--sensor", "OB", "--calib",
                 str(sim / "calib"), "--levels", "A,B", "--formats", "cdf", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fluxcal: error: "), err
    assert ("RPCMAG_140801_006_CALIB_OB.TXT: fitted by fluxcal rosetta fit on 2014-08-01, "
            f"inside the Appendix B interval {table.start_utc[row]} .. {table.end_utc[row]}"
            ) in err, err
    assert " ".join(f"{v:.4g}" for v in jump) in err and "--no-jumps" in err, err
    assert not out.exists() or not list(out.glob("*.cdf"))
    # without the jumps, or LEVEL_A alone, the fitted file is used
    for extra, name in ((["--levels", "A,B", "--no-jumps"], "no_jumps"), (["--levels", "A"],
                                                                         "level_a")):
        assert main(["-q", "rosetta", "calibrate", "--input", str(raw), "--sensor", "OB",
                     "--calib", str(sim / "calib"), "--formats", "cdf", "--out",
                     str(tmp_path / name), *extra]) == 0


def test_the_fitted_daily_file_names_its_input_without_its_folder(tmp_path):
    """entry 62: its ``# source:`` line held the input's full path (README: no product
    holds a folder of the machine that made it)."""
    sim = tmp_path / "sim"
    assert main(["-q", "simulate", "rosetta", "--hours", "24", "--rate", "1", "--out",
                 str(sim)]) == 0
    fitted = tmp_path / "fitted"
    assert main(["-q", "rosetta", "fit", "--input", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
                 "--sensor", "OB", "--out", str(fitted)]) == 0
    text = (fitted / "RPCMAG_140801_006_CALIB_OB.TXT").read_text()
    assert "# source: RPCMAG_20140801_RAW_OB.csv" in text, text
    assert str(tmp_path) not in text
