"""tau against its 5 % goal on saved MESSENGER fits (issue 34; messenger_fit.md entry 43).

    .venv/bin/python benchmarks/messenger_fit_tau.py /tmp/s39/mo16 /tmp/s39/late16 ...

Each FOLDER is a ``benchmarks/messenger_fit_pulls.py --save`` folder (``fit_*.pkl``: the
fit and the forward model's true tables).  Per folder one Markdown row: tau's stated
relative error (1 sigma) and its true error against the truth, the pulls' spread and
largest, the size in nT of a 5 % tau error (`fit_guards.tau_goal_cost_nt`, largest axis), how
many fits a guard ``stated <= 5 % / k`` would refuse for k = 1, 1.5, 2, and the first cause
the command line gives with this tree's guards (`messenger_fit_pulls.command_line_verdict`).
``--demo`` fits the fit demo's 2 days (`fit_demo.simulate_training`, its true tables) free
and with ``--hold-d0 z``, guards off, and prints tau's stated and true relative error::

    .venv/bin/python benchmarks/messenger_fit_tau.py --demo
"""

from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from messenger_fit_pulls import command_line_verdict  # noqa: E402

from fluxcal.missions.messenger.fit_guards import TAU_ERROR_GOAL, tau_goal_cost_nt  # noqa: E402

#: Coverage factors of the guards compared (stated <= goal / k).
FACTORS = (1.0, 1.5, 2.0)
#: The first words of each refusal the command line gives, and the name printed for it.
CAUSES = (("refused: relaxation time", "tau goal"), ("refused: duty-cycle law", "D0 goal"),
          ("refused: not converged", "not converged"),
          ("refused: predicted error", "merit"), ("refused: temperature law", "merit"))


def cause_of(verdict: str) -> str:
    """Short name of a `command_line_verdict`."""
    if verdict == "accepted":
        return "written"
    if "rejected as compressive" in verdict:
        return "compressive"
    return next((name for start, name in CAUSES if verdict.startswith(start)), verdict[:40])


def row(folder: Path) -> str:
    """The Markdown row of one saved folder."""
    stated, true, pull, cost, causes, days = [], [], [], [], {}, 0
    for path in sorted(folder.glob("fit_*.pkl")):
        res, truth = pickle.loads(path.read_bytes())
        r = res.relaxation
        tau = float(truth.constants["relaxation"]["tau_s"])
        stated.append(r.tau_err / r.tau)
        true.append(r.tau / tau - 1.0)
        pull.append((r.tau - tau) / r.tau_err)
        cost.append(np.max(tau_goal_cost_nt(res)))
        name = cause_of(command_line_verdict(res))
        causes[name] = causes.get(name, 0) + 1
        days = len(res.stats.days)
    s, t, p, c = (np.asarray(x, dtype=float) for x in (stated, true, pull, cost))
    if s.size == 0:
        return f"| {folder} | | 0 | | | | | | |"
    refused = " / ".join(str(int(np.sum(s > TAU_ERROR_GOAL / k))) for k in FACTORS)
    return (f"| {folder} | {days} | {s.size} | {100 * s.min():.2f} / {100 * np.median(s):.2f} / "
            f"{100 * s.max():.2f} | {100 * t[np.argmax(np.abs(t))]:+.2f} | {np.std(p):.2f} / "
            f"{p[np.argmax(np.abs(p))]:+.2f} | {c.min():.3f}-{c.max():.3f} | {refused} | "
            + ", ".join(f"{k} {n}" for k, n in causes.items()) + " |")


def demo() -> None:
    """tau of the fit demo's world, free and with D0 z held (as its refusal advises)."""
    from fluxcal.missions.messenger import fit_demo
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit_passes import Chunk, fit_days

    with tempfile.TemporaryDirectory() as tmp:
        start = "2012-06-01T00:00:00"
        truth = fit_demo.perturbed_folder(Path(tmp) / "truth_tables")
        train = fit_demo.simulate_training(Path(tmp) / "training", truth, start, 2.0)
        chunks = [Chunk("training", (train["science"],), (train["heater"],),
                        (train["temperature"],), (train["kernels"],))]
        base = load_calibration(start)
        tau = float(load_calibration(fit_demo.UNSEEN_START, truth)
                    .constants["relaxation"]["tau_s"])
        for held in ((), ("z",)):
            r = fit_days(chunks, base, estimator="variance", guard=False,
                         hold_d0=held).relaxation
            print(f"fit demo, hold_d0={held}: tau {r.tau:.1f} +- {r.tau_err:.1f} s, stated "
                  f"{100 * r.tau_err / r.tau:.2f} %, true {100 * (r.tau / tau - 1):+.2f} %",
                  flush=True)


def main() -> None:
    """Print the table (or the demo's tau)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="*", type=Path)
    ap.add_argument("--demo", action="store_true", help="The fit demo's 2 days instead.")
    args = ap.parse_args()
    if args.demo:
        demo()
        return
    if not args.folders:
        ap.error("give one or more --save folders, or --demo")
    print("| folder | days | fits | tau stated %, min / median / max | true %, largest | "
          "pull spread / largest | 5 % of tau (nT) | refused by stated > 5 % / k, k = "
          + " / ".join(f"{k:g}" for k in FACTORS) + " | first cause, this tree |")
    print("|---|---|---|---|---|---|---|---|---|")
    for folder in args.folders:
        print(row(folder), flush=True)


if __name__ == "__main__":
    main()
