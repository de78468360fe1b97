"""Pictures and ``index.html`` of ``fluxcal messenger fit`` (issue 34, item 6).

The law drawn is compared with the law of the written table, evaluated here from the CSV
by eq. 3a/3b (the larger of the two lines ``A0 + B0 T`` and ``A1 + B1 T``) with no
fluxcal code; the figure's line data are read back from matplotlib.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.missions.messenger import fit_pictures as mfp
from tests.missions.messenger._fit_tables import applied_law

pytest.importorskip("matplotlib")

START = "2012-06-01T00:00:00"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A zero-mean fit of 6 h of the demo's training streams through the command; the
    pictures drawn.

    One pass without the guards, written as a study (a converged fit of these streams
    takes ~12 passes, 4 min on the 2-core machine; the pictures draw what any pass
    returns, and tests/missions/messenger/test_fit.py runs the converged command).
    """
    from fluxcal.missions.messenger import fit_passes, fit_write
    from fluxcal.missions.messenger.fit_demo import perturbed_folder, simulate_training

    tmp = tmp_path_factory.mktemp("fit_pictures")
    files = simulate_training(tmp, perturbed_folder(tmp / "truth"), START, 0.25,
                              field="quiet", sigma_nt=0.1)
    drawn = []
    real = mfp.write_fit_report

    def spy(out, pictures, title):
        drawn.extend(pictures)
        return real(out, pictures, title)

    mp = pytest.MonkeyPatch()
    mp.setattr(mfp, "write_fit_report", spy)
    real_fit, real_write = fit_passes.fit_days, fit_write.write_calibration_folder
    mp.setattr(fit_passes, "fit_days",
               lambda *a, **k: real_fit(*a, **{**k, "passes": 1, "guard": False}))
    mp.setattr(fit_write, "write_calibration_folder",
               lambda *a, **k: real_write(*a, **{**k, "study": True}))
    try:
        assert main(["messenger", "fit", "--sci", str(files["science"]), "--heater",
                     str(files["heater"]), "--temperature", str(files["temperature"]),
                     "--kernels", str(files["kernels"]), "--estimator", "zero-mean",
                     "--out", str(tmp / "fitted")]) == 0
    finally:
        mp.undo()
    return tmp / "fitted", {p.name: p for p in drawn}


def links(index: Path) -> list[str]:
    return re.findall(r'(?:href|src)="([^"#][^"]*)"', index.read_text())


def test_pictures_and_index_written(fitted):
    out, drawn = fitted
    for name in ("fit_offsets_temperature", "fit_offsets_duty_cycle", "fit_relaxation",
                 "fit_pulls"):
        assert name in drawn
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "index.html").read_text()
    assert "fit_report.txt" in page and "offsets_temperature_v2.csv" in page
    assert "stated 1-sigma band" in page  # the caption says what the picture shows
    targets = links(out / "index.html")
    assert {f"{n}.png" for n in drawn} <= set(targets)
    for rel in targets:  # every link relative and resolving inside the folder
        assert not rel.startswith(("/", "http")) and (out / unquote(rel)).is_file(), rel


def _table_law(out: Path, t: np.ndarray) -> np.ndarray:
    rows = [r for r in csv.DictReader(line for line in (out / "offsets_temperature_v2.csv")
                                      .read_text().splitlines() if not line.startswith("#"))]
    # as the table applies it (eq. 3a, 3b, 4), not the larger line
    return applied_law(np.array([[float(r[k]) for k in ("A0", "B0", "A1", "B1")]
                                 for r in rows]), t)


