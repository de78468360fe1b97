"""The law's band at its narrowest near the regulated -50 C, over saved pull-study fits.

    PYTHONPATH=src .venv/bin/python benchmarks/messenger_law_pivot.py DIR [DIR ...]

``DIR``: ``benchmarks/messenger_fit_pulls.py --save`` folders (``fit_<seed>.pkl``).
Per folder (verification section 58, issue 34):

- how far the last pass moved the law at -50 C, against the band there (is the fit
  stopped before the law settled? `fit_passes.LAW_TOLERANCE_COUNTS` allows 0.2 counts);
- the largest |error / band| over the stated T_RANGE's 1-C grid, seen beyond 3, and the
  number expected beyond 3 if the truth were normal with the covariance of the fit's own
  resamples (the band is their spread at each temperature;
  `messenger_fit_pulls.law_max_false_alarm`): a largest value over a grid of a 2-4
  parameter law exceeds 3 more often than one pull (0.27 %); and the simultaneous
  threshold that keeps 0.27 % for it (`messenger_fit_pulls.simultaneous_law_threshold`,
  decision entry 61), with the fits beyond it;
- the law's pulls at -50 / -40 / -30 C and that largest value with candidate floors
  (`FLOORS_NT`, and the last pass's law change at -50 C) added to the band in quadrature.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import messenger_fit_pulls as mp  # noqa: E402

from fluxcal.missions.messenger import fit_passes  # noqa: E402
from fluxcal.missions.messenger import fit_variance as fv  # noqa: E402

#: Candidate floors (nT) on the law's stated error, added in quadrature: 1-3 mnT, and the
#: convergence tolerance `fit_passes.LAW_TOLERANCE_COUNTS` (0.2 counts, 0.0094 nT).
FLOORS_NT = (0.0, 0.001, 0.0015, 0.002, 0.003,
             fit_passes.LAW_TOLERANCE_COUNTS * mp.NT_PER_COUNT)
#: Temperatures (C) of the pull rows.
ROWS_C = (-50.0, -40.0, -30.0)


def fit_record(path: Path) -> dict:
    """Errors, bands (nT) over the T_RANGE grid, the last pass's law change at -50 C and
    the chance of the largest |pull| beyond 3 for one saved fit (`mp.law_max_false_alarm`,
    its seeded draws) and its simultaneous threshold."""
    res, true = pickle.loads(path.read_bytes())
    lo, hi = res.fitted_range
    t = np.arange(np.ceil(lo), hi + 0.01, 1.0)
    t = t[res.stated_ranges.contains(t)]
    truth = np.column_stack([true.a0, true.b0, true.a1, true.b1])
    err = mp.NT_PER_COUNT * mp.law_difference(res.calibration.temperature_coefficients, truth, t)
    band = mp.NT_PER_COUNT * res.law_error(t)
    b_law = np.asarray(res.bootstrap["law"], dtype=float)
    dev = fv.law_values(b_law, t)
    dev = dev - dev.mean(axis=0)  # (resamples, T, 3): the band is its spread per T
    p_beyond = mp.law_max_false_alarm(b_law, t, 3.0)
    own_max = np.max(np.abs(dev / dev.std(axis=0)), axis=1)
    threshold = mp.simultaneous_law_threshold(b_law, t)
    m50 = np.array([-50.0])
    last = np.full(3, np.nan)
    if len(res.passes) > 1:
        c1, c0 = (np.asarray(h["temperature_coefficients"]) for h in res.passes[-2:][::-1])
        last = mp.NT_PER_COUNT * np.abs(mp.law_difference(c1, c0, m50))[0]
    return {"seed": int(path.stem[4:]), "t": t, "err": err, "band": band,
            "p_beyond": p_beyond, "p_own": (own_max > 3).mean(axis=0),
            "p_own_threshold": (own_max > threshold).mean(axis=0), "threshold": threshold,
            "passes": len(res.passes),
            "last_50": last, "band_50": mp.NT_PER_COUNT * res.law_error(m50)[0]}


def summary(folder: Path) -> None:
    """Print the folder's convergence, largest-pull and floor lines."""
    recs = [fit_record(p) for p in sorted(folder.glob("fit_*.pkl"))]
    print(f"== {folder}: {len(recs)} fits")
    ratio = np.array([r["last_50"] / r["band_50"] for r in recs])
    last = np.array([r["last_50"] for r in recs])
    print(f"last pass's law change at -50 C: median {1e3 * np.nanmedian(last):.3f} mnT, "
          f"largest {1e3 * np.nanmax(last):.3f} mnT; over the band there median "
          f"{np.nanmedian(ratio):.4f}, largest {np.nanmax(ratio):.3f}")
    p50 = np.array([(r["err"] / r["band"])[r["t"] == -50.0][0] for r in recs]).ravel()
    print(f"pulls at -50 C: N {p50.size}, spread {np.std(p50, ddof=1):.2f}; beyond 2 / 2.5 / 3: "
          + " / ".join(f"{int((np.abs(p50) > c).sum())} (normal {p50.size * q:.2f})"
                       for c, q in ((2, 0.0455), (2.5, 0.0124), (3, 0.0027))))
    for floor in (*FLOORS_NT, "last"):
        rows = []
        for tc in ROWS_C:
            p = np.array([(r["err"] / np.hypot(r["band"], r["last_50"] if floor == "last"
                                               else floor))[r["t"] == tc][0]
                          for r in recs if np.any(r["t"] == tc)])
            spread = np.std(p, axis=0, ddof=1) if len(p) > 1 else np.full(3, np.nan)
            rows.append(f"{tc:+.0f} C N {len(p)} {np.round(spread, 2)} "
                        f">3: {int((np.abs(p) > 3).sum())}")
        big = np.array([np.max(np.abs(r["err"] / np.hypot(
            r["band"], np.nan_to_num(r["last_50"]) if floor == "last" else floor)), axis=0)
            for r in recs])
        worst = [f"{r['seed']} {'xyz'[j]} {big[i, j]:.2f}"
                 for i, r in enumerate(recs) for j in range(3) if big[i, j] > 3]
        name = ("the last pass's change at -50 C" if floor == "last"
                else f"{1e3 * floor:4.1f} mnT")
        print(f"floor {name}: " + "; ".join(rows)
              + f"; largest over T_RANGE beyond 3: {len(worst)} {worst}")
    expected = np.sum([r["p_beyond"] for r in recs], axis=0)
    print(f"largest |error / band| over T_RANGE beyond 3 expected (normal, the resamples' "
          f"covariance) x / y / z {np.round(expected, 2)}, {expected.sum():.2f} in "
          f"{3 * len(recs)} axis-fits ({100 * expected.sum() / (3 * len(recs)):.2f} %); "
          f"by the resamples themselves {np.sum([r['p_own'] for r in recs]):.2f}")
    thr = np.array([r["threshold"] for r in recs])
    big = np.array([np.max(np.abs(r["err"] / r["band"]), axis=0) for r in recs])
    over = [f"{r['seed']} {'xyz'[j]} {big[i, j]:.2f} > {thr[i, j]:.2f}"
            for i, r in enumerate(recs) for j in range(3) if big[i, j] > thr[i, j]]
    print(f"simultaneous threshold (0.27 % for the largest, `simultaneous_law_threshold`): "
          f"min / median / max {thr.min():.2f} / {np.median(thr):.2f} / {thr.max():.2f}; "
          f"beyond it {len(over)} {over} (expected {0.0027 * thr.size:.2f}); by the "
          f"resamples themselves {np.sum([r['p_own_threshold'] for r in recs]):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", type=Path, nargs="+")
    args = ap.parse_args()
    for folder in args.folders:
        summary(folder)


if __name__ == "__main__":
    main()
