"""The one-call API (`fluxcal.api`) in a fresh interpreter: each mission's run in one call,
returning time-indexed Datasets on which ``.sel`` and ``.resample`` work.

The accuracy of each chain is tested where the chain is (forward models, the IMAP team's
files); here: the shape of what one call returns.  Rosetta LEVEL_A's time index is checked
against its exact ``epoch``; IMAP's vector count against the team's (96 per sensor of the
team's normal-mode packets in ../shared/data/imap, `mag_l1a_test_output.csv`).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fluxcal.cli import main
from tests.missions.imap.conftest import CALIBRATION, IMAP, MISSING, SCLK, XTCE

NORM_PACKETS = IMAP / "mag_l1_test_data.pkts"


def _fresh(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.splitlines()[-1])


@pytest.fixture(scope="module")
def messenger_day(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("api_msgr")
    assert main(["simulate", "messenger", "--out", str(out), "--duration", "600"]) == 0
    return {p.stem: p for p in out.rglob("*") if p.is_file()}


def test_messenger_day_in_one_call(messenger_day) -> None:
    files = {k: str(v) for k, v in messenger_day.items()}
    sci = next(v for k, v in files.items() if k.endswith("science"))
    heat = next(v for k, v in files.items() if k.endswith("heater"))
    temp = next(v for k, v in files.items() if k.endswith("temperature"))
    kernels = next(v for v in files.values() if v.endswith(".tm"))
    code = f"""
import json, numpy as np, fluxcal
made = fluxcal.calibrate_messenger([{sci!r}], [{heat!r}], [{temp!r}], {kernels!r},
                                   frames=("mso", "rtn"))
ds = made["mso"]
part = ds.sel(time=slice(ds.time.values[10], ds.time.values[200]))
minute = ds["b"].resample(time="1min").mean()
print(json.dumps({{"n": int(ds.sizes["time"]), "part": int(part.sizes["time"]),
                   "minutes": int(minute.sizes["time"]), "frames": sorted(made),
                   "vars": sorted(ds.data_vars)}}))
"""
    got = _fresh(code)
    assert got["part"] == 191 and got["minutes"] >= 10
    assert got["frames"] == ["mso", "rtn"] and {"b", "b_total", "quality"} <= set(got["vars"])


def test_rosetta_run_in_one_call(tmp_path: Path) -> None:
    assert main(["simulate", "rosetta", "--out", str(tmp_path), "--hours", "0.05"]) == 0
    code = f"""
import json, numpy as np, fluxcal
levels = fluxcal.calibrate_rosetta({str(tmp_path / "RPCMAG_20140801_RAW_OB.csv")!r}, "OB",
                                   levels=("A", "B"), calib={str(tmp_path / "calib")!r})
a = levels["A"]
first = a.sel(time=a.time.values[0])
print(json.dumps({{"levels": sorted(levels), "n": int(a.sizes["time"]),
                   "index": str(a.indexes["time"].dtype),
                   "ns": int(a["epoch"].values[1] - a["epoch"].values[0]),
                   "dt": int((a.time.values[1] - a.time.values[0]).astype("int64"))}}))
"""
    got = _fresh(code)
    assert got["levels"] == ["A", "B"] and got["n"] > 100
    assert got["index"] == "datetime64[ns]" and got["ns"] == got["dt"]  # no leap second here


def test_imap_packets_in_one_call() -> None:
    if not NORM_PACKETS.is_file():
        pytest.skip(MISSING)
    code = f"""
import json, fluxcal
out = fluxcal.calibrate_imap([{str(NORM_PACKETS)!r}], kernels={str(SCLK)!r},
                             calib={str(CALIBRATION)!r}, xtce={str(XTCE)!r})
ds = out["norm-mago"]
print(json.dumps({{"keys": sorted(out), "n": int(ds.sizes["time"]),
                   "sel": int(ds.sel(time=slice(ds.time.values[0], ds.time.values[9]))
                              .sizes["time"]), "units": ds["b"].attrs.get("units")}}))
"""
    got = _fresh(code)
    assert got["keys"] == ["norm-magi", "norm-mago"]
    assert got["n"] == 96 and got["sel"] >= 10 and got["units"] == "nT"


def test_read_product_reads_tables_with_a_time_index(tmp_path: Path) -> None:
    import fluxcal

    (path,) = [p for p in _imap_cdf(tmp_path)]
    ds = fluxcal.read_product(path)
    assert ds.indexes["time"].dtype.kind == "M"
    assert ds.sel(time=ds.time.values[:5]).sizes["time"] == 5


def _imap_cdf(tmp_path: Path) -> list[Path]:
    if not NORM_PACKETS.is_file():
        pytest.skip(MISSING)
    assert main(["imap", "calibrate", "--input", str(NORM_PACKETS), "--out", str(tmp_path),
                 "--kernels", str(SCLK), "--calib", str(CALIBRATION), "--xtce", str(XTCE)]) == 0
    return sorted(tmp_path.glob("*mago*.cdf"))
