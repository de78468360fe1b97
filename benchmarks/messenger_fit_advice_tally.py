"""Tally `messenger_fit_advice.py --record` chains: the own-value holds' pulls by share.

Issue 34, item 2 (verification section 66): the own-value D0 hold a refusal advises
is widened by entry 52's split factor below `fit_merit.ADVICE_MAX_COMPRESSIVE_SHARE`
(entry 60) and carries the split the fit states above it (entry 52).  Per chain: the
compressive share where the hold was advised, the held axis's pull (held value minus
the forward model's truth over the advised width), and a written table's largest law
pull over T_RANGE, tau pull, fitted D0 pulls and unseen day against predicted; then per
side of the 25 % the held pulls' mean, spread and count beyond 3, the written tables
beyond 3 of any stated error, and the ``lambda`` in entry 52's factor
``sqrt(1 + (lambda rho)^2)`` that would bring the held pulls' spread to 1::

    .venv/bin/python benchmarks/messenger_fit_advice_tally.py /tmp/near25/chains.jsonl

The ``lambda`` solve re-widens the advised width from the refused fit's own D0 error
and rho (below 25 %: ``error x sqrt(1 + (lambda rho)^2)``, rounded up to two digits as
`fit_guards.d0_goal_refusal` does; above: the stated error with entry 52's added draws
scaled by ``lambda``): the held value and the truth do not depend on ``lambda``, only
the width does (the chains are not refitted).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from fluxcal.missions.messenger.fit_merit import ADVICE_MAX_COMPRESSIVE_SHARE  # noqa: E402

#: Pulls of a stated error (1 sigma) allowed (`messenger_fit_advice.MAX_PULL`).
MAX_PULL = 3.0


def up_to_two_digits(x: np.ndarray) -> np.ndarray:
    """``x`` rounded up to two significant digits (`fit_guards._up_to_two_digits`)."""
    x = np.asarray(x, dtype=float)
    step = 10.0 ** (np.floor(np.log10(x)) - 1)
    return np.ceil(np.round(x / step, 9)) * step


def hold_share(chain: dict) -> float:
    """The compressive share of the fit whose refusal advised the own-value hold."""
    step = next((s for s in chain["steps"] if "this fit's value and error" in s["verdict"]),
                chain["steps"][0])
    n, judged = step["share"]
    return n / judged


def widths_at(chains: list[dict], lam: float) -> np.ndarray:
    """The advised widths at ``lambda`` (module docstring), one per chain."""
    out = []
    for c in chains:
        h = c["own_hold"]
        if h["split_added"] is not None:  # above 25 %: the fit states the split
            e0 = np.sqrt(max(h["fit_error"] ** 2 - h["split_added"] ** 2, 0.0))
            out.append(up_to_two_digits(np.hypot(e0, lam * h["split_added"])))
        else:
            out.append(up_to_two_digits(h["fit_error"] * np.sqrt(1 + (lam * h["rho_named"]) ** 2)))
    return np.asarray(out, dtype=float)


def spread(x: np.ndarray) -> float:
    """Standard deviation (``ddof=1``); NaN under two values."""
    return float(np.std(x, ddof=1)) if len(x) > 1 else float("nan")


def lambda_for_spread(chains: list[dict], target: float = 1.0) -> float:
    """The smallest ``lambda`` in 0..10 (0.01 steps) whose held pulls' spread is at most
    ``target`` (the spread falls as ``lambda`` grows); NaN if none, or if the spread is
    below ``target`` already at ``lambda`` 0 (no ``lambda`` brings it up to ``target``)."""
    dev = np.array([c["own_hold"]["value"] - c["true_d0"] for c in chains])
    if spread(dev / widths_at(chains, 0.0)) < target:
        return float("nan")
    for lam in np.arange(0.0, 10.0001, 0.01):
        if spread(dev / widths_at(chains, lam)) <= target:
            return float(lam)
    return float("nan")


def cause(verdict: str) -> str:
    """A chain's end in a few words: the refusal's kind (or ``written``)."""
    for key, word in (("WRITTEN", "written"), ("not converged", "not converged"),
                      ("relaxation time", "tau goal"), ("predicted error", "predicted error"),
                      ("duty-cycle law", "D0 goal"), ("temperature law", "law band"),
                      ("compressive", "share")):
        if verdict.startswith(key) or (key == "compressive" and key in verdict[:80]):
            return word
    return verdict.split(":")[0][:30]


def level_rows(chains: list[dict]) -> list[str]:
    """Per compressive level: chains, first-fit shares, own-value holds each side of the
    25 %, and how the chains ended (markdown rows)."""
    out = ["| C | chains | share at the first fit: median (range) | own-value holds: at or "
           "below 25 % / above | chain ends |", "|---|---|---|---|---|"]
    for level in sorted({c["compressive"] for c in chains}):
        part = [c for c in chains if c["compressive"] == level]
        share = np.array([c["steps"][0]["share"][0] / c["steps"][0]["share"][1] for c in part])
        held = [c for c in part if c["own_hold"]]
        n_below = sum(1 for c in held if hold_share(c) <= ADVICE_MAX_COMPRESSIVE_SHARE)
        ends: dict[str, int] = {}
        for c in part:
            k = cause(c["steps"][-1]["verdict"])
            ends[k] = ends.get(k, 0) + 1
        out.append(f"| {level} | {len(part)} | {np.median(share):.1%} ({share.min():.1%}-"
                   f"{share.max():.1%}) | {n_below} / {len(held) - n_below} | "
                   + ", ".join(f"{k} {v}" for k, v in sorted(ends.items(), key=lambda x: -x[1]))
                   + " |")
    return out


def row(c: dict) -> str:
    """One chain as a markdown table row."""
    h = c["own_hold"]
    first = c["steps"][0]["verdict"].split(":")[0][:40]
    hold = ("-" if not h else f"{h['axis']}={h['value']:.4g}+-{h['width']:.2g} ("
            + (f"{h['factor']:.2f}x, rho {h['rho_named']:+.2f}" if h["split_added"] is None
               else f"split stated, rho {h['split_rho']:+.2f}") + ")")
    end = c["steps"][-1]
    if c["written"]:
        goal = end["goal"]
        how = f"written{'' if goal is None else f' at {goal:g}'} ({len(c['steps']) - 1} advices)"
        ratio = np.max(np.asarray(c["unseen_in_both"]) / np.asarray(c["predicted"]))
        d0 = np.abs(c["d0_pull"])
        rest = (f"{max(c['law_pull']):.2f} | {c['tau_pull']:+.2f} | {d0.max():.2f} | "
                + " / ".join(f"{u:.3f}" for u in c["unseen_in_both"]) + " vs "
                + " / ".join(f"{p:.3f}" for p in c["predicted"]) + f" ({ratio:.2f}x) | "
                + ("meets" if all(c["ok"].values()) else
                   "FAILS " + ",".join(k for k, v in c["ok"].items() if not v)))
    else:
        how = "refused: " + end["verdict"].split(";")[0][:70]
        rest = "- | - | - | - | -"
    held = f"{c['held_pull']:+.2f}" if "held_pull" in c else "-"
    n, judged = c["steps"][0]["share"]
    return (f"| {c['compressive']} | {c['seed']} | {n / judged:.1%} | {first} | {hold} | "
            f"{how} | {held} | {rest} |")


def side_summary(name: str, chains: list[dict]) -> list[str]:
    """The held pulls and the written tables of one side of the 25 %."""
    held = np.array([c["held_pull"] for c in chains])
    written = [c for c in chains if c["written"]]
    out = [f"{name}: {len(chains)} chains with an own-value hold, {len(written)} written"]
    if len(held):
        out.append(f"  held pulls: mean {held.mean():+.2f}, std {spread(held):.2f}, rms "
                   f"{np.sqrt(np.mean(held ** 2)):.2f}, range {held.min():+.2f}..{held.max():+.2f}"
                   f", |pull| > 3: {int(np.sum(np.abs(held) > MAX_PULL))}, > 2: "
                   f"{int(np.sum(np.abs(held) > 2))}")
        lam = lambda_for_spread(chains)
        dev = np.array([c["own_hold"]["value"] - c["true_d0"] for c in chains])
        bare = dev / widths_at(chains, 0.0)
        seeds = [c["seed"] for c in chains]
        first = [seeds.index(x) for x in sorted(set(seeds))]  # one chain per seed
        out.append(f"  {len(first)} seeds; one chain per seed (its lowest C): std "
                   f"{spread(held[first]):.2f}; unwidened (lambda 0): std {spread(bare):.2f}, "
                   f"range {bare.min():+.2f}..{bare.max():+.2f}, |pull| > 3: "
                   f"{int(np.sum(np.abs(bare) > MAX_PULL))}")
        out.append(f"  lambda bringing the held spread to 1.0: {lam:.2f} (now 1.0; NaN: "
                   f"none, the spread below 1 even unwidened); "
                   f"spread at lambda 0 / 1 / 1.5 / 2: " + " / ".join(
                       f"{spread(dev / widths_at(chains, la)):.2f}" for la in (0, 1, 1.5, 2)))
    if written:
        law = np.array([max(c["law_pull"]) for c in written])
        tau = np.array([c["tau_pull"] for c in written])
        d0 = np.array([np.max(np.abs(c["d0_pull"])) for c in written])
        ratio = np.array([np.max(np.asarray(c["unseen_in_both"]) / np.asarray(c["predicted"]))
                          for c in written])
        beyond = sum(1 for c in written if max(c["law_pull"]) > MAX_PULL
                     or abs(c["tau_pull"]) > MAX_PULL
                     or np.max(np.abs(c["d0_pull"])) > MAX_PULL)
        out += [f"  written: law max |err/band| median {np.median(law):.2f}, max {law.max():.2f};"
                f" tau pull mean {tau.mean():+.2f}, std {spread(tau):.2f}, max |.| "
                f"{np.abs(tau).max():.2f}; D0 (any axis) max |pull| {d0.max():.2f}",
                f"  unseen / predicted (worst axis): median {np.median(ratio):.2f}, max "
                f"{ratio.max():.2f}, above 1.5: {int(np.sum(ratio > 1.5))}",
                f"  written tables beyond 3 of any stated error: {beyond} of {len(written)}; "
                f"failing the harness: {sum(1 for c in written if not all(c['ok'].values()))}"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", type=Path, nargs="+")
    args = ap.parse_args()
    chains = [json.loads(line) for p in args.records for line in p.read_text().splitlines()
              if line.strip()]
    chains.sort(key=lambda c: (c["compressive"] or 0, c["seed"]))
    print("| C | seed | share | first refusal | own value advised (width; factor, rho) | "
          "chain end | held pull | law max pull | tau pull | D0 max pull | unseen vs "
          "predicted nT (worst ratio) | harness |")
    print("|" + "---|" * 12)
    for c in chains:  # the chains that reach a hold or a table (the rest: `level_rows`)
        if c["own_hold"] or c["written"]:
            print(row(c))
    print("\n" + "\n".join(level_rows(chains)))
    held = [c for c in chains if c["own_hold"] and "true_d0" in c]
    below = [c for c in held if hold_share(c) <= ADVICE_MAX_COMPRESSIVE_SHARE]
    above = [c for c in held if hold_share(c) > ADVICE_MAX_COMPRESSIVE_SHARE]
    same = np.isclose(widths_at(held, 1.0), [c["own_hold"]["width"] for c in held]) if held else []
    print(f"\n{len(chains)} chains; {len(held)} reach an own-value hold; the width re-made "
          f"at lambda 1 equals the advised one in {int(np.sum(same))} of {len(held)}")
    for name, part in (("at or below 25 %", below), ("above 25 %", above), ("all", held)):
        print("\n".join(side_summary(name, part)))
    print("held pulls by the share where the hold was advised:")
    for lo, hi in ((0.0, 0.22), (0.22, 0.25), (0.25, 0.28), (0.28, 1.0)):
        part = np.array([c["held_pull"] for c in held if lo < hold_share(c) <= hi])
        if len(part):
            print(f"  {lo:.0%}-{hi:.0%}: {len(part)}, mean {part.mean():+.2f}, std "
                  f"{spread(part):.2f}, largest |pull| {np.abs(part).max():.2f}")
    others = [c for c in chains if c["written"] and not c["own_hold"]]
    if others:
        print("\n".join(side_summary("written without an own-value hold", others)[1:]))


if __name__ == "__main__":
    main()
