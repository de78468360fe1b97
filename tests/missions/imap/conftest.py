"""Fixtures of the IMAP MAG tests: the team's files in ../shared/data/imap, the SCLK clock."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import SHARED_DATA

IMAP = SHARED_DATA / "imap"
T010 = IMAP / "validation" / "T010"
T010_L1A = T010 / "MAGScience-normal-(2,2)-8s-20250206-12h05.csv"


@pytest.fixture(scope="session")
def imap_data() -> Path:
    """The IMAP team's test and validation files (../shared/data/imap); skip if absent."""
    if not (IMAP / "mag_l0_test_data.pkts").is_file():
        pytest.skip(f"IMAP MAG data not found at {IMAP}: put the shared data folder beside "
                    "the checkout (../shared/data, see README)")
    return IMAP


@pytest.fixture()
def clock(imap_data: Path) -> Iterator:
    """The IMAP SCLK (-43) of the team's kernel in ../shared, loaded for the test."""
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import SclkKernel

    with KernelPool([imap_data / "imap_sclk_0036.tsc"], fluxcal_frames=False):
        yield SclkKernel.from_pool(-43)
