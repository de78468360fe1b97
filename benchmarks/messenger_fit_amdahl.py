"""The MESSENGER fit's speed-up on N workers from its measured parts (issue 34, item 7).

    .venv/bin/python benchmarks/messenger_fit.py --days-1hz 4 --days-20hz 0 --workers 1 \\
        --json runs/d4_w1_r1.json                       # and --workers 2, 8 days, repeated
    .venv/bin/python benchmarks/messenger_fit_amdahl.py runs/*.json
    .venv/bin/python benchmarks/messenger_fit_amdahl.py runs/*.json --project 64:16:13.54

Reads the ``--json`` files of `benchmarks/messenger_fit.py` (each a serial fit and a Dask
fit of the same simulated days, split per pass into the work that divides by the workers
and the rest; see its `_serial_parts` and `_dask_parts`) and states the model of
docs/decisions/messenger_fit.md entry 53:

    serial  T1 = A + P (D w + m + s) + Z
    Dask    TN = A + P ((D w' + (1 - x) m') / c + F + g (D + D / 3) / N + I(D, N) + L
                        + s_own + b / c + o_rs) + Z

per pass, with ``P`` passes of ``D`` days: ``w`` the reduce of one day and ``m`` the
merges, serially (``w'``, ``m'`` the same on a worker; both divide by the workers); ``s``
the client's fit of a pass run serially (its bootstrap resamples ``b`` included);
``s_own`` the client's fit on Dask less the resamples (which run on the workers); ``o_rs``
what sending the resamples to the workers costs per pass; ``F`` the wait for the first
task (the scatter, the submission); ``L`` the merge tree's tail, from the last day to the
merged statistics gathered (the merges on that chain, a share ``x`` of ``m'``, and the
gather: they do not divide); ``g`` the scheduling gap per task (about D + D/3 tasks: days
and merges of four); ``I`` the uneven
days (list scheduling of the measured per-day spread, simulated); ``A`` and ``Z`` the
set-up and the once-per-fit work (column errors, merit, folder, pictures: serial in
both; messenger_fit.py times ``Z`` apart, its ``once_per_fit``, and a file without it
counts 0); ``c`` the pure-CPU control's speed-up on N workers (the parallelism the machine
offers; `_control.control`).  Every part is CPU seconds of one core
(``time.process_time`` of the client, Dask's per-task thread CPU of the workers) or, for
the latencies, the wall of the 1-worker runs, so waits for a core on a shared host stay
out of it; on a quiet machine the wall of each serial part is its CPU.  Scaling every CPU
part by the same per-core speed leaves the ratios unchanged.

Prints, per number of days: the parts' medians and spreads over the runs; the model's
speed-up and its ratio to the run's own control for every run (the 1-worker parts
predicting the 2-worker runs: the check this host can make), against the measured ones,
with the samples (vectors) per second of each run; and the projection to ``--project
DAYS:WORKERS:CONTROL`` (default the issue's 64 days on 16 workers at the device's 13.54x
and the 9.92x of fit_scaling.md S6): the parts extrapolated linearly in the days, their
uncertainty from resampling the runs (10th-90th percentile), and the serial share that
would reach 80 % of the control, ``f <= 0.25 / (c - 1)``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

#: The devices' measurements the projection is set against: (label, days, workers,
#: speed-up, control) -- issue 34 item 7 (docs/decisions/messenger_fit.md entry 33) and
#: docs/decisions/fit_scaling.md S6.
DEVICE = (("issue 34 (eabefb7)", 64, 16, 8.20, 13.54), ("fit_scaling S6", 64, 16, 8.69, 9.92))
TARGET = 0.8
#: The model's parts taken from the 1-worker runs (`parts`).
PARTS = ("w", "w_workers", "m", "m_workers", "s", "s_own", "b", "z", "o_rs", "setup",
         "first", "gap", "tail")
#: The parts in CPU seconds (the rest are wall seconds or counts).
CPU_PARTS = ("w", "w_workers", "m", "m_workers", "s", "s_own", "b", "z")
#: Parts per day or per call, which do not grow with the days.
PER_DAY = ("w", "w_workers", "o_rs", "setup", "first", "gap")
#: Wall waits of the Dask passes, taken as the least over the runs (`parts_at`).
WAITS = ("o_rs", "first", "gap", "tail")


def _median(x: list[float]) -> float:
    return statistics.median(x) if x else float("nan")


def parts(r: dict[str, Any]) -> dict[str, float]:
    """One run's model inputs (per pass unless said), from messenger_fit.py's JSON."""
    sp, dp, dc = r["serial_parts"], r["dask_parts"], r["dask_client_cpu"]
    wk = r["worker_cpu"]
    n_pass, days, n = len(sp["reduce_cpu_s"]), r["days"], r["workers"]
    n_dask = len(dp)
    s = list(sp["client_cpu_s"])
    own = list(dc["client_cpu_s"])
    # the once-per-fit work (messenger_fit.py's `once_per_fit`: column errors, merit,
    # folder, pictures), timed apart; a written fit's last pass holds it already
    once = r.get("once_per_fit") or {}
    z = float(once.get("total_cpu_s", 0.0))
    if z and r.get("outcome") == "written":
        s[-1] = max(s[-1] - z, 0.0)
    if z and r.get("outcome_parallel", r.get("outcome")) == "written" and own:
        own[-1] = max(own[-1] - z, 0.0)
    b = wk.get("resample_fits:thread-cpu", 0.0) / max(n_dask, 1)
    out = {
        "days": days, "workers": n, "passes": n_pass, "control": r["control"],
        "serial_s": r["serial_s"], "parallel_s": r["parallel_s"], "samples": r["samples"],
        # divides by the workers
        "w": sum(sp["reduce_cpu_s"]) / (days * n_pass),
        "w_workers": wk.get("reduce_chunk:thread-cpu", 0.0) / (days * max(n_dask, 1)),
        "m": _median(sp["merge_cpu_s"]),
        "m_workers": wk.get("merge_parts:thread-cpu", 0.0) / max(n_dask, 1),
        "b": b,
        # the client's fit per pass, serially and on Dask (the passes differ: one or two
        # bootstraps), without the once-per-fit work ``z`` (after the last pass: column
        # errors, merit, folder, pictures; serial in both runs; 0 in a file without it)
        "s": sum(s) / n_pass,
        "s_own": sum(own) / max(n_dask, 1),
        "z": z,
        "z_serial": s[-1] - min(s),
        "setup": sp["setup_s"],
        # whether the timed fits themselves did the once-per-fit work (else a refusal)
        "written": r.get("outcome") == "written",
        # the client process during the Dask reduce (parallel to the workers)
        "q": _median(dc["reduce_cpu_s"]) + _median(dc["gather_cpu_s"]),
        # wall latencies of the Dask passes
        "idle": _median([p["idle_s"] for p in dp]),
        # the 1-worker idle less the first task's wait and the tail's own waits, per task
        "gap": max(0.0, _median([(p["idle_s"] - p["first_task_s"] - p["tail_s"]
                                  + tail_share(days) * p["merge_compute_s"])
                                 / (days + p["merges"]) for p in dp])) if dp else 0.0,
        "first": _median([p["first_task_s"] for p in dp]),
        "tail": _median([p["tail_s"] for p in dp]),
        "transfer": _median([p["transfer_s"] for p in dp]),
        "o_rs": _median([p["client_wall_s"] - o - p["resample_union_s"]
                         for p, o in zip(dp[:-1], own[:-1], strict=True)]) if n_dask > 1
        else float("nan"),
        # the days' spread within a pass (the first pass also hashes the inputs)
        "day_spread": _median([float(np.std(p["day_s"]) / np.mean(p["day_s"]))
                               for p in dp if len(p["day_s"]) > 1]),
        # the serial run's wall per CPU second (its waits for a core)
        "kappa": r["serial_s"] / max(sum(sp["reduce_cpu_s"]) + sum(sp["merge_cpu_s"])
                                     + sum(s) + sp["setup_s"], 1e-9),
    }
    return out


def tail_share(days: int, fan_in: int = 4) -> float:
    """Share of a pass's merge work on the chain after its last day (`fit_passes._merge_tree`).

    The days merge in consecutive groups of ``fan_in``, level by level; a merge costs in
    proportion to the days it holds.  After the last day only the last group of each
    level is left: the days they hold over the days all merges hold.
    """
    sizes, chain, total = [1] * days, 0, 0
    while len(sizes) > 1:
        groups = [sizes[i:i + fan_in] for i in range(0, len(sizes), fan_in)]
        merged = [g for g in groups if len(g) > 1]
        total += sum(sum(g) for g in merged)
        chain += sum(groups[-1]) if len(groups[-1]) > 1 else 0
        sizes = [sum(g) for g in groups]
    return chain / total if total else 0.0


def imbalance(days: int, workers: int, spread: float, rng: np.random.Generator,
              draws: int = 400) -> float:
    """Mean extra wall (in days' reduce times) of list-scheduling ``days`` uneven days.

    Each day's time is drawn with relative standard deviation ``spread`` (a gamma
    distribution, mean 1); the days go to the first free worker in order, as Dask's
    scheduler queues them; the extra is the makespan less the sum over the workers.
    """
    if workers <= 1 or spread <= 0.0:
        return 0.0
    k = 1.0 / spread ** 2
    extra = 0.0
    for _ in range(draws):
        t = rng.gamma(k, 1.0 / k, days)
        free = np.zeros(workers)
        for x in t:
            i = int(np.argmin(free))
            free[i] += x
        extra += free.max() - t.sum() / workers
    return extra / draws


def model(p: dict[str, float], days: int, workers: int, control: float,
          spread_extra: float) -> tuple[float, float, dict]:
    """(T1, TN, parts of one Dask pass) of the model in the module docstring (CPU s)."""
    passes = p["passes"]
    t1 = p["setup"] + passes * (days * p["w"] + p["m"] + p["s"]) + p["z"]
    tasks = days + days / 3.0
    dask_pass = {
        "reduce / c": days * p["w"] / control,
        "the days' extra on a worker / c": days * (p["w_workers"] - p["w"]) / control,
        "merges / c": (1.0 - tail_share(days)) * p["m_workers"] / control,
        "first task": p["first"],
        "task gaps g (D + D/3) / N": p["gap"] * tasks / workers,
        "merge tree's tail and gather": p["tail"],
        "uneven days I": spread_extra * p["w_workers"],
        "client s_own": p["s_own"], "resamples b / c": p["b"] / control,
        "sending resamples o_rs": max(p["o_rs"], 0.0),
    }
    tn = p["setup"] + passes * sum(dask_pass.values()) + p["z"]
    return t1, tn, dask_pass


def _linear(runs: list[dict[str, float]], key: str, days: float) -> float:
    """The part ``key`` at ``days``: a line through the runs' values (a median if one D)."""
    x = np.array([q["days"] for q in runs], dtype=float)
    y = np.array([q[key] for q in runs], dtype=float)
    if len(set(x)) < 2:
        return float(np.median(y))
    slope, icpt = np.polyfit(x, y, 1)
    return float(icpt + slope * days)


