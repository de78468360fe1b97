"""Where the unseen day crosses its goal against the compressive share (issue 34).

Issue 34, "Done when": "for each guard, the boundary measured (e.g. the compressive share
where the unseen error crosses the goal)".  Reads ``--save`` folders of
``benchmarks/messenger_fit_pulls.py --unseen`` (one folder per compressive level, the same
seeds in each: the same wind and law with only the compressive part scaled) and prints

- per realisation: the share of the judged intervals rejected as compressive, passes and
  convergence, the unseen day inside T_RANGE and D_RANGE (the fit's guards off), the
  predicted error, the law's largest error inside T_RANGE, tau and D0 against the
  forward model's truth, the command line's verdict, and **each guard judged alone**
  (`each_guard`: the compressive share, convergence, `check_fit`, `check_merit` with the
  share's limit lifted), so that a band of share shows which guards would refuse there;
- per folder: the share's median and range, the worst axis's unseen day and prediction
  against `GOAL_NT`, the fits whose unseen day exceeds it while the prediction puts every
  axis within it (the figure of merit's guard would pass them), how many converged and
  were written;
- per seed: the share where its worst-axis unseen day first crosses `GOAL_NT`, linear
  between the two levels around it (`crossing_share`);
- per folder (verification section 54): the share's quartiles, the fraction of fits
  whose worst axis exceeds `GOAL_NT` with its central 68 % Clopper-Pearson interval
  (`binomial_interval`), and how often each guard refuses, alone and as the verdict
  (`guard_tally`); then how the seeds lie against the goal at the lowest and highest
  level (`bracket_counts`).

::

    .venv/bin/python benchmarks/messenger_fit_crossing.py /tmp/cross/c0.055 /tmp/cross/c0.065 ...

docs/decisions/messenger_fit_verification.md section 51.
"""

from __future__ import annotations

import argparse
import dataclasses
import pickle
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.stats import beta

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import messenger_fit_pulls as pulls_bench  # noqa: E402

from fluxcal.errors import FitRefusedError  # noqa: E402
from fluxcal.missions.messenger import fit_merit  # noqa: E402
from fluxcal.missions.messenger.fit_guards import check_fit  # noqa: E402

#: The issue's goal for the unseen day, per axis (nT rms; MESSENGER's default `--error-goal`).
GOAL_NT = fit_merit.ERROR_GOAL_NT


def crossing_share(points: list[tuple[float, float]], goal: float = GOAL_NT
                   ) -> tuple[str, float]:
    """Where ``error`` first crosses ``goal`` along ``share``.

    ``points``: ``(share, error)`` of one seed over the levels.  Returns ``("at", s)``
    with ``s`` linear between the two points around the first rise past ``goal``,
    ``("below", s0)`` when the first point already exceeds it (``s0`` its share),
    ``("above", s1)`` when none does (``s1`` the largest share).
    """
    pts = sorted(points)
    if pts[0][1] > goal:
        return "below", pts[0][0]
    for (s0, e0), (s1, e1) in zip(pts, pts[1:], strict=False):
        if e0 <= goal < e1:
            return "at", s0 + (goal - e0) * (s1 - s0) / (e1 - e0)
    return "above", pts[-1][0]


#: The central probability of `binomial_interval` (one normal sigma either side).
ONE_SIGMA_LEVEL = 0.6827


def binomial_interval(k: int, n: int, level: float = ONE_SIGMA_LEVEL
                      ) -> tuple[float, float]:
    """Central Clopper-Pearson interval of a binomial fraction, ``k`` of ``n``.

    The lower end is the ``p`` whose chance of ``k`` or more is ``(1 - level) / 2`` (0 at
    ``k = 0``), the upper the ``p`` whose chance of ``k`` or fewer is that (1 at ``k = n``):
    the beta quantiles ``B((1 - level) / 2; k, n - k + 1)`` and ``B((1 + level) / 2; k + 1,
    n - k)``.
    """
    tail = (1.0 - level) / 2.0
    lo = float(beta.ppf(tail, k, n - k + 1)) if k > 0 else 0.0
    hi = float(beta.ppf(1.0 - tail, k + 1, n - k)) if k < n else 1.0
    return lo, hi


