"""The batch demo's MESSENGER input simulation (split of the streams by UTC day)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from fluxcal.missions.messenger.batch_task import simulate_messenger_days


def test_messenger_streams_split_by_utc_day(tmp_path: Path) -> None:
    days = simulate_messenger_days(tmp_path, duration_s=240.0)  # 2 min each side of midnight
    assert days == [dt.date(2012, 6, 1), dt.date(2012, 6, 2)]
    whole = tmp_path / "simulation" / "inputs" / "MAG_science.csv"
    n_whole = len(whole.read_text().splitlines()) - 1
    parts = sorted(tmp_path.glob("MAGSCI_*.csv"))
    assert [p.name for p in parts] == ["MAGSCI_2012153.csv", "MAGSCI_2012154.csv"]
    rows = [np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2) for p in parts]
    assert sum(len(r) for r in rows) == n_whole
    # MET increases across the split: the first day ends before the second begins
    assert rows[0][-1, 1] < rows[1][0, 1]
    assert (tmp_path / "kernels.tm").exists()
    assert sorted(p.name[:6] for p in tmp_path.glob("MAG*_*.csv")) == (
        ["MAGHTR"] * 2 + ["MAGSCI"] * 2 + ["MAGTMP"] * 2)
