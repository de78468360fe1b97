"""ISTP attributes of the CDF writer, read with cdflib (an independent reader)."""

from __future__ import annotations

from pathlib import Path

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import read_fluxcal_product, write_product
from fluxcal.products.cdf import istp_file_stem, istp_logical_source

from .conftest import EPOCH0

# ISTP Guidelines: mandatory global attributes and data-variable attributes.
GLOBAL_REQUIRED = ["Project", "Source_name", "Discipline", "Data_type", "Descriptor",
                   "Data_version", "Logical_file_id", "PI_name", "PI_affiliation", "TEXT",
                   "Instrument_type", "Mission_group", "Logical_source",
                   "Logical_source_description"]
DATA_REQUIRED = ["FIELDNAM", "CATDESC", "VAR_TYPE", "DEPEND_0", "FILLVAL", "VALIDMIN",
                 "VALIDMAX", "UNITS", "FORMAT", "DISPLAY_TYPE"]


def _flat(g: dict) -> dict:
    return {k: (v[0] if isinstance(v, list) and len(v) == 1 else v) for k, v in g.items()}


def _write(ds: xr.Dataset, tmp_path: Path, **kw) -> Path:
    (path,) = write_product(ds, tmp_path / "P", formats=("cdf",), **kw)
    return path


def test_istp_attributes(dataset: xr.Dataset, tmp_path: Path) -> None:
    cdf = cdflib.CDF(str(_write(dataset, tmp_path)))
    g = _flat(cdf.globalattsget())
    for key in GLOBAL_REQUIRED:
        assert key in g, key
    # Logical_source by the ISTP rule source_descriptor_datatype (short forms, lower case)
    assert g["Logical_source"] == "fluxcal_mag_l2"
    # 2024-01-01 is the UTC day of the samples; Data_version "1" -> v01
    assert g["Logical_file_id"] == "fluxcal_mag_l2_20240101_v01"
    assert g["Software_version"] == "0.1.0"
    assert "software_version" not in g  # one attribute per meaning
    assert cdf.varinq("Epoch").Data_Type_Description == "CDF_TIME_TT2000"
    ea = cdf.varattsget("Epoch")
    assert ea["VAR_TYPE"] == "support_data"
    assert ea["MONOTON"] == "INCREASE"
    for name in ("B_mso", "position", "quality", "temperature"):
        a = cdf.varattsget(name)
        for key in DATA_REQUIRED:
            assert key in a, (name, key)
        assert a["DEPEND_0"] == "Epoch"
        assert a["VAR_TYPE"] == "data"  # the quality flag is data too
        assert a["FIELDNAM"] == name
        assert not {"units", "description", "long_name"} & set(a), name
    b = cdf.varattsget("B_mso")
    assert b["DEPEND_1"] == "component" and b["LABL_PTR_1"] == "component_label"
    assert "LABLAXIS" not in b  # vectors are labelled through LABL_PTR_1
    assert b["UNITS"] == "nT"
    # physical range from valid_range_by_units (nT), never the old +-1e30 placeholders
    assert (float(b["VALIDMIN"]), float(b["VALIDMAX"])) == (-1e5, 1e5)
    assert cdf.varattsget("temperature")["LABLAXIS"] == "temperature"
    assert cdf.varattsget("quality")["LABLAXIS"] == "Quality"  # from istp_variables.yaml
    lab = cdf.varattsget("component_label")
    assert lab["VAR_TYPE"] == "metadata" and lab["FORMAT"] == "A1" and lab["FILLVAL"] == " "
    assert [s.strip() for s in cdf.varget("component_label")] == ["x", "y", "z"]
    assert cdf.varattsget("component")["VAR_TYPE"] == "support_data"
    first = cdflib.cdfepoch.encode_tt2000(int(cdf.varget("Epoch")[0]))
    assert first.startswith("2024-01-01T00:00:00")
    # FILLVAL has the variable's own type, the ISTP value
    assert np.asarray(cdf.varattsget("quality")["FILLVAL"]).item() == -(2**31)
    assert np.asarray(b["FILLVAL"]).item() == -1e31


