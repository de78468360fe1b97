from __future__ import annotations

from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import write_product
from fluxcal.products.quicklook import (
    envelope,
    quicklook_figure,
    spectrogram_figure,
    split_days,
    write_quicklooks,
)

from .conftest import EPOCH0, make_dataset


def _messenger_like(n: int = 3000) -> xr.Dataset:
    ds = make_dataset(n)
    ds["offset"] = (("time", "component"), np.tile([1.0, -2.0, 3.0], (n, 1)),
                    {"units": "nT", "description": "Applied offset"})
    return ds


def _labels(fig) -> list[str]:
    return [ax.get_ylabel() for ax in fig.axes]


def test_panels_follow_the_dataset() -> None:
    fig = quicklook_figure(_messenger_like(), title="MAGMSOSCI24001")
    labels = _labels(fig)
    assert labels[0] == "B mso (nT)"
    assert labels[1] == "|B| (nT)"
    assert "offset (nT)" in labels
    assert "T (degC)" in labels  # the float32 'temperature' variable
    assert "quality" in labels
    assert labels[-1] == "distance (km)"
    assert fig.axes[-1].get_xlabel().startswith("Hours of 2024-01-01")
    assert fig._suptitle.get_text() == "MAGMSOSCI24001"
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["Bx", "By", "Bz"]
    # the magnitude panel draws |B| (envelope keeps the extremes)
    ymax = max(line.get_ydata().max() for line in fig.axes[1].get_lines())
    ds = _messenger_like()
    assert ymax == pytest.approx(np.linalg.norm(ds["B_mso"].values, axis=1).max())


def test_chosen_field_and_frame() -> None:
    ds = _messenger_like(200)
    ds["b_sensor"] = ds["B_mso"] * 2
    fig = quicklook_figure(ds, field="b_sensor", frame="MSGR_MAG")
    assert fig.axes[0].get_ylabel() == "B MSGR_MAG (nT)"
    with pytest.raises(InputFormatError, match="quality"):
        quicklook_figure(ds, field="quality")


def test_minimal_product_has_two_panels() -> None:
    ds = make_dataset(100)[["B_mso"]]
    fig = quicklook_figure(ds)
    assert _labels(fig) == ["B mso (nT)", "|B| (nT)"]


def test_png_per_day(tmp_path: Path) -> None:
    ds = _messenger_like(2000)
    # spread the samples over ~2 UTC days: 2000 samples * 90 s = 50 h
    ds = ds.assign_coords(epoch=("time", EPOCH0 + np.arange(2000, dtype=np.int64) * 90 * 10**9))
    paths = write_quicklooks(ds, tmp_path, "P")
    assert [p.name for p in paths] == ["P_20240101.png", "P_20240102.png", "P_20240103.png"]
    for p in paths:
        img = mpimg.imread(p)
        assert img.shape[1] == 1100  # 11 in at 100 dpi
        assert img.shape[0] == 100 * (2 * 6 + 1)  # six panels
        assert p.stat().st_size > 20_000
    assert sum(sub.sizes["time"] for _, sub in split_days(ds)) == 2000


def test_daily_product_starting_before_midnight_gives_one_png(tmp_path: Path) -> None:
    ds = make_dataset(600)
    # 3 samples before 00:00 UTC, then 24 h: one product day, one PNG named by that day.
    epoch = EPOCH0 - 3 * 10**9 + np.arange(600, dtype=np.int64) * 144 * 10**9
    ds = ds.assign_coords(epoch=("time", epoch))
    (day, sub), = split_days(ds)
    assert day == "20240101" and sub.sizes["time"] == 600
    paths = write_quicklooks(ds, tmp_path, "P")
    assert [p.name for p in paths] == ["P_20240101.png"]


def test_envelope_keeps_extremes() -> None:
    x = np.arange(100_000.0)
    y = np.sin(x / 1000)
    y[12_345] = 50.0
    xs, ys = envelope(x, y, bins=1000)
    assert len(ys) == 2000
    assert ys.max() == 50.0 and ys.min() == pytest.approx(y.min())


def test_spectrogram_finds_the_line() -> None:
    n, fs = 8192, 20.0
    ds = make_dataset(n)
    t = np.arange(n) / fs
    ds = ds.assign_coords(epoch=("time", EPOCH0 + np.arange(n, dtype=np.int64) * 50_000_000))
    ds["B_mso"].values[:] = np.sin(2 * np.pi * 3.0 * t)[:, None]  # a 3 Hz line
    fig = spectrogram_figure(ds)
    mesh = fig.axes[0].collections[0]
    power = np.asarray(mesh.get_array()).reshape(129, -1)
    freqs = np.linspace(0, fs / 2, 129)
    assert freqs[power.mean(axis=1).argmax()] == pytest.approx(3.0, abs=fs / 256)
    assert fig.axes[0].get_ylabel() == "Frequency (Hz)"


def test_no_field_is_an_error() -> None:
    ds = make_dataset(10)[["quality"]]
    with pytest.raises(InputFormatError, match="no field vector"):
        quicklook_figure(ds)


@pytest.mark.parametrize("fmt,suffix", [("cdf", ".cdf"), ("nc", ".nc"), ("tab", ".TAB")])
def test_cli_plot(fmt: str, suffix: str, tmp_path: Path) -> None:
    from fluxcal.cli import main

    write_product(_messenger_like(500), tmp_path / "P", formats=(fmt,))
    assert main(["plot", str(tmp_path / f"P{suffix}"), "--out", str(tmp_path / "ql"),
                 "--spectrogram"]) == 0
    assert sorted(p.name for p in (tmp_path / "ql").iterdir()) == ["P_20240101.png",
                                                                   "P_spec.png"]
