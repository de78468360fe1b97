"""CPU of the MESSENGER fit's merges on reduced days, and a hash of what they merge to.

    .venv/bin/python benchmarks/messenger_fit_merge.py --days 16 --save /tmp/parts16.pkl
    PYTHONPATH=OTHER/src .venv/bin/python benchmarks/messenger_fit_merge.py \\
        --load /tmp/parts16.pkl                       # the same days, another code

Simulates ``--days`` cruise days at 1 Hz (`flight_sim.simulate_flight`, as
benchmarks/messenger_fit.py does) and reduces each once (`fit_passes.reduce_chunk`, variance
estimator), or loads reduced days saved with ``--save``, then times, ``--repeats``
times, in CPU seconds (``time.process_time``):

- ``fit_passes._merge_all`` of all the days: a pass's merges, in `fit_passes._merge_tree`'s groups;
- the merge tree's tail: the last merge of each level, which on Dask runs after the last
  day has been reduced (docs/decisions/messenger_fit.md entries 53 and 54);
- the top merge alone.

It prints the median and range of each and the sha256 of every number the merge gives
(the same on two codes that merge bit for bit).  Loading a saved file runs pickled
code's classes: load only files you made.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import logging
import os
import pickle
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from fluxcal.missions.messenger import fit_passes  # noqa: E402
from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.fit_cli import _first_time, parse_days  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402


def reduced_days(days: int) -> list[Any]:
    """``days`` simulated days reduced once about the shipped tables."""
    with tempfile.TemporaryDirectory(prefix="fit-merge-") as work:
        run = simulate_flight(Path(work) / "sim", FlightConfig(start="2010-03-01", days=days),
                              truth=False)
        chunks = fit_passes.day_chunks(run.input_dir, parse_days(f"{run.days[0]}:{run.days[-1]}",
                                                          run.input_dir), None)
        base = load_calibration(_first_time(chunks[0]), None)
        return [fit_passes.reduce_chunk(c, base, None, fit_passes.FitSettings(), False, "variance")
                for c in chunks]


def digest(obj: Any, h: Any) -> None:
    """Feed every number (and string) of ``obj`` to the hash ``h``, in a fixed order."""
    if isinstance(obj, np.ndarray):
        h.update(np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, (float, int, str, np.floating, np.integer)):
        h.update(repr(obj).encode())
    elif isinstance(obj, dict):
        for k in sorted(obj, key=str):
            h.update(str(k).encode())
            digest(obj[k], h)
    elif isinstance(obj, (list, tuple)):
        for x in obj:
            digest(x, h)
    elif dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            digest(getattr(obj, f.name), h)


def tail_nodes(parts: list[Any]) -> list[list[Any]]:
    """The inputs of the last merge of each level of `fit_passes._merge_tree`."""
    k, level, out = fit_passes.MERGE_FAN_IN, list(parts), []
    while len(level) > 1:
        if len(level[-k:]) > 1 and (len(level) - 1) % k:
            out.append(level[len(level) - 1 - (len(level) - 1) % k:])
        level = [fit_passes._merge_parts(*level[i:i + k]) for i in range(0, len(level), k)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--days", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--save", type=Path, help="write the reduced days here")
    ap.add_argument("--load", type=Path, help="read reduced days written by --save")
    args = ap.parse_args()
    logging.getLogger("fluxcal").setLevel(logging.ERROR)
    if args.load:
        with args.load.open("rb") as f:
            parts = pickle.load(f)
    else:
        parts = reduced_days(args.days)
    if args.save:
        with args.save.open("wb") as f:
            pickle.dump(parts, f)
    chain = tail_nodes(parts)
    times: dict[str, list[float]] = {"merge_all": [], "tail": [], "top": []}
    for _ in range(args.repeats):
        t = time.process_time()
        merged = fit_passes._merge_all(parts)
        times["merge_all"].append(time.process_time() - t)
        t = time.process_time()
        for node in chain:
            fit_passes._merge_parts(*node)
        times["tail"].append(time.process_time() - t)
        t = time.process_time()
        fit_passes._merge_parts(*chain[-1])
        times["top"].append(time.process_time() - t)
    h = hashlib.sha256()
    digest(merged, h)
    print(f"{len(parts)} days, {len(chain)} merges on the tail, {args.repeats} repeats "
          f"({fit_passes.__file__})")
    for name, x in times.items():
        print(f"  {name:10s} {statistics.median(x):.4f} CPU s ({min(x):.4f}-{max(x):.4f})")
    print(f"  sha256 of the merged statistics {h.hexdigest()}")


if __name__ == "__main__":
    main()
