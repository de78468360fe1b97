"""Progress and ``-v`` account of a run (issue 31, "a user's daily friction").

Every mission's single run reports its steps through the one progress callback of
`fluxcal.runs.driver.run` (a rich bar:
`fluxcal.runs.display_cli.progress_display`)
and logs one INFO line per step that matters: kernels loaded, inputs read with their
counts, calibration chosen, each level done with its vectors, products written.  The
counts expected here come from the inputs themselves (CSV rows, the products read back),
not from the pipeline's own summary.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import pytest

from fluxcal.missions.imap.options import ImapOptions
from fluxcal.missions.imap.routes import ImapRun
from fluxcal.missions.imap.sources import TEAM_FILES, sclk_kernels, shared_folder
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.routes import run_files
from fluxcal.missions.rosetta.simulate import write_simulation
from fluxcal.products import read_fluxcal_product
from fluxcal.runs import driver


def _check_steps(seen: list[tuple[str, int, int]], written: list[Path]) -> None:
    """Steps are (text, done, total) with 0 <= done <= total; the run ends with its files.

    A total of 0 is unknown (each declared product written, `fluxcal.products.declared`).
    """
    assert seen, "no progress reported"
    assert all(isinstance(d, str) and 0 <= n and (t == 0 or n <= t) for d, n, t in seen), seen
    assert seen[0] == ("reading inputs", 0, 1)
    assert ("writing products", 0, 1) in seen
    assert seen[-1] == (f"wrote {len(written)} files", 1, 1)


def _messages(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records
            if r.name.startswith("fluxcal") and r.levelno == logging.INFO]


def test_rosetta_run_reports_progress_and_steps(tmp_path: Path, caplog) -> None:
    sim = write_simulation(tmp_path / "sim", hours=0.01, seed=3)
    rows = len(sim["science_OB"].read_text().splitlines()) - 1  # the CSV's records
    seen: list[tuple[str, int, int]] = []
    options = RosettaOptions(calib=sim["calib"], formats=("cdf",), levels=("A", "B"))
    with caplog.at_level(logging.INFO, logger="fluxcal"):
        written = run_files(sim["science_OB"], "OB", tmp_path / "out", options=options,
                            progress=lambda *step: seen.append(step))
    _check_steps(seen, written)
    assert ("OB: calibrating LEVEL_A,B", 0, 1) in seen and ("calibrated", 1, 1) in seen
    text = _messages(caplog)
    assert f"read 1 input file(s): {rows:,} vectors" in text
    assert any(m.startswith("OB calibration: GroundCalibration(OB, ") for m in text), text
    assert f"OB science: {rows:,} records from {sim['science_OB'].name}" in text
    for level in "AB":  # each level done with the vectors its product holds
        cdf = tmp_path / "out" / f"rosetta_rpcmag_cl{level.lower()}-ob_20140801_v01.cdf"
        n = read_fluxcal_product(cdf).sizes["time"]
        assert f"OB LEVEL_{level} done: {n:,} vectors" in text, (level, text)
    assert f"wrote {len(written)} product file(s) to {tmp_path / 'out'}" in text
    assert len(text) <= 12  # one line per step, not a line per sample or file


def test_imap_run_reports_progress_and_steps(tmp_path: Path, caplog) -> None:
    folder = shared_folder()
    if folder is None:
        pytest.skip("the IMAP MAG team's files are not in ../shared/data/imap")
    inputs = (folder / TEAM_FILES["norm"], folder / TEAM_FILES["burst"])
    options = ImapOptions(level="l1b", calib=folder / TEAM_FILES["calib"],
                          xtce=folder / TEAM_FILES["xtce"])
    seen: list[tuple[str, int, int]] = []
    with caplog.at_level(logging.INFO, logger="fluxcal"):
        written, n_vectors = driver.run(ImapRun(), inputs,
                                        sclk_kernels(folder / TEAM_FILES["sclk"]),
                                        tmp_path / "out", options,
                                        progress=lambda *step: seen.append(step))
    _check_steps(seen, written)
    keys = [d for d, _n, _t in seen if d.startswith("L1B ")]
    assert keys[-1] == "L1B calibrated" and len(keys) >= 3  # a step per (mode, sensor)
    text = _messages(caplog)
    assert any(m.startswith("kernels loaded: ") and m.endswith(f"{TEAM_FILES['sclk']})")
               for m in text), text
    assert f"calibration: {TEAM_FILES['calib']}" in text
    assert any(m.startswith(f"read {TEAM_FILES['norm']}: norm-") for m in text), text
    products = [read_fluxcal_product(p) for p in written if Path(p).suffix == ".cdf"]
    assert sum(p.sizes["time"] for p in products) == n_vectors  # every vector written
    done = [m for m in text if re.match(r"L1B \w+-mag[io] done: [\d,]+ vectors", m)]
    assert sum(int(re.search(r"([\d,]+) vectors", m)[1].replace(",", "")) for m in done) \
        == n_vectors
    assert len(text) <= 12
