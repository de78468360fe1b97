"""``fluxcal simulate rosetta`` + ``fluxcal rosetta calibrate`` end to end, and the demo."""

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.missions.rosetta.simulate import read_truth_csv
from fluxcal.products import read_fluxcal_product


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", "rosetta", "--out", str(out), "--hours", "0.05", "--seed", "4"]) == 0
    return out


def test_simulate_writes_inputs(sim):
    names = {p.name for p in sim.iterdir()}
    assert {
        "RPCMAG_20140801_RAW_OB.csv",
        "RPCMAG_20140801_RAW_IB.csv",
        "RPCMAG_20140801_RAW_HK.csv",
        "RPCMAG_20140801_TRUTH_OB.csv",
        "kernels",
        "calib",
    } <= names
    assert (sim / "calib" / "RPCMAG_SC_ALIGN.TXT").is_file()
    assert (sim / "calib" / "RPCMAG_140801_006_CALIB_IB.TXT").is_file()
    head = (sim / "RPCMAG_20140801_RAW_OB.csv").read_text().splitlines()[:2]
    assert head[0] == "time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality"
    assert head[1].startswith("2014-08-01T00:00:00.0")


def _calibrate(sim, out, levels: str, sensor: str = "OB") -> list[str]:
    """``fluxcal rosetta calibrate`` of the simulated day's ``sensor`` file into ``out``."""
    return ["rosetta", "calibrate", "--science", str(sim / f"RPCMAG_20140801_RAW_{sensor}.csv"),
            "--sensor", sensor, "--levels", levels, "--out", str(out)]


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_calibrate_all_levels(sim, tmp_path, sensor):
    args = [*_calibrate(sim, tmp_path, "A,B,C,E,F,G", sensor), "--calib", str(sim / "calib"),
            "--kernels", str(sim / "kernels" / "rosetta_synthetic.tm"),
            "--hk", str(sim / "RPCMAG_20140801_RAW_HK.csv")]
    assert main(args + ["--frame", "ECLIPJ2000"]) == 0  # the frame of the simulator's truth
    for code in ("CLA", "CLB", "CLC"):  # archive names, one table per mode segment
        tabs = sorted(tmp_path.glob(f"RPCMAG140801T*_{code}_{sensor}_M*.TAB"))
        assert tabs and all(t.with_suffix(".LBL").is_file() for t in tabs), code
    for code in ("CLE", "CLF", "CLG"):
        assert (tmp_path / f"RPCMAG140801_{code}_{sensor}_A01.TAB").is_file(), code
        assert (tmp_path / f"RPCMAG140801_{code}_{sensor}_A01.LBL").is_file(), code
    for code in ("cla", "clb", "clc"):
        assert (tmp_path / f"rosetta_rpcmag_{code}-{sensor.lower()}_20140801_v01.cdf").is_file()
    for code in ("cle", "clf", "clg"):
        name = f"rosetta_rpcmag_{code}-{sensor.lower()}-a01_20140801_v01.cdf"
        assert (tmp_path / name).is_file()
    assert (tmp_path / "RPCMAG_20140801_HKA.TAB").is_file()
    # LEVEL_G table with the archive's column positions (sec. 4.8): TIME.UTC TIME.OBT
    # POSITION.X Y Z BX BY BZ QUALITY, read by a whitespace split
    g = read_fluxcal_product(tmp_path / f"rosetta_rpcmag_clg-{sensor.lower()}-a01_20140801_v01.cdf")
    rows = (tmp_path / f"RPCMAG140801_CLG_{sensor}_A01.TAB").read_text().splitlines()
    cols = np.array([[float(x) for x in r.split()[1:]] for r in rows])
    assert cols.shape == (g.sizes["time"], 8)
    np.testing.assert_allclose(cols[:, 1:4], g["position"].values, atol=5e-4)  # F15.3 km
    np.testing.assert_allclose(cols[:, 4:7], g["b"].values, atol=5e-4)  # F11.3 nT
    label = next(tmp_path.glob(f"RPCMAG140801T*_CLA_{sensor}_M*.LBL")).read_text()
    assert "RPCMAG_001_CALIB_FSDPU_FM" in label and "006_CALIB" in label
    # products recover the truth written by the simulator
    truth = read_truth_csv(sim / f"RPCMAG_20140801_TRUTH_{sensor}.csv")
    good = truth["good"]
    ref = truth["b_ref"][good][np.argsort(truth["epoch"][good], kind="stable")]
    c = read_fluxcal_product(tmp_path / f"rosetta_rpcmag_clc-{sensor.lower()}_20140801_v01.cdf")
    rms = np.sqrt(((c["b"].values - ref) ** 2).mean(axis=0))
    assert np.all(rms < 0.03), rms


def test_calibrate_c_without_kernels_fails(sim, tmp_path, capsys):
    assert main(_calibrate(sim, tmp_path, "A,C")) == 2
    assert "need SPICE kernels" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_calibrate_unknown_level(sim, tmp_path, capsys):
    assert main(_calibrate(sim, tmp_path, "A,Q")) == 2
    assert "unknown level" in capsys.readouterr().err


def test_calibrate_level_a_from_utc_only(sim, tmp_path):
    # without kernels times come from time_utc; LEVEL_A with the ground calibration alone
    assert main([*_calibrate(sim, tmp_path, "A,B"), "--formats", "tab"]) == 0
    label = next(tmp_path.glob("RPCMAG140801T*_CLA_OB_M*.LBL")).read_text()
    assert "ground calibration alone" in label
    # fluxcal's default alignment file is a placeholder and the LEVEL_B label says so
    assert "PLACEHOLDER identity" in next(tmp_path.glob("RPCMAG140801T*_CLB_OB_M*.LBL")).read_text()


def test_stitch_state_file_between_runs(tmp_path):
    """Two consecutive days processed by two command runs: the state file carries the
    end-of-day offset (sec. 4.2.3.3) so day 2's offset continues day 1's."""
    import json

    from fluxcal.missions.rosetta.simulate import write_simulation

    sim = write_simulation(tmp_path / "sim", start_utc="2014-08-01T23:58:00", hours=0.05)
    state = tmp_path / "state.json"
    from fluxcal.missions.rosetta.day_edges import read_stitch_state
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import calibrate_levels, run_files

    options = RosettaOptions(calib=sim["calib"], formats=("tab",))
    whole = calibrate_levels(sim["science_OB"], "OB", options=options)
    # split the raw file at midnight and process the halves one after the other
    lines = sim["science_OB"].read_text().splitlines()
    day1 = [ln for ln in lines[1:] if ln.startswith("2014-08-01")]
    day2 = [ln for ln in lines[1:] if ln.startswith("2014-08-02")]
    (tmp_path / "d1.csv").write_text("\n".join([lines[0], *day1]) + "\n")
    (tmp_path / "d2.csv").write_text("\n".join([lines[0], *day2]) + "\n")
    run_files(tmp_path / "d1.csv", "OB", tmp_path / "p1", options=options, state_file=state)
    assert read_stitch_state(state) is not None and "stitch_correction_nt" in json.loads(
        state.read_text()
    )
    made = {}
    run_files(tmp_path / "d2.csv", "OB", tmp_path / "p2", options=options, state_file=state,
              on_calibrated=lambda run: made.update(run.sensors[0].levels))
    a_whole, a2 = whole["A"], made["A"]
    sel = np.isin(a_whole["epoch"].values, a2["epoch"].values)
    np.testing.assert_allclose(a2["b"].values, a_whole["b"].values[sel], atol=1e-9)
