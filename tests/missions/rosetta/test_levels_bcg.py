"""LEVEL_B, C (seed 003 sec. 4.3-4.4, App. B) and E/F/G averages (sec. 4.6-4.8)."""

from pathlib import Path

import numpy as np
import pytest
import spiceypy
from scipy.spatial.transform import Rotation

from fluxcal.errors import CalibrationError, FluxcalError
from fluxcal.geometry.days import day_midnight
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import tt2000_to_et, utc_to_tt2000
from fluxcal.missions.rosetta import averaged, calib, level_a, level_b, level_c
from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels
from tests.missions.rosetta._tables import rosetta_tables, simulate_with

START = "2014-08-01T00:00:00"
DURATION = 600.0


@pytest.fixture(scope="module")
def kernels(tmp_path_factory):
    return write_rosetta_like_kernels(
        tmp_path_factory.mktemp("ros"), START, DURATION, margin_s=1200
    )


def _alignment():
    rots = Rotation.from_euler(
        "zyx", [[30, -20, 10], [5, 80, -45], [-60, 10, 170], [90, 0, 0]], degrees=True
    ).as_matrix()
    keys = [("OB", "deployed"), ("OB", "stowed"), ("IB", "deployed"), ("IB", "stowed")]
    return calib.Alignment(dict(zip(keys, rots, strict=True)), "test alignment", "t1")


@pytest.fixture(scope="module")
def run(kernels):
    with KernelPool(kernels):
        tables = rosetta_tables(alignment=_alignment())
        cals, ts, nom, al, jumps = tables
        sim = simulate_with(tables, START, DURATION, with_kernels=True, seed=5)
        out = {}
        for sensor in ("OB", "IB"):
            a = level_a.level_a(sim.science[sensor], cals[sensor], ts, nom)
            b = level_b.level_b(a, al, jumps)
            c = level_c.level_c(b, frame="ECLIPJ2000")  # the frame of the simulator's truth
            c_oracle = level_c.level_c(
                b.isel(time=slice(0, None, 97)), frame="ECLIPJ2000", method="oracle"
            )
            out[sensor] = dict(a=a, b=b, c=c, c_oracle=c_oracle, truth=sim.truth[sensor])
        yield out


def _truth(truth, name):
    good = truth["good"].values
    order = np.argsort(truth["epoch"].values[good], kind="stable")
    return truth[name].values[good][order]


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_level_b_and_c_recover_truth(run, sensor):
    r = run[sensor]
    for level, name in (("b", "b_sc"), ("c", "b_ref")):
        diff = r[level]["b"].values - _truth(r["truth"], name)
        # rotations preserve the LEVEL_A quantisation error (0.015 nT rms), see test_round_trip
        assert np.all(np.sqrt((diff**2).mean(axis=0)) < 0.03), (level, diff)


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_level_c_against_oracle(run, sensor):
    r = run[sensor]
    fast = r["c"].isel(time=slice(0, None, 97))
    # interpolated attitude vs pxform per sample: tolerance of the interpolation (1e-9 rad)
    # times |B| < 100 nT
    np.testing.assert_allclose(fast["b"].values, r["c_oracle"]["b"].values, atol=1e-6)
    np.testing.assert_allclose(
        fast["position"].values, r["c_oracle"]["position"].values, atol=1e-3
    )  # km
    # |B| is preserved by the rotations
    np.testing.assert_allclose(
        np.linalg.norm(r["c"]["b"].values, axis=1),
        np.linalg.norm(r["b"]["b"].values, axis=1),
        rtol=1e-12,
    )


def test_level_c_position_is_spkpos(run, kernels):
    c = run["OB"]["c"].isel(time=[0, 5000, -1])
    with KernelPool(kernels):
        et = tt2000_to_et(c["epoch"].values)
        for i, t in enumerate(et):
            pos = spiceypy.spkpos("ROSETTA", float(t), "ECLIPJ2000", "NONE", "SUN")[0]
            np.testing.assert_allclose(c["position"].values[i], pos, atol=1e-3)
            m = spiceypy.pxform("ROS_SPACECRAFT", "ECLIPJ2000", float(t))
            np.testing.assert_allclose(
                c["b"].values[i], m @ run["OB"]["b"]["b"].values[[0, 5000, -1]][i], atol=1e-6
            )


def test_level_b_rotation_closed_form(run):
    a, b = run["IB"]["a"], run["IB"]["b"]
    rot = _alignment().matrix("IB", "deployed")
    jump = calib.load_offset_jump_table().jumps["IB"][10]  # 2014-07-25 .. 2014-09-13
    np.testing.assert_allclose(b["b"].values, a["b"].values @ rot.T - jump, atol=1e-12)
    assert b.attrs["n_offset_jump_corrected"] == b.sizes["time"]


