"""Pull study of the Rosetta variance estimators (issue 21, item 3).

    .venv/bin/python benchmarks/rosetta_fit_pulls.py --realisations 20 --rate 0.2
    .venv/bin/python benchmarks/rosetta_fit_pulls.py --realisations 20 --compressive 0.0

Each realisation ``k`` (seed ``2000 + k``) simulates one day of the independent
daily-mean wind of ``tests/missions/rosetta/_daily_mean_wind.py`` (3 nT, direction
wandering about a sector direction, ``--compressive`` relative |B| fluctuation) through
the seed's instrument model, makes the ground-calibrated LEVEL_A and fits the daily
polynomial with both estimators; then four days of the same wind in CSEQ under a
rotating attitude with two Appendix B intervals, fitted by the variance jump estimator.
Printed per realisation and over all: the pulls ``(fit - truth) / stated error`` of the
curve at the 10th, 50th and 90th percentile of the day's reduced temperature (x, y, z)
and of the jumps (2 intervals x 3 axes), and the curve's rms error over the day.

The truth of the daily model is the offset the LEVEL_A data carry, ``B_A - B_true`` per
vector (the forward model's field subtracted), not the forward model's polynomial alone:
the seed's count and thermistor-word conversions add a constant of (0.004, -0.000, 0.006)
nT (half an ADC step through the ground calibration) that is indistinguishable from an
offset, and that the fit rightly puts into ``P_0`` (a calibrated product then has none of
it).  The curve's truth at a temperature is the mean of ``B_A - B_true`` over the vectors
within 0.5 C of it; the coefficients' truth is the cubic
fitted to ``B_A - B_true`` against the pipeline's ``T~`` (numpy, not the fit code).
Compared with the polynomial alone, the curve pulls had a mean of +0.13 instead of -0.03
(100 realisations; docs/decisions/rosetta_fit.md, pulls section).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from numpy.polynomial import Polynomial

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.missions.rosetta import _daily_mean_wind as wind  # noqa: E402

from fluxcal.errors import FitRefusedError  # noqa: E402
from fluxcal.geometry.kernels import KernelPool  # noqa: E402
from fluxcal.missions.rosetta import calib, forward, level_a  # noqa: E402
from fluxcal.missions.rosetta.fit import fit_extended_model, reduced_temperature  # noqa: E402
from fluxcal.missions.rosetta.fit_variance import (  # noqa: E402
    fit_extended_model_variance,
    fit_offset_jumps_variance,
)

DAY = "2009-11-13"
JUMPS = wind.TRUE_JUMPS
#: Share of a unit Gaussian beyond 3 (two-sided).
GAUSS_BEYOND_3 = 0.0026998
INTERVALS = tuple(np.array(iv) for iv in wind.JUMP_INTERVALS)


def curve_pulls(k: int, rate: float, compressive: float) -> dict:
    """Daily model of realisation ``k``: pulls and rms errors of both estimators.

    ``pull`` (3 temperatures x 3 axes) of the curve, ``coef`` (P_0 .. P_3 x 3 axes) of the
    power-basis coefficients; truth as the module docstring says.
    """
    coef = wind.true_coefficients()
    cal = calib.load_ground_calibration("OB")
    raw, b_true, temp = wind.simulate_raw(DAY, 0.0, 24.0, coef, seed=2000 + k, rate_hz=rate,
                                          compression=compressive)
    a = level_a.level_a(raw, cal, calib.load_time_shift_table(),
                        calib.load_nominal_conversion())
    tt = reduced_temperature(a, cal)
    true_tt = forward.reduced_temperature(temp, cal)
    carried = a["b"].values - b_true  # the offset the data carry, per vector
    bands = [np.abs(true_tt - v) < 0.5 for v in np.percentile(true_tt, [10, 50, 90])]
    at = np.array([tt[m].mean() for m in bands])
    truth_at = np.stack([carried[m].mean(axis=0) for m in bands])
    truth_coef = np.stack([Polynomial.fit(tt, carried[:, i], 3).convert().coef
                           for i in range(3)], axis=1)
    out = {}
    try:
        variance = fit_extended_model_variance(a, tt, seed=k)
    except FitRefusedError as exc:  # a refusal is an outcome: counted, not a pull
        out["refused"] = str(exc)
        variance = None
    for name, fit in (("variance", variance), ("zero-mean", fit_extended_model(a, tt))):
        if fit is None:
            continue
        err = np.stack([(fit.offset(tt[m])).mean(axis=0) for m in bands]) - truth_at
        out[name] = {
            "pull": err / fit.offset_sigma(at),
            "coef": (fit.coefficients[:4] - truth_coef) / fit.sigma[:4],
            "rms": np.sqrt(((fit.offset(tt) - carried) ** 2).mean(axis=0)),
            "intervals": fit.notes.get("intervals", ""),
            "rms_polynomial": np.sqrt(((wind.curve(fit.coefficients, true_tt)
                                        - wind.curve(coef, true_tt)) ** 2).mean(axis=0)),
        }
    return out


def jump_pulls(k: int, compressive: float, rate: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Jumps of realisation ``k``: pulls and errors (2 x 3)."""
    epoch, b_sc, _, _ = wind.jump_data(3000 + k, rate, compressive, JUMPS)
    fit = fit_offset_jumps_variance(epoch, b_sc, *INTERVALS, sensor="OB", seed=k)
    err = fit.jumps - JUMPS
    return err / fit.sigma, err


