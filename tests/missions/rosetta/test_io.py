"""Bad inputs: messages name file, line and field (issue 4)."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.missions.rosetta import calib, io, level_a

HEADER = "time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality"
GOOD = [
    "2014-08-01T00:00:00.000000,366076800.000000,2,1000,-2000,300,16000,17000,0",
    "2014-08-01T00:00:00.050000,366076800.050000,2,1001,-2001,301,16000,17000,0",
    "2014-08-01T00:00:00.100000,366076800.100000,2,1002,-2002,302,16000,17000,0",
]


def _file(tmp_path, rows, header=HEADER):
    path = tmp_path / "sci.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def _read(tmp_path, rows, sensor="OB", **kw):
    return io.read_science_csv(_file(tmp_path, rows, kw.pop("header", HEADER)), sensor)


def test_good_file(pool, tmp_path):
    ds = _read(tmp_path, GOOD)
    assert ds.sizes["time"] == 3
    np.testing.assert_array_equal(ds["b_counts"].values[1], [1001, -2001, 301])
    assert np.diff(ds["epoch"].values).tolist() == [50_000_000, 50_000_000]
    assert ds["row"].values.tolist() == [2, 3, 4]


def test_non_numeric_field(pool, tmp_path):
    rows = [GOOD[0], GOOD[1].replace("-2001", "-20x1"), GOOD[2]]
    with pytest.raises(
        InputFormatError, match=r"sci.csv, line 3, field 'by': '-20x1' is not an integer"
    ):
        _read(tmp_path, rows)


def test_time_going_backwards(pool, tmp_path):
    rows = [GOOD[0], GOOD[2], GOOD[1]]
    with pytest.raises(InputFormatError, match=r"line 4, field 'time_utc': time goes backwards"):
        _read(tmp_path, rows)


def test_bad_time_string(pool, tmp_path):
    rows = [GOOD[0], "2014-08-01X00:00:00.05," + GOOD[1].split(",", 1)[1], GOOD[2]]
    with pytest.raises(InputFormatError, match=r"line 3, field 'time_utc'"):
        _read(tmp_path, rows)


def test_wrong_field_count_and_header(pool, tmp_path):
    with pytest.raises(InputFormatError, match=r"line 3: 8 fields, expected 9"):
        _read(tmp_path, [GOOD[0], GOOD[1].rsplit(",", 1)[0], GOOD[2]])
    with pytest.raises(InputFormatError, match=r"line 1: header"):
        _read(tmp_path, GOOD, header=HEADER.replace("sid", "mode"))


def test_counts_out_of_range(pool, tmp_path):
    rows = [GOOD[0], GOOD[1].replace(",1001,", ",600000,"), GOOD[2]]
    with pytest.raises(InputFormatError, match=r"line 3, field 'bx': 600000 outside"):
        _read(tmp_path, rows)


def _level_a(ds, sensor="OB"):
    return level_a.level_a(
        ds,
        calib.load_ground_calibration(sensor),
        calib.load_time_shift_table(),
        calib.load_nominal_conversion(),
    )


def test_quality_bits_dropped_and_counted(pool, tmp_path):
    rows = [GOOD[0], GOOD[1][:-1] + "5", GOOD[2]]  # bits 0 and 2: x and z bad
    a = _level_a(_read(tmp_path, rows))
    assert a.sizes["time"] == 2 and a.attrs["n_dropped_quality"] == 1


def test_quality_of_other_sensor(pool, tmp_path):
    rows = [GOOD[0], GOOD[1][:-1] + "8", GOOD[2]]  # bit 3 set: an IB vector in an OB file
    with pytest.raises(InputFormatError, match=r"sci.csv, line 3, field 'quality'"):
        _level_a(_read(tmp_path, rows))


def test_sid_not_in_table(pool, tmp_path):
    # SID 6 (Test) has no SECONDARY time shift (sec. 4.2.3.5): IB is secondary by default
    rows = [r.replace(",2,", ",6,").rsplit(",", 1)[0] + ",8" for r in GOOD]
    with pytest.raises(
        InputFormatError, match=r"line 2, field 'sid': filter mode SID 6 .* secondary"
    ):
        _level_a(_read(tmp_path, rows, "IB"), "IB")
    rows = [GOOD[0], GOOD[1].replace(",2,", ",9,"), GOOD[2]]
    with pytest.raises(InputFormatError, match=r"line 3, field 'sid': filter mode SID 9"):
        _level_a(_read(tmp_path, rows))


def test_hk_round_trip(pool, tmp_path):
    from fluxcal.missions.rosetta import simulate

    cals = {s: calib.load_ground_calibration(s) for s in ("OB", "IB")}
    sim = simulate.simulate(
        "2014-08-01T00:00:00",
        120.0,
        calibrations=cals,
        time_shifts=calib.load_time_shift_table(),
        nominal=calib.load_nominal_conversion(),
        alignment=calib.load_alignment(),
        hk_period_s=8.0,
    )
    path = io.write_hk_csv(sim.hk, tmp_path / "hk.csv")
    raw = io.read_hk_csv(path)
    from fluxcal.missions.rosetta import hk

    out = hk.hk_level_a(raw, cals["OB"].thermistor, calib.load_nominal_conversion())
    assert out["ref_voltage"].values[0] == pytest.approx(2.4996, abs=1e-5)
    assert out["pos_voltage"].values[0] == pytest.approx(5.0)
    assert out["neg_voltage"].values[0] == pytest.approx(-5.0)
    # HK temperature without T_OFF (sec. 4.2.2.5) = calibrated + T_OFF, in K
    t_true = sim.truth["OB"]["temperature"].values[::160][: out.sizes["time"]]
    np.testing.assert_allclose(out["t_ob"].values, t_true + cals["OB"].thermistor_offset, atol=0.05)


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.lists(
        st.tuples(
            st.integers(-(2**19), 2**19 - 1),
            st.integers(0, 2**16 - 1),
            st.integers(1, 6),
            st.integers(0, 7),
        ),
        min_size=1,
        max_size=30,
    )
)
def test_science_csv_round_trip(pool, tmp_path, rows):
    import xarray as xr

    n = len(rows)
    c, w, sid, q = (np.array(v) for v in zip(*rows, strict=True))
    epoch = 460_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 50_000_123
    ds = xr.Dataset(
        {
            "obt": ("time", 3.6e8 + np.arange(n) * 0.05),
            "sid": ("time", sid),
            "b_counts": (("time", "component"), np.stack([c, -c - 1, c // 3], axis=1)),
            "t_ob_counts": ("time", w),
            "t_ib_counts": ("time", w[::-1]),
            "quality": ("time", q),
        },
        coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]},
    )
    back = io.read_science_csv(io.write_science_csv(ds, tmp_path / "rt.csv"), "OB")
    for name in ("sid", "b_counts", "t_ob_counts", "t_ib_counts", "quality"):
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    np.testing.assert_allclose(back["obt"].values, ds["obt"].values, atol=5e-7)
    assert np.abs(back["epoch"].values - epoch).max() <= 1000  # 6 decimals of UTC seconds


SHARED = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "kernels"


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"real kernels not found at {SHARED}: put the "
                    "shared data folder beside the checkout (../shared/data, see README)")
def test_obt_through_real_rosetta_sclk(tmp_path):
    """OBT -> time with the real Rosetta SCLK (MANIFEST: 1/0370000000 is
    2014-09-22T09:47:49.694 UTC)."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel, tt2000_to_utc

    rows = [
        "2014-09-22T09:47:49.694000,370000000.000000,2,0,0,0,16000,16000,0",
        "2014-09-22T09:47:49.744000,370000000.050000,2,0,0,0,16000,16000,0",
    ]
    with KernelPool([SHARED / "rosetta" / "ROS_160929_STEP.TSC"]):
        ds = io.read_science_csv(_file(tmp_path, rows), "OB", sclk=SclkKernel.from_pool(-226))
        utc = tt2000_to_utc(ds["epoch"].values, digits=3)
    assert ds.attrs["time_source"] == "obt"
    assert utc[0] == "2014-09-22T09:47:49.694"
    assert abs(np.diff(ds["epoch"].values)[0] - 50_000_000) < 100  # clock rate ~1


