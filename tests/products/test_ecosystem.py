"""fluxcal products in the tools space physicists use: spacepy's and cdflib's ISTP checks,
cdflib's xarray loader, pyspedas, sunpy and plain xarray (netCDF and Zarr).

Every product type is covered through a small dataset shaped like the real product (its
variable names, dtypes, units, dimension labels and the mission's ISTP tables):
MESSENGER full resolution (MSO and RTN) and averaged, Rosetta calibrated levels,
resampled levels and housekeeping, and the synthetic batch product.  Expected values come
from the datasets themselves and from cdflib's own TT2000 conversion, never from fluxcal's
readers.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import cdflib
import cdflib.xarray as cx
import numpy as np
import pytest
import xarray as xr

from fluxcal.missions.messenger.products import istp_files as messenger_istp
from fluxcal.missions.rosetta.products import istp_yaml as rosetta_istp
from fluxcal.products import read_fluxcal_product, write_product, zarr_available
from fluxcal.products.cdf import istp_file_stem
from tests.products._istp import SPACEPY_TOLERATED, istp_problems

N = 1200  # 20 minutes at 1 Hz



def _epoch(day: str, step_s: float = 1.0, n: int = N) -> np.ndarray:
    y, m, d = map(int, day.split("-"))
    t0 = int(cdflib.cdfepoch.compute_tt2000([y, m, d, 0, 0, 0, 0, 0, 0]))
    return t0 + (np.arange(n, dtype=np.int64) * int(step_s * 1e9)) + 250_000_000


def _field(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 200.0, (n, 3))


def _prov() -> dict:
    return {"software": "fluxcal", "software_version": "0.1.0", "command_line": "test",
            "creation_time": "2026-01-01T00:00:00Z", "Data_version": "1",
            "inputs": [{"name": "in.dat", "path": "in.dat", "sha256": "ab" * 32}]}


def messenger_full(frame: str, averaged: bool = False) -> xr.Dataset:
    """Shaped like missions/messenger/products.py: product_dataset / average."""
    step = 60.0 if averaged else 1.0
    n = N // 60 if averaged else N
    epoch = _epoch("2012-06-01", step, n)
    sec = (epoch - epoch[0]) / 1e9 + 0.25
    t = ("time",)
    labels = ["B_R", "B_T", "B_N"] if frame == "rtn" else ["B_X", "B_Y", "B_Z"]
    b = _field(n, 1)
    b[5, 1] = np.nan  # a gap: FILLVAL in the file
    data: dict = {
        "year": (t, np.full(n, 2012, np.int16), {"units": "year"}),
        "doy": (t, np.full(n, 153, np.int16), {"units": "day"}),
        "hour": (t, (sec // 3600).astype(np.int8), {"units": "h"}),
        "minute": (t, (sec // 60 % 60).astype(np.int8), {"units": "min"}),
        "second": (t, sec % 60, {"units": "s"}),
        "met": (t, 2.4e8 + sec, {"units": "s", "description": "lag-corrected MET"}),
        "b": (("time", "b_component"), b, {"units": "nT", "description": "field",
                                           "coordinate_system": f"{frame.upper()}"}),
        "b_total": (t, np.sqrt(np.nansum(b * b, axis=1)), {"units": "nT"}),
        "quality": (t, (np.arange(n) % 3).astype(np.int16), {"units": "1"}),
    }
    if frame == "rtn":
        data["r"] = (t, np.full(n, 6.9e7), {"units": "km"})
        data["latitude"] = (t, np.full(n, 3.4), {"units": "deg"})
        data["azimuth"] = (t, np.linspace(-170, 170, n), {"units": "deg"})
    else:
        data["position"] = (("time", "position_component"),
                            np.full((n, 3), 2400.0) + _field(n, 2),
                            {"units": "km", "coordinate_system": frame.upper()})
    coords: dict = {"epoch": ("time", epoch), "b_component": labels}
    if frame != "rtn":
        coords["position_component"] = ["X", "Y", "Z"]
    if averaged:
        data["count"] = (t, np.full(n, 1200, np.int32), {"units": "1"})
        data["b_std"] = (("time", "b_component"), np.abs(_field(n, 3)) / 100, {"units": "nT"})
    attrs = _prov() | ({"averaging_interval_s": 60} if averaged else {})
    return xr.Dataset(data, coords=coords, attrs=attrs)


def rosetta_level(level: str) -> xr.Dataset:
    """Shaped like missions/rosetta/products.level_products (LEVEL_A/B/C/E/F/G)."""
    step = 60.0 if level in "EFG" else 1.0
    n = N // 60 if level in "EFG" else N
    epoch = _epoch("2014-08-01", step, n)
    t = ("time",)
    frame = {"A": "URF", "B": "ROS_SPACECRAFT", "C": "67P/C-G_CSEQ"}.get(level, "ECLIPJ2000")
    data: dict = {
        "time_utc": (t, np.array([f"2014-08-01T00:{i // 60 % 60:02d}:{i % 60:02d}.250000"
                                  for i in range(n)]), {"units": "UTC"}),
        "obt": (t, 3.5e8 + (epoch - epoch[0]) / 1e9, {"units": "s"}),
        "sid": (t, np.full(n, 3, np.int16), {"units": "1"}),
        "b": (("time", "component"), _field(n, 4), {"units": "nT",
                                                    "coordinate_system": frame}),
        "quality": (t, np.zeros(n, np.int32), {"units": "1"}),
    }
    if level in "AB":
        data["temperature"] = (t, np.full(n, 150.0), {"units": "K"})
    if level in "CG":
        data["position"] = (("time", "component"), np.full((n, 3), 1.0e5),
                            {"units": "km", "coordinate_system": frame})
    if level in "EFG":
        data["n_samples"] = (t, np.full(n, 1200, np.int32), {"units": "1"})
    return xr.Dataset(data, coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]},
                      attrs=_prov() | {"level": level, "sensor": "OB"})


def rosetta_hk() -> xr.Dataset:
    """Shaped like missions/rosetta/hk.py + products.hk_product."""
    n = N // 32
    epoch = _epoch("2014-08-01", 32.0, n)
    t = ("time",)
    data = {
        "time_utc": (t, np.array(["2014-08-01T00:00:00.250000"] * n), {"units": "UTC"}),
        "obt": (t, 3.5e8 + (epoch - epoch[0]) / 1e9, {"units": "s"}),
        "t_ob": (t, np.full(n, 140.0), {"units": "K"}),
        "t_ib": (t, np.full(n, 150.0), {"units": "K"}),
        "stage_a_id": (t, np.ones(n, np.int32), {"units": "1"}),
        "stage_b_id": (t, np.ones(n, np.int32), {"units": "1"}),
        "filter_cfg": (t, np.ones(n, np.int32), {"units": "1"}),
        "ref_voltage": (t, np.full(n, 2.5), {"units": "V"}),
        "pos_voltage": (t, np.full(n, 5.0), {"units": "V"}),
        "neg_voltage": (t, np.full(n, -5.0), {"units": "V"}),
        "b_ob": (("time", "component"), _field(n, 5), {"units": "nT",
                                                       "coordinate_system": "URF"}),
    }
    return xr.Dataset(data, coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]},
                      attrs=_prov() | {"level": "A (HK)"})


def synthetic() -> xr.Dataset:
    """Shaped like products/synthetic_task.py (the batch product)."""
    epoch = _epoch("2024-03-01")
    return xr.Dataset(
        {"B": (("time", "component"), _field(N, 6), {"units": "nT",
                                                     "description": "Synthetic field"})},
        coords={"epoch": ("time", epoch, {"units": "ns", "description": "TT2000"}),
                "component": ["x", "y", "z"]}, attrs=_prov())


def _messenger_kw(source: str) -> dict:
    g, v = messenger_istp()
    return {"global_yaml": g, "variable_yaml": v, "label_extra": {"Logical_source": source}}


def _rosetta_kw(source: str) -> dict:
    return {**rosetta_istp(), "label_extra": {"Logical_source": source}}


#: product type -> (dataset builder, UTC day, write_product keywords)
PRODUCTS: dict[str, tuple[Callable[[], xr.Dataset], str, dict]] = {
    "messenger_mso_full": (lambda: messenger_full("mso"), "2012-06-01",
                           _messenger_kw("messenger_mag_mso-sci")),
    "messenger_rtn_full": (lambda: messenger_full("rtn"), "2012-06-01",
                           _messenger_kw("messenger_mag_rtn-sci")),
    "messenger_mso_avg60": (lambda: messenger_full("mso", True), "2012-06-01",
                            _messenger_kw("messenger_mag_mso-avg60")),
    "rosetta_level_a": (lambda: rosetta_level("A"), "2014-08-01",
                        _rosetta_kw("rosetta_rpcmag_cla-ob")),
    "rosetta_level_c": (lambda: rosetta_level("C"), "2014-08-01",
                        _rosetta_kw("rosetta_rpcmag_clc-ob")),
    "rosetta_level_g": (lambda: rosetta_level("G"), "2014-08-01",
                        _rosetta_kw("rosetta_rpcmag_clg-ob")),
    "rosetta_hk": (rosetta_hk, "2014-08-01", _rosetta_kw("rosetta_rpcmag_hka")),
    "synthetic": (synthetic, "2024-03-01", {"label_extra": {"Logical_source": "synth_mag_l2"}}),
}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> dict[str, tuple[xr.Dataset, Path]]:
    """Every product type written as CDF (ISTP file name), netCDF and Zarr."""
    out = tmp_path_factory.mktemp("ecosystem")
    fmts = ("cdf", "nc", *(("zarr",) if zarr_available() else ()))
    result = {}
    for kind, (build, day, kw) in PRODUCTS.items():
        ds = build()
        stem = istp_file_stem(kw["label_extra"]["Logical_source"], day, 1)
        write_product(ds, out / kind, fmts, cdf_stem=out / stem, **kw)
        result[kind] = (ds, out / kind)
    return result


def _cdf(stem: Path) -> Path:
    (path,) = [p for p in stem.parent.glob("*.cdf") if p.stem.startswith(
        PRODUCTS[stem.name][2]["label_extra"]["Logical_source"] + "_")]
    return path


def _vectors(ds: xr.Dataset) -> list[str]:
    return [str(n) for n in ds.data_vars if ds[n].ndim == 2]


KINDS = list(PRODUCTS)


@pytest.mark.parametrize("kind", KINDS)
def test_spacepy_istp_checks_pass(kind: str, written) -> None:
    from spacepy import pycdf
    from spacepy.pycdf import istp

    with pycdf.CDF(str(_cdf(written[kind][1]))) as f:
        errors = istp.FileChecks.all(f, catch=False)
    assert [e for e in errors if not SPACEPY_TOLERATED.match(e)] == []
    # the tolerated message is about exactly the vector variables
    assert sorted(e.split(":")[0] for e in errors) == sorted(_vectors(written[kind][0]))


@pytest.mark.parametrize("kind", KINDS)
def test_cdflib_loads_and_its_istp_checks_pass(kind: str, written, tmp_path: Path,
                                               caplog: pytest.LogCaptureFixture) -> None:
    ds, stem = written[kind]
    path = _cdf(stem)
    x = cx.cdf_to_xarray(str(path))
    # DEPEND_1 names the vector dimension (no anonymous dim0) and its labels come along
    for name in _vectors(ds):
        dim = ds[name].dims[1]
        assert x[name].dims == ("Epoch", dim), name
        assert [s.strip() for s in x[f"{dim}_label"].values] == ds[dim].values.tolist()
        np.testing.assert_array_equal(x[name].values, np.where(
            np.isnan(ds[name].values), -1e31, ds[name].values))
    expected_utc = cdflib.cdfepoch.to_datetime(ds["epoch"].values)
    np.testing.assert_array_equal(x["Epoch"].values, expected_utc)
    # cdflib's inverse: to netCDF (integer Epoch: cdflib turns the TT2000-typed FILLVAL and
    # VALIDMIN/MAX into datetime64 attributes with to_datetime=True, which no netCDF holds)
    raw = cx.cdf_to_xarray(str(path), to_datetime=False)
    raw.to_netcdf(tmp_path / "from_cdflib.nc")
    # cdflib's own ISTP checks (xarray_to_cdf istp=True) log every compliance warning
    caplog.set_level(logging.INFO, logger="cdflib")
    caplog.clear()
    cx.xarray_to_cdf(raw, str(tmp_path / "rewritten.cdf"), istp=True)
    assert [r.getMessage() for r in caplog.records if r.name.startswith("cdflib")] == []


@pytest.mark.parametrize("kind", KINDS)
def test_pyspedas_loads_with_frame(kind: str, written) -> None:
    pyspedas = pytest.importorskip("pyspedas")
    ds, stem = written[kind]
    names = pyspedas.cdf_to_tplot(str(_cdf(stem)))
    data_vars = [n for n in ds.data_vars if ds[n].dtype.kind not in "US"
                 and (ds[n].attrs.get("var_type", "data") == "data")
                 and n not in ("year", "doy", "hour", "minute", "second", "met", "obt", "sid")]
    assert set(data_vars) <= set(names)
    unix = (cdflib.cdfepoch.to_datetime(ds["epoch"].values).astype("M8[ns]").astype(np.int64)
            / 1e9)
    for name in data_vars:
        got = pyspedas.get_data(name)
        # pyspedas keeps float64 Unix seconds: resolution ~2.4e-7 s at 1.7e9 s
        np.testing.assert_allclose(got.times, unix, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(got.y, ds[name].values)  # FILLVAL -> NaN by pyspedas
        frame = ds[name].attrs.get("coordinate_system")
        if frame is not None:
            assert pyspedas.get_coords(name) == frame.split(">")[0]


@pytest.mark.parametrize("kind", ["messenger_mso_full", "rosetta_level_c", "synthetic"])
def test_sunpy_reads_the_cdf(kind: str, written) -> None:
    # sunpy's CDF reader lives in sunpy.timeseries, which needs sunpy[timeseries]'s
    # mpl-animators; without it the reader cannot be imported at all
    pytest.importorskip("mpl_animators")
    from sunpy.io._cdf import read_cdf as sunpy_read_cdf

    ds, stem = written[kind]
    (series,) = sunpy_read_cdf(str(_cdf(stem)))
    frame = series.to_dataframe()
    name = _vectors(ds)[0]
    for j in range(3):
        np.testing.assert_array_equal(frame[f"{name}_{j}"].to_numpy(), ds[name].values[:, j])
    assert str(series.units[f"{name}_0"]) == "nT"


def _check_cf_time(opened: xr.Dataset, ds: xr.Dataset) -> None:
    assert opened["time"].dtype == np.dtype("M8[ns]")
    assert opened.indexes["time"].is_monotonic_increasing
    np.testing.assert_array_equal(opened["epoch"].values, ds["epoch"].values)
    assert opened["epoch"].dtype == np.int64
    utc = cdflib.cdfepoch.to_datetime(ds["epoch"].values).astype("M8[ns]")
    np.testing.assert_array_equal(opened["time"].values, utc)
    t0 = utc[0].astype("M8[m]") + np.timedelta64(2, "m")
    sel = opened.sel(time=slice(t0, t0 + np.timedelta64(5, "m")))
    assert sel.sizes["time"] == int(((utc >= t0) & (utc <= t0 + np.timedelta64(5, "m"))).sum())
    name = _vectors(ds)[0]
    mean = opened[name].resample(time="60s").mean()
    minute = utc.astype("M8[m]")
    first = minute == minute[0]
    np.testing.assert_allclose(mean.values[0], np.nanmean(ds[name].values[first], axis=0),
                               rtol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_plain_xarray_open_dataset_has_a_time_index(kind: str, written) -> None:
    ds, stem = written[kind]
    with xr.open_dataset(stem.with_name(stem.name + ".nc")) as opened:
        _check_cf_time(opened.load(), ds)


@pytest.mark.skipif(not zarr_available(), reason="optional zarr not installed")
@pytest.mark.parametrize("kind", ["messenger_mso_full", "rosetta_hk", "synthetic"])
def test_plain_xarray_open_zarr_has_a_time_index(kind: str, written) -> None:
    ds, stem = written[kind]
    with xr.open_zarr(stem.with_name(stem.name + ".zarr")) as opened:
        _check_cf_time(opened.load(), ds)


@pytest.mark.parametrize("kind", KINDS)
def test_fluxcal_readers_return_the_time_index_and_exact_values(kind: str, written) -> None:
    ds, stem = written[kind]
    for path in (_cdf(stem), stem.with_name(stem.name + ".nc")):
        back = read_fluxcal_product(path)
        assert "time" in back.indexes, path
        np.testing.assert_array_equal(back["epoch"].values, ds["epoch"].values)
        for name in ds.data_vars:
            np.testing.assert_array_equal(back[name].values, ds[name].values, err_msg=name)
            assert back[name].dtype == ds[name].dtype, name
        t = back["time"].values[10]
        assert back.sel(time=str(t))["epoch"].item() == ds["epoch"].values[10]


def test_the_cdflib_check_is_not_vacuous(written, tmp_path: Path,
                                         caplog: pytest.LogCaptureFixture) -> None:
    """The log capture above sees cdflib's messages: a missing VALIDMIN is reported."""
    raw = cx.cdf_to_xarray(str(_cdf(written["synthetic"][1])), to_datetime=False)
    del raw["B"].attrs["VALIDMIN"]
    caplog.set_level(logging.INFO, logger="cdflib")
    caplog.clear()
    cx.xarray_to_cdf(raw, str(tmp_path / "broken.cdf"), istp=True)
    assert any("VALIDMIN required for variable B" in r.getMessage() for r in caplog.records)