def test_offset_jump_intervals(pool):
    table = calib.load_offset_jump_table()
    t = utc_to_tt2000(
        np.array(
            [
                "2014-03-30T00:00:00",  # between intervals: no jump
                "2014-11-12T08:34:59",
                "2014-11-12T08:35:00",  # shared boundary
                "2014-04-16T22:00:00",
            ]
        )
    )
    jump, idx = level_b.offset_jumps(t, table, "OB")
    np.testing.assert_array_equal(idx, [-1, 13, 14, 2])
    np.testing.assert_array_equal(jump[0], 0.0)
    # Appendix B.1: interval 13 and 14 values, applied once each (half-open intervals)
    np.testing.assert_array_equal(jump[1], [8.2876, 13.2751, -4.4664])
    np.testing.assert_array_equal(jump[2], [-7.8000, 8.9000, -15.7000])
    late = utc_to_tt2000(np.array(["2015-06-01T00:00:00"]))
    jump, _ = level_b.offset_jumps(late, table, "OB")
    np.testing.assert_array_equal(jump[0], [-4.52, 25.26, -5.52])
    jump, _ = level_b.offset_jumps(late, table, "IB")  # Appendix B.2, last interval
    np.testing.assert_array_equal(jump[0], [-13.74, -0.4424, 0.7735])
    # a user table may leave a value unknown: data in that interval are refused
    ib = table.jumps["IB"].copy()
    ib[18, 2] = np.nan
    unknown = calib.OffsetJumpTable(table.start_utc, table.end_utc, {**table.jumps, "IB": ib}, "u")
    with pytest.raises(CalibrationError, match="IB offset jump .* unknown"):
        level_b.offset_jumps(late, unknown, "IB")


def test_stowed_uses_other_matrix(run):
    a = run["OB"]["a"]
    b = level_b.level_b(a, _alignment(), None, boom="stowed")
    np.testing.assert_allclose(b["b"].values, a["b"].values @ _alignment().matrix("OB", "stowed").T)
    assert b.attrs["offset_jumps"] == "not applied"