def bracket_counts(by_seed: dict[int, list[tuple[float, float]]], goal: float = GOAL_NT
                   ) -> dict[str, list[int]]:
    """The seeds by where their worst axis lies against ``goal`` at their lowest and highest
    share: ``within`` at both, ``crossed`` within then above (the crossing between them),
    ``above`` at both (the crossing below the lowest level), ``fell`` above then within."""
    out: dict[str, list[int]] = {"within": [], "crossed": [], "above": [], "fell": []}
    for seed, points in sorted(by_seed.items()):
        pts = sorted(points)
        if len(pts) < 2:
            continue
        first, last = pts[0][1] > goal, pts[-1][1] > goal
        out[{(False, False): "within", (False, True): "crossed", (True, True): "above",
             (True, False): "fell"}[(first, last)]].append(seed)
    return out


def guard_tally(verdicts: list[str], alone: list[dict[str, str]]) -> dict[str, dict[str, int]]:
    """How often each guard refuses: ``verdict`` (the command line's first refusal, by
    `_guard_name`) and, for each guard judged alone (`each_guard`'s keys), its refusals
    by name (``-``, passing, left out)."""
    out: dict[str, dict[str, int]] = {"verdict": defaultdict(int)}
    for v in verdicts:
        out["verdict"][_guard_name(v)] += 1
    for guards in alone:
        for key, message in guards.items():
            name = _guard_name(message)
            out.setdefault(key, defaultdict(int))
            if name != "-":
                out[key][name] += 1
    return {k: dict(sorted(v.items(), key=lambda kv: (-kv[1], kv[0]))) for k, v in out.items()}


def each_guard(res) -> dict[str, str]:
    """Each of the command line's guards judged alone on ``res`` (``""``: passes).

    ``share``: `fit_merit.compressive_refusal`; ``converged``: the pass loop's stop;
    ``check_fit``: its first refusal; ``merit``: `fit_merit.check_merit` with the
    compressive limit lifted (its first refusal after the share)."""
    out = {"share": fit_merit.compressive_refusal(res.variance.reason),
           "converged": "" if res.convergence["converged"] else res.convergence["stop"]}
    lifted = dataclasses.replace(res, merit={**res.merit, "max_compressive_share": 1.0})
    for name, guard in (("check_fit", check_fit), ("merit", fit_merit.check_merit)):
        try:
            guard(lifted)
            out[name] = ""
        except FitRefusedError as exc:
            out[name] = str(exc)
    return out


#: A refusal's guard, named by the words its message starts with (`_guard_name`).
GUARD_NAMES = (("refused: ", ""), ("variance estimator: ", "share"),
               ("not converged", "not converged"), ("duty-cycle law", "D0"),
               ("relaxation time", "tau"), ("temperature law", "law band"),
               ("predicted error", "predicted"), ("regulated temperature", "regulated sum"))


def _guard_name(message: str) -> str:
    """The guard a refusal names, in a word or two (``-``: none); D0's axis kept."""
    if not message or message == "accepted":
        return "-" if not message else "written"
    message = message.removeprefix("refused: ")
    for start, name in GUARD_NAMES[1:]:
        if message.startswith(start):
            if name == "D0":
                return f"D0 {message.split('fitted D0 ')[1][0]}"
            return name
    return message[:40].replace("|", "\\|")


def _axes(values, fmt: str = "{:.3f}") -> str:
    return " / ".join(fmt.format(v) for v in np.asarray(values, dtype=float))


