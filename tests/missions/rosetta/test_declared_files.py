"""Rosetta's stitching states are declared run state (`fluxcal.products.declared.File`).

The state a run hands the next one is written with the run's products, all or nothing
(docs/decisions/products.md, "declared-rosetta"); it is not a product (no provenance,
not among the files a run returns).  Expected values: the JSON text of the state given,
and the files present before the run.
"""

import json

import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import FluxcalError
from fluxcal.missions.rosetta.day_edges import read_stitch_state, stitch_state_text
from fluxcal.products.declared import File, Product, write_declared

STATE = {"stitch_epoch": 460123626934000808, "stitch_offset_nt": [1.5, -0.25, 0.125],
         "stitch_correction_nt": [0.0, 0.0, 0.0]}


def _product(name="P_20140801", fail=False):
    epoch = np.int64(460_123_000_000_000_000) + np.arange(4, dtype=np.int64) * 10**9
    ds = xr.Dataset({"b": (("time", "component"), np.ones((4, 3)), {"units": "nT"})},
                    coords={"epoch": ("time", epoch, {"units": "ns"})})

    def make():
        if fail:
            raise FluxcalError("rejected")
        return ds

    return Product(name, make, formats=("nc",), day=np.datetime64("2014-08-01").item())


def test_state_text_round_trips_and_is_none_without_state(tmp_path):
    text = stitch_state_text(STATE)
    assert json.loads(text) == STATE
    (tmp_path / "s.json").write_text(text)
    assert read_stitch_state(tmp_path / "s.json").to_attrs() == STATE
    assert stitch_state_text(None) is None and stitch_state_text({}) is None


def test_state_is_written_with_the_products_and_not_listed(tmp_path):
    out = tmp_path / "out"
    paths = write_declared([_product(), File("state.json", stitch_state_text(STATE),
                                             listed=False)], out, lambda p: {})
    assert [p.name for p in paths] == ["P_20140801.nc"]
    assert json.loads((out / "state.json").read_text()) == STATE


def test_a_broken_chain_removes_the_stale_state_once_the_products_are_in(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "state.json").write_text("old")
    write_declared([File("state.json", stitch_state_text(None), listed=False), _product()],
                   out, lambda p: {})
    assert not (out / "state.json").exists() and (out / "P_20140801.nc").is_file()


@pytest.mark.parametrize("content", [stitch_state_text(STATE), None], ids=["new", "remove"])
def test_a_failed_product_leaves_the_older_state_as_it_was(tmp_path, content):
    out = tmp_path / "out"
    out.mkdir()
    (out / "state.json").write_text("old")
    with pytest.raises(FluxcalError, match="rejected"):
        write_declared([File("state.json", content, listed=False),
                        _product("Q_20140801", fail=True)], out, lambda p: {})
    assert (out / "state.json").read_text() == "old"
    assert sorted(p.name for p in out.iterdir()) == ["state.json"]


def test_an_absolute_path_and_a_drawn_file(tmp_path):
    out = tmp_path / "out"
    elsewhere = tmp_path / "elsewhere.json"
    paths = write_declared([File(elsewhere, "{}", listed=False),
                            File("pic.png", lambda path: path.write_bytes(b"\x89PNG"))],
                           out, lambda p: {})
    assert paths == [out / "pic.png"] and (out / "pic.png").read_bytes() == b"\x89PNG"
    assert elsewhere.read_text() == "{}"


def test_a_single_run_returns_its_products_not_its_state(tmp_path):
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import run_files
    from fluxcal.missions.rosetta.simulate import write_simulation

    sim = write_simulation(tmp_path / "sim", hours=0.02)
    state = tmp_path / "p" / "state.json"
    paths = run_files(sim["science_OB"], "OB", tmp_path / "p", state_file=state,
                      options=RosettaOptions(calib=sim["calib"], formats=("tab",)))
    assert state.is_file() and state not in paths
    assert read_stitch_state(state) is not None
    assert {p.suffix for p in paths} == {".TAB", ".LBL"}


def test_a_batch_day_refuses_a_product_of_another_day(tmp_path):
    """The safeguard of a batch day (its LEVEL_A is trimmed to the day): a level reaching
    into the next day is refused, naming the table it would write, and nothing is written."""
    import datetime as dt

    from fluxcal.errors import InputFormatError
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import (
        RosettaLevels,
        RosettaRun,
        SensorLevels,
        calibrate_levels,
    )
    from fluxcal.missions.rosetta.simulate import write_simulation

    sim = write_simulation(tmp_path / "sim", start_utc="2014-08-01T23:58:00", hours=0.05)
    levels = calibrate_levels(sim["science_OB"], "OB", options=RosettaOptions(calib=sim["calib"]))
    run = RosettaLevels([SensorLevels("OB", sim["science_OB"], levels, [], {})], ("A",),
                        day=dt.date(2014, 8, 1))
    out = tmp_path / "out"
    with KernelPool([]), pytest.raises(InputFormatError,
                                       match=r"outside the day 2014-08-01 .*RPCMAG140802T"):
        write_declared(RosettaRun().products(run, RosettaOptions(formats=("tab",))), out,
                       lambda p: {})
    assert not any(out.iterdir())