def test_nan_is_fillval_in_the_file_and_nan_again(dataset: xr.Dataset, tmp_path: Path) -> None:
    ds = dataset.copy(deep=True)
    ds["B_mso"].values[4, 2] = np.nan
    path = _write(ds, tmp_path)
    raw = cdflib.CDF(str(path)).varget("B_mso")
    assert raw[4, 2] == -1e31 and not np.isnan(raw).any()
    back = read_fluxcal_product(path)
    assert np.isnan(back["B_mso"].values[4, 2])
    np.testing.assert_array_equal(back["B_mso"].values, ds["B_mso"].values)


def test_a_value_equal_to_fillval_is_an_error(dataset: xr.Dataset, tmp_path: Path) -> None:
    ds = dataset.copy(deep=True)
    ds["B_mso"].values[1, 0] = -1e31
    with pytest.raises(InputFormatError, match="B_mso"):
        _write(ds, tmp_path)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("steps, monoton", [([1, 1, 1], True), ([1, -1, 2], False),
                                            ([1, 0, 1], False)])
def test_monoton_only_when_strictly_increasing(dataset: xr.Dataset, tmp_path: Path,
                                               steps: list[int], monoton: bool) -> None:
    ds = dataset.isel(time=slice(0, 4))
    epoch = EPOCH0 + np.cumsum([0, *steps]).astype(np.int64) * 10**9
    ds = ds.assign_coords(epoch=("time", epoch))
    ea = cdflib.CDF(str(_write(ds, tmp_path))).varattsget("Epoch")
    assert ("MONOTON" in ea) is monoton
    if monoton:
        assert ea["MONOTON"] == "INCREASE"


def test_attrs_map_to_istp_and_back(dataset: xr.Dataset, tmp_path: Path) -> None:
    ds = dataset.copy()
    ds["B_mso"].attrs.update(coordinate_system="MSO>Mercury Solar Orbital",
                             valid_min=-2000.0, valid_max=2000.0)
    ds["temperature"].attrs.update(long_name="T sensor", var_type="support_data")
    path = _write(ds, tmp_path)
    cdf = cdflib.CDF(str(path))
    b = cdf.varattsget("B_mso")
    assert b["COORDINATE_SYSTEM"] == "MSO>Mercury Solar Orbital"
    assert (float(b["VALIDMIN"]), float(b["VALIDMAX"])) == (-2000.0, 2000.0)
    assert np.asarray(b["VALIDMIN"]).dtype == np.float64  # the variable's type
    t = cdf.varattsget("temperature")
    assert t["LABLAXIS"] == "T sensor" and t["VAR_TYPE"] == "support_data"
    assert "DISPLAY_TYPE" not in t
    assert np.asarray(t["VALIDMIN"]).dtype == np.float32
    back = read_fluxcal_product(path)
    assert back["B_mso"].attrs["coordinate_system"] == "MSO>Mercury Solar Orbital"
    assert back["B_mso"].attrs["valid_min"] == -2000.0
    assert back["temperature"].attrs["long_name"] == "T sensor"
    assert back["temperature"].attrs["var_type"] == "support_data"
    assert "UNITS" not in back["B_mso"].attrs and back["B_mso"].attrs["units"] == "nT"


def test_component_labels_come_from_the_coordinate(dataset: xr.Dataset,
                                                   tmp_path: Path) -> None:
    ds = dataset[["B_mso"]].rename({"B_mso": "b", "component": "b_component"})
    ds = ds.assign_coords(b_component=["B_R", "B_T", "B_N"])
    cdf = cdflib.CDF(str(_write(ds, tmp_path)))
    assert [s.strip() for s in cdf.varget("b_component_label")] == ["B_R", "B_T", "B_N"]
    assert cdf.varattsget("b")["LABL_PTR_1"] == "b_component_label"
    back = read_fluxcal_product(tmp_path / "P.cdf")
    assert back["b"].dims == ("time", "b_component")
    assert back["b_component"].values.tolist() == ["B_R", "B_T", "B_N"]
    assert "b_component_label" not in back.variables


def test_float_without_physical_range_is_an_error(dataset: xr.Dataset,
                                                  tmp_path: Path) -> None:
    ds = dataset.copy()
    ds["temperature"].attrs["units"] = "furlong"
    with pytest.raises(InputFormatError, match="temperature.*valid range"):
        _write(ds, tmp_path)


