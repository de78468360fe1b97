"""``xr.open_dataset(path, engine="fluxcal")`` and ``open_mfdataset`` over days (issue 32).

Expected values come from the inputs, not from fluxcal's readers: the synthetic day task
computes ``B = gain * (counts - offset)`` from CSVs written here, so the field is
recomputed from the CSV with numpy; the time index is 00:00 UTC of the day plus the
CSV's nanoseconds (the synthetic days have no leap second).
"""

from __future__ import annotations

import datetime as dt
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from fluxcal.runs.batch import run_batch
from fluxcal.runs.synthetic_task import (
    SyntheticDayTask,
    day_epoch0,
    input_path,
    write_synthetic_inputs,
)
from fluxcal.xarray_backend import FluxcalBackendEntrypoint

DAYS = [dt.date(2024, 3, 1), dt.date(2024, 3, 2)]
N = 24
ROOT = Path(__file__).resolve().parents[2]


def _expected(inp: Path, day: dt.date) -> tuple[np.ndarray, np.ndarray]:
    raw = np.loadtxt(input_path(inp, day), delimiter=",", skiprows=1, dtype=np.int64)
    field = 0.05 * (raw[:, 1:] - np.array([12.0, -7.0, 3.0]))
    ns = raw[:, 0] - day_epoch0(day)  # since 00:00 UTC of the day
    times = np.datetime64(day.isoformat(), "ns") + ns.astype("timedelta64[ns]")
    return field, times


@pytest.fixture(scope="module")
def days(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("engine")
    inp, out = root / "in", root / "out"
    write_synthetic_inputs(inp, DAYS, n_per_day=N)
    report = run_batch(DAYS, SyntheticDayTask(inp, out, formats=("tab", "cdf", "nc")), out,
                       scheduler="serial")
    assert report.ok
    return inp, out


@pytest.mark.parametrize("name", ["SYNTH_20240301_v01.cdf", "SYNTH_20240301.nc",
                                  "SYNTH_20240301.TAB", "SYNTH_20240301.LBL"])
def test_open_dataset_every_format(days, name: str) -> None:
    inp, out = days
    ds = xr.open_dataset(out / name, engine=FluxcalBackendEntrypoint)
    field, times = _expected(inp, DAYS[0])
    # the TAB prints the field with %10.3f: half a unit of the third decimal
    np.testing.assert_allclose(ds["B"].values, field, atol=5e-4 + 1e-9)
    np.testing.assert_array_equal(ds.indexes["time"].values, times)
    assert ds["B"].sel(time=slice("2024-03-01T06:00", "2024-03-01T12:00")).sizes["time"] > 0


def test_guess_and_drop_variables(days) -> None:
    engine = FluxcalBackendEntrypoint()
    assert engine.guess_can_open("a.cdf") and engine.guess_can_open(Path("A.LBL"))
    assert not engine.guess_can_open("a.nc") and not engine.guess_can_open(object())
    _, out = days
    ds = xr.open_dataset(out / "SYNTH_20240301_v01.cdf", engine=FluxcalBackendEntrypoint,
                         drop_variables="B")
    assert "B" not in ds


def test_open_mfdataset_joins_the_days_in_time(days) -> None:
    inp, out = days
    ds = xr.open_mfdataset(sorted(out.glob("SYNTH_*_v01.cdf")), engine=FluxcalBackendEntrypoint,
                           combine="by_coords", combine_attrs="drop_conflicts")
    expected = [_expected(inp, d) for d in DAYS]
    np.testing.assert_array_equal(ds.indexes["time"].values,
                                  np.concatenate([t for _, t in expected]))
    np.testing.assert_allclose(ds["B"].values, np.concatenate([f for f, _ in expected]),
                               atol=1e-9)
    assert ds.sizes["time"] == 2 * N


def test_bad_file_is_the_readers_error(tmp_path: Path) -> None:
    from fluxcal.errors import InputFormatError

    bad = tmp_path / "x.cdf"
    bad.write_bytes(b"not a cdf")
    with pytest.raises(InputFormatError, match="x.cdf"):
        xr.open_dataset(bad, engine=FluxcalBackendEntrypoint)


def test_engine_name_from_the_declared_entry_point(days, tmp_path: Path) -> None:
    """``engine="fluxcal"``: the entry point pyproject.toml declares, found by xarray.

    A dist-info with that entry point on ``PYTHONPATH`` stands for the installed
    package (the shared test environment's metadata may predate the entry point).
    """
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())
    ref = declared["project"]["entry-points"]["xarray.backends"]["fluxcal"]
    assert ref == "fluxcal.xarray_backend:FluxcalBackendEntrypoint"
    dist = tmp_path / "fluxcal_engine_check-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: fluxcal-engine-check\n"
                                   "Version: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[xarray.backends]\nfluxcal = {ref}\n")
    inp, out = days
    script = (
        "import sys, xarray as xr\n"
        "assert 'fluxcal' in xr.backends.list_engines()\n"
        f"ds = xr.open_dataset({str(out / 'SYNTH_20240302.TAB')!r}, engine='fluxcal')\n"
        f"mf = xr.open_mfdataset({str(out)!r} + '/SYNTH_*_v01.cdf', engine='fluxcal',"
        " combine='by_coords', combine_attrs='drop_conflicts')\n"
        "print(ds.sizes['time'], mf.sizes['time'], mf.indexes['time'].values[0])\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(tmp_path), str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    _, times = _expected(inp, DAYS[0])
    assert done.stdout.split() == [str(N), str(2 * N), str(times[0])]
