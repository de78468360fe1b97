from __future__ import annotations

from pathlib import Path

import matplotlib.dates as mdates
import matplotlib.image as mpimg
import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import write_product
from fluxcal.products.quicklook import (
    envelope,
    quicklook_figure,
    split_days,
    write_quicklooks,
)
from fluxcal.products.spectrogram import spectrogram_figure

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
    # UTC date ticks (before: decimal "Hours of 2024-01-01")
    assert fig.axes[-1].get_xlabel() == "Time (UTC)"
    assert isinstance(fig.axes[-1].xaxis.get_major_formatter(), mdates.ConciseDateFormatter)
    assert fig._suptitle.get_text() == "MAGMSOSCI24001"
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["B_X", "B_Y", "B_Z"]  # the components x, y, z of B_mso
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


# --- issue 12: per-day PNGs, .TAB time columns, variable-rate spectrogram ------------------


def _tt2000(y: int, mo: int, d: int, h: int = 0, mi: int = 0, s: int = 0) -> int:
    import cdflib

    return int(cdflib.cdfepoch.compute_tt2000([y, mo, d, h, mi, s, 0, 0, 0]))


def test_run_over_two_days_gives_a_png_per_day(tmp_path: Path) -> None:
    """20 h from 12:00 (before: one PNG, the run was within the old 25 h slack)."""
    n = 2000
    ds = make_dataset(n)
    step = 20 * 3600 * 10**9 // n
    epoch = _tt2000(2024, 1, 1, 12) + np.arange(n, dtype=np.int64) * step
    ds = ds.assign_coords(epoch=("time", epoch))
    days = split_days(ds)
    assert [d for d, _ in days] == ["20240101", "20240102"]
    # 12 h then 8 h of samples at a constant spacing
    assert [sub.sizes["time"] for _, sub in days] == [1200, 800]
    paths = write_quicklooks(ds, tmp_path, "P")
    assert [p.name for p in paths] == ["P_20240101.png", "P_20240102.png"]


def test_small_edge_at_the_end_is_drawn_with_its_day() -> None:
    ds = make_dataset(1000)
    # a day ending 2 samples (latency-shifted) past midnight: one day
    epoch = _tt2000(2024, 1, 1) + 86_400 * 10**9 - 998 * 10**9 + np.arange(1000) * 10**9
    ds = ds.assign_coords(epoch=("time", epoch.astype(np.int64)))
    ((day, sub),) = split_days(ds)
    assert day == "20240101" and sub.sizes["time"] == 1000


def test_epoch_from_rosetta_time_utc() -> None:
    from fluxcal.products.quicklook import epoch_from_table

    utc = np.array(["2014-08-01T00:00:08.200000", "2015-06-30T23:59:60.500000",
                    "2015-07-01T00:00:00.000001"])
    ds = xr.Dataset({"time_utc": ("time", utc)})
    got = epoch_from_table(ds)["epoch"].values
    # cdflib's own leap-second table and calendar (independent of fluxcal's)
    expect = [_tt2000(2014, 8, 1, 0, 0, 8) + 200_000_000,
              _tt2000(2015, 6, 30, 23, 59, 59) + 1_500_000_000,  # inside the leap second
              _tt2000(2015, 7, 1) + 1_000]
    assert got.tolist() == expect


def test_epoch_from_messenger_fields() -> None:
    from fluxcal.products.quicklook import epoch_from_table

    ds = xr.Dataset({"year": ("time", np.array([2012, 2012, 2013])),
                     "doy": ("time", np.array([153, 366, 1])),
                     "hour": ("time", np.array([0, 23, 0])),
                     "minute": ("time", np.array([0, 59, 0])),
                     "second": ("time", np.array([0.07, 59.5, 0.0]))})
    got = epoch_from_table(ds)["epoch"].values
    expect = [_tt2000(2012, 6, 1) + 70_000_000, _tt2000(2012, 12, 31, 23, 59, 59) + 500_000_000,
              _tt2000(2013, 1, 1)]
    assert got.tolist() == expect


