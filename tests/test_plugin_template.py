"""The plugin template installed by pip as an out-of-tree package, run through the CLI.

``pip install --no-index --no-deps --no-build-isolation --target`` of
templates/fluxcal-plugin-groundtest (offline: its build backend, setuptools >= 70.1, is
the one of this environment; the test extra requires it).  A fresh process with the
target folder on its path finds the mission by its entry point alone (no
``FLUXCAL_MISSIONS``) and runs ``calibrate`` with ``--config`` and the HTML report,
``batch``, ``plot``, ``compare`` and ``provenance`` on its products.
"""

from __future__ import annotations

import importlib.metadata
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = ROOT / "templates" / "fluxcal-plugin-groundtest"


def _can_build_offline() -> bool:
    try:
        major, minor = (int(x) for x in importlib.metadata.version("setuptools").split(".")[:2])
    except importlib.metadata.PackageNotFoundError:
        return False
    return (major, minor) >= (70, 1)


SCRIPT = textwrap.dedent("""
    import datetime as dt, sys
    from pathlib import Path
    from fluxcal.cli import main
    from fluxcal_groundtest.simulate import simulate_days

    work = Path(sys.argv[1])
    simulate_days(work / "in", [dt.date(2024, 3, 12)])
    (work / "run.toml").write_text('formats = ["cdf"]\\nquicklook = true\\n')
    csv = str(work / "in" / "GT_20240312.csv")
    runs = [
        ["groundtest", "calibrate", "--input", csv, "--out", str(work / "one"),
         "--config", str(work / "run.toml")],
        ["batch", "groundtest", "--start", "2024-03-12", "--end", "2024-03-13", "--input",
         str(work / "in"), "--out", str(work / "many"), "--scheduler", "serial", "--quiet",
         "--formats", "cdf,tab"],
        ["plot", str(work / "many" / "GROUNDTEST_20240313.TAB"), "--out", str(work / "png")],
        ["compare", str(work / "one" / "GROUNDTEST_20240313.cdf"),
         str(work / "many" / "GROUNDTEST_20240313.cdf"), "--out", str(work / "cmp")],
        ["provenance", str(work / "one" / "GROUNDTEST_20240312.cdf")],
    ]
    for args in runs:
        code = main(args)
        print("EXIT", args[0], code, flush=True)
""")


@pytest.mark.skipif(not _can_build_offline(),
                    reason="setuptools >= 70.1 (the test extra) is needed to build the "
                           "template offline")
def test_installed_template_runs_through_the_cli(tmp_path: Path) -> None:
    source = tmp_path / "src"
    shutil.copytree(TEMPLATE, source, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    site = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-index",
                          "--no-deps", "--no-build-isolation", "--target", str(site),
                          str(source)], capture_output=True, text=True, timeout=120)
    assert pip.returncode == 0, pip.stderr
    assert (list(site.glob("fluxcal_plugin_groundtest-*.dist-info/entry_points.txt"))[0]
            .read_text().count("groundtest = fluxcal_groundtest.mission:MISSION") == 1)
    env = {k: v for k, v in os.environ.items() if k != "FLUXCAL_MISSIONS"}
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(ROOT / "src")])
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "work")], cwd=tmp_path,
                          capture_output=True, text=True, env=env, timeout=180)
    assert done.returncode == 0, done.stderr
    exits = [line.split()[1:] for line in done.stdout.splitlines() if line.startswith("EXIT")]
    assert exits == [[c, "0"] for c in ("groundtest", "batch", "plot", "compare",
                                        "provenance")], done.stdout + done.stderr
    work = tmp_path / "work"
    one = sorted(p.name for p in (work / "one").iterdir())
    assert one == ["GROUNDTEST_20240312.cdf", "GROUNDTEST_20240313.cdf",
                   "GROUNDTEST_QL_20240312.png", "GROUNDTEST_QL_20240313.png", "index.html"]
    assert "GROUNDTEST_20240313.TAB" in (work / "many" / "index.html").read_text()
    assert list((work / "png").glob("GROUNDTEST_20240313*.png"))
    assert "groundtest_calib_v1.txt" in done.stdout and "GT_20240312.csv" in done.stdout
