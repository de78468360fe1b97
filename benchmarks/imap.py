"""IMAP MAG: fluxcal's L1A/L1B on simulated packets, and the team's package on the same.

Simulates burst-mode science packets (64 + 8 vectors/s, 4-s packets; compression widths
cycled every 4 packets, 0 = uncompressed; range changes inside every third packet) with
fluxcal's forward model (`fluxcal.missions.imap.simulate`) and its own SCLK kernel,
calibration CDF and XTCE, then, each case in a fresh child process:

* **fluxcal in-process**: ``chain.process`` to L1A, and to L1B (the L1A included),
  timed after a warm-up on a small file in the same process (imports, numba cache
  loaded), the best of two runs each, no product written;
* **fluxcal whole process**: ``fluxcal imap calibrate`` (the CLI entry point
  `fluxcal.cli.main`: interpreter start, imports, decode, L1B, CDF products written);
* **team in-process** (when a Python with ``imap-processing`` is found: ``--team-python``,
  ``FLUXCAL_TEAM_PYTHON`` or ``/work/venv-imap/bin/python``): ``mag_l1a`` on the same
  packet file, then ``mag_l1b`` of each sensor's L1A (the team's default calibration
  file: the values do not change the work), timed after the same warm-up;
* **team whole process**: the same in a fresh interpreter, start-up and imports
  included (no CDF written).

Peak memory is the child's ``VmHWM`` (``/proc/self/status``: the high-water mark of its
own resident memory, not the parent's).  For the in-process cases it is reset after the
warm-up (``/proc/self/clear_refs`` = 5), so it is the timed run's peak, imports and
warm-up data included as they stay resident.  The time ratio and memory ratio are
team / fluxcal.

Usage: .venv/bin/python benchmarks/imap.py [--vectors 100000,1000000] [--widths 0,16,18,13]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from products import peak_rss_mb  # benchmarks/products.py: VmHWM, else ru_maxrss

#: Vectors per second of the simulated burst mode (MAGo 64 + MAGi 8).
BURST_VECTORS_PER_S = 72

_TEAM = r"""
import json, sys, time
from pathlib import Path
import spiceypy
spiceypy.furnsh(sys.argv[1]); spiceypy.furnsh(sys.argv[2])
from imap_processing.mag.l1a.mag_l1a import mag_l1a
from imap_processing.mag.l1b.mag_l1b import mag_l1b
import cdflib, numpy as np, xarray as xr
DAY = np.datetime64("2025-10-17", "ns")  # the day of the simulated packets
_cdf = cdflib.CDF(sys.argv[5])
CAL = xr.Dataset({name: (("epoch", "row", "col", "range")[:1 + _cdf.varget(name).ndim],
                         _cdf.varget(name)[None]) for name in ("MFOTOURFO", "MFITOURFI")}
                 | {name: (("epoch",), np.atleast_1d(_cdf.varget(name)))
                    for name in ("OTS", "ITS")},
                 coords={"epoch": [DAY]})

def hwm():
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0

def run(path):
    t = time.perf_counter()
    l1a = [ds for ds in mag_l1a(Path(path)) if "vectors" in ds]
    t_l1a = time.perf_counter() - t
    n = sum(ds.sizes["epoch"] for ds in l1a)
    for ds in l1a:
        mag_l1b(ds, DAY, CAL)
    return n, t_l1a, time.perf_counter() - t

if sys.argv[4]:
    run(sys.argv[4])  # warm-up
    Path("/proc/self/clear_refs").write_text("5")
