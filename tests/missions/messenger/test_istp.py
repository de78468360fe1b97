"""ISTP attributes of the MESSENGER MAG CDF products (issue 6, mission YAML data files)."""

import cdflib
import pytest
import yaml

from fluxcal.cli import main
from fluxcal.missions.messenger.calibration_data import data_dir
from fluxcal.missions.messenger.products import istp_product_attrs


@pytest.fixture(scope="module")
def cdf_products(tmp_path_factory, simulated_files, messenger_kernels):
    out = tmp_path_factory.mktemp("istp")
    code = main(["messenger", "edr2cdr", "--sci", str(simulated_files["science"]),
                 "--heater", str(simulated_files["heater"]), "--temperature",
                 str(simulated_files["temperature"]), "--kernels", str(messenger_kernels),
                 "--out", str(out), "--frames", "mso,rtn", "--average", "60",
                 "--formats", "cdf"])
    assert code == 0
    return out


def _globals(path):
    return {k: v[0] if len(v) == 1 else v for k, v in cdflib.CDF(path).globalattsget().items()}


# values prescribed by the task (issue 6) for every MESSENGER product
EXPECTED = {
    "Project": "NASA>MESSENGER",
    "Source_name": "MESSENGER>MErcury Surface, Space ENvironment, GEochemistry, and Ranging",
    "Discipline": "Space Physics>Magnetospheric Science",
    "Descriptor": "MAG>Magnetometer",
    "Mission_group": "MESSENGER",
    "PI_name": "B. J. Anderson",
    "Instrument_type": "Magnetic Fields (space)",
}


@pytest.mark.parametrize("logical_source", [
    "messenger_mag_mso-sci", "messenger_mag_rtn-sci", "messenger_mag_mso-avg60",
])
def test_cdf_global_attributes(cdf_products, logical_source):
    # ISTP file names: <Logical_source>_<yyyymmdd>_v<nn> (version 1 by default)
    name = f"{logical_source}_20120601_v01"
    g = _globals(cdf_products / f"{name}.cdf")
    for key, value in EXPECTED.items():
        assert g[key] == value, key
    assert g["Logical_source"] == logical_source
    assert g["Logical_file_id"] == name
    # ISTP: Logical_source = source_descriptor_datatype (short forms, lower case)
    short = [g[k].split(">")[0] for k in ("Source_name", "Descriptor", "Data_type")]
    assert g["Logical_source"] == "_".join(short).lower()
    assert g["Data_type"].startswith(logical_source.split("_")[-1].upper() + ">")
    assert g["Logical_source_description"].startswith("MESSENGER MAG")
    # every mandatory ISTP global attribute is present and non-empty
    for key in ("Project", "Source_name", "Discipline", "Data_type", "Descriptor",
                "Data_version", "Logical_file_id", "Logical_source",
                "Logical_source_description", "PI_name", "PI_affiliation", "TEXT",
                "Mission_group", "Instrument_type", "Generation_date"):
        assert str(g[key]).strip(), key
    # science, heater, temperature inputs: CSV files by name (ISTP "CDF>" is for CDFs)
    parents = g["Parents"] if isinstance(g["Parents"], list) else [g["Parents"]]
    assert len(parents) == 3 and not any(p.startswith("CDF>") or "/" in p for p in parents)


def test_every_yaml_global_is_written(cdf_products):
    """All keys of the mission YAML reach the CDF (per-product ones overridden)."""
    table = yaml.safe_load((data_dir() / "istp_global.yaml").read_text())
    g = _globals(cdf_products / "messenger_mag_mso-sci_20120601_v01.cdf")
    per_product = set(istp_product_attrs("mso"))
    for key, value in table.items():
        if key not in per_product:
            assert g[key] == value, key


def test_variable_attributes(cdf_products):
    cdf = cdflib.CDF(cdf_products / "messenger_mag_mso-sci_20120601_v01.cdf")
    b = cdf.varattsget("b")
    assert b["VAR_TYPE"] == "data" and b["DEPEND_0"] == "Epoch"
    assert b["DEPEND_0"] == "Epoch" and b["LABL_PTR_1"].startswith("b_component")
    assert cdf.varget(b["LABL_PTR_1"]).tolist() == ["B_X", "B_Y", "B_Z"]
    assert b["UNITS"] == "nT" and b["DISPLAY_TYPE"] == "time_series"
    assert b["COORDINATE_SYSTEM"] == "MSO"
    assert cdf.varattsget("quality")["VAR_TYPE"] == "data"  # a data variable (issue 10)
    assert cdf.varattsget("position")["UNITS"] == "km"
    assert cdf.varattsget("b_total")["UNITS"] == "nT"
    assert "year" not in cdf.cdf_info().zVariables  # UTC columns are TAB only
    epoch = cdf.varattsget("Epoch")
    assert epoch["TIME_SCALE"] == "Terrestrial Time" and "latency" in epoch["CATDESC"]
    assert cdf.varinq("Epoch").Data_Type_Description == "CDF_TIME_TT2000"
    rtn = cdflib.CDF(cdf_products / "messenger_mag_rtn-sci_20120601_v01.cdf")
    assert rtn.varget(rtn.varattsget("b")["LABL_PTR_1"]).tolist() == ["B_R", "B_T", "B_N"]
    assert [rtn.varattsget(v)["UNITS"] for v in ("r", "latitude", "azimuth")] == \
        ["km", "deg", "deg"]
    avg = cdflib.CDF(cdf_products / "messenger_mag_mso-avg60_20120601_v01.cdf")
    assert avg.varattsget("b_std")["UNITS"] == "nT"
    assert avg.varattsget("count")["LABLAXIS"] == "NAVG"


def test_istp_files_are_batch_inputs(tmp_path):
    """A changed ISTP file must make `fluxcal batch` redo a day (recorded as an input)."""
    import datetime as dt

    from fluxcal.missions.messenger.batch_task import make_day_task

    cal = make_day_task(tmp_path, tmp_path / "out").inputs(dt.date(2012, 6, 1)).calibration
    assert {"istp_global.yaml", "istp_variables.yaml", "istp_products.yaml"} <= set(cal)
