"""Fixtures shared by every test folder: paths to ../shared and synthetic kernel sets."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: Real public files (kernels) beside the checkout, as in CI (../shared/data/MANIFEST.md).
SHARED_DATA = REPO.parent / "shared" / "data"
SHARED_KERNELS = SHARED_DATA / "kernels"


@pytest.fixture(scope="session")
def shared_kernels() -> Path:
    """Folder of the real MESSENGER/Rosetta kernels (CI has ../shared beside the checkout).

    Without it the tests that need real kernels are skipped with one reason, not errors.
    """
    if not SHARED_KERNELS.is_dir():
        pytest.skip(f"real kernels not found at {SHARED_KERNELS}: put the shared data folder "
                    "beside the checkout (../shared/data, see README)")
    return SHARED_KERNELS


@pytest.fixture(scope="session")
def messenger_kernels(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Meta-kernel of a synthetic MESSENGER-like day (2012-06-01), +Y sunward 08:20-09:26."""
    from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels

    folder = tmp_path_factory.mktemp("msgr_kernels")
    return write_messenger_like_kernels(
        folder, "2012-06-01T00:00:00", 86400.0, plus_y_sunward=[(30000.0, 34000.0)]
    )


@pytest.fixture(scope="session")
def rosetta_kernels(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Meta-kernel of a synthetic Rosetta-like day (2014-09-01) escorting comet 67P."""
    from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels

    folder = tmp_path_factory.mktemp("ros_kernels")
    return write_rosetta_like_kernels(folder, "2014-09-01T00:00:00", 86400.0)


@pytest.fixture(autouse=True)
def _release_cached_worker_kernels():
    """Unload kernels a day task called in-process cached for its worker (test isolation)."""
    yield
    from fluxcal.runs.batch import release_worker_kernel_pool

    release_worker_kernel_pool()
