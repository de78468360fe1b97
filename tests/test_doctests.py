"""Every docstring example of the library runs (issue 25).

The modules are found by scanning ``src/fluxcal`` for ``>>>``, so a new example is
collected without touching this file. An example that needs files the reader supplies
(kernels, an archive) is marked ``# doctest: +SKIP`` in its docstring.
"""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
MODULES = sorted(
    ".".join(p.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__")
    for p in (SRC / "fluxcal").rglob("*.py")
    if ">>>" in p.read_text()
)


def test_the_scan_finds_the_modules_that_ran_before():
    # the three modules CI ran before this file (tests/products/test_docs.py and
    # tests/calibration/test_constrained_fits.py)
    assert {"fluxcal.products", "fluxcal.calibration.binned_stats",
            "fluxcal.calibration.constrained_fits"} <= set(MODULES)
    assert len(MODULES) >= 10


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an example that writes files writes them here
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE
                             | doctest.ELLIPSIS, report=True)
    assert result.failed == 0, f"{name}: {result.failed} of {result.attempted} failed"