# --- the products of the real pipelines ----------------------------------------------------


@pytest.fixture(scope="module")
def pipeline_products(tmp_path_factory) -> list[Path]:
    """One simulated MESSENGER day (6 frames, full resolution + 1 s + 60 s averages), one
    simulated Rosetta day (levels A, B, C, E, F, G of both sensors and HK) and one synthetic
    batch day, as CDF + netCDF."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.routes import run_edr2cdr
    from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
    from fluxcal.missions.rosetta.batch_task import simulate_days
    from fluxcal.missions.rosetta.routes import make_day_task
    from fluxcal.runs.batch import run_batch

    root = tmp_path_factory.mktemp("pipelines")
    start = "2012-06-01T00:00:00"
    config = SimulationConfig(start_utc=start, duration_s=600.0)
    kernels = write_messenger_like_kernels(root / "k", start, 2600.0,
                                           plus_y_sunward=[(100.0, 300.0)])
    with KernelPool(kernels):
        sim = simulate(config, load_calibration(start), SclkKernel.from_pool(-236))
    files = write_inputs(sim, root / "msgr_in")
    paths = run_edr2cdr([files["science"]], [files["heater"]], [files["temperature"]],
                        kernels, root / "out", frames=("mso", "j2000", "mbf", "rtn", "sc", "vso"),
                        averages=(1, 60), formats=("cdf", "nc"))
    import datetime as dt

    day = dt.date(2014, 11, 1)
    simulate_days(root / "ros_in", [day], minutes=5.0, truth=False, seed=3)
    task = make_day_task(root / "ros_in", root / "out", formats=("cdf", "nc"),
                         frame="ECLIPJ2000")
    report = run_batch([day], task, root / "out", scheduler="serial")
    assert report.ok, report.days
    paths += [root / "out" / p for d in report.days for p in d.products]
    from fluxcal.runs.synthetic_task import SyntheticDayTask, write_synthetic_inputs

    day = dt.date(2024, 3, 1)
    write_synthetic_inputs(root / "synth_in", [day], n_per_day=2000)
    paths += SyntheticDayTask(root / "synth_in", root / "out", formats=("cdf", "nc"))(day).products
    return sorted(set(paths))


def test_pipeline_cdfs_pass_spacepy_and_cdflib_istp_checks(
        pipeline_products, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    cdfs = [p for p in pipeline_products if p.suffix == ".cdf"]
    kinds = {p.name.split("_")[2] for p in cdfs}
    # MESSENGER: 6 frames x (sci, avg1, avg60); Rosetta: A B C E F G x (OB, IB) + HK; synthetic
    assert len(cdfs) == 18 + 13 + 1, sorted(p.name for p in cdfs)
    assert {"mso-sci", "rtn-avg60", "cla-hk", "clg-ib-a01"} <= kinds
    problems = {path.name: errors for path in cdfs
                if (errors := istp_problems(path, tmp_path, caplog))}
    assert problems == {}


def test_pipeline_netcdf_opens_with_a_time_index(pipeline_products) -> None:
    for path in (p for p in pipeline_products if p.suffix == ".nc"):
        with xr.open_dataset(path) as ds:
            assert ds["time"].dtype == np.dtype("M8[ns]"), path.name
            assert ds.indexes["time"].is_monotonic_increasing, path.name
            assert ds["epoch"].dtype == np.int64
            np.testing.assert_array_equal(
                ds["time"].values, cdflib.cdfepoch.to_datetime(ds["epoch"].values))
            assert ds.resample(time="60s").mean().sizes["time"] >= 1


def test_pipeline_rtn_product_in_pyspedas(pipeline_products) -> None:
    pyspedas = pytest.importorskip("pyspedas")
    (path,) = [p for p in pipeline_products
               if p.name.startswith("messenger_mag_rtn-sci") and p.suffix == ".cdf"]
    names = pyspedas.cdf_to_tplot(str(path))
    back = read_fluxcal_product(path)
    field = "b"
    assert field in names and back[field].ndim == 2
    assert back["b_component"].values.tolist() == ["B_R", "B_T", "B_N"]
    assert pyspedas.get_coords(field) == back[field].attrs["coordinate_system"].split(">")[0]
    np.testing.assert_array_equal(pyspedas.get_data(field).y, back[field].values)
