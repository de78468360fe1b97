"""Products hold no path of the machine that made them; ``fluxcal provenance`` reads them.

The real commands (MESSENGER ``edr2cdr`` from archive-style EDRs, Rosetta ``calibrate``
and ``clean``, IMAP ``calibrate``, a batch with a failing day) write every format into a
temporary folder; the bytes of every file written are then searched for the temporary
folder, the checkout, ``site-packages`` and ``$HOME`` (issue 25 item 5).
"""

from __future__ import annotations

import datetime as dt
import json
import os
import site
import sys
from pathlib import Path

import cdflib
import pytest

import fluxcal
from fluxcal.cli import main
from fluxcal.products.cdf import istp_parents
from fluxcal.products.provenance import (
    portable_command_line,
    portable_text,
    provenance_attrs,
)
from fluxcal.products.provenance_read import read_provenance
from tests.conftest import SHARED_DATA

T010_L1A = (SHARED_DATA / "imap" / "validation" / "T010"
            / "MAGScience-normal-(2,2)-8s-20250206-12h05.csv")


def _forbidden(root: Path) -> dict[str, bytes]:
    """The folders no product may name, as bytes."""
    repo = Path(fluxcal.__file__).resolve().parents[2]
    found = {"tmp": str(root), "tmp (resolved)": str(root.resolve()), "checkout": str(repo),
             "prefix": sys.prefix}
    for i, sp in enumerate([*site.getsitepackages(), site.getusersitepackages()]):
        found[f"site-packages {i}"] = sp
    home = os.environ.get("HOME", "")
    if len(home) > 1:
        found["HOME"] = home
    return {k: v.encode() for k, v in found.items()}


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file())


def _leaks(path: Path, forbidden: dict[str, bytes]) -> list[str]:
    data = path.read_bytes()
    return [name for name, text in forbidden.items() if text in data]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """Run each mission's command into its own folder; return the output folders."""
    root = tmp_path_factory.mktemp("prov")
    out: dict[str, Path] = {}
    # MESSENGER from archive-style EDRs (PDS3 labels + tables) and a mapping file
    msim = root / "msim"
    assert main(["simulate", "messenger", "--out", str(msim), "--duration", "600",
                 "--layout", "edr"]) == 0
    out["messenger"] = root / "m"
    assert main(["messenger", "edr2cdr", "--edr", str(msim / "edr"), "--mapping",
                 str(msim / "edr" / "edr_mapping.toml"), "--kernels",
                 str(msim / "kernels" / "messenger_synthetic.tm"), "--frames", "mso,rtn",
                 "--average", "60", "--formats", "tab,cdf,nc,zarr,png", "--quicklook",
                 "--out", str(out["messenger"])]) == 0
    # Rosetta from CSV telemetry: every level, every format, with kernels and a calib folder
    rsim = root / "rsim"
    assert main(["simulate", "rosetta", "--out", str(rsim), "--hours", "0.05"]) == 0
    out["rosetta"] = root / "r"
    assert main(["rosetta", "calibrate", "--science", str(rsim / "RPCMAG_20140801_RAW_OB.csv"),
                 "--sensor", "OB", "--hk", str(rsim / "RPCMAG_20140801_RAW_HK.csv"),
                 "--kernels", str(rsim / "kernels" / "rosetta_synthetic.tm"), "--calib",
                 str(rsim / "calib"), "--levels", "A,B,C,E,F,G", "--formats",
                 "tab,cdf,nc,zarr", "--quicklook", "--out", str(out["rosetta"])]) == 0
    out["clean"] = root / "c"
    assert main(["rosetta", "clean", "--level", "K", "--input",
                 str(out["rosetta"] / "rosetta_rpcmag_clb-ob_20140801_v01.cdf"),
                 "--formats", "tab,cdf,nc,zarr", "--out", str(out["clean"])]) == 0
    # IMAP from the team's L1A CSV (../shared/data), when present
    if T010_L1A.is_file():
        out["imap"] = root / "i"
        imap = T010_L1A.parents[2]
        assert main(["imap", "calibrate", "--input", str(T010_L1A), "--formats", "cdf,nc",
                     "--kernels", str(imap / "imap_sclk_0036.tsc"), "--calib",
                     str(imap / "imap_calibration_mag_20240229_v01.cdf"),
                     "--out", str(out["imap"])]) == 0
    # a batch: manifests and a report, one day failing (its error names its input)
    from fluxcal.runs.batch import run_batch
    from fluxcal.runs.synthetic_task import SyntheticDayTask, input_path, write_synthetic_inputs

    days = [dt.date(2024, 3, 1), dt.date(2024, 3, 2)]
    write_synthetic_inputs(root / "bin", days, n_per_day=200)
    bad = input_path(root / "bin", days[1])
    bad.write_text(bad.read_text().replace(",", ",1e", 3))
    out["batch"] = root / "b"
    report = run_batch(days, SyntheticDayTask(root / "bin", out["batch"]), out["batch"],
                       scheduler="serial")
    assert [d.status for d in report.days] == ["done", "failed"]
    return out | {"root": root}


