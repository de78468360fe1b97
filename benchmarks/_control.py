"""The benchmarks' CPU-parallelism control, shared by benchmarks/batch.py and messenger_fit.py.

`control` times a pure-CPU task serially and on the Dask cluster: the ratio is the
parallelism the machine offers right now.  This module is not a package module (the
workers may not have benchmarks/ on their path), so it is pickled by value to the workers.
"""

from __future__ import annotations

import sys
import time

import cloudpickle

cloudpickle.register_pickle_by_value(sys.modules[__name__])


def burn(_: int) -> float:
    """A pure-CPU control task (~0.5 s)."""
    t = time.perf_counter()
    x = 0
    for k in range(8_000_000):
        x += k
    return time.perf_counter() - t


def control(cluster, n: int) -> float:
    """Speed-up of `n` `burn` tasks on `cluster` over running them here one after another."""
    from distributed import Client

    t = time.perf_counter()
    for i in range(n):
        burn(i)
    serial = time.perf_counter() - t
    with Client(cluster) as client:
        t = time.perf_counter()
        client.gather(client.map(burn, range(n), pure=False))
        return serial / (time.perf_counter() - t)
