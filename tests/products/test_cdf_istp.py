from __future__ import annotations

from pathlib import Path

import cdflib
import numpy as np
import xarray as xr

from fluxcal.products import write_product

# ISTP Guidelines: mandatory global attributes and data-variable attributes.
GLOBAL_REQUIRED = ["Project", "Source_name", "Discipline", "Data_type", "Descriptor",
                   "Data_version", "Logical_file_id", "PI_name", "PI_affiliation", "TEXT",
                   "Instrument_type", "Mission_group", "Logical_source",
                   "Logical_source_description"]
DATA_REQUIRED = ["FIELDNAM", "CATDESC", "VAR_TYPE", "DEPEND_0", "FILLVAL", "VALIDMIN",
                 "VALIDMAX", "UNITS", "FORMAT", "DISPLAY_TYPE"]


def test_istp_attributes(dataset: xr.Dataset, tmp_path: Path) -> None:
    (path,) = write_product(dataset, tmp_path / "P", formats=("cdf",))
    cdf = cdflib.CDF(str(path))
    g = cdf.globalattsget()
    for key in GLOBAL_REQUIRED:
        assert key in g, key
    assert g["Logical_file_id"] == "P" or g["Logical_file_id"] == ["P"]
    assert cdf.varinq("Epoch").Data_Type_Description == "CDF_TIME_TT2000"
    ea = cdf.varattsget("Epoch")
    assert ea["VAR_TYPE"] == "support_data"
    for name in ("B_mso", "position", "quality", "temperature"):
        a = cdf.varattsget(name)
        for key in DATA_REQUIRED:
            assert key in a, (name, key)
        assert a["DEPEND_0"] == "Epoch"
    assert cdf.varattsget("B_mso")["LABL_PTR_1"] == "component"
    assert cdf.varattsget("B_mso")["UNITS"] == "nT"
    assert cdf.varattsget("B_mso")["LABLAXIS"] == "B MSO"  # from istp_variables.yaml
    assert cdf.varinq("component").Data_Type_Description == "CDF_CHAR"
    assert cdf.varattsget("component")["VAR_TYPE"] == "metadata"
    # Epoch decodes to the expected UTC (cdflib's own TT2000 -> UTC conversion)
    first = cdflib.cdfepoch.encode_tt2000(int(cdf.varget("Epoch")[0]))
    assert first.startswith("2024-01-01T00:00:00")
    # FILLVAL has the variable's own type
    assert np.asarray(cdf.varattsget("quality")["FILLVAL"]).item() == -(2**31)


def test_mission_yaml_overrides(dataset: xr.Dataset, tmp_path: Path) -> None:
    vy = tmp_path / "vars.yaml"
    vy.write_text("defaults:\n  VAR_TYPE: data\nB_mso:\n  LABLAXIS: 'B (MSO)'\n")
    gy = tmp_path / "glob.yaml"
    gy.write_text("Project: 'NASA>Discovery>MESSENGER'\nMission_group: MESSENGER\n")
    (path,) = write_product(dataset, tmp_path / "P", formats=("cdf",), variable_yaml=vy,
                            global_yaml=gy, label_extra={"PI_name": "S. C. Solomon"})
    cdf = cdflib.CDF(str(path))
    assert cdf.varattsget("B_mso")["LABLAXIS"] == "B (MSO)"
    g = cdf.globalattsget()
    flat = {k: (v[0] if isinstance(v, list) and len(v) == 1 else v) for k, v in g.items()}
    assert flat["Project"] == "NASA>Discovery>MESSENGER"
    assert flat["PI_name"] == "S. C. Solomon"


def test_reads_a_foreign_istp_cdf(tmp_path: Path) -> None:
    """A CDF written by plain cdflib (no fluxcal attributes) is readable and plottable."""
    from cdflib.cdfwrite import CDF

    from fluxcal.products import read_product
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
    ds = read_product(tmp_path / "foreign.cdf")
    np.testing.assert_array_equal(ds["epoch"].values, epoch)
    np.testing.assert_array_equal(ds["B_GSE"].values, b)
    assert ds["B_GSE"].dims == ("time", "label_B")
    fig = quicklook_figure(ds)
    assert fig.axes[0].get_ylabel() == "B GSE (nT)"
