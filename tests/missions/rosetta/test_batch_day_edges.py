"""Day edges of ``fluxcal batch rosetta`` (issue 12, decision 30): filter time shifts move
the last vectors of a raw day past midnight; they belong to the next day's product.

One simulated stretch 23:30-00:30 UTC (forward model, `batch_task.simulate_days`) is split
into two day folders at midnight of the raw (unshifted) telemetry time, as real raw day
files are.  Filter modes at the end of day 1: Normal (SID 2: OB primary 8.2 s, IB secondary
31.95 s) and, 23:45-23:52, Minimum (SID 1: OB 223.7 s, IB 1023.95 s); seed 003 sec.
4.2.3.5, filter time-shift tables.  The reference is the simulator's truth file (event
times and LEVEL_A field of every raw record, in telemetry order), which shares no code
with the pipeline.
"""

import datetime as dt
import logging
import shutil

import numpy as np
import pytest

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.rosetta import simulate as simulate_module
from fluxcal.missions.rosetta.batch_task import science_file, simulate_days
from fluxcal.missions.rosetta.routes import make_day_task
from fluxcal.missions.rosetta.simulate import read_truth_csv
from fluxcal.products import read_fluxcal_product
from fluxcal.runs.batch import run_batch

D1, D2 = dt.date(2014, 11, 1), dt.date(2014, 11, 2)
RATE_HZ = 4.0
#: seed 003 sec. 4.2.3.5, the two filter time-shift tables (s): SID -> (primary, secondary)
SEED_SHIFT = {1: (223.7, 1023.95), 2: (8.2, 31.95)}


def _schedule(n):
    """SID per record of the 23:30-00:30 stretch: Normal, Minimum 23:45-23:52, Normal."""
    rel = np.arange(n) / RATE_HZ
    return np.where((rel >= 900.0) & (rel < 1320.0), 1, 2).astype(np.int16)


def _split(path, day_path, keep_header=True):
    """Move the lines of ``path`` stamped on D2 (first column, raw time) to ``day_path``."""
    lines = path.read_text().splitlines()
    head, rows = lines[0], lines[1:]
    second = [r for r in rows if r.startswith(D2.isoformat())]
    first = [r for r in rows if not r.startswith(D2.isoformat())]
    path.write_text("\n".join([head, *first]) + "\n")
    day_path.parent.mkdir(parents=True, exist_ok=True)
    day_path.write_text("\n".join([head, *second]) + "\n")
    return len(first), len(second)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    root = tmp_path_factory.mktemp("rosetta_day_edges")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(simulate_module, "mode_schedule", _schedule)
        # D2's own stretch (23:30 on D2) is discarded: simulate_days is asked for both
        # days only so that both daily extended-temperature models exist and the forward
        # model applies D2's model (stitched at midnight) to the records after midnight
        simulate_days(root, [D1, D2], start_time="23:30:00", minutes=60.0, rate_hz=RATE_HZ,
                      truth=True, seed=11)
    d1, d2 = root / f"{D1:%Y%m%d}", root / f"{D2:%Y%m%d}"
    shutil.rmtree(d2)
    for sensor in ("OB", "IB"):
        shutil.move(d1 / f"truth_{sensor}.csv", root / f"truth_{sensor}.csv")
        _split(d1 / f"science_{sensor}.csv", d2 / f"science_{sensor}.csv")
    _split(d1 / "hk.csv", d2 / "hk.csv")
    return root


def _midnight():
    with KernelPool():
        return int(utc_to_tt2000(np.array([f"{D2}T00:00:00"]))[0])


def _raw_rows(path):
    rows = np.array([r.split(",") for r in path.read_text().splitlines()[1:]])
    return rows


