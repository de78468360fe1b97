"""``fluxcal batch imap`` and ``fluxcal imap calibrate`` are the same driver: same products.

The inputs are the real ground-test packets shipped with fluxcal; the expected values are
the single run's products (a route the batch shares no per-mission code with beyond the
pipeline), compared field by field and in time.
"""

from __future__ import annotations

import json
from pathlib import Path

import cdflib
import numpy as np

from fluxcal.cli import main
from fluxcal.missions.imap.routes import SAMPLE_DAYS, simulate_days


def test_batch_day_equals_the_single_run(tmp_path: Path) -> None:
    simulate_days(tmp_path / "in", list(SAMPLE_DAYS.values()))
    packets = sorted((tmp_path / "in").glob("*.pkts"))
    single = ["imap", "calibrate", "--out", str(tmp_path / "single")]
    for p in packets:
        single += ["--input", str(p)]
    assert main(single) == 0
    assert main(["batch", "imap", "--start", "2023-10-25", "--end", "2023-10-26",
                 "--input", str(tmp_path / "in"), "--out", str(tmp_path / "batch"),
                 "--scheduler", "serial", "--quiet"]) == 0
    report = json.loads((tmp_path / "batch" / "batch_report_imap.json").read_text())
    assert report["counts"]["done"] == 1 and report["counts"]["no_data"] == 1
    made = sorted(p.name for p in (tmp_path / "batch").glob("*.cdf"))
    assert made == ["imap_mag_l1b_burst-magi_20231025_v001.cdf",
                    "imap_mag_l1b_burst-mago_20231025_v001.cdf"]
    for name in made:
        a = cdflib.CDF(str(tmp_path / "single" / name))
        b = cdflib.CDF(str(tmp_path / "batch" / name))
        for var in ("epoch", "b"):
            np.testing.assert_array_equal(a.varget(var), b.varget(var))


def test_a_file_named_for_the_day_before_loses_no_vector(tmp_path: Path) -> None:
    """Issue 31: a day's file holding another day's vectors; before, its task reported them
    done and wrote nothing (they are not of its day), and their day had no file (no_data).
    Now their day takes them from its neighbour's file: batch = single run, vector for
    vector, and each day's reported count is what its products hold."""
    import datetime as dt

    from fluxcal.missions.imap.packets import data_file

    day = SAMPLE_DAYS["mag_sample_norm.pkts"]
    before = day - dt.timedelta(days=1)
    inp = tmp_path / "in"
    inp.mkdir()
    packets = inp / f"imap_mag_l0_norm_{before:%Y%m%d}_v001.pkts"  # named for the day before
    packets.write_bytes(data_file("mag_sample_norm.pkts").read_bytes())
    assert main(["imap", "calibrate", "--out", str(tmp_path / "single"), "--input",
                 str(packets)]) == 0
    assert main(["batch", "imap", "--start", f"{before}", "--end", f"{day}", "--input",
                 str(inp), "--out", str(tmp_path / "batch"), "--scheduler", "serial",
                 "--quiet"]) == 0
    report = json.loads((tmp_path / "batch" / "batch_report_imap.json").read_text())
    status = {d["day"]: (d["status"], d["n_vectors"]) for d in report["days"]}
    assert status[f"{before}"][0] == "no_data"
    made = sorted(p.name for p in (tmp_path / "single").glob("*.cdf"))
    assert made and made == sorted(p.name for p in (tmp_path / "batch").glob("*.cdf"))
    written = 0
    for name in made:
        a = cdflib.CDF(str(tmp_path / "single" / name))
        b = cdflib.CDF(str(tmp_path / "batch" / name))
        for var in ("epoch", "b"):
            np.testing.assert_array_equal(a.varget(var), b.varget(var))
        written += len(b.varget("epoch"))
    assert status[f"{day}"] == ("done", written)
