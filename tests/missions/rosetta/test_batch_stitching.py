"""Midnight stitching (sec. 4.2.3.3) in ``fluxcal batch rosetta``: days processed one by one,
in any order, give what one run over the whole campaign gives (decision 27).

Raw files are hand-made (constant counts, stepped thermistor words), so no forward model
is involved; the reference is a single `calibrate_levels` run over the concatenated days,
whose in-run stitching is checked against the closed form in test_level_a_formulas.py.
"""

import datetime as dt

import numpy as np
import pytest

from fluxcal.missions.rosetta import calib
from fluxcal.missions.rosetta.batch_task import science_file, stitch_file
from fluxcal.missions.rosetta.calib import DailyOffsetModel
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.routes import calibrate_levels, make_day_task

from ._raw import HEADER, write_raw_csv

D1, D2, D3 = dt.date(2014, 11, 1), dt.date(2014, 11, 2), dt.date(2014, 11, 3)


@pytest.fixture
def campaign(tmp_path):
    """Three contiguous days (22:00 on D1 to 02:00 on D3, 1 vector/min) with their models."""
    inp = tmp_path / "in"
    write_raw_csv(science_file(inp, D1, "OB"), "2014-11-01T22:00:00", 120, 60.0,
                  t_words=np.linspace(11000, 11500, 120).astype(int))
    write_raw_csv(science_file(inp, D2, "OB"), "2014-11-02T00:00:00", 1440, 60.0,
                  t_words=np.linspace(11800, 13000, 1440).astype(int))  # +~17 C over the day
    write_raw_csv(science_file(inp, D3, "OB"), "2014-11-03T00:00:00", 120, 60.0,
                  t_words=np.full(120, 12600))
    (inp / "calib").mkdir()
    for k, day in enumerate((D1, D2, D3)):
        c = np.zeros((6, 3))
        c[0] = [2.0 + 3 * k, -1.0 - 2 * k, 0.5 * k]  # nT: steps of several nT between days
        c[1] = [0.05 * (k + 1), -0.03, 0.02 * k]  # nT/C
        c[2] = [1e-4 * k, 0.0, -2e-4]
        calib.write_daily_offset_model(
            DailyOffsetModel(np.datetime64(day.isoformat(), "D"), "OB", c), inp / "calib"
        )
    whole = tmp_path / "whole.csv"
    lines = [HEADER]
    for day in (D1, D2, D3):
        lines += science_file(inp, day, "OB").read_text().splitlines()[1:]
    whole.write_text("\n".join(lines) + "\n")
    return inp, whole


def _a(path, inp, previous=None, stitch_gap_s=3 * 3600.0):
    options = RosettaOptions(calib=inp / "calib", levels=("A",),
                             stitch_gap_hours=stitch_gap_s / 3600.0)
    return calibrate_levels(path, "OB", options=options, previous=previous)["A"]


def _incoming(task, day):
    """The stitching state ``day`` starts from (the batch's chain of earlier days)."""
    return task.pipeline.chain(task.input_dir, task.options).incoming_state(day, "OB")


def test_incoming_state_equals_one_run(campaign, tmp_path, pool):
    inp, whole = campaign
    ref = _a(whole, inp)
    task = make_day_task(inp, tmp_path / "out", formats=("cdf",), levels=("A",))
    for order in ((D3, D2, D1), (D1, D2, D3)):  # any order: the chain is resolved from files
        for day in order:
            a = _a(science_file(inp, day, "OB"), inp, previous=_incoming(task, day))
            sel = np.isin(ref["epoch"].values, a["epoch"].values)
            assert sel.sum() == a.sizes["time"]
            # same arithmetic on the same numbers as the one run (1e-9 nT: summation order)
            np.testing.assert_allclose(a["b"].values, ref["b"].values[sel], rtol=0, atol=1e-9)
    # without the chain (the batch before decision 27) day 2 started with its own P_2:
    alone = _a(science_file(inp, D2, "OB"), inp)
    sel = np.isin(ref["epoch"].values, alone["epoch"].values)
    jump = np.abs(alone["b"].values[0] - ref["b"].values[sel][0])
    # the midnight jump the chain removes: 1.01, 2.17, 1.45 nT (x, y, z) in this campaign
    assert jump.max() > 2.0
    # the state files hold each day's first/last vector, keyed by its raw file
    assert stitch_file(tmp_path / "out", D1, "OB").is_file()
    assert stitch_file(tmp_path / "out", D2, "OB").is_file()


def test_chain_breaks_without_model_or_across_gap(campaign, tmp_path, pool):
    inp, _ = campaign
    task = make_day_task(inp, tmp_path / "out", formats=("cdf",), levels=("A",))
    assert _incoming(task, D1) is None  # no day before
    state = _incoming(task, D2)
    assert state is not None
    # D1 ends 23:59:00, D2 starts 00:00:00: a 60-s gap continues with a 60-s limit only
    alone = _a(science_file(inp, D2, "OB"), inp)
    for limit, stitched in ((60.0, True), (59.0, False)):
        a = _a(science_file(inp, D2, "OB"), inp, previous=state, stitch_gap_s=limit)
        assert (np.abs(a["b"].values - alone["b"].values).max() > 1.0) == stitched
    (inp / "calib" / "RPCMAG_141102_006_CALIB_OB.TXT").unlink()  # D2 without a model
    assert _incoming(task, D3) is None


def test_changed_earlier_day_changes_later_inputs(campaign, tmp_path, pool):
    inp, _ = campaign
    task = make_day_task(inp, tmp_path / "out", levels=("A",))
    before = task.inputs(D3).calibration["stitch_in/OB"]
    path = science_file(inp, D1, "OB")
    lines = path.read_text().splitlines()
    fields = lines[-1].split(",")
    fields[6] = fields[7] = "9000"  # the last thermistor word of D1
    lines[-1] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    after = task.inputs(D3).calibration["stitch_in/OB"]
    assert before != after and before != "none"


def test_day_task_writes_stitched_products(campaign, tmp_path, pool):
    from fluxcal.products import read_fluxcal_product

    inp, whole = campaign
    ref = _a(whole, inp)
    out = tmp_path / "out"
    task = make_day_task(inp, out, formats=("cdf",), levels=("A",))
    for day in (D2, D3, D1):
        result = task(day)
        cdf = [p for p in result.products if str(p).endswith(".cdf")]
        assert len(cdf) == 1
        a = read_fluxcal_product(cdf[0])
        sel = np.isin(ref["epoch"].values, a["epoch"].values)
        # products keep the field to 1e-3 nT or better; the stitch shifts are > 2 nT
        np.testing.assert_allclose(a["b"].values, ref["b"].values[sel], atol=1e-3)
        assert stitch_file(out, day, "OB").is_file()
