"""`fluxcal.calibrate` returns what `fluxcal.read_product` reads back (issue 32, item 3).

The contract (docs/decisions/products.md, decision 72): for every product kind the
in-memory result of ``fluxcal.calibrate(mission, ...)`` has the variable names, the
dimension names, the component labels and the values of the full-resolution product
the same inputs give through the command line.  Expected values are the products' own
contents, read back by the one public reader; tolerances: none for CDF and netCDF
(float64 and int64 stored as they are), the printed precision for the TAB (``F11.3``
nT: 0.0005 nT; UTC with the milliseconds truncated: < 1 ms, never later).
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import fluxcal
from fluxcal.cli import main
from fluxcal.errors import FluxcalError, InputFormatError

FRAMES = ("mso", "rtn")


def _same(made: xr.Dataset, back: xr.Dataset, ignore: set[str] = frozenset()) -> None:
    """Assert equal names, dims, component labels and values (exactly)."""
    assert set(back.data_vars) - ignore == set(made.data_vars)
    for name in made.data_vars:
        assert back[name].dims == made[name].dims, name
        np.testing.assert_array_equal(back[name].values, made[name].values, err_msg=name)
    for dim in made.dims:
        if dim in made.coords:
            assert list(back[dim].values) == list(made[dim].values), dim
    np.testing.assert_array_equal(back["epoch"].values, made["epoch"].values)
    np.testing.assert_array_equal(back["time"].values, made["time"].values)


@pytest.fixture(scope="module")
def messenger(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("api_contract_msgr")
    assert main(["-q", "simulate", "messenger", "--out", str(out), "--duration", "300"]) == 0
    inputs = {s: [out / "inputs" / f"MAG_{s}.csv"] for s in ("science", "heater", "temperature")}
    kernels = out / "kernels" / "messenger_synthetic.tm"
    made = fluxcal.calibrate("messenger", inputs, kernels=kernels, frames=FRAMES)
    products = out / "products"
    assert main(["-q", "messenger", "edr2cdr", "--sci", str(inputs["science"][0]),
                 "--heater", str(inputs["heater"][0]), "--temperature",
                 str(inputs["temperature"][0]), "--kernels", str(kernels), "--out",
                 str(products), "--frames", ",".join(FRAMES), "--formats", "tab,cdf,nc",
                 "--average", ""]) == 0
    return {"made": made, "products": products, "inputs": inputs, "kernels": kernels}


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("suffix", [".cdf", ".nc"])
def test_messenger_calibrate_round_trips_through_the_products(messenger, frame, suffix):
    made = messenger["made"][frame]
    assert made["b"].dims == ("time", "b_component")
    assert list(made["b_component"].values) == (["B_R", "B_T", "B_N"] if frame == "rtn"
                                                 else ["B_X", "B_Y", "B_Z"])
    back = fluxcal.read_product(
        messenger["products"] / f"messenger_mag_{frame}-sci_20120601_v01{suffix}")
    _same(made, back)


@pytest.mark.parametrize("frame", FRAMES)
def test_messenger_calibrate_matches_the_table_to_its_printed_precision(messenger, frame):
    made = messenger["made"][frame]
    back = fluxcal.read_product(messenger["products"] / f"MAG{frame.upper()}SCI12153_V01.TAB")
    assert set(back.data_vars) <= set(made.data_vars)  # the archive's columns: a subset
    assert list(back["b_component"].values) == list(made["b_component"].values)
    np.testing.assert_allclose(back["b"].values, made["b"].values, rtol=0, atol=0.0005 + 1e-9)
    lag = made["epoch"].values - back["epoch"].values
    assert lag.min() >= 0 and lag.max() < 1_000_000  # ns: the TAB's ms truncated


def test_the_internal_table_reader_gives_the_time_index_too(messenger):
    from fluxcal.products import read_fluxcal_product

    tab = messenger["products"] / "MAGMSOSCI12153_V01.TAB"
    raw = read_fluxcal_product(tab)  # fluxcal's column names, epoch from the UTC fields
    assert raw.indexes["time"].dtype.kind == "M"
    np.testing.assert_array_equal(raw["epoch"].values, fluxcal.read_product(tab)["epoch"].values)


def test_the_wrapper_is_calibrate(messenger):
    inputs = messenger["inputs"]
    got = fluxcal.calibrate_messenger(inputs["science"], inputs["heater"],
                                      inputs["temperature"], messenger["kernels"],
                                      frames=("mso",))
    assert list(got) == ["mso"]
    xr.testing.assert_identical(got["mso"], messenger["made"]["mso"])


def test_messenger_inputs_name_their_streams(messenger):
    with pytest.raises(InputFormatError, match="missing: heater"):
        fluxcal.calibrate("messenger", {"science": [], "temperature": []},
                          kernels=messenger["kernels"])


def test_an_unknown_mission_is_one_error():
    with pytest.raises(FluxcalError, match="no mission 'nosuch'"):
        fluxcal.calibrate("nosuch", [])


@pytest.fixture(scope="module")
def rosetta(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("api_contract_ros")
    assert main(["-q", "simulate", "rosetta", "--out", str(out), "--hours", "0.05"]) == 0
    raw, calib = out / "RPCMAG_20140801_RAW_OB.csv", out / "calib"
    made = fluxcal.calibrate("rosetta", raw, sensor="OB", levels=("A", "B"), calib=calib)
    products = out / "products"
    assert main(["-q", "rosetta", "calibrate", "--science", str(raw), "--sensor", "OB",
                 "--calib", str(calib), "--levels", "A,B", "--formats", "tab,cdf,nc",
                 "--out", str(products)]) == 0
    return {"made": made, "products": products}


@pytest.mark.parametrize("level", ["A", "B"])
@pytest.mark.parametrize("suffix", [".cdf", ".nc"])
def test_rosetta_calibrate_round_trips_through_the_products(rosetta, level, suffix):
    made = rosetta["made"][level]
    assert made["b"].dims == ("time", "component")
    back = fluxcal.read_product(
        rosetta["products"] / f"rosetta_rpcmag_cl{level.lower()}-ob_20140801_v01{suffix}")
    _same(made, back, ignore={"time_utc"})  # the UTC text of epoch, for the tables
    assert "mode_segment" not in made.coords


def test_rosetta_table_names_are_the_calibrated_names(rosetta):
    made = rosetta["made"]["A"]
    tables = sorted(rosetta["products"].glob("RPCMAG*_CLA_OB_M*.TAB"))
    back = xr.concat([fluxcal.read_product(t) for t in tables], dim="time")
    # b_total: the archive's magnitude column, which the archive reader keeps
    assert set(back.data_vars) - {"b_total"} <= set(made.data_vars)
    assert list(back["component"].values) == list(made["component"].values)
    assert back.sizes["time"] == made.sizes["time"]