# --- issue 22 item 5: memory-lean reading and writing give the same arrays and bytes -------


def _random_rows(n: int, seed: int = 3) -> list[str]:
    """Valid records with awkward numbers: signs, leading zeros, long OBT fractions."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        b = rng.integers(-524288, 524288, 3)
        obt = 366076800.0 + i * 0.05 + float(rng.uniform(0, 1e-6))
        lead = "0" if i % 7 == 0 and b[0] >= 0 else ""
        rows.append(f"2014-08-01T00:{i // 1200:02d}:{(i % 1200) / 20:09.6f},{obt!r},"
                    f"{2 + i // 500},{lead}{b[0]},{b[1]},{b[2]},{16000 + i % 9},"
                    f"{17000 - i % 5},{int(rng.integers(0, 8))}")
    return rows


@pytest.mark.parametrize("sclk", [False, True])
def test_fast_reader_equals_the_text_reader(pool, tmp_path, sclk):
    """pyarrow's parse (`io._read_fast`) gives the arrays of the line-by-line text reader."""
    path = _file(tmp_path, _random_rows(2000))
    kinds = {"obt": float} | {n: int for n in ("sid", "bx", "by", "bz", "t_ob", "t_ib",
                                               "quality")}
    utc, fast = io._read_fast(path, io.SCIENCE_COLUMNS, kinds, utc_text=not sclk)
    table = io._read_table(path, io.SCIENCE_COLUMNS)
    for j, name in enumerate(io.SCIENCE_COLUMNS):
        if name in kinds:
            slow = io._numeric(table, j, name, kinds[name], path)
            assert fast[name].dtype == slow.dtype
            np.testing.assert_array_equal(fast[name], slow)  # bit for bit
    assert [utc[i] for i in (0, 999, 1999)] == [str(table[i, 0]) for i in (0, 999, 1999)]


