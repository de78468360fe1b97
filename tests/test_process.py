"""Process-wide settings of a ``fluxcal`` command (`fluxcal.process`; issue 10 item 8).

Each runs in a fresh interpreter: they act on state that lives as long as the process
(glibc's allocator, xarray's module cache).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

GLIBC = sys.platform.startswith("linux") and os.confstr("CS_GNU_LIBC_VERSION") is not None


def _huge_pages_always() -> bool:
    """Transparent huge pages for every mapping (then a 40 MB block faults in 2 MiB steps)."""
    try:
        with open("/sys/kernel/mm/transparent_hugepage/enabled") as fh:
            return "[always]" in fh.read()
    except OSError:
        return False


def _run(code: str, *args: str, **env_changes: str | None) -> list[str]:
    """The words ``code`` prints in a fresh interpreter (an env value None unsets it)."""
    env = dict(os.environ)
    for name, value in env_changes.items():
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True,
                          text=True, check=True, env=env).stdout.split()


#: Page faults of the second allocation and touch of a 40 MB array (a 20 Hz day of
#: float64 3-vectors), after the first one was freed.
REFAULT = """
import resource, sys
from fluxcal.process import malloc_defaults
applied = malloc_defaults() if sys.argv[-1] == "apply" else False
if sys.argv[-1] == "command":  # a `fluxcal` command ran first in this process
    from fluxcal.cli import main
    applied = main(["version"]) == 0
import numpy as np
def touch():
    a = np.empty(5_000_000)
    a[:] = 1.0
    return float(a[-1])
touch()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
touch()
print(applied, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _refaults(apply: bool | str, **env: str | None) -> tuple[str, int]:
    env.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")  # 4 KiB pages: faults = pages touched
    mode = apply if isinstance(apply, str) else "apply" if apply else "keep"
    applied, faults = _run(REFAULT, mode, **env)[-2:]
    return applied, int(faults)


@pytest.mark.skipif(not GLIBC, reason="glibc's mallopt")
def test_heap_reuse_removes_the_page_faults_of_a_reallocated_day_array():
    # 40 MB = 9,766 pages of 4 KiB.  glibc's default maps a block this size afresh each
    # time (above its 32 MB dynamic limit), so every page faults again; with the heap
    # kept, the freed block is reused and (almost) no page faults.
    applied, faults = _refaults(True)
    assert applied == "True"
    assert faults < 500
    _, default_faults = _refaults(False)
    if not _huge_pages_always():  # 4 KiB pages: every page of the new mapping faults
        assert default_faults > 9_000


@pytest.mark.skipif(not GLIBC, reason="glibc's mallopt")
def test_a_fluxcal_command_applies_the_heap_reuse():
    ran, faults = _refaults("command")
    assert ran == "True"
    assert faults < 500


@pytest.mark.skipif(not GLIBC, reason="glibc's mallopt")
@pytest.mark.parametrize("name", ["GLIBC_TUNABLES", "MALLOC_MMAP_THRESHOLD_",
                                  "MALLOC_TRIM_THRESHOLD_"])
def test_a_users_allocator_setting_is_kept(name):
    value = "glibc.malloc.check=0" if name == "GLIBC_TUNABLES" else "33554432"
    applied, _ = _refaults(True, **{name: value})
    assert applied == "False"