def test_epoch_from_messenger_fields_in_a_leap_second() -> None:
    # 2012-06-30 (day 182) ended with 23:59:60; the second after it is 2012-07-01 00:00:00
    from fluxcal.products.quicklook import epoch_from_table

    ds = xr.Dataset({"year": ("time", np.full(3, 2012)),
                     "doy": ("time", np.array([182, 182, 183])),
                     "hour": ("time", np.array([23, 23, 0])),
                     "minute": ("time", np.array([59, 59, 0])),
                     "second": ("time", np.array([59.95, 60.25, 0.05]))})
    got = epoch_from_table(ds)["epoch"].values
    expect = [_tt2000(2012, 6, 30, 23, 59, 59) + 950_000_000,
              _tt2000(2012, 6, 30, 23, 59, 60) + 250_000_000,
              _tt2000(2012, 7, 1) + 50_000_000]
    assert got.tolist() == expect


def test_epoch_from_table_without_time_is_an_error() -> None:
    from fluxcal.products.quicklook import epoch_from_table

    with pytest.raises(InputFormatError, match="time_utc"):
        epoch_from_table(xr.Dataset({"b": ("time", np.zeros(3))}))


def _variable_rate_dataset() -> tuple[xr.Dataset, float]:
    """4000 s at 20 Hz (3 Hz line), then 4000 s at 1 Hz (0.2 Hz line), from 06:00."""
    t20 = np.arange(80_000) / 20.0
    t1 = 4000.0 + np.arange(4000) / 1.0
    t = np.r_[t20, t1]
    sig = np.r_[np.sin(2 * np.pi * 3.0 * t20), np.sin(2 * np.pi * 0.2 * t1)]
    start = _tt2000(2024, 1, 1, 6)
    epoch = start + np.round(t * 1e9).astype(np.int64)
    ds = xr.Dataset({"B": (("time", "component"), np.column_stack([sig, sig, sig]),
                           {"units": "nT"})},
                    coords={"epoch": ("time", epoch)})
    return ds, 6 * 3600.0


def test_spectrogram_keeps_real_times_when_the_rate_changes() -> None:
    """Before: 84,000 samples at the median 20 Hz were drawn over 4,200 s instead of 8,000 s."""
    ds, t0 = _variable_rate_dataset()
    fig = spectrogram_figure(ds)
    ax = fig.axes[0]
    meshes = ax.collections
    assert len(meshes) == 2  # one per evenly sampled run
    # UTC date ticks; x in matplotlib days from 2024-01-01 00:00 UTC, turned into seconds
    assert isinstance(ax.xaxis.get_major_formatter(), mdates.ConciseDateFormatter)
    day0 = mdates.date2num(np.datetime64("2024-01-01T00:00", "ns"))
    x_ranges = [(m.get_coordinates()[0, [0, -1], 0] - day0) * 86_400.0 for m in meshes]
    # each run spans its own real seconds of the day (within one segment, 256 samples)
    assert x_ranges[0][0] == pytest.approx(t0, abs=256 / 20)
    assert x_ranges[0][1] == pytest.approx(t0 + 4000, abs=256 / 20)
    assert x_ranges[1][0] == pytest.approx(t0 + 4000, abs=256)
    assert x_ranges[1][1] == pytest.approx(t0 + 8000, abs=256)
    for mesh, line, fs in zip(meshes, (3.0, 0.2), (20.0, 1.0), strict=True):
        # 'nearest' shading: cell edges around the nperseg/2 + 1 = 129 frequencies
        power = np.asarray(mesh.get_array()).reshape(129, -1)
        centres = np.linspace(0, fs / 2, 129)
        assert centres[power.mean(axis=1).argmax()] == pytest.approx(line, abs=fs / 256)


def test_spectrogram_titles_do_not_overlap_the_panel_above() -> None:
    ds, _ = _variable_rate_dataset()
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = spectrogram_figure(ds)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    panels = [ax for ax in fig.axes if ax.get_ylabel() == "Frequency (Hz)"]
    assert len(panels) == 3
    for upper, lower in zip(panels[:-1], panels[1:], strict=True):
        title = lower.title.get_window_extent(renderer)
        above = upper.get_tightbbox(renderer)
        assert title.y1 <= above.y0 + 0.5, (title, above)  # display pixels


# --- issue 22: every sample is drawn, the last (partial) envelope bin included -------------

SPIKE_NT = 300.0


@pytest.mark.parametrize("n,bins", [(10_001, 4000), (8_001, 4000), (99_999, 1000), (5, 2)])
def test_envelope_represents_every_sample(n: int, bins: int) -> None:
    """Each sample lies between the min and max drawn for its bin (checked by brute force)."""
    rng = np.random.default_rng(n)
    x = np.arange(n, dtype=float)
    y = rng.normal(0.0, 1.0, n)
    y[-3] = SPIKE_NT
    xs, ys = envelope(x, y, bins=bins)
    assert SPIKE_NT in ys
    if len(xs) == n:  # short series are drawn sample by sample
        return
    assert len(ys) <= 2 * bins
    starts = xs[::2]
    assert starts[0] == 0.0 and starts[-1] <= n - 1
    lo, hi = ys[0::2], ys[1::2]
    k = np.searchsorted(starts, x, side="right") - 1  # the bin of every sample
    assert np.all((lo[k] <= y) & (y <= hi[k]))


