"""Issue 10: Rosetta tables under the archive's names, read with the archive's column
positions (plain whitespace split, numpy/cdflib only, no fluxcal reader).

Archive layout (seed 003 sec. 4.2.3.5, 4.3.1, 4.6, 4.7; names from the archive's
calibrated/resampled data sets):

- ``RPCMAG<yymmdd>T<hhmm>_CL<A|B>_<OB|IB>_M<mode>.TAB``: TIME.UTC TIME.OBT BX BY BZ T QUALITY
- ``RPCMAG<yymmdd>_CL<E|F>_<OB|IB>_A<NN>.TAB``: TIME.UTC TIME.OBT BX BY BZ QUALITY
"""

import cdflib
import numpy as np
import pytest

from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.routes import run_files

from ._raw import write_raw_csv

SHIFT_SID2 = 8.2  # s, seed 003 sec. 4.2.3.5, primary sensor, SID2 (Normal)


@pytest.fixture
def run(tmp_path, pool):
    """Three mode segments: SID2 10:00-10:01, SID3 10:01-10:02, SID2 10:02-10:03 (1 Hz)."""
    sid = np.repeat([2, 3, 2], 60)
    words = np.linspace(12000, 12600, 180).astype(int)
    raw = write_raw_csv(tmp_path / "raw.csv", "2014-08-01T10:00:00", 180, 1.0, sid=sid,
                        t_words=words)
    out = tmp_path / "out"
    made = {}
    run_files(raw, "OB", out, options=RosettaOptions(levels=("A", "B", "E", "F"), average_s=1.0),
              on_calibrated=lambda run: made.update(run.sensors[0].levels))
    return out, made, sid


def _rows(path):
    return [line.split() for line in path.read_text().splitlines()]


def test_calibrated_files_split_by_mode(run):
    out, res, _ = run
    names = sorted(p.name for p in out.glob("RPCMAG*_CLA_*.TAB"))
    assert names == ["RPCMAG140801T1000_CLA_OB_M2.TAB", "RPCMAG140801T1001_CLA_OB_M3.TAB",
                     "RPCMAG140801T1002_CLA_OB_M2.TAB"]
    assert sorted(p.name for p in out.glob("RPCMAG*_CLB_*.TAB")) == [
        n.replace("CLA", "CLB") for n in names]
    assert [p.name for p in out.glob("RPCMAG*_CLE_*.TAB")] == ["RPCMAG140801_CLE_OB_A01.TAB"]
    assert [p.name for p in out.glob("RPCMAG*_CLF_*.TAB")] == ["RPCMAG140801_CLF_OB_A01.TAB"]


@pytest.mark.parametrize("level", ["A", "B"])
def test_calibrated_table_archive_columns(run, level):
    out, res, sid = run
    ds = res[level]
    epoch = ds["epoch"].values
    for path, mode, first in (("T1000", 2, 0), ("T1001", 3, 60), ("T1002", 2, 120)):
        rows = _rows(out / f"RPCMAG140801{path}_CL{level}_OB_M{mode}.TAB")
        assert len(rows) == 60 and all(len(r) == 7 for r in rows)
        utc = np.array([r[0] for r in rows], dtype="M8[us]")
        # TIME.UTC: 6 decimals, the raw time tag plus the mode's filter shift
        assert all(len(r[0]) == 26 and r[0][19] == "." for r in rows)
        raw_t = np.datetime64("2014-08-01T10:00:00", "us") + np.arange(first, first + 60) * 10**6
        shift = np.timedelta64(int(round(SHIFT_SID2 * 1e6)) if mode == 2 else 0, "us")
        np.testing.assert_array_equal(utc, raw_t + shift)
        # the same vectors in memory, found by their (independently converted) times
        mem_utc = np.array(cdflib.cdfepoch.to_datetime(epoch)).astype("M8[us]")
        idx = np.searchsorted(mem_utc, utc)
        np.testing.assert_array_equal(mem_utc[idx], utc)
        cols = np.array([[float(x) for x in r[1:]] for r in rows])
        np.testing.assert_allclose(cols[:, 0], ds["obt"].values[idx], atol=5e-7)  # F17.6
        np.testing.assert_allclose(cols[:, 1:4], ds["b"].values[idx], atol=5e-4)  # F11.3
        np.testing.assert_allclose(cols[:, 4], ds["temperature"].values[idx], atol=5e-3)  # K
        assert 150 < cols[:, 4].min() and cols[:, 4].max() < 300  # kelvin, not deg C
        np.testing.assert_array_equal(cols[:, 5], 0)  # QUALITY of good OB vectors


@pytest.mark.parametrize("level", ["E", "F"])
def test_resampled_table_archive_columns(run, level):
    out, res, _ = run
    ds = res[level]
    rows = _rows(out / f"RPCMAG140801_CL{level}_OB_A01.TAB")
    assert len(rows) == ds.sizes["time"] and all(len(r) == 6 for r in rows)
    utc = np.array([r[0] for r in rows], dtype="M8[us]")
    # bin centres of 1-s UTC bins (sec. 4.6-4.8: "the middle of the regarded interval")
    frac = (utc - utc.astype("M8[s]")).astype(np.int64)
    np.testing.assert_array_equal(frac, 500_000)
    cols = np.array([[float(x) for x in r[1:]] for r in rows])
    np.testing.assert_allclose(cols[:, 1:4], ds["b"].values, atol=5e-4)
    np.testing.assert_array_equal(cols[:, 4], 0)


def test_cdf_logical_source_without_date(run):
    out, _, _ = run
    for source in ("rosetta_rpcmag_cla-ob", "rosetta_rpcmag_clf-ob-a01"):
        path = out / f"{source}_20140801_v01.cdf"
        g = cdflib.CDF(str(path)).globalattsget()
        assert g["Logical_source"] in (source, [source])
        assert "2014" not in str(g["Logical_source"])
        assert "20140801" in str(g["Logical_file_id"])


def test_labels_name_the_seed_columns(run):
    """The PDS3 labels load with pvl and name the columns as the seed's tables, in order."""
    import pvl

    out, _, _ = run
    expect = {
        "RPCMAG140801T1001_CLA_OB_M3.LBL": ["TIME.UTC", "TIME.OBT", "BX", "BY", "BZ", "T",
                                           "QUALITY"],
        "RPCMAG140801_CLF_OB_A01.LBL": ["TIME.UTC", "TIME.OBT", "BX", "BY", "BZ", "QUALITY"],
    }
    for name, columns in expect.items():
        label = pvl.load(str(out / name))
        table = label["TABLE"]
        assert [c["NAME"] for c in table.getall("COLUMN")] == columns
        assert label["LEVEL"] == ("LEVEL_A" if "CLA" in name else "LEVEL_F")
