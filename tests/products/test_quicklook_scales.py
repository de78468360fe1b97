"""Quicklook content (issue 12): |B| on a log scale when it spans a wide range, the
quality flag as categories, a labelled distance (Rosetta: Sun distance in AU).

Figures are inspected as objects (axis scale, ticks, labels), never by pixels.
"""

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from fluxcal.missions.rosetta.products import AU_KM, with_distance
from fluxcal.products.quicklook import quicklook_figure

from .conftest import make_dataset


def _orbit_like(n: int = 2000) -> xr.Dataset:
    ds = make_dataset(n)
    # a MESSENGER-like orbit: ~400 nT for 5 % of the time, ~20 nT elsewhere
    scale = np.where(np.arange(n) < n // 20, 400.0, 20.0)
    ds["B_mso"] = ds["B_mso"] / np.linalg.norm(ds["B_mso"].values, axis=1)[:, None] \
        * scale[:, None]
    ds["quality"] = ("time", np.where(np.arange(n) % 7 == 0, 2, 0).astype(np.int16),
                     {"units": "1"})
    return ds


def test_wide_magnitude_on_log_scale_and_quality_categories():
    fig = quicklook_figure(_orbit_like())
    axes = {ax.get_ylabel(): ax for ax in fig.axes}
    assert axes["|B| (nT)"].get_yscale() == "log"  # before: linear, 20 nT flat at the bottom
    q = axes["quality"]
    assert [t.get_text() for t in q.get_yticklabels()] == ["0", "2"]  # the values seen
    plt.close(fig)
    # a narrow range keeps the linear scale
    ds = _orbit_like()
    ds["B_mso"] = ds["B_mso"] * 0.0 + [10.0, 20.0, 30.0]
    fig = quicklook_figure(ds)
    assert {ax.get_ylabel(): ax for ax in fig.axes}["|B| (nT)"].get_yscale() == "linear"
    plt.close(fig)


def test_quality_meanings_name_the_ticks():
    ds = _orbit_like()
    ds["quality"].attrs.update(flag_values=np.array([0, 2]), flag_meanings="good coarse")
    fig = quicklook_figure(ds)
    q = {ax.get_ylabel(): ax for ax in fig.axes}["quality"]
    assert [t.get_text() for t in q.get_yticklabels()] == ["good", "coarse"]
    plt.close(fig)


def test_rosetta_sun_distance_in_au():
    ds = make_dataset(300).rename({"B_mso": "b"})
    # 1.5 AU along a unit vector rotated per sample (independent: AU from its definition)
    ang = np.linspace(0.0, 1.0, 300)
    pos = 1.5 * AU_KM * np.column_stack([np.cos(ang), np.sin(ang), 0 * ang])
    ds["position"] = (("time", "component"), pos, {"units": "km"})
    ds.attrs["position_centre"] = "SUN"
    out = with_distance(ds)
    np.testing.assert_allclose(out["distance"].values, 1.5, rtol=1e-12)  # float rounding
    fig = quicklook_figure(out, field="b")
    assert fig.axes[-1].get_ylabel() == "Sun distance (AU)"
    plt.close(fig)
    ds.attrs["position_centre"] = "CHURYUMOV-GERASIMENKO"
    assert with_distance(ds)["distance"].attrs["units"] == "km"
