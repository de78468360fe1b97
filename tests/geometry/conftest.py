"""The geometry tests' shared fixture: the MESSENGER-like kernels loaded (per module)."""

import pytest

from fluxcal.geometry.kernels import KernelPool


@pytest.fixture(scope="module")
def msgr_pool(messenger_kernels):
    """The synthetic MESSENGER-like kernel set of tests/conftest.py, loaded for a module."""
    with KernelPool([messenger_kernels]) as pool:
        yield pool
