"""The package as a user installs it: version from the tags, the wheel in a fresh venv.

Issue 25 item 4.  The version tests run ``python -m setuptools_scm`` on a clone without
tags and on a tree without git metadata (seconds).  The wheel test (slow: it installs
the core dependencies from the package registry) is `tools/wheel_check.py`, the same
as ``make wheel-check``.
"""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import wheel_check  # noqa: E402

needs_scm = pytest.mark.skipif(importlib.util.find_spec("setuptools_scm") is None,
                               reason="setuptools-scm is not installed (the test extra)")
needs_git = pytest.mark.skipif(not (ROOT / ".git").exists(),
                               reason="not a git checkout: nothing to take a version from")


def _scm_version(tree: Path) -> str:
    run = subprocess.run([sys.executable, "-m", "setuptools_scm"], cwd=tree,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    return run.stdout.strip().splitlines()[-1]


@needs_scm
@needs_git
def test_a_clone_without_tags_gets_a_dev_version(tmp_path):
    src = tmp_path / "src"
    subprocess.run(["git", "clone", "--quiet", "--no-tags", str(ROOT), str(src)], check=True)
    commits = int(subprocess.run(["git", "rev-list", "--count", "HEAD"], cwd=src, check=True,
                                 capture_output=True, text=True).stdout)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=src, check=True,
                          capture_output=True, text=True).stdout.strip()
    version = _scm_version(src)
    # no tag: 0.1.dev<number of commits>+g<hash> (PEP 440; sorts before 0.1.0)
    assert re.fullmatch(rf"0\.1\.dev{commits}\+g{head[:7]}\w*", version), version
    subprocess.run(["git", "tag", "v0.1.0"], cwd=src, check=True)
    assert _scm_version(src) == "0.1.0"  # a release is a tag


@needs_scm
@needs_git
def test_a_tree_without_git_gets_the_fallback_version(tmp_path):
    archive = tmp_path / "src.tar"
    subprocess.run(["git", "archive", "--output", str(archive), "HEAD", "pyproject.toml"],
                   cwd=ROOT, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(tmp_path / "src", filter="data")
    assert _scm_version(tmp_path / "src") == "0.1.dev0"


def test_the_installed_version_is_the_one_fluxcal_reports():
    from importlib.metadata import PackageNotFoundError, version

    from fluxcal.version import software_version

    try:
        installed = version("fluxcal")
    except PackageNotFoundError:
        pytest.skip("fluxcal is not installed (a source tree on PYTHONPATH)")
    assert software_version() == installed
    run = subprocess.run([sys.executable, "-m", "fluxcal.cli", "--version"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and installed in run.stdout


@pytest.mark.slow
@needs_git
def test_the_wheel_installs_without_extras_and_runs(tmp_path):
    if importlib.util.find_spec("build") is None:
        pytest.skip("the 'build' package is not installed (the test extra)")
    if not wheel_check.registry_reachable():
        pytest.skip("the package registry cannot be reached: the wheel's dependencies "
                    "cannot be installed in a fresh venv")
    wheel = wheel_check.build(wheel_check.clean_clone(tmp_path), tmp_path)
    assert re.fullmatch(r"fluxcal-0\.1\.\w+(\+\w+(\.\w+)*)?-py3-none-any\.whl", wheel.name)
    binary = wheel_check.install(wheel, tmp_path)
    seen = wheel_check.run_checks(binary, tmp_path, wheel)
    assert "messenger_mag_mso-sci_" in seen["cdf"]
    assert seen["refusal"].startswith("fluxcal: error: --quicklook needs matplotlib")
    assert wheel_check.site_packages_size(binary) < 900 * 2**20
