"""The generic fit pictures (`fluxcal.products.fit_pictures`, `fit_plots`, `fit_report`).

Expected values are closed forms: pulls ``(y - law) / err`` computed here by hand, one
time-line row per reason with its count, the arrays passed in read back from the figure.
"""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest

from fluxcal.errors import MissingExtraError
from fluxcal.products import fit_pictures as fp
from fluxcal.products import fit_report


def _panel() -> fp.Panel:
    x = np.array([-20.0, 0.0, 20.0])
    y = np.array([[1.0, 2.0], [3.0, 1.0], [5.0, 0.0]])
    grid = np.linspace(-30.0, 30.0, 13)
    return fp.Panel("fit_law", "law", "T (C)", "nT", ("x", "y"), "a law", fp.Points(
        x, y, np.full_like(y, 0.5)), fp.Curve(grid, np.stack([3 + grid / 10, 1 - grid / 20], 1),
                                              np.full((13, 2), 0.2)), (-20.0, 20.0))


def test_pull_values_closed_form():
    pts = fp.Points(np.arange(3.0), np.array([[1.0], [2.0], [np.nan]]),
                    np.array([[0.5], [0.0], [1.0]]))
    np.testing.assert_array_equal(fp.pull_values(pts, np.array([[0.0], [0.0], [0.0]])),
                                  [2.0])  # err 0 and NaN left out
    assert fp.pull_values(fp.Points(np.arange(2.0), np.ones((2, 1))), np.zeros((2, 1))).size == 0


def test_figures_hold_the_arrays_given():
    plt = pytest.importorskip("matplotlib.pyplot")
    from fluxcal.products.fit_plots import panel_figure, rejections_figure

    panel = _panel()
    fig = panel_figure(panel)
    for j, ax in enumerate(fig.axes[:2]):
        x, y = ax.get_lines()[0].get_data()
        np.testing.assert_array_equal(x, panel.curve.x)
        np.testing.assert_array_equal(y, panel.curve.y[:, j])
    plt.close(fig)
    start = np.datetime64("2012-06-01T00:00") + np.arange(5).astype("m8[h]")
    rej = fp.Rejections("fit_intervals", "t", "c", start,
                        np.array(["", "compressive", "", "gap", "compressive"]))
    fig = rejections_figure(rej)
    labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    assert labels == ["accepted (2)", "compressive (2)", "gap (1)"]
    plt.close(fig)


def test_report_pictures_captions_and_relative_links(tmp_path):
    pytest.importorskip("matplotlib")
    (tmp_path / "table.csv").write_text("a,b\n1,2\n")
    written, note = fit_report.write_fit_report(tmp_path, [_panel()], "a fit")
    assert note == "" and {p.name for p in written} == {"fit_law.png", "index.html"}
    page = (tmp_path / "index.html").read_text()
    assert 'src="fit_law.png"' in page and "fit_law.png: a law" in page
    assert 'href="table.csv"' in page and str(tmp_path) not in page


def test_without_matplotlib_index_only_and_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(fit_report, "available", lambda extra: False)
    (tmp_path / "table.csv").write_text("a,b\n1,2\n")
    written, note = fit_report.write_fit_report(tmp_path, [_panel()], "a fit")
    assert [p.name for p in written] == ["index.html"] and not list(tmp_path.glob("*.png"))
    assert note == fit_report.NO_PLOT_NOTE and "\n" not in note and "fluxcal[plot]" in note
    assert "fluxcal[plot]" in (tmp_path / "index.html").read_text()


def test_drawing_module_says_which_extra_it_needs(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed
    monkeypatch.delitem(sys.modules, "fluxcal.products.fit_plots", raising=False)
    with pytest.raises(MissingExtraError, match=r"fluxcal\[plot\]"):
        importlib.import_module("fluxcal.products.fit_plots")
    monkeypatch.delitem(sys.modules, "fluxcal.products.fit_plots", raising=False)