@pytest.mark.slow
def test_no_product_names_a_folder_of_the_machine(runs) -> None:
    forbidden = _forbidden(runs["root"])
    scanned, leaks = 0, []
    for kind in ("messenger", "rosetta", "clean", "imap", "batch"):
        if kind not in runs:
            continue
        files = _files(runs[kind])
        assert files, kind
        for path in files:
            scanned += 1
            leaks += [f"{path.relative_to(runs['root'])}: {name}"
                      for name in _leaks(path, forbidden)]
    assert leaks == []
    assert scanned > 100  # CDF, netCDF, Zarr chunks and metadata, labels, tables, PNG, JSON
    # not vacuous: a file naming the output folder is caught (as every product was before)
    control = runs["root"] / "control.json"
    control.write_text(json.dumps({"path": str(runs["messenger"] / "x.cdf")}))
    assert "tmp" in _leaks(control, forbidden)


@pytest.mark.slow
def test_provenance_command_reads_every_format(runs, capsys) -> None:
    products = [runs["messenger"] / "messenger_mag_mso-sci_20120601_v01.cdf",
                runs["messenger"] / "messenger_mag_mso-sci_20120601_v01.nc",
                runs["messenger"] / "messenger_mag_mso-sci_20120601_v01.zarr",
                runs["messenger"] / "MAGMSOSCI12153_V01.LBL",
                runs["rosetta"] / "rosetta_rpcmag_clc-ob_20140801_v01.cdf",
                runs["clean"] / "rosetta_rpcmag_clk-ob_20140801_v01.zarr"]
    for path in products:
        capsys.readouterr()
        assert main(["provenance", str(path), "--json"]) == 0, path
        prov = json.loads(capsys.readouterr().out)
        assert prov["product"] == path.name
        assert prov["inputs"] and all(set(r) == {"name", "sha256"} and len(r["sha256"]) == 64
                                      for r in prov["inputs"])
        assert prov["kernels"] and prov["command_line"].startswith("fluxcal ")
        assert main(["provenance", str(path)]) == 0
        text = capsys.readouterr().out
        assert f"product: {path.name}" in text and "inputs (" in text
    # MESSENGER read EDR labels, their tables and the mapping: all by name
    prov = read_provenance(products[0])
    names = {r["name"] for r in prov["inputs"]}
    assert "edr_mapping.toml" in names and any(n.startswith("MAGSCI") for n in names)
    assert "--edr edr " in prov["command_line"]
    # the Rosetta LEVEL_K was made from the LEVEL_B CDF: an ISTP CDF parent
    assert read_provenance(products[-1])["inputs"][0]["name"] == \
        "rosetta_rpcmag_clb-ob_20140801_v01.cdf"


@pytest.mark.slow
def test_istp_parents_by_input_kind(runs) -> None:
    def parents(path: Path) -> list[str]:
        return list(cdflib.CDF(str(path)).globalattsget()["Parents"])

    # CSV telemetry: the file name, no "CDF>" (before: "CDF>RPCMAG_20140801_RAW_OB.csv")
    assert parents(runs["rosetta"] / "rosetta_rpcmag_clc-ob_20140801_v01.cdf") == [
        "RPCMAG_20140801_RAW_OB.csv", "RPCMAG_20140801_RAW_HK.csv"]
    # a CDF parent: CDF>logical_file_id
    assert parents(runs["clean"] / "rosetta_rpcmag_clk-ob_20140801_v01.cdf") == [
        "CDF>rosetta_rpcmag_clb-ob_20140801_v01"]
    # PDS3 EDR labels and tables
    msgr = parents(runs["messenger"] / "messenger_mag_mso-sci_20120601_v01.cdf")
    assert msgr and all(not p.startswith("CDF>") and "/" not in p for p in msgr)
    assert {Path(p).suffix for p in msgr} == {".LBL", ".TAB", ".toml"}


def test_parents_rule() -> None:
    assert istp_parents(["/x/y/a_v01.cdf", "B.CDF", "c.csv", "", "d.pkts"]) == [
        "CDF>a_v01", "CDF>B", "c.csv", "d.pkts"]


@pytest.mark.parametrize(("text", "expected"), [
    ("/home/u/data/RPCMAG_SC_ALIGN.TXT (version 1)", "RPCMAG_SC_ALIGN.TXT (version 1)"),
    ("model 006 daily files: rsim/calib/RPCMAG_140801_006_CALIB_OB.TXT",
     "model 006 daily files: RPCMAG_140801_006_CALIB_OB.TXT"),
    ('json:[{"path": "/opt/venv/lib/site-packages/x/de421.bsp"}]', 'json:[{"path": "de421.bsp"}]'),
    ("C:\\Users\\me\\k\\naif0012.tls", "naif0012.tls"),
    # not paths: frames, units, URLs, ratios stay as they are
    ("67P/C-G_CSEQ", "67P/C-G_CSEQ"), ("km/s", "km/s"), ("1/2.5", "1/2.5"),
    ("https://spdf.gsfc.nasa.gov/istp_guide/gattributes.html",
     "https://spdf.gsfc.nasa.gov/istp_guide/gattributes.html"),
])
def test_portable_text(text: str, expected: str) -> None:
    assert portable_text(text) == expected