def main() -> None:
    """Print the three tables for the folders given."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", type=Path, nargs="+",
                    help="--save folders of messenger_fit_pulls.py --unseen")
    args = ap.parse_args()
    by_seed: dict[int, list[tuple[float, float]]] = defaultdict(list)
    levels = []
    print("| folder | seed | compressive / judged | passes | unseen in T_RANGE, D_RANGE "
          "(nT) | predicted (nT) | law in T_RANGE (nT) | tau | D0 x / y / z | T_RANGE (C) "
          "| verdict | each alone: share, convergence, check_fit, merit |")
    print("|" + "---|" * 12)
    for folder in args.folders:
        share, worst, predicted, converged, written, missed = [], [], [], 0, 0, 0
        verdicts, alone = [], []
        for fit in sorted(folder.glob("fit_*.pkl")):
            res, true = pickle.loads(fit.read_bytes())
            row = pickle.loads((folder / fit.name.replace("fit_", "row_")).read_bytes())
            p = pulls_bench.pulls(res, true)
            n_comp, judged = p["compressive_share"]
            unseen = np.asarray(row["unseen_in_both_nt"], dtype=float)
            guards = each_guard(res)
            verdicts.append(row["verdict"])
            alone.append(guards)
            seed = int(fit.stem[4:])
            share.append(n_comp / judged)
            worst.append(float(unseen.max()))
            predicted.append(float(np.max(p["predicted_nt"])))
            converged += bool(res.convergence["converged"])
            written += row["verdict"] == "accepted"
            # above the goal where the prediction puts every axis within it (its guard passes)
            missed += bool(unseen.max() > GOAL_NT and np.max(p["predicted_nt"]) <= GOAL_NT)
            by_seed[seed].append((share[-1], worst[-1]))
            print(f"| {folder.name} | {seed} | {n_comp} / {judged} ({share[-1]:.1%}) | "
                  f"{p['passes']}{'' if res.convergence['converged'] else ', not conv.'} | "
                  f"{_axes(unseen)} | {_axes(p['predicted_nt'])} | {_axes(p['law_max_nt'])} "
                  f"| {100 * p['tau_rel']:+.1f} % | {_axes(100 * p['d0_rel'], '{:+.1f}')} % | "
                  f"{p['t_range']} | {_guard_name(row['verdict'])} | "
                  + ", ".join(_guard_name(guards[k]) for k in ("share", "converged", "check_fit",
                                                          "merit")) + " |", flush=True)
        if share:
            levels.append((folder.name, np.array(share), np.array(worst),
                           np.array(predicted), converged, written, missed,
                           guard_tally(verdicts, alone)))
    print("\n| folder | share: median (range) | N | worst-axis unseen: median / max (nT) | "
          f"above {GOAL_NT:g} | worst-axis predicted: median / max | above {GOAL_NT:g} | "
          "unseen above, every axis predicted within | converged | written |")
    print("|" + "---|" * 10)
    for name, share, worst, predicted, converged, written, missed, _ in levels:
        print(f"| {name} | {np.median(share):.1%} ({share.min():.1%}-{share.max():.1%}) | "
              f"{share.size} | {np.median(worst):.3f} / {worst.max():.3f} | "
              f"{np.sum(worst > GOAL_NT)} | {np.median(predicted):.3f} / "
              f"{predicted.max():.3f} | {np.sum(predicted > GOAL_NT)} | {missed} | {converged} | "
              f"{written} |")
    print(f"\n| folder | N | share: quartiles (range) | worst axis above {GOAL_NT:g} nT: "
          "fraction (68 % interval) | verdict | each alone: share | convergence | check_fit "
          "| merit (share lifted) |")
    print("|" + "---|" * 9)
    for name, share, worst, *_, tally in levels:
        k = int(np.sum(worst > GOAL_NT))
        lo, hi = binomial_interval(k, worst.size)
        q1, q2, q3 = np.percentile(share, [25, 50, 75])
        print(f"| {name} | {share.size} | {q1:.1%} / {q2:.1%} / {q3:.1%} ({share.min():.1%}-"
              f"{share.max():.1%}) | {k} of {worst.size}: {k / worst.size:.2f} ({lo:.2f}-"
              f"{hi:.2f}) | " + " | ".join(
                  ", ".join(f"{g} {c}" for g, c in tally.get(key, {}).items()) or "-"
                  for key in ("verdict", "share", "converged", "check_fit", "merit")) + " |")
    print("\n| seed | share: worst-axis unseen (nT), by level | crosses the goal |")
    print("|---|---|---|")
    at = []
    for seed, points in sorted(by_seed.items()):
        if len(points) < 2:  # a seed run at one level only says nothing of a crossing
            continue
        where, s = crossing_share(points)
        at += [s] if where == "at" else []
        print(f"| {seed} | " + ", ".join(f"{a:.1%}: {e:.3f}" for a, e in sorted(points))
              + f" | {where} {s:.1%} |")
    counts = bracket_counts(by_seed)
    print("\nseeds against the goal at their lowest / highest level: "
          + "; ".join(f"{k} {len(v)}" + (f" ({', '.join(map(str, v))})" if v else "")
                      for k, v in counts.items()))
    if at:
        print(f"\ncrossings: {len(at)} seeds, median {np.median(at):.1%}, "
              f"range {min(at):.1%}-{max(at):.1%}")


if __name__ == "__main__":
    main()