def _spike_at_the_end(n: int = 10_001) -> xr.Dataset:
    """A quiet product (|B| < 60 nT) with a 300 nT spike in its last 10 samples."""
    ds = make_dataset(n)
    t = np.arange(n) / n
    ds["B_mso"].values[:] = 40.0 * np.sin(2 * np.pi * t)[:, None] + [5.0, -5.0, 10.0]
    ds["B_mso"].values[n - 4, 2] = SPIKE_NT  # within the last n mod 4000 samples
    return ds


def test_quicklook_draws_a_spike_in_the_last_samples() -> None:
    fig = quicklook_figure(_spike_at_the_end())
    bz = fig.axes[0].get_lines()[2].get_ydata()
    assert np.max(bz) == SPIKE_NT
    assert np.max(fig.axes[1].get_lines()[0].get_ydata()) > SPIKE_NT  # |B| too


@pytest.mark.parametrize("fmt,suffix", [("nc", ".nc"), ("cdf", ".cdf")])
def test_cli_plot_draws_a_spike_in_the_last_samples(fmt: str, suffix: str, tmp_path: Path,
                                                    monkeypatch) -> None:
    from fluxcal.cli import main
    from fluxcal.products import quicklook

    figs = []
    save = quicklook.save_png
    monkeypatch.setattr(quicklook, "save_png", lambda fig, path: (figs.append(fig),
                                                                   save(fig, path))[1])
    write_product(_spike_at_the_end(), tmp_path / "P", formats=(fmt,))
    assert main(["plot", str(tmp_path / f"P{suffix}"), "--out", str(tmp_path / "ql")]) == 0
    (fig,) = figs
    assert np.max(fig.axes[0].get_lines()[2].get_ydata()) == SPIKE_NT


def test_talk_ready_axes_rtn_legend_and_a_flat_distance() -> None:
    """Before: legend 'BB_R BB_T BB_N', x in decimal hours, distance axis '1e-11+3e1'."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.ticker import ScalarFormatter

    n = 400
    epoch = EPOCH0 + np.arange(n, dtype=np.int64) * 10_000_000_000
    rng = np.random.default_rng(5)
    # a comet distance of 30 km +- 1e-11 km: rounding noise of a constant
    position = np.column_stack([30.0 + 1e-11 * rng.standard_normal(n), np.zeros(n),
                                np.zeros(n)])
    ds = xr.Dataset(
        {"b": (("time", "b_component"), rng.normal(0, 5, (n, 3)), {"units": "nT"}),
         "position": (("time", "position_component"), position, {"units": "km"})},
        coords={"epoch": ("time", epoch),
                "b_component": ["B_R", "B_T", "B_N"], "position_component": ["X", "Y", "Z"]})
    fig = quicklook_figure(ds, frame="RTN")
    FigureCanvasAgg(fig).draw()
    comps, _, dist = fig.axes
    assert [t.get_text() for t in comps.get_legend().get_texts()] == ["B_R", "B_T", "B_N"]
    assert comps.get_ylabel() == "B RTN (nT)"
    assert isinstance(dist.xaxis.get_major_formatter(), mdates.ConciseDateFormatter)
    assert isinstance(dist.xaxis.get_major_locator(), mdates.AutoDateLocator)
    # the x data are UTC datetimes: 2024-01-01 00:00:00 plus the samples' seconds
    first = comps.get_lines()[0].get_xdata()[0]
    assert str(np.datetime64(first, "s")) == "2024-01-01T00:00:00"
    fmt = dist.yaxis.get_major_formatter()
    assert isinstance(fmt, ScalarFormatter) and not fmt.get_useOffset()
    assert dist.yaxis.get_offset_text().get_text() == ""
    labels = [t.get_text() for t in dist.get_yticklabels() if t.get_text()]
    assert labels and all("e" not in t for t in labels)
    lo, hi = dist.get_ylim()
    assert lo < 30.0 < hi and hi - lo == pytest.approx(0.06)  # 30 +- 1e-3 x 30