def test_command_line_and_records_name_no_folder(tmp_path: Path) -> None:
    a = tmp_path / "sub" / "a.csv"
    a.parent.mkdir()
    a.write_bytes(b"abc")
    argv = [str(tmp_path / "venv" / "bin" / "fluxcal"), "rosetta", "calibrate", "--science",
            str(a), f"--out={tmp_path / 'out'}", "--frame", "67P/C-G_CSEQ", "--sensor", "OB"]
    assert portable_command_line(argv) == ("fluxcal rosetta calibrate --science a.csv "
                                           "--out=out --frame 67P/C-G_CSEQ --sensor OB")
    attrs = provenance_attrs(inputs=[a], calibration={"ground": a, "jumps": "v2"},
                             kernels=[a, tmp_path / "gone.bsp"], command_line=" ".join(argv))
    assert str(tmp_path) not in json.dumps(attrs)
    assert attrs["kernels"][1] == {"name": "gone.bsp"}
    assert attrs["calibration"] == {"ground": {"name": "a.csv", "sha256": attrs["inputs"][0][
        "sha256"]}, "jumps": {"version": "v2"}}


@pytest.mark.slow
def test_rosetta_cdfs_tag_their_frame_and_pass_the_istp_checks(runs, tmp_path: Path,
                                                                caplog) -> None:
    """COORDINATE_SYSTEM from each level's frame (pyspedas tags it); cleaned K its own names."""
    import logging

    import cdflib.xarray as cx
    import pyspedas
    from spacepy import pycdf
    from spacepy.pycdf import istp

    tolerated = "Multi dim variable with time_series display type."
    cdfs = sorted(runs["rosetta"].glob("*.cdf")) + sorted(runs["clean"].glob("*.cdf"))
    assert [p.name for p in runs["clean"].glob("*.cdf")] == [
        "rosetta_rpcmag_clk-ob_20140801_v01.cdf"]
    frames = {}
    caplog.set_level(logging.INFO, logger="cdflib")
    for path in cdfs:
        f = cdflib.CDF(str(path))
        g = f.globalattsget()
        assert g["Logical_file_id"] == [path.stem]
        if "b" in f.cdf_info().zVariables:
            frame = f.varattsget("b")["frame"]
            assert f.varattsget("b")["COORDINATE_SYSTEM"] == frame
            assert "b" in pyspedas.cdf_to_tplot(str(path))
            assert pyspedas.get_coords("b") == frame
            frames[g["Logical_source"][0]] = frame
        with pycdf.CDF(str(path)) as c:
            assert [e for e in istp.FileChecks.all(c) if not e.endswith(tolerated)] == []
        caplog.clear()
        cx.xarray_to_cdf(cx.cdf_to_xarray(str(path), to_datetime=False),
                         str(tmp_path / path.name), istp=True)
        assert [r.getMessage() for r in caplog.records if r.name.startswith("cdflib")] == []
    assert frames["rosetta_rpcmag_cla-ob"] == "ROS_RPC_MAG_OB (URF)"
    assert frames["rosetta_rpcmag_clb-ob"] == "ROS_SPACECRAFT"
    assert frames["rosetta_rpcmag_clk-ob"] == "ROS_SPACECRAFT"
    g = cdflib.CDF(str(cdfs[-1])).globalattsget()
    assert g["Data_type"] == ["CLK-OB>LEVEL_K heater disturbance removed"]


def test_each_cleaning_level_has_its_own_istp_names() -> None:
    from fluxcal.missions.rosetta.clean_cli import CLEAN_DESCRIPTION, clean_logical_source
    from fluxcal.products.cdf import istp_file_stem, istp_logical_source

    names = {}
    for level in CLEAN_DESCRIPTION:
        for sensor in ("OB", "IB", "EXT"):
            data_type, source = clean_logical_source(level, sensor)
            # the ISTP rule: Logical_source = source_descriptor_datatype (short forms)
            assert source == istp_logical_source("ROSETTA>x", "RPCMAG>y", data_type)
            names[(level, sensor)] = istp_file_stem(source, "2014-08-01", 1)
    assert len(set(names.values())) == len(names)
    assert names[("H", "OB")] == "rosetta_rpcmag_clh-ob_20140801_v01"


@pytest.mark.parametrize("name", ["not_a_product.cdf", "notes.txt", "x.nc"])
def test_provenance_of_a_non_product_is_one_line_exit_2(name: str, tmp_path: Path,
                                                         capsys) -> None:
    bad = tmp_path / name
    bad.write_text("hello\n")
    assert main(["provenance", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and name in err[0]
