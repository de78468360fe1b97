"""The per-run HTML report (``index.html``): content, staging, and that it opens offline.

A headless browser (Chromium's headless shell, when installed: Debian package
``chromium-headless-shell``) loads the page from its folder through ``file://`` and
reports, for every ``<img>``, whether it decoded and, for every link, whether its target
loads; without a browser that part is skipped.  A static check always runs: every
``href``/``src`` is relative and names an existing file, every PNG decodes, no script.
Expected gap and flag values are counted by hand from the constructed series.
"""

from __future__ import annotations

import datetime as dt
import shutil
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

import fluxcal.cli
from fluxcal.cli import build_app, main
from fluxcal.products.atomic import atomic_group, atomic_write_bytes
from fluxcal.products.html_report import (
    REPORT_NAME,
    Quality,
    flag_quality,
    time_quality,
    write_run_report,
)
from fluxcal.runs import registry
from tests.browser import browser, browser_check


class _Refs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.refs: list[tuple[str, str]] = []
        self.scripts = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.scripts += tag == "script"
        for name, value in attrs:
            if name in ("href", "src") and value is not None:
                self.refs.append((tag, value))


def static_check(page: Path) -> list[str]:
    """Return what is wrong with the page's references (empty: every one resolves)."""
    from PIL import Image

    parser = _Refs()
    parser.feed(page.read_text())
    problems = [f"{parser.scripts} script(s)"] if parser.scripts else []
    for _tag, ref in parser.refs:
        if ref.startswith("#"):
            if f'id="{ref[1:]}"' not in page.read_text():
                problems.append(f"anchor {ref}")
            continue
        parts = urlsplit(ref)
        if parts.scheme or parts.netloc or ref.startswith("/"):
            problems.append(f"not relative: {ref}")
            continue
        target = page.parent / unquote(parts.path)
        if not target.exists():
            problems.append(f"missing: {ref}")
        elif target.suffix == ".png":
            with Image.open(target) as im:
                im.load()  # raises on a truncated or corrupt PNG
    return problems


def test_gaps_are_long_intervals_not_rate_changes() -> None:
    # 1-s samples, a 60-s hole, then 0.1-s samples (a faster rate: no gap), a repeat
    seconds = np.r_[0, 1, 2, 3, 63, 64, 65, 65.1, 65.2, 65.3, 65.4, 65.4, 65.5]
    t = np.datetime64("2024-01-01T00:00:00", "ns") + (seconds * 1e9).astype("timedelta64[ns]")
    q = time_quality(t)
    assert (q.samples, q.n_gaps, q.backwards) == (13, 1, 1)
    assert q.gaps == [("2024-01-01T00:00:03.000", "2024-01-01T00:01:03.000", 60.0)]


def test_flag_counts_and_spans() -> None:
    t = np.datetime64("2024-01-01T00:00:00", "s") + np.arange(9).astype("timedelta64[s]")
    q = Quality()
    flag_quality(q, "quality", t, np.array([0, 0, 1, 1, 0, 2, 2, 2, 0]))
    assert q.flags == {"quality": {0: 4, 1: 2, 2: 3}}
    assert q.n_flag_spans == {"quality": 2}
    assert q.flag_spans["quality"] == [
        ("2024-01-01T00:00:02.000", "2024-01-01T00:00:03.000", 1),
        ("2024-01-01T00:00:05.000", "2024-01-01T00:00:07.000", 2)]


def test_report_is_staged_with_the_products(tmp_path: Path) -> None:
    """Inside the run's group the report names the final files and appears with them."""
    out = tmp_path / "out"
    with atomic_group():
        atomic_write_bytes(out / "a.txt", b"validation: ok\n")
        report = write_run_report(out)
        assert report == out / REPORT_NAME and not report.exists()  # staged
        assert not (out / "a.txt").exists()
    page = report.read_text()
    assert 'href="a.txt"' in page and "validation: ok" in page
    assert static_check(report) == []
    with pytest.raises(RuntimeError), atomic_group():  # a failed run: no report either
        atomic_write_bytes(tmp_path / "failed" / "b.txt", b"x")
        write_run_report(tmp_path / "failed")
        raise RuntimeError
    assert not (tmp_path / "failed" / REPORT_NAME).exists()
    with atomic_group():  # a run that wrote nothing lists no older file of the folder
        assert write_run_report(out) is None