def parts_at(runs: list[dict[str, float]], days: int) -> dict[str, float]:
    """The model's parts at ``days``: the runs' medians there, else extrapolated.

    The parts per day or per call (`PER_DAY`) come from every run; the others from the
    runs at these days (only the workers and the control are then modelled) or, if none,
    from a line through the runs' values against the days (a median if one number).  The
    waits (`WAITS`) are the least over the runs instead: on a shared host a wait only
    grows.  A day's reduce on a worker is the serial one times the runs' median ratio of
    the two (one run's ratio scatters 0.85-1.35 with the load).
    """
    same = [q for q in runs if q["days"] == days]

    def pick(k: str, qs: list[dict[str, float]]) -> float:
        vals = [q[k] for q in qs]
        return min(vals) if k in WAITS else _median(vals)

    if same:  # the parts per day or per call from every run: they do not grow
        at = {k: pick(k, runs if k in PER_DAY else same) for k in PARTS}
    else:
        at = {k: (pick(k, runs) if k in PER_DAY else _linear(runs, k, days))
              for k in PARTS}
        if "tail" in WAITS:  # the line through the least tail at each number of days
            least = [{"days": d, "tail": min(q["tail"] for q in runs if q["days"] == d)}
                     for d in sorted({q["days"] for q in runs})]
            at["tail"] = _linear(least, "tail", days)
    at["w_workers"] = at["w"] * _median([q["w_workers"] / q["w"] for q in runs])
    at["passes"] = round(_median([q["passes"] for q in same or runs]))
    return at


