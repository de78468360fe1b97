"""Process-wide settings a ``fluxcal`` command makes before and after its imports.

A command is one short process that allocates hundreds of day-long arrays (40 MB each
at 20 Hz) and imports a large scientific stack once.  The defaults of numpy, glibc's
allocator are tuned for other programs; `fluxcal.cli.main` applies the two settings
below, each kept out of the way of a user who chose otherwise and each a
no-op where it does not apply.  They change no number in any product (the benchmark
products are byte-identical with and without them; docs/decisions/products.md,
decisions 41 and 47).  Decision 48 (keeping xarray from importing ``dask.array`` through
an entry in xarray's private duck-array cache) is withdrawn: fluxcal does not reach into
another library's internals (docs/decisions/runs.md, R5).

This module imports nothing heavy: ``import fluxcal.cli`` must load no numpy.
"""

from __future__ import annotations

import ctypes
import os
import sys

#: numpy's import-time switch for ``madvise(MADV_HUGEPAGE)`` on large arrays (numpy
#: reference, "Global state"); a user's own setting is kept.
HUGEPAGE_ENV = "NUMPY_MADVISE_HUGEPAGE"

#: glibc ``mallopt`` parameters (``<malloc.h>``) and the environment variables by which
#: a user sets them at start-up (glibc manual, "Memory Allocation Tunables").
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
MALLOC_ENV = ("GLIBC_TUNABLES", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")

#: Blocks up to this size come from the heap, and this much free memory at its top is
#: kept for reuse (1 GiB: above any one array of a 20 Hz day, so none is mapped anew).
HEAP_REUSE_BYTES = 1 << 30


def numpy_allocation_defaults() -> None:
    """Ask numpy not to advise transparent huge pages, unless the user chose otherwise.

    With the common Linux setting ``transparent_hugepage/defrag = madvise`` the kernel
    compacts memory synchronously on the first touch of every advised array. A
    command allocates hundreds of short-lived day-long arrays (40 MB each at 20 Hz),
    and on the benchmark machine the compaction cost more than the huge pages saved:
    the system time of a CSV -> CDF ``edr2cdr`` of a 20 Hz day went from 1.8 s to 1.1 s,
    the wall time by 0.5-0.9 s, the bytes written unchanged (docs/decisions/products.md,
    decision 41). The switch is read when numpy is imported, so this runs first in
    `fluxcal.cli.main` (``import fluxcal.cli`` loads no numpy); a process that already
    imported numpy, or set ``NUMPY_MADVISE_HUGEPAGE`` itself, keeps its setting. Child
    processes (Dask workers of ``batch``) inherit it through the environment.
    """
    if "numpy" not in sys.modules:
        os.environ.setdefault(HUGEPAGE_ENV, "0")


def malloc_defaults() -> bool:
    """Let glibc reuse freed day-long arrays instead of unmapping them; return if set.

    glibc serves blocks above a threshold (at most 32 MB, adjusted as blocks are freed)
    with a fresh ``mmap`` and returns them to the system on ``free``; the next array of
    the same size is mapped again and each of its pages faulted in and zeroed by the
    kernel.  With blocks up to `HEAP_REUSE_BYTES` taken from the heap and that much
    free memory kept at its top, freed arrays are reused: for a CSV -> CDF ``edr2cdr``
    of a 20 Hz day, page faults 513k -> 169k, system time 2.1-3.1 s -> 0.8-1.5 s and
    peak memory 727 -> 777 MB (docs/decisions/products.md, decision 47).

    Applied only on Linux with glibc's ``mallopt``, and not when the user set glibc's
    own allocator variables (`MALLOC_ENV`), which glibc read at start-up.  Returns
    whether both settings were accepted.
    """
    if not sys.platform.startswith("linux") or any(name in os.environ for name in MALLOC_ENV):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt symbol to call)
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, HEAP_REUSE_BYTES)
                and mallopt(M_TRIM_THRESHOLD, HEAP_REUSE_BYTES))