@pytest.mark.parametrize("defect", ["1.5", "1_000", "12345678901234567890", "nan", '"12"'])
def test_fast_reader_leaves_unusual_fields_to_the_text_reader(tmp_path, defect):
    rows = [GOOD[0], GOOD[1].replace("1001", defect), GOOD[2]]
    kinds = {"obt": float, "bx": int}
    assert io._read_fast(_file(tmp_path, rows), io.SCIENCE_COLUMNS, kinds) is None


def test_chunked_csv_writer_gives_the_same_bytes(tmp_path, monkeypatch):
    """Written 16k records at a time (`io.WRITE_CHUNK`): the bytes of one whole pass."""
    n = 1000
    rng = np.random.default_rng(0)
    cols = [(np.arange(n) * 0.05 + 366076800.0, lambda v: np.char.mod("%.6f", v)),
            rng.integers(-9, 9, n), rng.normal(0, 1, n)]
    whole = io._write_atomic(tmp_path / "whole.csv", ("a", "b", "c"), cols).read_bytes()
    monkeypatch.setattr(io, "WRITE_CHUNK", 7)
    parts = io._write_atomic(tmp_path / "parts.csv", ("a", "b", "c"), cols).read_bytes()
    assert parts == whole
    expected = "a,b,c\n" + "".join(f"{x:.6f},{i},{z}\n" for x, i, z in
                                   zip(cols[0][0], cols[1], cols[2], strict=True))
    assert whole.decode() == expected  # Python's own formatting of each number


def test_chunked_forward_counts_equal_one_pass(monkeypatch):
    from fluxcal.missions.rosetta import simulate

    cal = calib.load_ground_calibration("OB")
    nominal = calib.load_nominal_conversion()
    rng = np.random.default_rng(1)
    b = rng.normal(0, 200, (500, 3))
    temp = rng.uniform(-100, 30, 500)
    ext = rng.normal(0, 1, (500, 3))
    whole = simulate.raw_counts(b, temp, cal, nominal, extended=ext)
    monkeypatch.setattr(simulate, "FORWARD_CHUNK", 64)
    np.testing.assert_array_equal(simulate.raw_counts(b, temp, cal, nominal, extended=ext),
                                  whole)