def _expected(sim, sensor):
    """Truth of each product day, from the truth file and the seed's shift table.

    The raw records are those of the two science files (telemetry order = truth order);
    a record's day is the UTC day of its time plus the seed's shift for its SID.
    """
    truth = read_truth_csv(sim / f"truth_{sensor}.csv")
    rows = np.concatenate([_raw_rows(science_file(sim, d, sensor)) for d in (D1, D2)])
    sid = rows[:, 2].astype(int)
    column = 0 if sensor == "OB" else 1
    shift = np.array([SEED_SHIFT[s][column] for s in sid])
    raw_day2 = np.char.startswith(rows[:, 0], D2.isoformat())
    good = truth["good"]
    midnight = _midnight()
    # the truth event time = raw time + shift: checked here independently of the pipeline
    raw_ns = truth["epoch"] - np.rint(shift * 1e9).astype(np.int64)
    assert np.array_equal(raw_ns >= midnight, raw_day2)
    in_day2 = truth["epoch"] >= midnight
    crossing = good & in_day2 & ~raw_day2
    return {
        D1: (truth["epoch"][good & ~in_day2], truth["b_urf"][good & ~in_day2]),
        D2: (truth["epoch"][good & in_day2], truth["b_urf"][good & in_day2]),
        "carried": crossing[good & in_day2],  # of the D2 vectors: those from D1's file
        "crossing": int(crossing.sum()),
        "crossing_raw": int((in_day2 & ~raw_day2).sum()),
    }


def _level_a(out, day, sensor):
    return read_fluxcal_product(out / f"rosetta_rpcmag_cla-{sensor.lower()}_{day:%Y%m%d}_v01.cdf")


def _check_day(out, sim, day, sensor, expected):
    """The product of ``day`` holds exactly the truth vectors of that UTC day."""
    ref_t, ref_b = expected[day]
    order = np.argsort(ref_t, kind="stable")
    a = _level_a(out, day, sensor)
    t = a["epoch"].values.astype(np.int64)
    assert t.size == ref_t.size, (day, sensor, t.size, ref_t.size)
    # times: the CSV carries OBT with 6 decimals, re-read through the SCLK (< 2 us)
    assert np.max(np.abs(t - ref_t[order])) < 2_000
    # field: 0.03 nT as in test_batch_task (20-bit words, 1 us time rounding); the vectors
    # carried from day 1 were calibrated with day 1's model and stitching
    err = a["b"].values - ref_b[order]
    rms = np.sqrt((err**2).mean(axis=0))
    assert np.all(rms < 0.03), (day, sensor, rms)
    if day == D2:  # the carried vectors alone (day 2's model on them: 0.29 nT rms off)
        carried = expected["carried"][order]
        assert carried.sum() == expected["crossing"] > 0
        rms = np.sqrt((err[carried] ** 2).mean(axis=0))
        assert np.all(rms < 0.03), (sensor, rms)
    return a


def _task(sim, out):
    return make_day_task(sim, out, formats=("tab", "cdf"), levels=("A", "B", "F"))


def test_split_layout(sim):
    # raw day folders split at midnight of the raw time; the last OB records of day 1 are
    # Normal mode (8.2 s), IB has Minimum mode (1023.95 s) in its last 15 minutes
    for sensor in ("OB", "IB"):
        r1 = _raw_rows(science_file(sim, D1, sensor))
        r2 = _raw_rows(science_file(sim, D2, sensor))
        assert all(t.startswith(D1.isoformat()) for t in r1[:, 0])
        assert all(t.startswith(D2.isoformat()) for t in r2[:, 0])
        assert r1[-1, 2] == "2" and "1" in set(r1[:, 2])
        assert r1.shape[0] == r2.shape[0] == int(1800 * RATE_HZ)


@pytest.mark.parametrize("order", [(D1, D2), (D2, D1)])
def test_both_days_every_vector_once(sim, tmp_path, order):
    out = tmp_path / "out"
    task = _task(sim, out)
    for day in order:
        task(day)
    for sensor in ("OB", "IB"):
        exp = _expected(sim, sensor)
        a1 = _check_day(out, sim, D1, sensor, exp)
        a2 = _check_day(out, sim, D2, sensor, exp)
        assert int(a1.attrs["vectors_to_next_day"]) == exp["crossing"]
        assert int(a2.attrs["vectors_from_previous_day"]) == exp["crossing"]
    # archive tables: the Normal-mode run continues across midnight as one segment file
    assert len(list(out.glob(f"RPCMAG{D2:%y%m%d}T0000_CLA_OB_M2.TAB"))) == 1
    assert len(list(out.glob(f"RPCMAG{D2:%y%m%d}T0002_CLA_IB_M1.TAB"))) == 1  # +1023.95 s


