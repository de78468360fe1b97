"""The CDF writer's attribute entries per variable, and its fill values.

Expected values: attributes and values read back with cdflib's reader; the ISTP fill
value -1e31 in the variable's own type.
"""

from __future__ import annotations

from pathlib import Path

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import cdf


def test_attribute_entries_in_variable_order_read_back(tmp_path: Path) -> None:
    ds = _one(np.arange(4.0)).assign(
        y=("time", np.arange(4.0), {"units": "s", "description": "y", "valid_min": 0.0,
                                    "valid_max": 9.0, "custom": "only y"}))
    path = cdf.write_cdf(ds, tmp_path / "x.cdf")
    got = cdflib.CDF(str(path))
    assert got.varattsget("x")["UNITS"] == "nT" and got.varattsget("y")["UNITS"] == "s"
    assert got.varattsget("y")["custom"] == "only y" and "custom" not in got.varattsget("x")


def _one(values: np.ndarray) -> xr.Dataset:
    n = values.shape[0]
    return xr.Dataset(
        {"x": ("time", values, {"units": "nT", "description": "test",
                                "valid_min": -1e3, "valid_max": 1e3})},
        coords={"epoch": ("time", 757_339_269_184_000_000
                          + np.arange(n, dtype=np.int64) * 50_000_000)},
    )


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_fill_value_of_the_variables_type_is_refused(tmp_path: Path, dtype) -> None:
    # float32(-1e31) is -9.9999998e30: above -1e31 as a float64, still the fill value
    values = np.array([1.0, dtype(-1e31), 2.0], dtype=dtype)
    with pytest.raises(InputFormatError, match="fill value"):
        cdf.write_cdf(_one(values), tmp_path / "x.cdf")


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_nan_becomes_fill_and_values_below_fill_pass(tmp_path: Path, dtype) -> None:
    values = np.array([1.5, np.nan, -np.inf, -1e32, 2.5, np.nan], dtype=dtype)
    path = cdf.write_cdf(_one(values), tmp_path / "x.cdf")
    raw = cdflib.CDF(str(path)).varget("x")
    fill = dtype(-1e31)
    expected = np.array([1.5, fill, -np.inf, dtype(-1e32), 2.5, fill], dtype=dtype)
    assert raw.dtype == dtype
    np.testing.assert_array_equal(raw, expected)


def test_values_above_fill_are_written_unchanged(tmp_path: Path) -> None:
    values = np.linspace(-1e30, 1e30, 11)
    path = cdf.write_cdf(_one(values), tmp_path / "x.cdf")
    np.testing.assert_array_equal(cdflib.CDF(str(path)).varget("x"), values)
