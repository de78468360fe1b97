"""IMAP MAG products: the command, ISTP names, and reading/comparing IMAP-layout CDFs."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import cdflib
import numpy as np
import pytest
from cdflib.cdfwrite import CDF as CDFWriter
from typer.testing import CliRunner

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.imap.cli import app
from fluxcal.products import read_fluxcal_product
from fluxcal.products.compare import compare, load_product
from tests.missions.imap.conftest import CALIBRATION, SCLK, T010, T010_L1A, XTCE

#: The team's files fluxcal does not ship, named as a user names them.
TEAM_ARGS = ("--kernels", str(SCLK), "--calib", str(CALIBRATION), "--xtce", str(XTCE))


def _run(*args: str, team: bool = True) -> None:
    result = CliRunner().invoke(app, ["calibrate", *args, *(TEAM_ARGS if team else ())])
    if result.exception is not None:
        raise result.exception
    assert result.exit_code == 0, result.output


def test_packets_and_team_l1a_csv_give_the_same_l1b(imap_data: Path, tmp_path: Path) -> None:
    # the same packets by two routes: decoded here, and the team's own L1A of them
    csv_in = tmp_path / "MAGScience-normal-(2,2)-8s-20231130-19h08.csv"
    shutil.copy(imap_data / "mag_l1a_test_output.csv", csv_in)
    _run("--input", str(imap_data / "mag_l1_test_data.pkts"), "--out", str(tmp_path / "a"))
    _run("--input", str(csv_in), "--out", str(tmp_path / "b"))
    for sensor in ("mago", "magi"):
        name = f"imap_mag_l1b_norm-{sensor}_20231130_v001.cdf"
        a, b = load_product(tmp_path / "a" / name), load_product(tmp_path / "b" / name)
        c = compare(a, b, 0)
        assert c.matched == c.n_a == c.n_b == 96
        assert all(s.max_abs == 0.0 for s in c.overall)
        assert c.units == "nT"


def test_cdf_product_names_and_contents(imap_data: Path, tmp_path: Path) -> None:
    _run("--input", str(T010_L1A), "--out", str(tmp_path), "--level", "l1a",
         "--formats", "cdf,nc")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [f"imap_mag_l1a_norm-{s}_20250206_v001.{x}"
                     for s in ("magi", "mago") for x in ("cdf", "nc")] + ["index.html"]
    ds = read_fluxcal_product(tmp_path / "imap_mag_l1a_norm-mago_20250206_v001.cdf")
    assert ds.attrs["Logical_file_id"] == "imap_mag_l1a_norm-mago_20250206_v001"
    assert ds["counts"].attrs["units"] == "count"
    with pytest.raises(InputFormatError, match="'counts' is in count, not nT"):
        compare(ds, ds, 0)


def test_bad_input_leaves_nothing(imap_data: Path, tmp_path: Path) -> None:
    data = (imap_data / "mag_l1_test_data.pkts").read_bytes()
    cut = tmp_path / "cut.pkts"
    cut.write_bytes(data[:-10])
    out = tmp_path / "out"
    with pytest.raises(InputFormatError, match="cut.pkts.*sequence count 10, APID 1052"):
        _run("--input", str(imap_data / "mag_l1_test_data.pkts"), "--input", str(cut),
             "--out", str(out))
    assert not out.exists() or not any(out.iterdir())


def test_duplicated_packets_are_dropped_counted_and_warned(
        imap_data: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    packets = imap_data / "mag_l1_test_data.pkts"  # 6 packets, 16 vectors per sensor each
    twice = tmp_path / "twice.pkts"
    data = packets.read_bytes()
    twice.write_bytes(data + data[: int.from_bytes(data[4:6], "big") + 7])  # packet 0 again
    _run("--input", str(packets), "--out", str(tmp_path / "once"))
    for name, inputs in (("given_twice", ("--input", str(packets), "--input", str(packets))),
                         ("file_twice", ("--input", str(twice)))):
        caplog.clear()
        _run(*inputs, "--out", str(tmp_path / name))
        warned = [r.getMessage() for r in caplog.records if "duplicated" in r.getMessage()]
        n = 6 if name == "given_twice" else 1
        assert warned == [f"IMAP MAG norm-{s}: {n} duplicated packet(s) dropped "
                          f"({16 * n} vectors read twice)" for s in ("magi", "mago")]
        for sensor in ("mago", "magi"):
            product = f"imap_mag_l1b_norm-{sensor}_20231130_v001.cdf"
            a = cdflib.CDF(str(tmp_path / "once" / product))
            b = cdflib.CDF(str(tmp_path / name / product))
            np.testing.assert_array_equal(a.varget("epoch"), b.varget("epoch"))
            np.testing.assert_array_equal(a.varget("b"), b.varget("b"))
            assert b.globalattsget()["FLUXCAL_DUPLICATES_DROPPED"] == [16 * n]


def test_inputs_are_recognised_by_content(imap_data: Path, tmp_path: Path) -> None:
    packets = tmp_path / "packets.csv"  # packets under a CSV's name
    packets.write_bytes((imap_data / "mag_l1_test_data.pkts").read_bytes())
    table = tmp_path / "l1a.bin"  # the team's L1A CSV under a packet file's name
    table.write_bytes(T010_L1A.read_bytes())
    _run("--input", str(packets), "--input", str(table), "--csv-layout", "normal-(2,2)-8s",
         "--out", str(tmp_path / "out"))
    assert sorted(p.name for p in (tmp_path / "out").glob("*.cdf")) == [
        f"imap_mag_l1b_norm-{s}_{d}_v001.cdf" for s in ("magi", "mago")
        for d in ("20231130", "20250206")]


def test_missing_team_files_are_one_line_each(imap_data: Path, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture) -> None:
    from fluxcal.cli import main
    from fluxcal.missions.imap import packets

    monkeypatch.setattr(packets, "team_package_xtce", lambda: None)
    pk = str(imap_data / "mag_l1_test_data.pkts")
    out = str(tmp_path / "out")
    cases = {"--kernels": ["--calib", str(CALIBRATION), "--xtce", str(XTCE)],
             "--calib": ["--kernels", str(SCLK), "--xtce", str(XTCE)],
             "--xtce": ["--kernels", str(SCLK), "--calib", str(CALIBRATION)]}
    for option, given in cases.items():
        assert main(["imap", "calibrate", "--input", pk, "--out", out, *given]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and option in err[0] and f"give {option} PATH" in err[0]
    assert not Path(out).exists() or not any(Path(out).iterdir())


def _one_number_less(text: str) -> str:
    rate = text.index(" 1.00000000000\n", text.index("SCLK01_COEFFICIENTS_43"))
    return text[:rate] + text[rate + len(" 1.00000000000"):]


def _zero_modulus(text: str) -> str:
    start = text.index("SCLK01_MODULI_43")
    end = text.index(")", start)
    return text[:start] + "SCLK01_MODULI_43 = ( 4294967296 0 " + text[end:]


@pytest.mark.parametrize(("edit", "named"), [(_one_number_less, "SCLK01_COEFFICIENTS_43"),
                                             (_zero_modulus, "SCLK01_MODULI_43")])
def test_a_damaged_sclk_kernel_is_one_line(edit, named: str, imap_data: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture) -> None:
    from fluxcal.cli import main

    bad = tmp_path / "edited.tsc"
    bad.write_text(edit(SCLK.read_text()))
    code = main(["imap", "calibrate", "--input", str(imap_data / "mag_l1_test_data.pkts"),
                 "--out", str(tmp_path / "out"), "--kernels", str(bad), "--calib",
                 str(CALIBRATION), "--xtce", str(XTCE)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert named in err[0] and "damaged or edited kernel" in err[0]


def _write_imap_layout(path: Path, epoch: np.ndarray, vectors: np.ndarray, units: str) -> None:
    """A CDF in the IMAP team's L1A/L1B layout, written with cdflib alone."""
    w = CDFWriter(str(path), cdf_spec={"Majority": "Row_major"}, delete=True)
    w.write_globalattrs({"Logical_source": {0: "imap_mag_l1b_norm-mago"}})

    def spec(name: str, dtype: int, dims: list[int], rv: bool, nelem: int = 1) -> dict:
        return {"Variable": name, "Data_Type": dtype, "Num_Elements": nelem, "Rec_Vary": rv,
                "Dim_Sizes": dims}

    w.write_var(spec("epoch", 33, [], True), var_attrs={"UNITS": "ns"}, var_data=epoch)
    w.write_var(spec("direction", 4, [4], False), var_attrs={"VAR_TYPE": "support_data"},
                var_data=np.arange(4, dtype=np.int32))
    w.write_var(spec("direction_label", 51, [4], False, 5), var_attrs={"VAR_TYPE": "metadata"},
                var_data=["x", "y", "z", "range"])
    w.write_var(spec("vectors", 45 if units == "nT" else 8, [4], True),
                var_attrs={"DEPEND_0": "epoch", "DEPEND_1": "direction",
                           "LABL_PTR_1": "direction_label", "UNITS": units},
                var_data=vectors)
    w.close()


