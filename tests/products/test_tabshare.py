"""Shared formatted fields (`fluxcal.products.tabshare`): reuse never changes a table.

Oracle: the same table written by a writer that shares nothing (a fresh
`SharedFields`), and Python's ``%`` formatting for values changed in place.
"""

from __future__ import annotations

import gc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import fluxcal.products.tab as tab_mod
from fluxcal.products import Column, write_tab
from fluxcal.products.tabshare import SharedFields

COLS = [Column("hour", "I2.2"), Column("second", "%06.3f"), Column("met", "F17.6"),
        Column("b", "F10.3", label="B{c}")]


@pytest.fixture
def shared(monkeypatch: pytest.MonkeyPatch) -> SharedFields:
    s = SharedFields()
    monkeypatch.setattr(tab_mod, "SHARED", s)
    return s


def _frame(time: dict[str, np.ndarray], seed: int) -> xr.Dataset:
    n = time["met"].size
    b = np.random.default_rng(seed).normal(0, 300, (n, 3))
    return xr.Dataset({**{k: ("time", v) for k, v in time.items()},
                       "b": (("time", "c"), b)}, coords={"c": ["x", "y", "z"]})


def _grid(n: int) -> dict[str, np.ndarray]:
    t = np.arange(n) * 0.05
    return {"hour": (t // 3600).astype(np.int8), "second": t % 60, "met": 2.4e8 + t}


def _fresh(ds: xr.Dataset, path: Path) -> bytes:
    """The table as written with nothing shared."""
    saved = tab_mod.SHARED
    tab_mod.SHARED = SharedFields()
    try:
        write_tab(ds, path, COLS)
    finally:
        tab_mod.SHARED = saved
    return path.with_suffix(".TAB").read_bytes()


def test_frames_of_one_grid_reuse_the_time_columns(shared: SharedFields,
                                                   tmp_path: Path) -> None:
    grid = _grid(2503)
    frames = [_frame(grid, s) for s in range(4)]
    found = []
    real_runs = shared.runs

    def spy(*args, **kwargs):
        runs = real_runs(*args, **kwargs)
        found.append([(r.first, r.stop, r.found) for r in runs])
        return runs

    shared.runs = spy  # type: ignore[method-assign]
    for k, ds in enumerate(frames):
        write_tab(ds, tmp_path / f"F{k}", COLS)
    # first frame: nothing seen; second: kept (hour, second, met); then copied
    assert found == [[], [(0, 3, False)], [(0, 3, True)], [(0, 3, True)]]
    for k, ds in enumerate(frames):
        assert (tmp_path / f"F{k}.TAB").read_bytes() == _fresh(ds, tmp_path / f"G{k}")


def test_values_changed_in_place_are_formatted_again(shared: SharedFields,
                                                     tmp_path: Path) -> None:
    grid = _grid(100)
    for k in range(2):
        write_tab(_frame(grid, k), tmp_path / f"F{k}", COLS)
    grid["met"][7] += 0.5  # same array object, new value
    grid["second"][3] = -0.0
    write_tab(_frame(grid, 2), tmp_path / "F2", COLS)
    rows = (tmp_path / "F2.TAB").read_bytes().split(b"\r\n")
    met, sec = "%17.6f", "%06.3f"  # printf is the oracle
    assert rows[7][10:27].decode() == met % grid["met"][7]
    assert rows[3][3:9].decode() == sec % -0.0 == "-0.000"
    assert (tmp_path / "F2.TAB").read_bytes() == _fresh(_frame(grid, 2), tmp_path / "G2")


def test_entries_go_with_their_arrays(shared: SharedFields, tmp_path: Path) -> None:
    grid = _grid(50)
    for k in range(2):
        write_tab(_frame(grid, k), tmp_path / f"F{k}", COLS)
    assert len(shared._entries) == 1
    del grid
    gc.collect()
    assert shared._entries == {} and shared._seen == {}


@pytest.mark.parametrize("n", [1, 7, 8, 13, 1001])
def test_fingerprint_sees_any_one_changed_byte(n: int) -> None:
    """Equal for an equal copy; different after changing any single byte (tail too)."""
    from fluxcal.products.tabshare import fingerprint

    a = np.random.default_rng(n).integers(0, 256, n).astype(np.uint8)
    assert fingerprint(a) == fingerprint(a.copy())
    for i in range(n):
        b = a.copy()
        b[i] ^= 1
        assert fingerprint(b) != fingerprint(a)
    assert fingerprint(a.view(np.int8)) != fingerprint(a)  # the dtype is part of it
