import pytest

from fluxcal.geometry.kernels import KernelPool


@pytest.fixture
def pool():
    """Generic kernels (LSK, DE421) loaded for the test, unloaded after."""
    with KernelPool() as p:
        yield p