def test_drawn_law_is_the_written_table(fitted):
    """The first line of each axis's subplot is the law of offsets_temperature_v2.csv.

    Tolerance 1e-3 counts: the table holds A and B to 6 decimals (<= 5e-5 counts at 50 C).
    """
    import matplotlib.pyplot as plt

    from fluxcal.products.fit_plots import panel_figure

    out, drawn = fitted
    fig = panel_figure(drawn["fit_offsets_temperature"])
    try:
        for j, ax in enumerate(fig.axes[:3]):
            x, y = (np.asarray(v, float) for v in ax.get_lines()[0].get_data())
            pick = np.linspace(0, x.size - 1, 7).astype(int)
            np.testing.assert_allclose(y[pick], _table_law(out, x[pick])[:, j], atol=1e-3)
            assert ax.collections, "the 1-sigma band is drawn"
    finally:
        plt.close(fig)
    band = drawn["fit_offsets_temperature"].curve.band
    assert np.all(np.isfinite(band)) and np.all(band > 0)


def test_bin_model_of_a_linear_stretch_is_the_law_at_its_mean_temperature(fitted):
    """The residuals are about the law averaged over each bin's temperatures; on a bin
    that holds no break that average is the law at the bin's mean temperature (a line's
    mean), evaluated here from the table (1e-3 counts as above)."""
    out, drawn = fitted
    pts = drawn["fit_offsets_temperature"].points
    rows = [r for r in csv.DictReader(line for line in (out / "offsets_temperature_v2.csv")
                                      .read_text().splitlines() if not line.startswith("#"))]
    breaks = np.array([float(r["Tm_c"]) for r in rows])
    clear = np.all(np.abs(pts.x[:, None] - breaks[None, :]) > 10.0, axis=1)
    assert clear.sum() >= 5
    np.testing.assert_allclose(pts.model[clear], _table_law(out, pts.x[clear]), atol=1e-3)


def test_rejected_intervals_on_a_utc_time_line():
    """ET 0 (J2000 TDB) is 2000-01-01T11:58:55.816 UTC (TT - UTC = 64.184 s in 2000)."""
    from types import SimpleNamespace

    from fluxcal.missions.messenger.fit_variance import VarianceStatistics

    v = VarianceStatistics(interval_start=np.array([0.0, 900.0, 1800.0]),
                           reason=np.array(["", "compressive", "small_fluctuations"]))
    rej = mfp._rejections(SimpleNamespace(variance=v))
    expect = np.datetime64("2000-01-01T11:58:55.816", "ns") + np.array(
        [0, 900, 1800]).astype("m8[s]")
    assert np.all(np.abs((rej.start - expect).astype(np.int64)) < 2_000_000)  # 2 ms: TDB-TT
    assert list(rej.reason) == ["", "compressive", "small_fluctuations"]


def test_variance_fit_without_bin_means_draws_what_it_has(tmp_path):
    """A variance fit from normal equations alone (no bin means, no epoch): the law with
    its band over the fitted range, the intervals' time line; nothing fails on the empty
    statistics."""
    from fluxcal.missions.messenger.calibration_data import load_calibration

    from .test_fit_variance import N_PARAMETERS, _variance_result

    res = _variance_result(load_calibration(START), np.zeros(N_PARAMETERS))
    res.variance.reason = res.variance.reason.astype("<U24")
    res.variance.reason[::3] = "compressive"
    res.variance.interval_start = np.arange(res.variance.reason.size) * 900.0
    (tmp_path / "fit_report.txt").write_text("a fit\n")
    written, note = mfp.write_fit_pictures(res, tmp_path)
    names = {p.name for p in written}
    assert note == "" and {"fit_offsets_temperature.png", "fit_intervals.png",
                           "index.html"} <= names
    assert "fit_pulls.png" not in names  # the bin means are not what a variance fit measured
    temp = {p.name: p for p in mfp.pictures(res)}["fit_offsets_temperature"]
    assert temp.fitted_range == ((-60.0, 40.0),) and temp.points is None  # none measured
    assert temp.curve.x.min() < -60.0 and temp.curve.x.max() > 40.0


def test_band_is_the_results_stated_law_error_when_it_has_one():
    """A result stating its own law error (break included) is drawn with that band."""
    from types import SimpleNamespace

    t = np.array([-20.0, 0.0, 30.0])
    own = SimpleNamespace(law_error=lambda x: np.outer(np.abs(x) + 1.0, [1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(mfp.law_band(own, t), np.outer(np.abs(t) + 1.0, [1, 2, 3]))
