"""Helpers of the IMAP L1C/L2/team-layout tests: the team's files, the team's package.

The team's own package (``imap-processing``, the outside oracle) is not a dependency of
fluxcal: the tests that run it look for a Python that imports it (``FLUXCAL_TEAM_PYTHON``,
else ``/work/venv-imap/bin/python``, else this interpreter) and skip without one.  Its
code runs in that interpreter as a script written here; results come back as ``.npz``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SHARED_DATA

TEAM = SHARED_DATA / "imap" / "team"
LSK = SHARED_DATA / "kernels" / "generic" / "naif0012.tls"


def team_dir() -> Path:
    """The team's validation files (../shared/data/imap/team); skip when absent."""
    if not (TEAM / "MANIFEST.tsv").is_file():
        pytest.skip(f"the IMAP team's files are not at {TEAM}: put the shared data folder "
                    "beside the checkout (../shared/data)")
    return TEAM


def team_python() -> str:
    """A Python interpreter that imports ``imap_processing``; skip when there is none."""
    candidates = [os.environ.get("FLUXCAL_TEAM_PYTHON", ""), "/work/venv-imap/bin/python",
                  sys.executable]
    for exe in filter(None, candidates):
        if not Path(exe).is_file():
            continue
        probe = subprocess.run([exe, "-c", "import imap_processing.mag.l1c.mag_l1c"],
                               capture_output=True, timeout=120)
        if probe.returncode == 0:
            return exe
    pytest.skip("the IMAP team's package (imap-processing) is not installed: set "
                "FLUXCAL_TEAM_PYTHON to a Python that has it")
    raise AssertionError  # unreachable


def run_team(script: str, *args: str | Path) -> dict[str, np.ndarray]:
    """Run ``script`` (its last argument is the .npz it writes) in the team's Python."""
    exe = team_python()
    out = Path(str(args[-1]))
    prelude = f"import spiceypy\nspiceypy.furnsh({str(LSK)!r})\n"
    res = subprocess.run([exe, "-c", prelude + script, *map(str, args)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    with np.load(out) as npz:
        return {k: npz[k] for k in npz.files}