def test_crossing_counts_from_seed_table(sim):
    # 4 Hz: OB crosses with the last 8.2 s of Normal mode (32 records, 23:59:52.00-59.75);
    # IB with all of Minimum mode 23:45-23:52 (7 min = 1680 records, +1023.95 s) and the
    # last 31.95 s of Normal mode (127 records, 23:59:28.25-59.75)
    assert _expected(sim, "OB")["crossing_raw"] == 32
    assert _expected(sim, "IB")["crossing_raw"] == 1680 + 127


def test_batch_report_no_day_fails(sim, tmp_path):
    out = tmp_path / "out"
    report = run_batch([D1, D2], _task(sim, out), out, scheduler="serial", name="rosetta")
    assert [d.status for d in report.days] == ["done", "done"], report.days
    # the report counts each raw record once (4 Hz, 30 min, two sensors)
    assert report.n_vectors == 2 * 2 * int(1800 * RATE_HZ)


def test_day1_alone_writes_its_part_and_says_the_rest_is_day2(sim, tmp_path, caplog):
    out = tmp_path / "out"
    with caplog.at_level(logging.INFO, logger="fluxcal"):
        _task(sim, out)(D1)
    for sensor in ("OB", "IB"):
        exp = _expected(sim, sensor)
        a1 = _check_day(out, sim, D1, sensor, exp)
        assert int(a1.attrs["vectors_to_next_day"]) == exp["crossing"]
        assert f"{exp['crossing']} vectors shifted past midnight belong to the product of " \
               f"{D2}" in caplog.text
    assert not list(out.glob(f"*{D2:%Y%m%d}*")) and not list(out.glob(f"*{D2:%y%m%d}*"))


def test_record_outside_the_raw_day_is_refused_with_file_and_line(sim, tmp_path):
    inp = tmp_path / "in"
    shutil.copytree(sim, inp)
    path = science_file(inp, D1, "OB")
    lines = path.read_text().splitlines()
    moved = science_file(inp, D2, "OB").read_text().splitlines()[1]
    path.write_text("\n".join([*lines, moved]) + "\n")  # a D2 record in the D1 folder
    with pytest.raises(InputFormatError) as err:
        make_day_task(inp, tmp_path / "out", formats=("cdf",), levels=("A",))(D1)
    text = str(err.value)
    assert "science_OB.csv" in text and f"line {len(lines) + 1}" in text, text
    assert "time_utc" in text and "not in 2014-11-01" in text


def test_negative_filter_shift_is_refused_with_table_and_sid():
    # the seed's tables hold delays >= 0 (sec. 4.2.3.5); a negative one would move vectors
    # before their day's midnight, which the day edges of decision 30 do not handle
    from fluxcal.errors import FluxcalError
    from fluxcal.missions.rosetta.calib import TimeShiftTable, load_time_shift_table
    from fluxcal.missions.rosetta.day_edges import check_shifts_nonnegative

    seed = load_time_shift_table()
    check_shifts_nonnegative(seed)
    assert np.nanmin(seed.primary) == 0.0 and np.nanmax(seed.secondary) == 1023.95
    bad = TimeShiftTable(seed.sid, seed.primary.copy(), seed.secondary, source="my_shifts.csv")
    bad.primary[1] = -2.0
    with pytest.raises(FluxcalError, match=rf"my_shifts.csv: SID {int(seed.sid[1])} .*-2.0"):
        check_shifts_nonnegative(bad)


def test_cli_batch_both_days_done(sim, tmp_path):
    # through the command line (issue 12): before, day 1 failed with "records outside the
    # day 2014-11-01 ... a day folder must hold that UTC day only" and exit 1
    import json

    from fluxcal.cli import main

    out = tmp_path / "out"
    code = main(["batch", "rosetta", "--start", D1.isoformat(), "--end", D2.isoformat(),
                 "--input", str(sim), "--out", str(out), "--quiet", "--scheduler", "serial",
                 "--formats", "cdf"])
    report = json.loads((out / "batch_report_rosetta.json").read_text())
    assert code == 0, report
    assert report["counts"] == {"done": 2, "skipped": 0, "no_data": 0, "failed": 0}
    for sensor in ("OB", "IB"):
        exp = _expected(sim, sensor)
        assert _level_a(out, D2, sensor).sizes["time"] == exp[D2][0].size
