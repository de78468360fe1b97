"""``--quicklook`` of ``fluxcal messenger edr2cdr`` and of the batch task (issue 6).

The figure is inspected as an object (panels, labels, plotted data), never by pixels.
"""

import numpy as np
import pytest

import fluxcal.products.quicklook as ql
from fluxcal.cli import main
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.batch_task import make_day_task
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.products import quicklook_dataset


def _args(files, kernels, out, *extra):
    return ["messenger", "edr2cdr", "--sci", str(files["science"]), "--heater",
            str(files["heater"]), "--temperature", str(files["temperature"]), "--kernels",
            str(kernels), "--out", str(out), "--average", "", "--formats", "tab", *extra]


@pytest.fixture
def figures(monkeypatch):
    """Record every quicklook figure built (write_quicklooks calls quicklook_figure)."""
    made = []
    real = ql.quicklook_figure

    def spy(*args, **kwargs):
        fig = real(*args, **kwargs)
        made.append(fig)
        return fig

    monkeypatch.setattr(ql, "quicklook_figure", spy)
    return made


def test_edr2cdr_quicklook_panels(tmp_path, simulated_files, messenger_kernels, figures):
    out = tmp_path / "out"
    code = main(_args(simulated_files, messenger_kernels, out, "--frames", "mso,sc",
                      "--quicklook"))
    assert code == 0
    png = out / "MAGMSOSCI12153_20120601.png"
    assert png.is_file() and png.stat().st_size > 10_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(figures) == 1  # one day, one quicklook (in the first product frame, MSO)
    axes = figures[0].axes
    labels = [ax.get_ylabel() for ax in axes]
    # issue 12: offsets in nT (before: counts), through the fine-range matrix of eq. 8
    assert labels == ["B MSGR_MSO (nT)", "|B| (nT)", "offset (nT)", "quality",
                      "distance (km)"]
    assert axes[-1].get_xlabel() == "Time (UTC)"
    assert [t.get_text() for t in axes[0].get_legend().get_texts()] == ["B_X", "B_Y", "B_Z"]
    # the offsets panel shows three per-axis series (x, y, z)
    assert [line.get_label() for line in axes[2].get_lines()] == ["x", "y", "z"]
    # the 2-h simulation runs over heater duty-cycle steps and a heater-off temperature
    # excursion: the plotted offset must vary by many counts (cT slope ~ counts per C)
    # (5 counts x 0.0467 nT/count, the Table 4 fine-range y gain: > 0.2 nT)
    y = axes[2].get_lines()[1].get_ydata()
    assert np.ptp(y) > 0.2
    # distance from Mercury's centre of the synthetic 200 x 15,200 km altitude orbit
    d = axes[4].get_lines()[0].get_ydata()
    assert 2440.0 + 150.0 < d.min() and d.max() < 2440.0 + 15_300.0


def test_quicklook_dataset_carries_the_applied_offsets(simulated, messenger_kernels,
                                                       calibration):
    """The quicklook's offset is the total cT(T) + Delta(t) the pipeline subtracted."""
    with KernelPool(messenger_kernels):
        ds = calibrate(simulated["science"], simulated["heater"], simulated["temperature"],
                       calibration, frames=("rtn",), max_offset_step=None)
    q = quicklook_dataset(ds, "rtn")
    assert set(q.data_vars) == {"b_rtn", "offset", "quality", "distance"}
    assert q["offset"].attrs["units"] == "counts"
    np.testing.assert_array_equal(q["offset"].values, ds["offset"].values)
    # forward-model truth of the offset (thermal + duty cycle, from the declared schedule,
    # relaxed over the whole history): tolerance the 0.6 DN that sec. 7's five-change
    # look-back neglects (test_round_trip.py::test_offsets_and_heater_recovered)
    np.testing.assert_allclose(q["offset"].values, simulated["truth"]["offset"].values,
                               atol=0.6)
    # distance = |MSO position| (independent: norm of the truth path is not stored, so
    # recompute from the product's own pos_mso with a loop)
    pos = ds["pos_mso"].values
    brute = np.array([sum(c * c for c in p) ** 0.5 for p in pos[::5000]])
    np.testing.assert_allclose(q["distance"].values[::5000], brute, rtol=1e-12)
    fig = ql.quicklook_figure(q, field="b_rtn", frame="MSGR_RTN")
    assert fig.axes[0].get_ylabel() == "B MSGR_RTN (nT)"


def test_batch_task_quicklook_option(tmp_path):
    task = make_day_task(tmp_path, tmp_path / "out", quicklook=True, quicklook_frame="rtn",
                         unknown_option=3)
    assert task.options.quicklook is True and task.options.quicklook_frame == "rtn"
    assert make_day_task(tmp_path, tmp_path).options.quicklook is False


def test_bad_quicklook_frame_is_an_error(tmp_path, simulated_files, messenger_kernels, capsys):
    out = tmp_path / "out"
    code = main(_args(simulated_files, messenger_kernels, out, "--frames", "mso",
                      "--quicklook", "--quicklook-frame", "gse"))
    assert code == 2
    assert "--quicklook-frame" in capsys.readouterr().err  # the option, by its name
    assert not out.exists() or not any(out.iterdir())

