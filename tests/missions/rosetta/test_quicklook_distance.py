"""``fluxcal rosetta calibrate --quicklook``: the distance panel is the Sun distance in AU
with its label (issue 12; before: "distance (km)", ~3e8 km on the axis)."""

import numpy as np
import pytest

import fluxcal.products.quicklook as ql
from fluxcal.cli import main
from fluxcal.missions.rosetta.products import AU_KM


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", "rosetta", "--out", str(out), "--hours", "0.05", "--seed", "4"]) == 0
    return out


def test_quicklook_sun_distance_in_au(sim, tmp_path, monkeypatch):
    figures = []
    real = ql.quicklook_figure

    def spy(*args, **kwargs):
        figures.append(real(*args, **kwargs))
        return figures[-1]

    monkeypatch.setattr(ql, "quicklook_figure", spy)
    args = ["rosetta", "calibrate", "--science", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
            "--sensor", "OB", "--levels", "A,B,C", "--calib", str(sim / "calib"),
            "--kernels", str(sim / "kernels" / "rosetta_synthetic.tm"), "--out",
            str(tmp_path), "--frame", "ECLIPJ2000", "--quicklook"]
    assert main(args) == 0
    assert len(figures) == 1
    ax = figures[0].axes[-1]
    assert ax.get_ylabel() == "Sun distance (AU)"
    d = ax.get_lines()[0].get_ydata()
    # Rosetta in August 2014 was 3.5-3.6 AU from the Sun; the synthetic kernels put it at
    # some heliocentric distance: a value in AU is between 0.1 and 10 (in km it was ~1e8)
    assert np.all((d > 0.1) & (d < 10.0)), d[:3]
    assert AU_KM == 149_597_870.7  # IAU 2012 B2, exact
