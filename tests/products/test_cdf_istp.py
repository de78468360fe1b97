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