def _common_speed(runs: list[dict[str, float]]) -> list[dict[str, float]]:
    """The runs' CPU parts at one per-core speed: each scaled by the median ``w`` / its own.

    On a shared host a core's CPU second does less work when its sibling is busy (the
    same reduce took 0.37-0.59 CPU s per day); the parts of one run share its
    contention, so their ratios to its own day's reduce are steadier than the parts.
    """
    ref = _median([q["w"] for q in runs])
    return [{**q, **{k: q[k] * ref / q["w"] for k in CPU_PARTS}} for q in runs]


def project(runs: list[dict[str, float]], days: int, workers: int, control: float,
            rng: np.random.Generator, n_boot: int,
            day_spread: float | None = None, tail_factor: float = 1.0) -> dict[str, Any]:
    """The model at (days, workers, control) from the 1-worker runs, resampled."""
    ones = [q for q in runs if q["workers"] == 1]

    def once(sample: list[dict[str, float]]) -> tuple[float, float, dict, dict]:
        sample = _common_speed(sample)
        at = parts_at(sample, days)
        at["tail"] *= tail_factor  # the chain's transfers between workers (1 worker: none)
        spread = (min(q["day_spread"] for q in sample) if day_spread is None
                  else day_spread)
        extra = imbalance(days, workers, spread, rng, draws=100)
        t1, tn, dp = model(at, days, workers, control, extra)
        return t1, tn, dp, at

    t1, tn, dp, at = once(ones)
    boot = []
    for _ in range(n_boot):
        sample = [ones[i] for i in rng.integers(0, len(ones), len(ones))]
        if not any(q["days"] == days for q in sample) and len({q["days"] for q in sample}) < 2:
            continue
        b1, bn, _, _ = once(sample)
        boot.append(b1 / bn / control)
    serial = at["setup"] + at["passes"] * (at["s_own"] + sum(
        v for k, v in dp.items() if k in ("first task", "task gaps g (D + D/3) / N",
                                          "merge tree's tail and gather",
                                          "uneven days I", "sending resamples o_rs"))) \
        + at["z"]
    return {"t1": t1, "tn": tn, "speed_up": t1 / tn, "ratio": t1 / tn / control,
            "ratio_p10": float(np.percentile(boot, 10)) if boot else float("nan"),
            "ratio_p90": float(np.percentile(boot, 90)) if boot else float("nan"),
            "pass": dp, "at": at, "serial_equivalent_share": serial / t1,
            "needed_share": (1.0 / TARGET - 1.0) / (control - 1.0),
            # a refused fit (the benchmark's, at 3 passes): no once-per-fit work
            "speed_up_refused": (t1 - at["z"]) / (tn - at["z"])}


