"""The core install: no matplotlib, dask or zarr (issue 25 item 4, `fluxcal.extras`).

Each test runs a fresh interpreter where those packages cannot be imported (a
``sys.modules`` entry of None makes ``import`` raise ImportError), as in a core install.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fluxcal.errors import FluxcalError, MissingExtraError
from fluxcal.extras import EXTRAS, require, require_for_options

ROOT = Path(__file__).resolve().parents[1]
BLOCK = ("import sys\n"
         "for m in ('matplotlib', 'dask', 'distributed', 'zarr'): sys.modules[m] = None\n")


def _core(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BLOCK + code], capture_output=True, text=True,
                          cwd=cwd, timeout=120, env={"PYTHONPATH": str(ROOT / "src"),
                                                     "PATH": "/usr/bin:/bin"})


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return _core(f"from fluxcal.cli import main\nsys.exit(main({args!r}))", cwd)


def test_the_core_modules_import_without_the_extras(tmp_path):
    run = _core("import fluxcal.cli, fluxcal.api, fluxcal.runs.driver, fluxcal.runs.batch\n"
                "import fluxcal.products.writer, fluxcal.missions.messenger.routes\n"
                "import fluxcal.missions.rosetta.products, fluxcal.missions.rosetta.day_edges\n"
                "import fluxcal.missions.imap.chain, fluxcal.missions.imap.products\n"
                "print('ok')", tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr


@pytest.mark.parametrize("args, needs", [
    (["plot", "x.cdf"], "quicklooks and figures needs matplotlib: install fluxcal[plot]"),
    (["compare", "a.cdf", "b.cdf"], "fluxcal compare (its difference plot) needs matplotlib"),
    (["batch", "synthetic", "--start", "2020-01-01", "--end", "2020-01-01", "--input",
      ".", "--out", "out"], "needs dask: install fluxcal[batch]"),
    (["batch", "synthetic", "--start", "2020-01-01", "--end", "2020-01-01", "--input",
      ".", "--out", "out", "--scheduler", "serial", "--quicklook"],
     "--quicklook needs matplotlib: install fluxcal[plot]"),
])
def test_a_command_needing_a_missing_extra_fails_in_one_line(tmp_path, args, needs):
    if args[0] == "plot":
        (tmp_path / "x.cdf").write_bytes(b"")  # typer checks it exists
    run = _cli(args, tmp_path)
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and needs in run.stderr, run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) in ([], ["x.cdf"])  # nothing written


def test_edr2cdr_with_png_is_refused_before_reading_and_names_the_option(tmp_path):
    run = _cli(["messenger", "edr2cdr", "--sci", "no.csv", "--heater", "no.csv",
                "--temperature", "no.csv", "--kernels", "no.tm", "--out", "out"], tmp_path)
    assert run.returncode == 2
    assert run.stderr.strip() == ("fluxcal: error: --formats png (the offset report figure) "
                                  "needs matplotlib: install fluxcal[plot] "
                                  "(pip install 'fluxcal[plot]')")


def test_require_and_the_options_check():
    require("plot", "anything")  # installed here (make test installs every extra)
    with pytest.raises(MissingExtraError, match=r"^--x needs nope_pkg: install fluxcal\[t\]"):
        EXTRAS["t"] = ("nope_pkg",)
        try:
            require("t", "--x")
        finally:
            del EXTRAS["t"]
    assert issubclass(MissingExtraError, FluxcalError) and issubclass(MissingExtraError,
                                                                      ImportError)

    class Options:
        quicklook = False
        formats = ("cdf", "tab")

    require_for_options(Options())
    require_for_options(object())  # options without those fields need nothing
