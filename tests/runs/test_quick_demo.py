"""``fluxcal demo`` (``make demo``): each mission's calibrated product, quicklook and report.

Issue 25 item 7: the first run a newcomer makes shows, for MESSENGER, Rosetta and IMAP, a
calibrated CDF, a quicklook and the run's HTML report, and an overview page linking them;
the full tour (fits, batch, cleaning, archive) is ``--full`` and is not run here.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fluxcal.cli import main
from tests.products.test_html_report import static_check


@pytest.mark.slow  # ~20 s of CPU: the three missions' pipelines on short inputs
def test_quick_demo_shows_a_product_quicklook_and_report_per_mission(tmp_path: Path,
                                                                     capsys) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    from fluxcal.missions.imap.sources import shared_folder

    folders = ["messenger/products", "rosetta/products"]
    if shared_folder() is not None:  # the IMAP team's files beside the checkout
        folders.append("imap")
    else:
        assert "IMAP MAG part skipped: the IMAP MAG team's files" in text
    for folder in folders:
        report = out / folder / "index.html"
        assert report.exists(), folder
        assert list(report.parent.glob("*.cdf")) and list(report.parent.glob("*.png")), folder
        assert static_check(report) == [], folder
        top = (out / "index.html").read_text()
        assert f'href="{folder}/index.html"' in top
        for product in report.parent.glob("*.cdf"):  # the product files too (issue 31)
            assert f'href="{folder}/{product.name}"' in top, product.name
    assert static_check(out / "index.html") == []
    assert not (out / "batch").exists() and not (out / "messenger_fit").exists()
    assert "fluxcal demo --full" in text
    # the accuracy lines of the chains (recovered - true), as in the full tour
    assert "fine_rms" in text and "LEVEL_C recovered - true rms" in text
