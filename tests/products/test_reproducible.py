"""The same run twice gives byte-identical science content (issue 6, provenance).

"Science content" is every byte of the data: the whole ``.TAB``, every CDF/netCDF/Zarr
variable's raw values (dtype and bytes, no decoding) and every variable attribute, and
every label line and global attribute except the creation time (``creation_time``,
``PRODUCT_CREATION_TIME``, CDF ``Generation_date``), which is the only thing allowed to
differ.  With ``SOURCE_DATE_EPOCH`` pinned, whole files are byte-identical.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.products import read_fluxcal_product, write_product, zarr_available
from fluxcal.runs.batch import manifest_path, run_batch
from fluxcal.runs.synthetic_task import SyntheticDayTask, write_synthetic_inputs

#: The only attributes / label keywords allowed to change between two identical runs.
CREATION_KEYS = {"creation_time", "Generation_date", "PRODUCT_CREATION_TIME"}
DAYS = [dt.date(2024, 3, 1), dt.date(2024, 3, 2)]
FORMATS = ("tab", "cdf", "nc", *(("zarr",) if zarr_available() else ()))


def _raw(value: Any) -> Any:
    """A comparable form that keeps dtype and every byte of array values."""
    if isinstance(value, np.ndarray | np.generic):
        arr = np.asarray(value)
        return (arr.dtype.str, arr.shape, arr.tobytes())
    if isinstance(value, list | tuple):
        return [_raw(v) for v in value]
    if isinstance(value, dict):
        return {k: _raw(v) for k, v in value.items()}
    return value


def _xarray_raw(ds: xr.Dataset) -> dict[str, Any]:
    return {
        "vars": {name: (var.dims, _raw(var.values), _raw(dict(var.attrs)))
                 for name, var in ds.variables.items()},
        "attrs": {k: _raw(v) for k, v in ds.attrs.items() if k not in CREATION_KEYS},
    }


def science_content(path: Path) -> Any:
    """Everything in a product file except its creation time, as raw bytes."""
    suffix = path.suffix.lower()
    if suffix in (".tab", ".txt", ".csv"):  # tables and text reports carry no creation time
        return path.read_bytes()
    if suffix == ".lbl":
        return [line for line in path.read_bytes().splitlines()
                if line.split(b"=")[0].strip().decode() not in CREATION_KEYS]
    if suffix == ".cdf":
        cdf = cdflib.CDF(str(path))
        info = cdf.cdf_info()
        return {
            "globals": {k: _raw(v) for k, v in cdf.globalattsget().items()
                        if k not in CREATION_KEYS},
            "vars": {name: (cdf.varinq(name).Data_Type, _raw(cdf.varget(name)),
                            _raw(cdf.varattsget(name)))
                     for name in [*info.rVariables, *info.zVariables]},
        }
    if suffix == ".nc":
        with xr.open_dataset(path, decode_cf=False, mask_and_scale=False) as ds:
            return _xarray_raw(ds.load())
    if suffix == ".zarr":
        with xr.open_dataset(path, engine="zarr", decode_cf=False,
                             mask_and_scale=False) as ds:
            return _xarray_raw(ds.load())
    if suffix == ".png":
        return None  # quicklooks are pictures, not science content
    raise AssertionError(f"no science-content rule for {path}")


def _products(out: Path) -> dict[str, Path]:
    return {p.name: p for p in sorted(out.iterdir()) if not p.name.startswith((".", "batch_"))
            and p.name not in ("manifests", "index.html")}


def _run(inp: Path, out: Path, sde: str, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", sde)
    task = SyntheticDayTask(inp, out, formats=FORMATS)
    report = run_batch(DAYS, task, out, scheduler="serial")
    assert report.ok, [d.error for d in report.days]
    return _products(out)


def test_same_run_twice_identical_science_content(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    inp = tmp_path / "in"
    write_synthetic_inputs(inp, DAYS, n_per_day=300)
    a = _run(inp, tmp_path / "a", "1000000000", monkeypatch)
    b = _run(inp, tmp_path / "b", "1700000000", monkeypatch)  # another creation time
    assert sorted(a) == sorted(b) and len(a) == len(DAYS) * (len(FORMATS) + 1)  # + .LBL
    for name in a:
        assert science_content(a[name]) == science_content(b[name]), name
    # the creation time really differed (the comparison above is not vacuous) ...
    cdf = next(n for n in a if n.endswith(".cdf"))
    assert (cdflib.CDF(str(a[cdf])).globalattsget()["creation_time"]
            != cdflib.CDF(str(b[cdf])).globalattsget()["creation_time"])
    assert a[cdf].read_bytes() != b[cdf].read_bytes()
    # ... and the rule sees a one-ulp change of one value
    ds = read_fluxcal_product(a[cdf])
    ds["B"].values[5, 1] = np.nextafter(ds["B"].values[5, 1], np.inf)
    write_product(ds, tmp_path / "c" / "P", formats=("cdf",))
    assert science_content(tmp_path / "c" / "P.cdf")["vars"]["B"] != \
        science_content(a[cdf])["vars"]["B"]


def test_pinned_creation_time_gives_identical_files(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    inp = tmp_path / "in"
    write_synthetic_inputs(inp, DAYS, n_per_day=300)
    a = _run(inp, tmp_path / "a", "1000000000", monkeypatch)
    b = _run(inp, tmp_path / "b", "1000000000", monkeypatch)
    for name in a:
        pa, pb = a[name], b[name]
        files = sorted(p.relative_to(pa) for p in pa.rglob("*") if p.is_file()) \
            if pa.is_dir() else [Path()]
        for rel in files:
            assert (pa / rel).read_bytes() == (pb / rel).read_bytes(), (name, rel)
    # the folder's HTML report too (it names no folder, time or path)
    assert (tmp_path / "a" / "index.html").read_bytes() == \
        (tmp_path / "b" / "index.html").read_bytes()
    # the manifests record the same product checksums
    for day in DAYS:
        ma = json.loads(manifest_path(tmp_path / "a", "synthetic", day).read_text())
        mb = json.loads(manifest_path(tmp_path / "b", "synthetic", day).read_text())
        assert [p["sha256"] for p in ma["products"]] == [p["sha256"] for p in mb["products"]]


@pytest.fixture(scope="module")
def messenger_input(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dt.date]:
    from fluxcal.missions.messenger.batch_task import simulate_days

    inp = tmp_path_factory.mktemp("messenger") / "in"
    day = dt.date(2012, 6, 1)
    assert simulate_days(inp, [day], seconds_per_day=300.0) == [day]
    return inp, day


def test_messenger_day_twice_identical_science_content(messenger_input, tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The whole MESSENGER day pipeline (SPICE geometry, offsets, averages) is deterministic."""
    from fluxcal.missions.messenger.batch_task import make_day_task

    inp, day = messenger_input
    runs = []
    for out, sde in ((tmp_path / "a", "1000000000"), (tmp_path / "b", "1700000000")):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", sde)
        task = make_day_task(inp, out, formats=("tab", "cdf"), frames=("mso", "rtn"),
                             averages=(60,))
        report = run_batch([day], task, out, scheduler="serial", name="messenger")
        assert report.ok, [d.error for d in report.days]
        runs.append({Path(p).name: out / p for p in report.days[0].products})
    a, b = runs
    assert sorted(a) == sorted(b) and any(n.endswith(".cdf") for n in a)
    for name in a:
        assert science_content(a[name]) == science_content(b[name]), name
