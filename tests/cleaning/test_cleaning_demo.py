"""The disturbance-removal demo recovers the known field it was built from."""

from __future__ import annotations

import re

from fluxcal.missions.rosetta.cleaning_demo import run_demo


def test_demo_recovers_the_injected_truth(tmp_path):
    summary = run_demo(tmp_path, hours=0.5)
    db = float(re.search(r"power down ([\d.]+) dB", summary).group(1))
    found, truth = map(int, re.search(r"(\d+) jumps found \(truth (\d+)\)", summary).groups())
    rms = [float(v) for v in summary.rsplit(":", 1)[1].split()]
    assert db >= 20.0  # issue 5: line power drops by >= 20 dB
    # every jump found; at most one spurious one: the second-pass threshold (nominally
    # 0.001 false alarms per series) sits at the noise tail, and with the issue-11 line
    # removal seed 3 gives one 0.11 nT false step (moving variance 5 % above the
    # threshold; 0 of seeds 1, 2, 4-8), whose removal costs < 0.01 nT rms
    assert truth <= found <= truth + 1
    assert max(rms) < 0.1  # issue 5: residual < 0.1 nT rms after step removal
    assert (tmp_path / "cleaning_summary.txt").is_file()