@pytest.fixture
def toy(monkeypatch, tmp_path: Path) -> Path:
    from tests.runs.toy_mission import simulate_days

    monkeypatch.setenv(registry.ENV, "tests.runs.toy_mission:MISSION")
    monkeypatch.setattr(fluxcal.cli, "app", build_app())
    simulate_days(tmp_path / "in", [dt.date(2024, 1, 1), dt.date(2024, 1, 2)])
    return tmp_path / "in"


def test_single_run_and_batch_leave_a_report(toy: Path, tmp_path: Path) -> None:
    assert main(["toy", "calibrate", "--input", str(toy / "TOY_20240101.csv"), "--out",
                 str(tmp_path / "one")]) == 0
    page = (tmp_path / "one" / REPORT_NAME).read_text()
    assert 'href="TOY_20240101.cdf"' in page
    assert main(["batch", "toy", "--start", "2024-01-01", "--end", "2024-01-02", "--input",
                 str(toy), "--out", str(tmp_path / "many"), "--scheduler", "serial",
                 "--quiet"]) == 0
    page = (tmp_path / "many" / REPORT_NAME).read_text()
    assert 'href="TOY_20240101.cdf"' in page and 'href="TOY_20240102.cdf"' in page
    assert "2 done" in page and "manifests/" not in page  # the batch report's table
    assert static_check(tmp_path / "many" / REPORT_NAME) == []
    assert str(tmp_path) not in page  # no absolute path


@pytest.fixture(scope="module")
def imap_run(tmp_path_factory) -> Path:
    """The quick IMAP demo: real packets -> L1B CDFs, quicklooks and the report."""
    from fluxcal.missions.imap.demo import run_quick_demo
    from fluxcal.missions.imap.sources import missing_team_files, shared_folder

    if shared_folder() is None:
        pytest.skip(missing_team_files())
    out = tmp_path_factory.mktemp("imap")
    run_quick_demo(out)
    return out


@pytest.mark.slow  # the IMAP run's imports: ~3 s alone, more on a loaded machine
def test_report_summarises_products_and_quality(imap_run: Path) -> None:
    page = (imap_run / REPORT_NAME).read_text()
    for name in ("imap_mag_l1b_norm-mago_20231130_v001.cdf",
                 "imap_mag_ql_norm-mago_20231130.png"):
        assert f'href="{name}"' in page
    assert '<img src="imap_mag_ql_burst-magi_20231025.png"' in page
    # the norm-mode sample: 96 vectors at 2 per second (the packets' own count)
    assert "<td class=\"num\">96</td>" in page and "<td class=\"num\">0.5</td>" in page
    assert "calibration_valid" in page  # what the product records about its calibration
    # and why it is not valid: the ground-test packets (2023) precede the file's validity
    assert "are outside the calibration file" in page and "calibration_validity: " in page
    assert "<script" not in page and "http" not in page.replace("http-equiv", "")


@pytest.mark.slow
def test_every_reference_resolves_offline(imap_run: Path) -> None:
    page = imap_run / REPORT_NAME
    assert static_check(page) == []


@pytest.mark.slow
@pytest.mark.skipif(browser() is None, reason="no headless Chromium on this machine "
                    "(apt-get install chromium-headless-shell)")
def test_browser_loads_every_image_and_link(imap_run: Path, tmp_path: Path) -> None:
    result = browser_check(imap_run / REPORT_NAME)
    # one image per quicklook the run wrote (the team's packets: norm and burst, both sensors)
    pngs = sorted(p.name for p in imap_run.glob("*.png"))
    assert len(pngs) >= 4 and sorted(src for src, _ok in result["images"]) == pngs, result
    assert all(ok for _src, ok in result["images"]), result
    assert len(result["links"]) >= 12 and all(ok for _href, ok in result["links"]), result
    # the check has teeth: a folder with one quicklook missing fails both checks
    broken = tmp_path / "broken"
    shutil.copytree(imap_run, broken)
    (broken / "imap_mag_ql_norm-mago_20231130.png").unlink()
    result = browser_check(broken / REPORT_NAME)
    assert [src for src, ok in result["images"] if not ok] == [
        "imap_mag_ql_norm-mago_20231130.png"]
    # the figure's link, the image and the products table's link
    assert static_check(broken / REPORT_NAME) == [
        "missing: imap_mag_ql_norm-mago_20231130.png"] * 3