def summary(label: str, pulls: np.ndarray) -> str:
    """One line: mean, std, range and count beyond 3 of a (realisations, ...) array."""
    p = pulls.ravel()
    return (f"{label:28s} mean {p.mean():+.2f}  std {p.std(ddof=1):.2f}  "
            f"range {p.min():+.2f}..{p.max():+.2f}  |pull|>3: {np.count_nonzero(abs(p) > 3)}"
            f" of {p.size} (Gaussian: {GAUSS_BEYOND_3 * p.size:.1f})")


def parameter_table(name: str, pulls: np.ndarray, labels: list[str]) -> list[str]:
    """Markdown rows ``| parameter | N | mean | std | max abs |`` of (realisations, rows, 3)."""
    out = []
    for r, label in enumerate(labels):
        for i, axis in enumerate("xyz"):
            p = pulls[:, r, i]
            out.append(f"| {name} {label} {axis} | {p.size} | {p.mean():+.2f} | "
                       f"{p.std(ddof=1):.2f} | {np.abs(p).max():.2f} |")
    return out


def main() -> None:
    """Run the study and print the pulls."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="first realisation (seed offset)")
    ap.add_argument("--rate", type=float, default=0.2, help="vector rate of the day (Hz)")
    ap.add_argument("--compressive", type=float, default=wind.COMPRESSION)
    ap.add_argument("--table", action="store_true", help="print the per-parameter table")
    args = ap.parse_args()
    rows, jumps = [], []
    start = time.perf_counter()
    with KernelPool():
        for k in range(args.first, args.first + args.realisations):
            t0 = time.perf_counter()
            r = curve_pulls(k, args.rate, args.compressive)
            try:
                jp, je = jump_pulls(k, args.compressive)
                jumps.append((jp, je))
            except FitRefusedError as exc:
                print(f"{k:3d} jumps refused: {exc}", flush=True)
                jp = je = np.full((2, 3), np.nan)
            rows.append(r)
            if "refused" in r:
                print(f"{k:3d} variance refused: {r['refused']}", flush=True)
                continue
            print(f"{k:3d} {time.perf_counter() - t0:5.1f} s  variance rms "
                  f"{np.round(r['variance']['rms'], 3)} pulls "
                  f"{np.round(r['variance']['pull'].ravel(), 1)}  zero-mean rms "
                  f"{np.round(r['zero-mean']['rms'], 2)}  jump err {np.round(je.ravel(), 3)}  "
                  f"intervals: {r['variance']['intervals']}",
                  flush=True)
    print(f"\n{args.realisations} realisations from {args.first}, rate {args.rate} Hz, "
          f"compressive {args.compressive}, {time.perf_counter() - start:.0f} s")
    refused = [r for r in rows if "refused" in r]
    print(f"variance refused {len(refused)} of {len(rows)} days")
    rows = [r for r in rows if "refused" not in r] or rows[:0]
    for name in ("variance", "zero-mean"):
        if not rows:
            break
        pulls = np.array([r[name]["pull"] for r in rows])
        rms = np.array([r[name]["rms"] for r in rows])
        rms_p = np.array([r[name]["rms_polynomial"] for r in rows])
        print(summary(f"curve pulls, {name}", pulls)
              + f"; curve rms {rms.min():.3f}..{rms.max():.3f} nT (against the polynomial "
              f"alone {rms_p.min():.3f}..{rms_p.max():.3f})")
        print(summary(f"P_0..P_3 pulls, {name}", np.array([r[name]["coef"] for r in rows])))
    print(f"jumps refused {args.realisations - len(jumps)} of {args.realisations}")
    if not jumps:
        return
    jp = np.array([j[0] for j in jumps])
    je = np.array([j[1] for j in jumps])
    print(summary("jump pulls, variance", jp)
          + f"; |error| max {np.abs(je).max():.3f} nT, rms {np.sqrt((je**2).mean()):.3f} nT")
    if args.table and rows:
        print("\n| parameter | N | mean | std | max abs |\n|---|---|---|---|---|")
        v = "variance"
        print("\n".join(
            parameter_table("curve", np.array([r[v]["pull"] for r in rows]),
                            ["T~10", "T~50", "T~90"])
            + parameter_table("coefficient", np.array([r[v]["coef"] for r in rows]),
                              ["P_0", "P_1", "P_2", "P_3"])
            + parameter_table("jump", jp, ["J_1", "J_2"])))


if __name__ == "__main__":
    main()