def _spread(x: list[float]) -> str:
    return f"{_median(x):.3f} ({min(x):.3f}-{max(x):.3f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="messenger_fit.py --json files")
    ap.add_argument("--project", action="append", default=None,
                    help="DAYS:WORKERS:CONTROL to project to (repeatable; default "
                    "64:16:13.54 and 64:16:9.92, the devices' controls)")
    ap.add_argument("--boot", type=int, default=200, help="resamples of the runs (200)")
    ap.add_argument("--day-spread", type=float, default=None,
                    help="the days' relative spread for the projection's uneven days "
                    "(default: the least of the runs', which a shared host inflates)")
    ap.add_argument("--tail-factor", type=float, default=1.0,
                    help="the projection's merge-tree tail times this (the chain's transfers "
                    "between workers, which the 1-worker runs lack; default 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    runs = []
    for path in args.runs:
        for r in json.loads(path.read_text()):
            if "dask_parts" in r and r.get("serial_parts", {}).get("reduce_cpu_s"):
                q = parts(r)
                q["file"] = path.name
                runs.append(q)
    if not any(q["workers"] == 1 for q in runs):
        print(f"messenger_fit_amdahl: error: {', '.join(str(p) for p in args.runs)}: no "
              "--workers 1 run to take the parts from; run benchmarks/messenger_fit.py "
              "--workers 1 --json FILE and give its file too", file=sys.stderr)
        raise SystemExit(2)
    out: dict[str, Any] = {"runs": runs}
    ones = [q for q in runs if q["workers"] == 1]
    print("Parts (CPU s of one core unless said), median (range) over the 1-worker runs:")
    keys = (("w", "reduce of one day, per pass"), ("w_workers", "  the same on the worker"),
            ("m", "merges per pass"), ("m_workers", "  the same on the workers"),
            ("s", "client fit per pass, serial (a written fit's once-per-fit work out)"),
            ("z_serial", "  its last pass's extra"),
            ("z", "once per fit: column errors, merit, folder, pictures"),
            ("s_own", "client fit per pass on Dask, resamples on the workers"),
            ("b", "bootstrap resamples per pass (workers)"), ("setup", "set-up (wall)"),
            ("q", "client CPU during the Dask reduce"), ("idle", "Dask reduce idle (wall)"),
            ("first", "  of it to the first task (wall)"),
            ("tail", "  from the last day to the gather (wall)"),
            ("gap", "  gap per task (wall)"),
            ("o_rs", "sending the resamples (wall)"), ("day_spread", "days' relative spread"),
            ("kappa", "serial wall per CPU s (load)"))
    for d in sorted({q["days"] for q in ones}):
        at = [q for q in ones if q["days"] == d]
        print(f"  {d} days, {len(at)} runs, {at[0]['passes']} passes:")
        for k, label in keys:
            vals = [q[k] for q in at if np.isfinite(q[k])]
            if vals:
                print(f"    {label:55s} {_spread(vals)}")

    print("\nEach run: measured against the model from the 1-worker runs' parts at its days "
          "(with its own control and its serial run's wall per CPU s):")
    print(f"  {'run':28s} {'vectors/s serial':>16s} {'Dask':>10s} {'control':>8s} "
          f"{'speed-up':>8s} {'ratio':>6s} {'model':>6s} {'model ratio':>11s}")
    checks = []
    ones_common = _common_speed(ones)
    for q in sorted(runs, key=lambda q: (q["days"], q["workers"], q["file"])):
        at = parts_at(ones_common, q["days"])
        at["passes"] = q["passes"]
        if not q["written"]:  # a refused fit did no once-per-fit work in either run
            at["z"] = 0.0
        same = [o for o in ones_common if o["days"] == q["days"]] or ones_common
        extra = imbalance(q["days"], q["workers"], _median([o["day_spread"] for o in same]),
                          rng, draws=200)
        t1, tn, _ = model(at, q["days"], q["workers"], q["control"], extra)
        measured = q["serial_s"] / q["parallel_s"]
        predicted = t1 / tn
        checks.append({"file": q["file"], "days": q["days"], "workers": q["workers"],
                       "control": q["control"], "speed_up": measured,
                       "model_speed_up": predicted})
        print(f"  {q['file']:28s} {q['samples'] / q['serial_s']:16,.0f} "
              f"{q['samples'] / q['parallel_s']:10,.0f} {q['control']:7.2f}x "
              f"{measured:7.2f}x {measured / q['control']:6.0%} {predicted:5.2f}x "
              f"{predicted / q['control']:11.0%}")
    out["checks"] = checks
    print("  per days and workers, medians (a single control measurement scatters: at 1 "
          "worker it is 1 by construction):")
    for d, n in sorted({(c["days"], c["workers"]) for c in checks}):
        at = [c for c in checks if (c["days"], c["workers"]) == (d, n)]
        su, ctrl = _median([c["speed_up"] for c in at]), _median([c["control"] for c in at])
        same = [o for o in ones_common if o["days"] == d] or ones_common
        p = parts_at(ones_common, d)
        if not any(q["written"] for q in runs if (q["days"], q["workers"]) == (d, n)):
            p["z"] = 0.0  # refused fits: no once-per-fit work in the runs measured
        extra = imbalance(d, n, _median([o["day_spread"] for o in same]), rng, draws=200)
        c_model = 1.0 if n == 1 else ctrl
        t1, tn, _ = model(p, d, n, c_model, extra)
        print(f"    {d} days x {n}: {len(at)} runs, speed-up {su:.2f}x "
              f"({min(c['speed_up'] for c in at):.2f}-{max(c['speed_up'] for c in at):.2f}), "
              f"control {ctrl:.2f}x, ratio {su / ctrl:.0%}; model at a control of "
              f"{c_model:.2f}x: {t1 / tn:.2f}x, {t1 / tn / c_model:.0%}")

    targets = ([tuple(float(v) for v in t.split(":")) for t in args.project]
               if args.project else [(64, 16, 13.54), (64, 16, 9.92)])
    out["projections"] = []
    for days, workers, ctrl in targets:
        pr = project(runs, int(days), int(workers), ctrl, rng, args.boot, args.day_spread,
                     args.tail_factor)
        pr.update({"days": int(days), "workers": int(workers), "control": ctrl})
        out["projections"].append(pr)
        how = ("measured at these days" if any(q["days"] == int(days) for q in ones)
               else "extrapolated in the days")
        print(f"\nProjection: {int(days)} days on {int(workers)} workers at a control of "
              f"{ctrl:.2f}x ({pr['at']['passes']} passes; the 1-worker runs' parts, {how}; "
              "a written fit, the once-per-fit work Z included):")
        spread = (f"resampled runs: {pr['ratio_p10']:.0%}-{pr['ratio_p90']:.0%}"
                  if np.isfinite(pr["ratio_p10"]) else "too few runs to resample")
        print(f"  serial fit {pr['t1']:.2f} CPU s; Dask {pr['tn']:.2f} s: speed-up "
              f"{pr['speed_up']:.2f}x, {pr['ratio']:.0%} of the control ({spread})")
        print(f"  serial-equivalent share {pr['serial_equivalent_share']:.1%}; 80 % needs at "
              f"most {pr['needed_share']:.1%} at this control")
        print("  one Dask pass: " + "; ".join(f"{k} {v:.3f} s" for k, v in pr["pass"].items()))
        print(f"  once per fit, both runs: Z {pr['at']['z']:.3f} s ({pr['at']['z'] / pr['t1']:.1%} "
              f"of the serial fit); a refused fit (no Z, as the benchmark's timed fits at 3 "
              f"passes): {pr['speed_up_refused']:.2f}x, "
              f"{pr['speed_up_refused'] / ctrl:.0%} of the control")
        for label, d, n, su, c in DEVICE:
            if (d, n) == (int(days), int(workers)):
                print(f"  device ({label}): {su:.2f}x of {c:.2f}x = {su / c:.0%}")
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
