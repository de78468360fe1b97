"""The MESSENGER tables read with the archive's column positions (issue 10 item 5).

A reader that knows only the archive layout -- blank-separated columns, CDR ``YEAR
DAY_OF_YEAR HOUR MINUTE SECOND TIME_TAG X Y Z BX BY BZ``, RDR ``YEAR DAY_OF_YEAR HOUR
MINUTE SECOND TIME_TAG NAVG X Y Z BX BY BZ DBX DBY DBZ`` -- reads fluxcal's tables with
plain numpy (no fluxcal code) and gets the right quantities: compared with the CDF
(cdflib), with averages recomputed from the full-resolution table, and with cdflib's
breakdown of the CDF epochs.  A table that takes the archive's name has exactly the
archive's columns (issue 32: no ``DEFECT_FLAG`` column; the flags are in the CDF).
"""

import re

import cdflib
import numpy as np
import pytest

from fluxcal.cli import main

# printed with 3 decimals (km, nT): half a unit in the last place
PRINT_TOL = 5e-4 + 1e-9


@pytest.fixture(scope="module")
def out(tmp_path_factory, simulated_files, messenger_kernels):
    folder = tmp_path_factory.mktemp("layout")
    f = simulated_files
    code = main(["messenger", "edr2cdr", "--sci", str(f["science"]), "--heater",
                 str(f["heater"]), "--temperature", str(f["temperature"]), "--kernels",
                 str(messenger_kernels), "--out", str(folder), "--frames", "mso,rtn,sc",
                 "--average", "1,60", "--formats", "tab,cdf", "--version", "3"])
    assert code == 0
    return folder


def _cdf_name(frame, seconds=None):
    """ISTP name of the CDF beside the archive-named table (version 3, 2012-06-01)."""
    kind = "sci" if seconds is None else f"avg{seconds}"
    return f"messenger_mag_{frame}-{kind}_20120601_v03.cdf"


def _table(path):
    return np.loadtxt(path)  # whitespace split, nothing else


def _cdf(path):
    c = cdflib.CDF(str(path))
    return c, {name: c.varget(name) for name in c.cdf_info().zVariables}


def test_names_carry_day_interval_and_version(out):
    names = {p.name for p in out.iterdir()}
    for stem in ("MAGMSOSCI12153_V03", "MAGMSOSCIAVG12153_01_V03", "MAGMSOSCIAVG12153_60_V03",
                 "MAGRTNSCI12153_V03", "MAGSCSCIAVG12153_60_V03"):
        assert {f"{stem}.TAB", f"{stem}.LBL"} <= names
    for frame, seconds in (("mso", None), ("mso", 1), ("mso", 60), ("rtn", None), ("sc", 60)):
        assert _cdf_name(frame, seconds) in names


def test_cdr_columns_are_the_archive_columns(out):
    tab = _table(out / "MAGMSOSCI12153_V03.TAB")
    assert tab.shape[1] == 12  # the archive's 12, nothing more (issue 32)
    cdf, v = _cdf(out / _cdf_name("mso"))
    np.testing.assert_allclose(tab[:, 6:9], v["position"], atol=PRINT_TOL)  # X Y Z
    np.testing.assert_allclose(tab[:, 9:12], v["b"], atol=PRINT_TOL)  # BX BY BZ
    np.testing.assert_allclose(tab[:, 5], v["met"], atol=5e-7)  # TIME_TAG
    # UTC columns: cdflib's breakdown of the CDF Epoch, milliseconds truncated
    ref = np.array(cdflib.cdfepoch.breakdown_tt2000(cdf.varget("Epoch")))
    np.testing.assert_array_equal(tab[:, 0], ref[:, 0])
    np.testing.assert_array_equal(tab[:, 2:4], ref[:, 3:5])
    np.testing.assert_allclose(tab[:, 4], ref[:, 5] + ref[:, 6] / 1000.0, atol=1e-9)
    # in time order (the simulated day has fast -> slow rate switches)
    assert (np.diff(cdf.varget("Epoch")) > 0).all() and (np.diff(tab[:, 5]) > 0).all()


def test_rdr_columns_and_values_from_the_cdr_table(out):
    full = _table(out / "MAGMSOSCI12153_V03.TAB")
    avg = _table(out / "MAGMSOSCIAVG12153_60_V03.TAB")
    assert avg.shape[1] == 16
    _, v = _cdf(out / _cdf_name("mso", 60))
    np.testing.assert_array_equal(avg[:, 6], v["count"])  # NAVG
    np.testing.assert_allclose(avg[:, 7:10], v["position"], atol=PRINT_TOL)
    np.testing.assert_allclose(avg[:, 13:16], v["b_std"], atol=PRINT_TOL)  # DBX DBY DBZ
    # recompute from the full-resolution table: group by the UTC minute of each row
    minute = (full[:, 1] * 1440 + full[:, 2] * 60 + full[:, 3]).astype(int)
    keys, start, count = np.unique(minute, return_index=True, return_counts=True)
    assert avg.shape[0] == keys.size
    np.testing.assert_array_equal(avg[:, 6], count)
    for k, (s, n) in enumerate(zip(start, count, strict=True)):
        rows = full[s:s + n]
        # means of values printed to 0.001: within the print tolerance
        np.testing.assert_allclose(avg[k, 10:13], rows[:, 9:12].mean(axis=0), atol=1e-3)
        np.testing.assert_allclose(avg[k, 13:16], rows[:, 9:12].std(axis=0), atol=1e-3)
    # the centre of the interval: SS.sss = 30.000 of each minute
    np.testing.assert_allclose(avg[:, 4], 30.0)


