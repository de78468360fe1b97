"""Dubious Rosetta inputs are reported as warnings, the data kept (issue 23, item 2).

Duplicate epochs, ``time_utc`` disagreeing with ``obt``, and a ``rosetta fit`` whose
block-mean residuals are far above the field's within-block fluctuation (the calm-phase
criterion of sec. 4.2.3.3 does not hold).  Inputs from the forward models
(`fluxcal simulate rosetta`, tests/missions/rosetta/test_fit.py).
"""

import logging

import numpy as np
import pytest

from fluxcal.api import read_product
from fluxcal.cli import main
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.rosetta.fit import (
    RESIDUAL_NOISE_FACTOR,
    fit_extended_model,
    fit_warnings,
    reduced_temperature,
    write_daily_model,
)
from tests.missions.rosetta.test_fit import (
    BLOCK_S,
    DAY,
    NS,
    level_a_ground,
    simulate_raw,
    true_model,
)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", "rosetta", "--out", str(out), "--hours", "0.02", "--seed", "5"]) == 0
    return out


def _calibrate(sim, science, out, *kernels):
    return main(["rosetta", "calibrate", "--science", str(science), "--sensor", "OB",
                 "--levels", "A", "--calib", str(sim / "calib"), "--out", str(out), *kernels])


def _edit(sim, tmp_path, edit):
    lines = (sim / "RPCMAG_20140801_RAW_OB.csv").read_text().splitlines()
    edit(lines)
    path = tmp_path / "science_OB.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_clean_simulation_gives_no_warning(sim, tmp_path, caplog):
    with caplog.at_level(logging.WARNING):
        assert _calibrate(sim, sim / "RPCMAG_20140801_RAW_OB.csv", tmp_path / "a") == 0
        kern = sim / "kernels" / "rosetta_synthetic.tm"
        assert _calibrate(sim, sim / "RPCMAG_20140801_RAW_OB.csv", tmp_path / "b",
                          "--kernels", str(kern)) == 0
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_duplicate_epoch_is_reported(sim, tmp_path, caplog):
    def dup(lines):
        lines.insert(11, lines[10])  # record of line 11 repeated as line 12
    path = _edit(sim, tmp_path, dup)
    with caplog.at_level(logging.WARNING):
        assert _calibrate(sim, path, tmp_path / "out") == 0
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "line 12" in text and "1 record(s) repeat the time" in text
    assert "dropped, the first of each time kept" in text
    # issue 31: the repeated record is dropped (counted): the product is the clean file's
    assert _calibrate(sim, sim / "RPCMAG_20140801_RAW_OB.csv", tmp_path / "clean") == 0
    (cdf,) = (tmp_path / "out").glob("*.cdf")
    product, clean = read_product(cdf), read_product(tmp_path / "clean" / cdf.name)
    assert int(product.attrs["duplicates_dropped"]) == 1
    assert "duplicates_dropped" not in clean.attrs
    np.testing.assert_array_equal(product["epoch"].values, clean["epoch"].values)
    np.testing.assert_array_equal(product["b"].values, clean["b"].values)


@pytest.mark.parametrize("kernels", [False, True])
def test_utc_a_day_off_obt_is_reported(sim, tmp_path, caplog, kernels):
    def day_off(lines):
        cells = lines[30].split(",")
        cells[0] = cells[0].replace("2014-08-01", "2014-08-02")
        lines[30] = ",".join(cells)
    if kernels:
        path = _edit(sim, tmp_path, day_off)
        args = ["--kernels", str(sim / "kernels" / "rosetta_synthetic.tm")]
    else:  # without kernels time_utc times the records: make the day off the last one
        def last_off(lines):
            cells = lines[-1].split(",")
            cells[0] = cells[0].replace("2014-08-01", "2014-08-02")
            lines[-1] = ",".join(cells)
        path = _edit(sim, tmp_path, last_off)
        args = []
    with caplog.at_level(logging.WARNING):
        assert _calibrate(sim, path, tmp_path / "out", *args) == 0
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "time_utc" in text and "2014-08-02" in text
    assert ("+86400.000 s" in text) if kernels else ("86400" in text)


@pytest.fixture(scope="module")
def fits():
    model = true_model(DAY)
    out = {}
    with KernelPool():
        raw, b, temp = simulate_raw(DAY + "T00:00:00", 24.0, model, seed=11)
        a, cal = level_a_ground(raw)
        out["calm"] = fit_extended_model(a, reduced_temperature(a, cal), block_s=BLOCK_S)
        # not calm: a 12-nT structure over 6 h in y does not average out over the blocks
        secs = (a["epoch"].values - a["epoch"].values[0]) / NS
        b2 = a["b"].values.copy()
        b2[:, 1] += 12.0 * np.sin(2 * np.pi * secs / 21600.0)
        a2 = a.copy(data={**{k: a[k].values for k in a.data_vars}, "b": b2})
        out["structured"] = fit_extended_model(a2, reduced_temperature(a2, cal),
                                               block_s=BLOCK_S)
    return out


def test_calm_day_fit_is_not_reported(fits):
    # measured on 13 forward-model days (seeds 11-23): rms / noise <= 1.53 per axis
    fit = fits["calm"]
    assert np.all(fit.rms < RESIDUAL_NOISE_FACTOR * fit.noise)
    assert fit_warnings(fit) == []


def test_structured_day_fit_is_reported_and_written(fits, tmp_path, caplog):
    fit = fits["structured"]
    warnings = fit_warnings(fit)
    assert len(warnings) == 1 and " y: block-mean residual rms" in warnings[0]
    with caplog.at_level(logging.WARNING):
        path = write_daily_model(fit, tmp_path)
    assert any("not a calm phase" in r.getMessage() for r in caplog.records)
    assert "# warning: OB" in path.read_text()