def _brute_force_average(epoch, values, width, origin):
    """One bin at a time, written independently of the vectorized code."""
    out = {}
    for t, v in zip(epoch.tolist(), values.tolist(), strict=True):
        k = (t - origin) // width
        out.setdefault(k, []).append(v)
    keys = sorted(out)
    centres = [origin + k * width + width // 2 for k in keys]
    means = [np.mean(out[k], axis=0) for k in keys]
    return np.array(centres), np.array(means), np.array([len(out[k]) for k in keys])


@pytest.mark.parametrize("seconds", [1.0, 2.5, 60.0])
def test_average_against_brute_force(run, seconds):
    c = run["OB"]["c"]
    with KernelPool():
        g = averaged.average(c, seconds)
    origin = g.attrs["average_origin_tt2000"]
    centres, means, counts = _brute_force_average(
        c["epoch"].values, c["b"].values, int(seconds * 1e9), origin
    )
    np.testing.assert_array_equal(g["epoch"].values, centres)
    np.testing.assert_allclose(g["b"].values, means, atol=1e-9)
    np.testing.assert_array_equal(g["n_samples"].values, counts)
    assert g.attrs["level"] == "G"
    assert np.all(np.diff(g["epoch"].values) > 0)


def test_average_origin_is_utc_midnight(pool):
    origin = day_midnight(int(utc_to_tt2000(np.array(["2014-08-01T13:14:15.5"]))[0]))
    assert origin == utc_to_tt2000(np.array(["2014-08-01T00:00:00"]))[0]


def test_average_omits_empty_bins_and_unsorted():
    from fluxcal.calibration.averaging import boxcar_average

    t = np.array([3500, 100, 900, 5200], dtype=np.int64)
    centre, mean, count = boxcar_average(t, np.array([4.0, 1.0, 3.0, 5.0]), 1000)
    np.testing.assert_array_equal(centre, [500, 3500, 5500])
    np.testing.assert_array_equal(mean, [2.0, 4.0, 5.0])
    np.testing.assert_array_equal(count, [2, 1, 1])


def test_obt_carried_to_bin_middle(run):
    a = run["OB"]["a"]
    with KernelPool():
        e = averaged.average(a, 1.0)
    # OBT is linear in time inside a bin: obt(middle) from a line fit through the samples
    sel = (a["epoch"].values >= e["epoch"].values[10] - 500_000_000) & (
        a["epoch"].values < e["epoch"].values[10] + 500_000_000
    )
    x = (a["epoch"].values[sel] - e["epoch"].values[10]) * 1e-9
    fit = np.polyfit(x, a["obt"].values[sel], 1)
    assert e["obt"].values[10] == pytest.approx(fit[1], abs=1e-6)
    assert Path(a.attrs["time_shift_table"]).name == "RPCMAG_FILTER_TIMESHIFT.csv"


def test_level_c_cseq(run, kernels):
    b = run["OB"]["b"].isel(time=slice(0, None, 211))
    with KernelPool(kernels):
        c = level_c.level_c(b, frame="CSEQ", centre="67P/C-G")
        oracle = level_c.level_c(b, frame="CSEQ", centre="67P/C-G", method="oracle")
        et = tt2000_to_et(b["epoch"].values[:1])[0]
        # CSEQ definition: +X from the comet to the Sun
        sun = spiceypy.spkpos("SUN", float(et), "67P/C-G_CSEQ", "NONE", "67P/C-G")[0]
    assert c.attrs["output_frame"] == "67P/C-G_CSEQ"
    np.testing.assert_allclose(sun[1:] / np.linalg.norm(sun), 0.0, atol=1e-12)
    np.testing.assert_allclose(c["b"].values, oracle["b"].values, atol=1e-6)
    # the synthetic spacecraft escorts the comet at 30 km
    np.testing.assert_allclose(np.linalg.norm(c["position"].values, axis=1), 30.0, rtol=1e-6)


def test_level_c_frame_by_date(run, kernels):
    """Issue 11: sec. 4.4.1 "Update 2014" makes CSEQ the standard LEVEL_C frame in the comet
    phase.  Default: CSEQ centred on the comet from 2014-01-20 (the simulated day is
    2014-08-01), ECLIPJ2000 from the Sun before; explicit choices still win.  (Before: always
    ECLIPJ2000 from the Sun.)"""
    b = run["OB"]["b"].isel(time=slice(0, None, 401))
    with KernelPool(kernels):
        auto = level_c.level_c(b)
        cseq = level_c.level_c(b, frame="CSEQ", centre="67P/C-G")
        eclip = level_c.level_c(b, frame="ECLIPJ2000")
        before = utc_to_tt2000(np.array(["2010-07-10T12:00:00", "2014-01-19T23:59:59"]))
        after = utc_to_tt2000(np.array(["2014-01-20T00:00:00", "2016-09-30T10:00:00"]))
        assert level_c.default_frame(before) == ("ECLIPJ2000", "SUN")
        assert level_c.default_frame(after) == ("CSEQ", "67P/C-G")
        with pytest.raises(FluxcalError, match="comet phase"):
            level_c.default_frame(np.r_[before[1:], after[:1]])
    assert auto.attrs["output_frame"] == "67P/C-G_CSEQ"
    assert auto.attrs["position_centre"] == "67P/C-G"
    np.testing.assert_array_equal(auto["b"].values, cseq["b"].values)
    np.testing.assert_array_equal(auto["position"].values, cseq["position"].values)
    assert eclip.attrs["position_centre"] == "SUN"  # explicit frame, centre by frame
    # a rotation: |B| is the same in both frames, the components are not
    np.testing.assert_allclose(
        np.linalg.norm(auto["b"].values, axis=1), np.linalg.norm(eclip["b"].values, axis=1),
        rtol=1e-12,
    )
    assert np.abs(auto["b"].values - eclip["b"].values).max() > 1.0


MAG_FK = """KPL/FK
\\begindata
   FRAME_ROS_RPC_MAG_OB      = -226541
   FRAME_-226541_NAME        = 'ROS_RPC_MAG_OB'
   FRAME_-226541_CLASS       = 4
   FRAME_-226541_CLASS_ID    = -226541
   FRAME_-226541_CENTER      = -226
   TKFRAME_-226541_RELATIVE  = 'ROS_SPACECRAFT'
   TKFRAME_-226541_SPEC      = 'ANGLES'
   TKFRAME_-226541_UNITS     = 'DEGREES'
   TKFRAME_-226541_AXES      = ( 1, 3, 1 )
   TKFRAME_-226541_ANGLES    = ( -90.234, 89.944, 0.145 )
\\begintext
"""


def test_alignment_from_spice_frames(run, kernels, tmp_path):
    """Issue 4: where the frames kernel (and boom CK) define ROS_RPC_MAG_OB, LEVEL_B may take
    R_UVW2SC from SPICE; it must equal the file path with the same matrix."""
    fk = tmp_path / "mag.tf"
    fk.write_text(MAG_FK)
    a = run["OB"]["a"].isel(time=slice(0, 2000))
    with KernelPool([kernels, fk]):
        et0 = tt2000_to_et(a["epoch"].values[:1])[0]
        rot = spiceypy.pxform("ROS_RPC_MAG_OB", "ROS_SPACECRAFT", float(et0))
        b_spice = level_b.level_b(a, None, None)
    keys = [("OB", "deployed"), ("OB", "stowed"), ("IB", "deployed"), ("IB", "stowed")]
    al = calib.Alignment(dict.fromkeys(keys, rot), "from pxform", "x")
    b_file = level_b.level_b(a, al, None)
    np.testing.assert_allclose(b_spice["b"].values, b_file["b"].values, atol=1e-9)
    assert "SPICE frames ROS_RPC_MAG_OB" in b_spice.attrs["alignment"]
    assert not np.allclose(rot, np.eye(3))