def test_rtn_and_sc_layouts(out):
    rtn = _table(out / "MAGRTNSCI12153_V03.TAB")
    assert rtn.shape[1] == 12
    _, v = _cdf(out / _cdf_name("rtn"))
    np.testing.assert_allclose(rtn[:, 6], v["r"], atol=0.05 + 1e-6)  # R printed to 0.1 km
    np.testing.assert_allclose(rtn[:, 7], v["latitude"], atol=5e-6)
    np.testing.assert_allclose(rtn[:, 8], v["azimuth"], atol=5e-6)
    np.testing.assert_allclose(rtn[:, 9:12], v["b"], atol=PRINT_TOL)
    assert 0.3 * 1.496e8 < rtn[:, 6].min() and rtn[:, 6].max() < 0.47 * 1.496e8
    sc = _table(out / "MAGSCSCI12153_V03.TAB")
    assert sc.shape[1] == 9  # no position
    sc_avg = _table(out / "MAGSCSCIAVG12153_60_V03.TAB")
    assert sc_avg.shape[1] == 13


#: The archive's columns (docs/formats/messenger.md, table "CDR column / RDR column"; the
#: seed's sec. 12 keeps the SHC quality flag out of them), written out here by hand.
_TIME = ["YEAR", "DAY_OF_YEAR", "HOUR", "MINUTE", "SECOND", "TIME_TAG"]
ARCHIVE_COLUMNS = {
    ("MSO", False): [*_TIME, "X", "Y", "Z", "BX", "BY", "BZ"],
    ("MSO", True): [*_TIME, "NAVG", "X", "Y", "Z", "BX", "BY", "BZ", "DBX", "DBY", "DBZ"],
    ("RTN", False): [*_TIME, "R", "LATITUDE", "AZIMUTH", "BR", "BT", "BN"],
    ("RTN", True): [*_TIME, "NAVG", "R", "LATITUDE", "AZIMUTH", "BR", "BT", "BN", "DBR",
                    "DBT", "DBN"],
    ("SC", False): [*_TIME, "BX", "BY", "BZ"],
    ("SC", True): [*_TIME, "NAVG", "BX", "BY", "BZ", "DBX", "DBY", "DBZ"],
}


@pytest.mark.parametrize("frame, averaged", sorted(ARCHIVE_COLUMNS))
def test_archive_named_tables_have_exactly_the_archive_columns(out, frame, averaged):
    """Names and count from the label (pvl, not fluxcal), and the rows' field count."""
    import pvl

    stem = f"MAG{frame}SCI{'AVG' if averaged else ''}12153{'_60' if averaged else ''}_V03"
    label = pvl.load(str(out / f"{stem}.LBL"))
    names = [c["NAME"] for k, c in label["TABLE"].items() if k == "COLUMN"]
    assert names == ARCHIVE_COLUMNS[frame, averaged]
    assert label["TABLE"]["COLUMNS"] == len(names)
    assert _table(out / f"{stem}.TAB").shape[1] == len(names)


def test_order_and_quality_reported_in_label_and_cdf(out):
    label = (out / "MAGMSOSCI12153_V03.LBL").read_text()
    moved = int(re.search(r"FLUXCAL_REORDERED_SAMPLES\s*=\s*(\d+)", label).group(1))
    assert moved > 0  # the rate switches 10 -> 8 -> 6 move samples back
    assert re.search(r"FLUXCAL_DUPLICATES_DROPPED\s*=\s*0", label)
    cdf, v = _cdf(out / _cdf_name("mso"))
    g = cdf.globalattsget()
    assert int(np.ravel(g["FLUXCAL_REORDERED_SAMPLES"])[0]) == moved
    # the SHC flags present are listed in the label (the table has no flag column)
    flags = re.search(r"DATA_QUALITY_ID\s*=\s*\(?([^)\r\n]*)", label).group(1)
    assert sorted(re.findall(r"\d{3}", flags)) == [f"{q:03d}" for q in np.unique(v["quality"])]
    np.testing.assert_allclose(v["b_total"], np.linalg.norm(v["b"], axis=1), rtol=1e-12)


def test_pvl_and_pdr_read_the_products(out):
    """The archive's own tools: pvl parses the label, pdr reads the table by it."""
    import pdr
    import pvl

    for stem in ("MAGMSOSCI12153_V03", "MAGRTNSCIAVG12153_60_V03", "MAGSCSCI12153_V03"):
        label = pvl.load(out / f"{stem}.LBL")
        assert label["PRODUCT_ID"] == stem
        assert label["FLUXCAL_DUPLICATES_DROPPED"] == 0
        table = pdr.read(out / f"{stem}.LBL")["TABLE"]
        plain = _table(out / f"{stem}.TAB")
        assert table.shape == plain.shape
        np.testing.assert_array_equal(table[table.columns[-1]].to_numpy(), plain[:, -1])
