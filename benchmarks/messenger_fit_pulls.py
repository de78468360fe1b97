"""Pull study of the MESSENGER variance estimator (issue 21, item 3).

    .venv/bin/python benchmarks/messenger_fit_pulls.py --realisations 20 --days 2
    .venv/bin/python benchmarks/messenger_fit_pulls.py --realisations 6 --compressive 0.03

Each realisation simulates ``--days`` days of the independent realistic wind of
``tests/missions/messenger/_realistic_wind.py`` (18 nT, Alfvenic rotations, sectors;
``--compressive`` relative |B| fluctuation) through `flight_sim` with seed ``1000 + k``,
fits it with ``--estimator variance`` (guards off: the estimator's own errors), and
prints, per realisation and then over all, the pulls ``(fit - truth) / stated error`` of
tau and D0 (x, y, z) and the law's largest error over -60..+40 C.  The stated errors are
the bootstrap over 3-h blocks.  Pulls with mean ~0 and spread ~1 mean the errors mean
what they say.
"""

from __future__ import annotations

import argparse
import datetime as dt
import functools
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.missions.messenger._realistic_wind import realistic_wind  # noqa: E402

from fluxcal.missions.messenger import forward  # noqa: E402
from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.fit import day_chunks, fit_days  # noqa: E402
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight  # noqa: E402


def one(k: int, days: int, compressive: float, passes: int) -> dict:
    """Simulate, fit and compare realisation ``k``."""
    with tempfile.TemporaryDirectory() as tmp:
        wind = functools.partial(realistic_wind, compressive=compressive)
        run = simulate_flight(Path(tmp) / "sim", FlightConfig(start="2010-03-01", days=days,
                                                              seed=1000 + k),
                              wind=wind, truth=False)
        true = forward.read_tables(sorted(run.calibration_dir.glob("*_v*.*")))
        base = load_calibration(np.datetime64("2010-03-01"))
        res = fit_days(day_chunks(run.input_dir, run.days), base, passes=passes,
                       estimator="variance", guard=False)
    cal = res.calibration
    t = np.arange(-60.0, 40.01, 1.0)
    tc = np.column_stack([true.a0, true.b0, true.a1, true.b1])

    def law(c):
        return np.maximum(c[:, 0] + c[:, 1] * t[:, None], c[:, 2] + c[:, 3] * t[:, None])

    tau_true = true.constants["relaxation"]["tau_s"]
    return {
        "tau_pull": (res.relaxation.tau - tau_true) / res.relaxation.tau_err,
        "tau_rel": res.relaxation.tau / tau_true - 1.0,
        "d0_pull": (cal.duty_cycle_d0 - true.d0) / np.array([f.slope_err for f in res.duty]),
        "d0_rel": cal.duty_cycle_d0 / true.d0 - 1.0,
        "law_max": np.abs(law(cal.temperature_coefficients) - law(tc)).max(axis=0),
    }


def main() -> None:
    """Run the study and print the pulls."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=20)
    ap.add_argument("--days", type=int, default=2)
    ap.add_argument("--compressive", type=float, default=0.0)
    ap.add_argument("--passes", type=int, default=4)
    args = ap.parse_args()
    rows = []
    for k in range(args.realisations):
        t0 = time.perf_counter()
        r = one(k, args.days, args.compressive, args.passes)
        rows.append(r)
        print(f"{k:3d} {time.perf_counter() - t0:6.1f} s  tau pull {r['tau_pull']:+.2f} "
              f"({r['tau_rel']:+.3f})  D0 pulls {np.round(r['d0_pull'], 2)} "
              f"({np.round(r['d0_rel'], 3)})  law max {np.round(r['law_max'], 2)} counts",
              flush=True)
    tau = np.array([r["tau_pull"] for r in rows])
    d0 = np.stack([r["d0_pull"] for r in rows])
    print(f"{dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M} UTC, {len(rows)} realisations, "
          f"{args.days} days, compressive {args.compressive}")
    print(f"tau pull: mean {tau.mean():+.2f} std {tau.std(ddof=1):.2f} "
          f"range {tau.min():+.2f}..{tau.max():+.2f}")
    for j, a in enumerate("xyz"):
        print(f"D0 {a} pull: mean {d0[:, j].mean():+.2f} std {d0[:, j].std(ddof=1):.2f} "
              f"range {d0[:, j].min():+.2f}..{d0[:, j].max():+.2f}")


if __name__ == "__main__":
    main()
