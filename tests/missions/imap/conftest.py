"""Fixtures of the IMAP MAG tests: the team's files in ../shared/data/imap, the SCLK clock.

fluxcal ships none of the IMAP MAG team's files; every test that needs one reads it from
``../shared/data/imap/`` beside the checkout and is skipped, saying so, without it.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import SHARED_DATA

IMAP = SHARED_DATA / "imap"
TEAM = IMAP / "team"
MANIFEST = TEAM / "MANIFEST.tsv"
T010 = IMAP / "validation" / "T010"
T010_L1A = T010 / "MAGScience-normal-(2,2)-8s-20250206-12h05.csv"
XTCE = IMAP / "MAG_SCI_COMBINED.xml"
SCLK = IMAP / "imap_sclk_0036.tsc"
CALIBRATION = IMAP / "imap_calibration_mag_20240229_v01.cdf"
MISSING = (f"IMAP MAG team data not found at {IMAP}: put the shared data folder beside the "
           "checkout (../shared/data, see README); fluxcal ships none of the team's files")


def team_cases(level: str) -> list:
    """The team's validation cases of ``level`` (``L1a``, ``L1b``) listed in MANIFEST.tsv.

    Without the shared folder: one parameter that is skipped, saying why.
    """
    if not MANIFEST.is_file():
        return [pytest.param(None, marks=pytest.mark.skip(reason=MISSING))]
    lines = MANIFEST.read_text().splitlines()
    return sorted({line.split("/")[1] for line in lines if line.startswith(f"{level}/")})


@pytest.fixture(scope="session")
def imap_data() -> Path:
    """The IMAP team's test and validation files (../shared/data/imap); skip if absent."""
    if not (IMAP / "mag_l0_test_data.pkts").is_file() or not XTCE.is_file():
        pytest.skip(MISSING)
    return IMAP


@pytest.fixture()
def clock(imap_data: Path) -> Iterator:
    """The IMAP SCLK (-43) of the team's kernel in ../shared, loaded for the test."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel

    with KernelPool([SCLK], fluxcal_frames=False):
        yield SclkKernel.from_pool(-43)
