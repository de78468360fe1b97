"""``fluxcal batch imap`` and ``fluxcal imap calibrate`` are the same driver: same products.

The inputs are the IMAP MAG team's real ground-test packets from ../shared/data/imap (laid
out under batch names of their days); the expected values are the single run's products
(a route the batch shares no per-mission code with beyond the pipeline), compared field by
field and in time.
"""

from __future__ import annotations

import json
from pathlib import Path

import cdflib
import numpy as np
import pytest

from fluxcal.cli import main
from tests.missions.imap.conftest import CALIBRATION, SCLK, XTCE

TEAM_ARGS = ["--kernels", str(SCLK), "--calib", str(CALIBRATION), "--xtce", str(XTCE)]


@pytest.mark.parametrize("named_for", ["20231130", "20231129"])
def test_batch_day_equals_the_single_run(imap_data: Path, tmp_path: Path,
                                         named_for: str) -> None:
    """The vectors of 2023-11-30 in a file named for their day, or for the day before.

    Issue 31: named for the day before, that day's task reported them done and wrote
    nothing (they are not of its day) and their day, without a file, was no_data.  Now
    their day takes them from its neighbour's file; each day's count is what it wrote.
    """
    (tmp_path / "in").mkdir()
    packets = tmp_path / "in" / f"imap_mag_l0_raw_{named_for}_v001.pkts"
    packets.write_bytes((imap_data / "mag_l1_test_data.pkts").read_bytes())
    single = ["imap", "calibrate", "--out", str(tmp_path / "single"), "--input", str(packets)]
    assert main(single + TEAM_ARGS) == 0
    assert main(["batch", "imap", "--start", "2023-11-29", "--end", "2023-11-30",
                 "--input", str(tmp_path / "in"), "--out", str(tmp_path / "batch"),
                 "--scheduler", "serial", "--quiet", *TEAM_ARGS]) == 0
    report = json.loads((tmp_path / "batch" / "batch_report_imap.json").read_text())
    status = {d["day"]: (d["status"], d["n_vectors"]) for d in report["days"]}
    assert status["2023-11-29"][0] == "no_data"
    made = sorted(p.name for p in (tmp_path / "batch").glob("*.cdf"))
    assert made == ["imap_mag_l1b_norm-magi_20231130_v001.cdf",
                    "imap_mag_l1b_norm-mago_20231130_v001.cdf"]
    written = 0
    for name in made:
        a = cdflib.CDF(str(tmp_path / "single" / name))
        b = cdflib.CDF(str(tmp_path / "batch" / name))
        for var in ("epoch", "b"):
            np.testing.assert_array_equal(a.varget(var), b.varget(var))
        written += len(b.varget("epoch"))
    assert status["2023-11-30"] == ("done", written)