n, t_l1a, t_l1b = run(sys.argv[3])
print(json.dumps({"vectors": n, "l1a_s": t_l1a, "l1b_s": t_l1b, "peak_mib": hwm()}))
"""


def simulate_files(folder: Path, vectors: list[int], widths: tuple[int, ...]) -> dict:
    """Write the support files, a small warm-up file and one packet file per size."""
    from fluxcal.missions.imap import simulate

    paths = {k: str(v) for k, v in simulate.write_support(folder).items()}
    met = simulate.met_of_utc("2025-10-17T01:00:00")
    for n in [2000, *vectors]:
        seconds = -(-n // (BURST_VECTORS_PER_S * 4)) * 4
        sim = simulate.simulate(met, seconds, plan=simulate.BURST, widths=widths)
        path = folder / f"burst_{n}.pkts"
        path.write_bytes(sim.packets)
        paths[n] = str(path)
    return paths


def child_fluxcal(paths: dict, n: str) -> dict:
    """In-process fluxcal: L1A, then L1B, after a warm-up on the small file."""
    from fluxcal.missions.imap.chain import process

    def run(path: str, level: str) -> tuple[int, float]:
        t = time.perf_counter()
        out = process([Path(path)], level=level, calib=paths["calib"],
                      kernels=paths["kernels"], xtce=paths["xtce"])
        return sum(ds.sizes["time"] for ds in out.values()), time.perf_counter() - t

    run(paths["2000"], "l1b")
    Path("/proc/self/clear_refs").write_text("5")
    times: dict[str, list[float]] = {"l1a": [], "l1b": []}
    for _ in range(2):  # the best of two: the first run also grows the heap
        for level in times:
            vec, seconds = run(paths[n], level)
            times[level].append(seconds)
    return {"vectors": vec, "l1a_s": min(times["l1a"]), "l1b_s": min(times["l1b"]),
            "peak_mib": peak_rss_mb()}


def child_cli(paths: dict, n: str, out: str) -> dict:
    """Whole-process fluxcal: ``fluxcal imap calibrate`` as a user runs it."""
    from fluxcal.cli import main

    code = main(["imap", "calibrate", "--input", paths[n], "--kernels", paths["kernels"],
                 "--calib", paths["calib"], "--xtce", paths["xtce"], "--out", out])
    return {"exit": code, "peak_mib": peak_rss_mb()}


def team_python(given: str | None) -> str | None:
    """A Python that imports ``imap_processing``, or None."""
    for exe in (given, os.environ.get("FLUXCAL_TEAM_PYTHON"), "/work/venv-imap/bin/python"):
        if exe and Path(exe).is_file() and subprocess.run(
                [exe, "-c", "import imap_processing.mag.l1b.mag_l1b"],
                capture_output=True, timeout=300).returncode == 0:
            return exe
    return None


def _child(argv: list[str], timeout: float) -> tuple[dict, float]:
    t = time.perf_counter()
    res = subprocess.run(argv, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t
    if res.returncode != 0:
        raise RuntimeError(f"{argv[:3]}: exit {res.returncode}\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1]), wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--vectors", default="100000,1000000")
    parser.add_argument("--widths", default="0,16,18,13")
    parser.add_argument("--team-python", default=None)
    parser.add_argument("--no-team", action="store_true")
    parser.add_argument("--timeout", type=float, default=3600.0)
    parser.add_argument("--child", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, paths_json, n, *rest = args.child
        paths = json.loads(Path(paths_json).read_text())
        result = (child_fluxcal(paths, n) if kind == "fluxcal"
                  else child_cli(paths, n, rest[0]))
        print(json.dumps(result))
        return
    vectors = [int(v) for v in args.vectors.split(",")]
    widths = tuple(int(w) for w in args.widths.split(","))
    team = None if args.no_team else team_python(args.team_python)
    lsk = Path(__file__).resolve().parents[1].parent / "shared/data/kernels/generic/naif0012.tls"
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t = time.perf_counter()
        paths = simulate_files(folder, vectors, widths)
        print(f"simulated {vectors} vectors (widths {widths}) in "
              f"{time.perf_counter() - t:.1f} s; team package: {team or 'not found'}")
        paths_json = folder / "paths.json"
        paths_json.write_text(json.dumps({str(k): v for k, v in paths.items()}))
        rows = []
        me = [sys.executable, __file__, "--child"]
        for n in vectors:
            size = Path(paths[n]).stat().st_size / 2**20
            fx, _ = _child(me + ["fluxcal", str(paths_json), str(n)], args.timeout)
            cli, cli_wall = _child(me + ["cli", str(paths_json), str(n), str(folder / "o")],
                                   args.timeout)
            row = {"n": n, "mib": size, "fx": fx, "cli": cli, "cli_wall": cli_wall}
            if team and lsk.is_file():
                base = [team, "-c", _TEAM, str(lsk), paths["kernels"], paths[n]]
                row["team"], _ = _child(base + [paths[2000], paths["calib"]], args.timeout)
                row["team_proc"], row["team_wall"] = _child(base + ["", paths["calib"]],
                                                            args.timeout)
            rows.append(row)
            _print(row)
        print()
        print("| vectors | packets MiB | case | fluxcal s | team s | team/fluxcal | "
              "fluxcal peak MiB | team peak MiB | peak team/fluxcal |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            for line in _table(r):
                print(line)


def _print(r: dict) -> None:
    fx = r["fx"]
    print(f"{r['fx']['vectors']} vectors ({r['mib']:.1f} MiB of packets): fluxcal in-process "
          f"L1A {fx['l1a_s']:.2f} s, L1B {fx['l1b_s']:.2f} s "
          f"({fx['vectors'] / fx['l1b_s']:,.0f} vectors/s), peak {fx['peak_mib']:.0f} MiB; "
          f"whole process {r['cli_wall']:.1f} s, peak {r['cli']['peak_mib']:.0f} MiB")
    if "team" in r:
        tm = r["team"]
        print(f"  team in-process L1A {tm['l1a_s']:.2f} s, L1A+L1B {tm['l1b_s']:.2f} s, peak "
              f"{tm['peak_mib']:.0f} MiB (ratio L1A {tm['l1a_s'] / fx['l1a_s']:.1f}x, "
              f"L1A+L1B {tm['l1b_s'] / fx['l1b_s']:.1f}x); whole process "
              f"{r['team_wall']:.1f} s, peak {r['team_proc']['peak_mib']:.0f} MiB")
        if tm["vectors"] != fx["vectors"]:
            print(f"  WARNING: the team's L1A has {tm['vectors']} vectors, fluxcal "
                  f"{fx['vectors']}")


def _table(r: dict) -> list[str]:
    fx, n, mib = r["fx"], r["n"], f"{r['mib']:.1f}"
    tm, tp = r.get("team"), r.get("team_proc")

    def cells(mine: float, theirs: float | None, mine_mb: float, theirs_mb: float | None
              ) -> str:
        if theirs is None:
            return f"{mine:.2f} | - | - | {mine_mb:.0f} | - | -"
        return (f"{mine:.2f} | {theirs:.2f} | {theirs / mine:.1f}x | {mine_mb:.0f} | "
                f"{theirs_mb:.0f} | {theirs_mb / mine_mb:.2f}")

    return [
        f"| {n:,} | {mib} | L1A in-process | " + cells(
            fx["l1a_s"], tm and tm["l1a_s"], fx["peak_mib"], tm and tm["peak_mib"]) + " |",
        f"| {n:,} | {mib} | L1A+L1B in-process | " + cells(
            fx["l1b_s"], tm and tm["l1b_s"], fx["peak_mib"], tm and tm["peak_mib"]) + " |",
        f"| {n:,} | {mib} | whole process | " + cells(
            r["cli_wall"], r.get("team_wall"), r["cli"]["peak_mib"],
            tp and tp["peak_mib"]) + " |",
    ]


if __name__ == "__main__":
    main()
