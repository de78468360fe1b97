"""The demo's top ``index.html`` links every part's product files; a cold start says so.

Before, its "Products" listed the parts' reports and quicklooks only: no CDF, table or
text report could be reached from the page a newcomer opens first.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit
from PIL import Image

from fluxcal.runs import demo
from fluxcal.runs.contract import DemoPart
from fluxcal.runs.display_cli import COMPILE_NOTICE
from tests.products.test_html_report import static_check


def test_top_index_links_every_product_file_of_each_part(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    products = out / "mission_a" / "products"
    products.mkdir(parents=True)
    (products / "index.html").write_text("<!DOCTYPE html><title>a</title>")
    (products / "a_20240101_v01.cdf").write_bytes(b"not read: linked only")
    (products / "A_20240101.TAB").write_text("1,2,3\n")
    (products / "A_20240101.LBL").write_text("PDS_VERSION_ID = PDS3\nEND\n")
    (products / "offsets.txt").write_text("offsets report\n")
    Image.new("RGB", (4, 4)).save(products / "a_20240101.png")
    inputs = out / "mission_a" / "simulation"  # the simulated inputs: no report, no product
    inputs.mkdir()
    (inputs / "science.csv").write_text("t,x\n")
    imap = out / "mission_b"
    imap.mkdir()
    (imap / "index.html").write_text("<!DOCTYPE html><title>b</title>")
    (imap / "b_l1b_20231025_v001.cdf").write_bytes(b"x")
    page = demo._overview(out)
    assert page == out / "index.html"
    text = page.read_text()
    for name in ("mission_a/products/index.html", "mission_a/products/a_20240101_v01.cdf",
                 "mission_a/products/A_20240101.TAB", "mission_a/products/A_20240101.LBL",
                 "mission_a/products/offsets.txt", "mission_a/products/a_20240101.png",
                 "mission_b/index.html", "mission_b/b_l1b_20231025_v001.cdf"):
        assert f'href="{name}"' in text, name
    assert "science.csv" not in text
    assert "<p>8 files.</p>" in text  # 2 reports + 6 product files
    assert static_check(page) == []  # every link resolves, relative to the page


def compiling_part(out: Path) -> str:
    """A demo part that compiles two fresh numba functions (a cold cache)."""
    njit(lambda x: x + 1)(np.int64(1))
    njit(lambda x: x * 2)(np.int64(1))
    return "compiled"


def test_demo_says_once_that_it_compiles(tmp_path: Path, monkeypatch, capsys) -> None:
    part = DemoPart("compiling", "tests.runs.test_demo_overview:compiling_part", "c", 1, True)
    monkeypatch.setattr(demo, "parts", lambda full: [part, part])
    demo.run_demo(tmp_path / "demo")
    captured = capsys.readouterr()
    assert captured.err.count(COMPILE_NOTICE) == 1  # two parts, four compilations: once
    assert captured.out.count("compiled") == 2
