"""LEVEL_K's undecidable case: flagged, and unbiased once the heater direction is stated.

Forward model (issue 23): one heater of constant current (1.2 nT, 40 % on, 30-s period)
seen "on" from the first vector, on a red-noise background.  No rule of
`heater_off_segments` can tell the off level (no quiet stretch, the on level never
changes); fluxcal takes the first level as off, 1.2 nT wrong, and now says so.
"""

import logging

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.rosetta import cleaning_levels as cl
from fluxcal.missions.rosetta.clean_cli import clean
from fluxcal.products import read_fluxcal_product
from tests.cleaning._synthetic import red_noise, rotating_field
from tests.cleaning.test_rosetta_cleaning import FS, START, _dataset, _write, lsk  # noqa: F401


def _case(lsk, sign):  # noqa: F811
    rng = np.random.default_rng(5)
    n = 12000
    t = np.arange(n) / FS
    bg = rotating_field(t, period=3600.0) + red_noise(n, FS, 1e-3, rng, floor=1e-5)
    sq = np.where((t % 30) < 12, 1.2, 0.0)
    d = sign * np.array([1.0, 2.0, -1.0]) / np.sqrt(6)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    ds = _dataset(t0 + np.round(t * 1e9).astype(np.int64), bg + sq[:, None] * d, level="B")
    return ds, bg, d


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_undecidable_is_flagged_and_stated_direction_is_unbiased(lsk, sign, caplog):  # noqa: F811
    ds, bg, d = _case(lsk, sign)
    with caplog.at_level(logging.WARNING):
        guessed = cl.level_k(ds)
    assert guessed.attrs["heater_off_undecided"] == 1
    assert any("not decidable" in r.getMessage() for r in caplog.records)
    stated = cl.level_k(ds, heater_direction=3.0 * d)  # any length
    r = stated["b"].values - bg
    assert stated.attrs["heater_off_undecided"] == 0
    assert abs(np.mean(r @ d)) < 0.01  # unbiased (the guess: 1.2 nT)
    assert np.sqrt(np.mean(np.sum(r**2, axis=1))) < 0.1
    np.testing.assert_allclose(stated.attrs["heater_direction"], d, atol=1e-12)


def test_heater_direction_from_the_command(tmp_path, lsk):  # noqa: F811
    ds, bg, d = _case(lsk, 1.0)
    files = _write(ds, tmp_path / "in", lsk)
    app = typer.Typer()
    app.command()(clean)
    app.command("noop")(lambda: None)
    out = tmp_path / "out"
    arg = ",".join(f"{v:.6f}" for v in d)
    res = CliRunner().invoke(app, ["clean", "--level", "K", "--input", str(files[".cdf"]),
                                   "--out", str(out), "--heater-direction", arg, "--no-plot"])
    assert res.exit_code == 0, res.output
    k = read_fluxcal_product(out / "rosetta_rpcmag_clk-ob_20140801_v01.cdf")
    assert abs(np.mean((k["b"].values - bg) @ d)) < 0.01
    bad = CliRunner().invoke(app, ["clean", "--level", "K", "--input", str(files[".cdf"]),
                                   "--out", str(out), "--heater-direction", "0,0,0"])
    assert bad.exit_code == 2
