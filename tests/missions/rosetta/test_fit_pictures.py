"""Pictures and ``index.html`` of ``fluxcal rosetta fit`` (issue 34, item 6).

The curve drawn is compared with the polynomial of the written daily file, read with the
pipeline's reader and evaluated with numpy's Polynomial (not the fit's own basis).
"""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pytest
from numpy.polynomial import Polynomial

from fluxcal.cli import main
from fluxcal.missions.rosetta import calib, io
from fluxcal.missions.rosetta import fit_pictures as rfp
from fluxcal.products import fit_report
from tests.browser import browser, browser_check

from .test_fit import DAY, simulate_raw, true_model

pytest.importorskip("matplotlib")

DAILY = "RPCMAG_091113_006_CALIB_OB.TXT"


@pytest.fixture(scope="module")
def science(tmp_path_factory):
    """12 h of the forward model's cruise day at 0.5 Hz, as a raw science CSV."""
    from fluxcal.geometry.kernels import KernelPool

    tmp = tmp_path_factory.mktemp("rosetta_pictures")
    with KernelPool():
        raw, _, _ = simulate_raw(DAY + "T00:00:00", 12.0, true_model(DAY), seed=5, rate_hz=0.5)
        io.write_science_csv(raw, tmp / "day.csv")
    return tmp / "day.csv"


def _fit(science: Path, out: Path) -> int:
    return main(["rosetta", "fit", "--science", str(science), "--sensor", "OB",
                 "--estimator", "zero-mean", "--out", str(out)])


def _capture_pictures(monkeypatch) -> list:
    """The pictures the fit hands to ``write_fit_report``, collected as it writes them."""
    drawn = []
    real = rfp.write_fit_report
    monkeypatch.setattr(rfp, "write_fit_report",
                        lambda out, pics, title: (drawn.extend(pics), real(out, pics, title))[1])
    return drawn


def _links(index: Path) -> list[str]:
    return re.findall(r'(?:href|src)="([^"#][^"]*)"', index.read_text())


def test_daily_curve_drawn_is_the_written_file(science, tmp_path, monkeypatch):
    """The first line of each subplot is P(T~) of the daily file (to 1e-6 nT: float64)."""
    import matplotlib.pyplot as plt

    from fluxcal.products.fit_plots import panel_figure

    drawn = _capture_pictures(monkeypatch)
    out = tmp_path / "fit"
    assert _fit(science, out) == 0
    png = out / f"fit_{DAY}_OB.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    targets = _links(out / "index.html")
    assert png.name in targets and DAILY in targets
    for rel in targets:
        assert not rel.startswith(("/", "http")) and (out / unquote(rel)).is_file(), rel
    if browser() is not None:  # a headless browser opens the page from the folder
        seen = browser_check(out / "index.html")
        assert seen["images"] and all(ok for _src, ok in seen["images"]), seen
        assert all(ok for _href, ok in seen["links"]), seen
    p = calib.read_daily_offset_model(out / DAILY).coefficients
    (panel,) = drawn
    lo, hi = panel.fitted_range
    fig = panel_figure(panel)
    try:
        for j, ax in enumerate(fig.axes[:3]):
            t, y = (np.asarray(v, float) for v in ax.get_lines()[0].get_data())
            pick = np.linspace(0, t.size - 1, 9).astype(int)
            np.testing.assert_allclose(y[pick], Polynomial(p[:, j])(t[pick]), atol=1e-6)
            assert ax.collections, "the 1-sigma band is drawn"
    finally:
        plt.close(fig)
    assert t.min() < lo < hi < t.max()  # drawn beyond the data, the data's range shaded


def test_without_matplotlib_the_fit_runs_and_says_so(science, tmp_path, monkeypatch, caplog):
    """No plot extra: the daily file and the index are written, no PNG, one warning line."""
    monkeypatch.setattr(fit_report, "available", lambda extra: False)
    out = tmp_path / "fit"
    assert _fit(science, out) == 0
    assert (out / DAILY).is_file() and (out / "index.html").is_file()
    assert not list(out.glob("*.png"))
    notes = [r.getMessage() for r in caplog.records if "fluxcal[plot]" in r.getMessage()]
    assert len(notes) == 1 and "\n" not in notes[0]
    assert "fluxcal[plot]" in (out / "index.html").read_text()


def test_jump_fit_picture(tmp_path, capsys, monkeypatch):
    """``--jumps``: the interval offsets drawn are the written Appendix B table's."""
    drawn = _capture_pictures(monkeypatch)
    sim = tmp_path / "sim"
    assert main(["simulate", "rosetta", "--out", str(sim), "--hours", "0.1", "--rate", "2"]) == 0
    out = tmp_path / "out"
    assert main(["rosetta", "fit", "--science", str(sim / "RPCMAG_20140801_RAW_OB.csv"),
                 "--sensor", "OB", "--kernels", str(sim / "kernels" / "rosetta_synthetic.tm"),
                 "--calib", str(sim / "calib"), "--jumps", "--estimator", "zero-mean",
                 "--block-seconds", "60", "--max-sigma", "1e9", "--out", str(out)]) == 0
    capsys.readouterr()
    assert (out / "fit_jumps_OB.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert {"fit_jumps_OB.png", calib.JUMPS_FILE} <= set(_links(out / "index.html"))
    table = calib.read_offset_jump_table(out / calib.JUMPS_FILE)
    (panel,) = drawn
    assert [str(t) for t in panel.points.x] == list(table.start_utc)
    np.testing.assert_allclose(panel.points.y, table.jumps["OB"], atol=1e-4)  # table: 4 dp
