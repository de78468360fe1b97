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
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.missions.rosetta import _daily_mean_wind as wind  # noqa: E402

from fluxcal.geometry.kernels import KernelPool  # noqa: E402
from fluxcal.geometry.time import utc_to_tt2000  # noqa: E402
from fluxcal.missions.rosetta import calib, forward, level_a  # noqa: E402
from fluxcal.missions.rosetta.fit import fit_extended_model, reduced_temperature  # noqa: E402
from fluxcal.missions.rosetta.fit_variance import (  # noqa: E402
    fit_extended_model_variance,
    fit_offset_jumps_variance,
)

DAY = "2009-11-13"
JUMPS = np.array([[4.1, -7.3, 2.6], [-3.8, 5.2, -9.4]])
INTERVALS = (np.array(["2014-08-01T00:00:00", "2014-08-03T00:00:00"]),
             np.array(["2014-08-03T00:00:00", "2014-08-05T00:00:00"]))


def curve_pulls(k: int, rate: float, compressive: float) -> dict:
    """Daily model of realisation ``k``: pulls and rms errors of both estimators."""
    coef = wind.true_coefficients()
    cal = calib.load_ground_calibration("OB")
    raw, _, temp = wind.simulate_raw(DAY, 0.0, 24.0, coef, seed=2000 + k, rate_hz=rate,
                                     compression=compressive)
    a = level_a.level_a(raw, cal, calib.load_time_shift_table(),
                        calib.load_nominal_conversion())
    tt = reduced_temperature(a, cal)
    true_tt = forward.reduced_temperature(temp, cal)
    at = np.percentile(true_tt, [10, 50, 90])
    out = {}
    for name, fit in (("variance", fit_extended_model_variance(a, tt, seed=k)),
                      ("zero-mean", fit_extended_model(a, tt))):
        err = wind.curve(fit.coefficients, at) - wind.curve(coef, at)
        out[name] = {
            "pull": (err / fit.offset_sigma(at)).ravel(),
            "rms": np.sqrt(((wind.curve(fit.coefficients, true_tt)
                             - wind.curve(coef, true_tt)) ** 2).mean(axis=0)),
        }
    return out


def jump_pulls(k: int, compressive: float, rate: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Jumps of realisation ``k``: pulls and errors (2 x 3)."""
    rng = np.random.default_rng(3000 + k)
    t0 = int(utc_to_tt2000(INTERVALS[0][:1])[0])
    split = int(utc_to_tt2000(INTERVALS[0][1:])[0])
    secs = np.arange(0.0, 4 * 86400.0, 1.0 / rate)
    epoch = t0 + np.rint(secs * wind.NS).astype(np.int64)
    second = epoch >= split
    b = wind.daily_mean_field(secs.size, 1.0 / rate, rng, compression=compressive)
    rot = Rotation.from_euler("zyx", np.stack([60 * np.sin(secs / 40_000.0),
                                               20 * np.sin(secs / 25_000.0),
                                               10 * np.cos(secs / 17_000.0)], 1),
                              degrees=True).as_matrix()
    b_sc = np.einsum("nji,nj->ni", rot, b) + np.where(second[:, None], JUMPS[1], JUMPS[0])
    fit = fit_offset_jumps_variance(epoch, b_sc, *INTERVALS, sensor="OB", seed=k)
    err = fit.jumps - JUMPS
    return err / fit.sigma, err


def summary(label: str, pulls: np.ndarray) -> str:
    """One line: mean, std, range and count beyond 3 of a (realisations, n) array."""
    p = pulls.ravel()
    return (f"{label:28s} mean {p.mean():+.2f}  std {p.std(ddof=1):.2f}  "
            f"range {p.min():+.2f}..{p.max():+.2f}  |pull|>3: {np.count_nonzero(abs(p) > 3)}"
            f" of {p.size}")


def main() -> None:
    """Run the study and print the pulls."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=20)
    ap.add_argument("--rate", type=float, default=0.2, help="vector rate of the day (Hz)")
    ap.add_argument("--compressive", type=float, default=wind.COMPRESSION)
    args = ap.parse_args()
    rows, jumps = [], []
    with KernelPool():
        for k in range(args.realisations):
            t0 = time.perf_counter()
            r = curve_pulls(k, args.rate, args.compressive)
            jp, je = jump_pulls(k, args.compressive)
            rows.append(r)
            jumps.append((jp, je))
            print(f"{k:3d} {time.perf_counter() - t0:5.1f} s  variance rms "
                  f"{np.round(r['variance']['rms'], 3)} pulls {np.round(r['variance']['pull'], 1)}"
                  f"  zero-mean rms {np.round(r['zero-mean']['rms'], 2)}  jump err "
                  f"{np.round(je.ravel(), 3)}", flush=True)
    print(f"\n{args.realisations} realisations, rate {args.rate} Hz, compressive "
          f"{args.compressive}")
    for name in ("variance", "zero-mean"):
        pulls = np.array([r[name]["pull"] for r in rows])
        rms = np.array([r[name]["rms"] for r in rows])
        print(summary(f"curve pulls, {name}", pulls)
              + f"; curve rms {rms.min():.3f}..{rms.max():.3f} nT")
    jp = np.array([j[0] for j in jumps])
    je = np.array([j[1] for j in jumps])
    print(summary("jump pulls, variance", jp)
          + f"; |error| max {np.abs(je).max():.3f} nT, rms {np.sqrt((je**2).mean()):.3f} nT")


if __name__ == "__main__":
    main()