def test_istp_file_stem() -> None:
    assert istp_file_stem("messenger_mag_mso-sci", "2011-04-10", 1) == \
        "messenger_mag_mso-sci_20110410_v01"
    assert istp_file_stem("a_b_c", np.datetime64("2014-08-01T12:00"), "v12") == \
        "a_b_c_20140801_v12"
    assert istp_file_stem("a_b_c", "20140801", "03") == "a_b_c_20140801_v03"
    assert istp_file_stem("imap_mag_l1b_norm-mago", "20250206", "001") == \
        "imap_mag_l1b_norm-mago_20250206_v001"
    with pytest.raises(InputFormatError, match="version"):
        istp_file_stem("a_b_c", "20140801", "beta")
    assert istp_logical_source("ROSETTA>x", "RPCMAG>y", "CLC-OB>z") == "rosetta_rpcmag_clc-ob"


def test_mission_yaml_overrides(dataset: xr.Dataset, tmp_path: Path) -> None:
    vy = tmp_path / "vars.yaml"
    vy.write_text("defaults:\n  VAR_TYPE: data\ntemperature:\n  LABLAXIS: 'T (sensor)'\n"
                  "  VALIDMIN: -50\n  VALIDMAX: 150\n")
    gy = tmp_path / "glob.yaml"
    gy.write_text("Project: 'NASA>Discovery>MESSENGER'\nMission_group: MESSENGER\n"
                  "Source_name: 'MESSENGER>x'\nDescriptor: 'MAG>y'\nData_type: 'MSO-SCI>z'\n")
    path = _write(dataset, tmp_path / "out", variable_yaml=vy, global_yaml=gy,
                  label_extra={"PI_name": "S. C. Solomon"})
    cdf = cdflib.CDF(str(path))
    t = cdf.varattsget("temperature")
    assert t["LABLAXIS"] == "T (sensor)"
    assert (float(t["VALIDMIN"]), float(t["VALIDMAX"])) == (-50.0, 150.0)
    # a mission table without valid_range_by_units still gets the generic ranges
    assert float(cdf.varattsget("B_mso")["VALIDMAX"]) == 1e5
    flat = _flat(cdf.globalattsget())
    assert flat["Project"] == "NASA>Discovery>MESSENGER"
    assert flat["PI_name"] == "S. C. Solomon"
    assert flat["Logical_file_id"] == "messenger_mag_mso-sci_20240101_v01"


def test_reads_a_foreign_istp_cdf(tmp_path: Path) -> None:
    """A CDF written by plain cdflib (no fluxcal attributes) is readable and plottable."""
    from cdflib.cdfwrite import CDF

    from fluxcal.products.quicklook import quicklook_figure

    epoch = np.arange(100, dtype=np.int64) * 10**9 + 757_339_269_184_000_000
    b = np.column_stack([np.arange(100.0), np.ones(100), -np.ones(100)])
    cdf = CDF(tmp_path / "foreign.cdf")
    cdf.write_var({"Variable": "Epoch", "Data_Type": 33, "Num_Elements": 1, "Rec_Vary": True,
                   "Dim_Sizes": []}, {"VAR_TYPE": "support_data"}, epoch)
    cdf.write_var({"Variable": "B_GSE", "Data_Type": 45, "Num_Elements": 1, "Rec_Vary": True,
                   "Dim_Sizes": [3]},
                  {"DEPEND_0": "Epoch", "LABL_PTR_1": "label_B", "UNITS": "nT",
                   "VAR_TYPE": "data"}, b)
    cdf.write_var({"Variable": "label_B", "Data_Type": 51, "Num_Elements": 4, "Rec_Vary": False,
                   "Dim_Sizes": [3]}, {"VAR_TYPE": "metadata"}, ["Bx  ", "By  ", "Bz  "])
    cdf.close()
    ds = read_fluxcal_product(tmp_path / "foreign.cdf")
    np.testing.assert_array_equal(ds["epoch"].values, epoch)
    np.testing.assert_array_equal(ds["B_GSE"].values, b)
    assert ds["B_GSE"].dims == ("time", "label_B")
    fig = quicklook_figure(ds)
    assert fig.axes[0].get_ylabel() == "B GSE (nT)"