def test_compare_reads_an_imap_layout_l1b(imap_data: Path, tmp_path: Path) -> None:
    # the team's expected T010 L1B, as an ISTP CDF with time variable 'epoch'
    with (T010 / "mag-l1a-l1b-t010-mago-out.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    with KernelPool([]):
        epoch = utc_to_tt2000(np.array([r["t"] for r in rows]))
    vec = np.array([[float(r["x"]), float(r["y"]), float(r["z"]), float(r["range"])]
                    for r in rows])
    team = tmp_path / "team_l1b.cdf"
    _write_imap_layout(team, epoch, vec, "nT")
    ds = read_fluxcal_product(team)
    assert ds["vectors"].dims == ("time", "direction") and ds.sizes["time"] == 16
    _run("--input", str(T010_L1A), "--out", str(tmp_path / "ours"))
    ours = load_product(tmp_path / "ours" / "imap_mag_l1b_norm-mago_20250206_v001.cdf")
    c = compare(ours, load_product(team), 1000)
    assert c.matched == 16 and c.components == ["x", "y", "z"]
    assert max(s.max_abs for s in c.overall) <= 1e-9
    counts = tmp_path / "team_l1a.cdf"
    _write_imap_layout(counts, epoch, vec.astype(np.int64), "counts")
    with pytest.raises(InputFormatError, match="'vectors' is in counts, not nT"):
        compare(ours, load_product(counts), 1000)
    assert cdflib.CDF(str(counts)).varinq("epoch").Data_Type_Description == "CDF_TIME_TT2000"


@pytest.mark.slow
def test_products_pass_spacepy_and_cdflib_istp_checks(imap_data: Path, tmp_path: Path,
                                                       caplog: pytest.LogCaptureFixture) -> None:
    from tests.products._istp import istp_problems

    _run("--input", str(imap_data / "mag_l0_test_data.pkts"), "--out", str(tmp_path / "b"),
         "--quicklook")
    assert len(list((tmp_path / "b").glob("imap_mag_ql_*-ma*_20231025.png"))) == 4
    _run("--input", str(imap_data / "mag_l1_test_data.pkts"), "--out", str(tmp_path / "a"),
         "--level", "l1a")
    cdfs = sorted((tmp_path / "a").glob("*.cdf")) + sorted((tmp_path / "b").glob("*.cdf"))
    assert len(cdfs) == 6  # l1a norm x2, l1b norm and burst x2
    problems, repeated = {}, []
    for path in cdfs:
        errors = istp_problems(path, tmp_path, caplog)
        if np.any(np.diff(cdflib.CDF(str(path)).varget("Epoch")) == 0):
            # the L0 sample's ground-test packets overlap in time: two vectors share a
            # time tag; fluxcal keeps both (docs/decisions/imap.md), cdflib says "not monotonic"
            repeated.append(path.parent.name)
            errors = [e for e in errors if "monoton" not in e and "no variable named" not in e]
        if errors:
            problems[path.name] = errors
    assert problems == {}
    assert set(repeated) == {"b"}  # only products of the overlapping L0 sample
