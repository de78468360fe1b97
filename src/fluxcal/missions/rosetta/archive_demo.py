"""Rosetta round trip through archive-style files (issue 14, ``make demo``).

simulate -> archive-style EDITED raw products -> calibrate -> archive-style CALIBRATED /
RESAMPLED tables -> `fluxcal.products.compare.compare` against (a) the products of the
same simulation calibrated from the CSV layout (must agree exactly) and (b) the truth
the simulator started from.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1 (EDITED raw), 4.2-4.8 (levels).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import xarray as xr

#: The level compared and the truth variable it recovers (simulate.write_truth_csv):
#: LEVEL_C in ECLIPJ2000, the end of the chain (A and B are byte-compared only; reading
#: a fluxcal table label costs ~0.5 s of pvl parsing, so the demo reads few of them).
LEVEL, TRUTH = "C", "b_ref"


def _level_tables(folder: Path, level: str, sensor: str) -> xr.Dataset:
    """Every mode table of one calibrated level and sensor, read back and joined in time.

    Read as archived products are (`fluxcal.archive.products.read_product`).
    """
    from fluxcal.archive.products import read_product
    from fluxcal.missions.rosetta.archive_products import READER

    parts = [read_product(p.with_suffix(".LBL"), {"rosetta": READER})
             for p in sorted(folder.glob(f"RPCMAG*_CL{level}_{sensor}_M*.TAB"))]
    joined = xr.concat(parts, dim="time", data_vars="minimal", coords="minimal",
                       compat="override", combine_attrs="override")
    return joined.isel(time=np.argsort(joined["epoch"].values, kind="stable"))


def _truth(path: Path, name: str) -> xr.Dataset:
    from fluxcal.missions.rosetta.simulate import read_truth_csv

    t = read_truth_csv(path)
    good = t["good"]
    return xr.Dataset({"b": (("time", "component"), t[name][good], {"units": "nT"})},
                      coords={"epoch": ("time", t["epoch"][good]),
                              "component": ["x", "y", "z"]})


def run_demo(out: Path, *, hours: float = 0.25) -> str:
    """Run the archive round trip in ``out`` and return a few summary lines.

    Returns
    -------
    str
        Files written, whether the two input layouts gave byte-identical tables, and the
        `compare` statistics (archive route - CSV route; archive route - truth).
    """
    from fluxcal.missions.rosetta.archive import find_products
    from fluxcal.missions.rosetta.options import RosettaOptions
    from fluxcal.missions.rosetta.routes import run_files
    from fluxcal.missions.rosetta.simulate import write_simulation
    from fluxcal.products.compare import compare

    t0 = time.perf_counter()
    out = Path(out)
    paths = write_simulation(out / "raw", hours=hours, layouts=("files", "archive"))
    edited = paths["archive"]
    n_raw = len(find_products(edited))
    lines = [f"Rosetta RPC-MAG archive round trip: {hours:g} h simulated at 20 Hz as {n_raw} "
             f"EDITED products (labels + tables) in {edited}"]
    routes = {"archive": {"OB": edited, "IB": edited, "hk": edited},
              "csv": {"OB": paths["science_OB"], "IB": paths["science_IB"], "hk": paths["hk"]}}
    for route, src in routes.items():
        for sensor in ("OB", "IB"):
            run_files(src[sensor], sensor, out / f"products_{route}",
                      hk=src["hk"] if sensor == "OB" else None, kernels=paths["kernels"],
                      options=RosettaOptions(calib=paths["calib"], levels=tuple("ABCEFG"),
                                             frame="ECLIPJ2000", formats=("tab",)))
    tabs = {r: {p.name: p.read_bytes() for p in (out / f"products_{r}").glob("*.TAB")}
            for r in routes}
    same = sum(tabs["archive"].get(k) == v for k, v in tabs["csv"].items())
    lines.append(f"  {len(tabs['archive'])} CALIBRATED/RESAMPLED tables from the archive "
                 f"route; {same} of {len(tabs['csv'])} byte-identical to the CSV route's")
    for sensor in ("OB", "IB"):
        a = _level_tables(out / "products_archive", LEVEL, sensor)
        b = _level_tables(out / "products_csv", LEVEL, sensor)
        same_route = compare(a, b, 0, path_a="archive", path_b="csv")
        # truth at the event times; the tables' TIME.UTC is rounded to 1 us: 1 ms tolerance
        truth = compare(a, _truth(paths[f"truth_{sensor}"], TRUTH), 1_000_000,
                        path_a="archive", path_b="truth")
        d_max = max(s.max_abs for s in same_route.overall)
        rms = " ".join(f"{s.rms:.4f}" for s in truth.overall)
        worst = max(s.max_abs for s in truth.overall)
        lines.append(f"  {sensor} LEVEL_C (ECLIPJ2000) compare: archive - csv route max |d| "
                     f"{d_max:g} nT over {same_route.matched} vectors; archive - truth rms "
                     f"x y z {rms} nT, max {worst:.3f} nT ({truth.matched} vectors)")
    lines.append(f"  products in {out / 'products_archive'} and {out / 'products_csv'} "
                 f"({time.perf_counter() - t0:.1f} s)")
    return "\n".join(lines)
