"""When `calibrate` warns that a day's own heater-waveform error exceeds the stated one (issue 34).

    nice -n 10 env OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD/src:$PWD .venv/bin/python \\
        benchmarks/messenger_fit_warn.py --out /tmp/warn [--rare 28]
    ... benchmarks/messenger_fit_warn.py --saved /tmp/lead/mo16_save [...]

The constructed case (``--out``; about 3 min on one core): the fit demo's two training
days (`fit_demo.fit_training`, its truth tables and wind) with the schedule's duty cycles
in the ``--rare`` % column's bin moved to the neighbouring bins but for one 1000-s block,
so that column rests on one block of data; written at the goal its refusal advises, as
the demo does.  Then two unseen 2-h orbits of the demo's (`fit_demo.simulate_unseen`'s
configuration): heater on at ``--rare`` % throughout (the mix where the columns are
poorly determined: it must warn), and the demo's own schedule.  Each is calibrated with
the fitted folder (`chain.calibrate`, whose warning is printed), and the line gives the
day's own waveform part (`chain.day_waveform_part`), the verdict of the rule before
(any axis above 1.001x the stated part) and now (`heater_error.exceeds_stated`), and
the truth's rms inside T_RANGE and D_RANGE against the stated total.

``--saved``: the rule on the unseen days of `messenger_fit_pulls.py --unseen --save`
folders whose rows carry the unseen day's own prediction (``day_prediction``; stop 38
on): the stated numbers from the saved fit, the day's part from the row (3 decimals).
docs/decisions/messenger_fit.md entry 36, messenger_fit_verification.md section 29.
"""

from __future__ import annotations

import argparse
import logging
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.missions.messenger._unseen_day import commanded_duty  # noqa: E402

from fluxcal.calibration.heater_error import exceeds_stated  # noqa: E402
from fluxcal.geometry.kernels import KernelPool  # noqa: E402
from fluxcal.geometry.time import SclkKernel  # noqa: E402
from fluxcal.missions.messenger import fit_demo, levels  # noqa: E402
from fluxcal.missions.messenger.calibration_data import load_calibration  # noqa: E402
from fluxcal.missions.messenger.chain import calibrate, day_waveform_part  # noqa: E402
from fluxcal.missions.messenger.fit_reduce import WAVEFORM_FOLDS  # noqa: E402
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID  # noqa: E402
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate  # noqa: E402

#: The old rule: any axis above the stated part by more than the header's rounding.
OLD_SLACK = 1.001


def rare_schedule(rare: int, blocks: int = 180) -> list[int]:
    """The demo's training schedule with the ``rare`` % bin's duty cycles moved 4 % away
    (below the bin's centre down, else up), and one block at ``rare`` % (block 100)."""
    cycle = [d if not (rare - 2 <= d < rare + 2) else (d - 4 if d < rare else d + 4)
             for d in fit_demo.TRAINING_DUTY]
    sched = (cycle * (blocks // len(cycle) + 1))[:blocks]
    sched[100 if sched[100] else 101] = rare
    return sched


def verdicts(part, cal) -> tuple[bool, bool, np.ndarray]:
    """(old, new, the day's total) of a day's part against a fitted folder's numbers."""
    stated = np.asarray(cal.waveform_part_nt)
    fit = cal.constants["fit"]
    beyond, total = exceeds_stated(part, stated, np.asarray(fit["predicted_error_nt"]),
                                   float(fit["error_goal_nt"]), WAVEFORM_FOLDS)
    return bool(np.any(part > OLD_SLACK * stated)), bool(beyond.any()), total


def constructed(out: Path, rare: int) -> None:
    """Fit (or reuse ``out / "fit.pkl"``), then the two orbits."""
    pk = out / "fit.pkl"
    if not pk.exists():
        # the training schedule is a module constant `simulate_training` reads
        fit_demo.TRAINING_DUTY = rare_schedule(rare)
        verdict, fitted, res, truth = fit_demo.fit_training(out)
        pk.write_bytes(pickle.dumps((verdict, str(fitted), res, str(truth))))
    verdict, fitted, res, truth = pickle.loads(pk.read_bytes())
    m = res.merit
    print(f"fit: {verdict[-160:]}\n  stated {np.round(m['total_nt'], 3)} nT (waveform part "
          f"{np.round(m['waveform_nt'], 3)}), goal {m['goal_nt']:g}, D_RANGE {res.duty_range}; "
          f"fitted heater-on samples per bin "
          f"{[int(w.count.sum()) for w in res.stats.waveform]}")
    tc = load_calibration(fit_demo.UNSEEN_START, truth)
    cal = load_calibration(fit_demo.UNSEEN_START, fitted)
    err = np.asarray(res.waveform_error)
    true = np.sqrt(np.mean((np.asarray(res.calibration.heater_signal)[:, :100]
                            - np.asarray(tc.heater_signal)[:, :100]) ** 2, axis=1))
    k = int((rare - 10) // 4)
    print(f"  the {rare}-% column: stated {err[:, k].round(2)} counts, true {true[:, k].round(2)}")
    for name, duty in ((f"heater on at {rare} %", [rare]),
                       ("the demo's schedule", SimulationConfig().duty_cycles_percent)):
        with KernelPool(fit_demo.unseen_kernels(out), frames=FRAME_KERNELS):
            sclk = SclkKernel.from_pool(SPACECRAFT_ID)
            sim = simulate(SimulationConfig(start_utc=fit_demo.UNSEEN_START, duration_s=7200.0,
                                            duty_cycles_percent=duty), tc, sclk)
            ds = calibrate(sim["science"], sim["heater"], sim["temperature"], cal,
                           frames=("sc",), max_offset_step=None)
            periods, _ = levels.find_heater_periods(sim["heater"], cal, sclk)
            cd = commanded_duty(sim["truth"]["et"].values, fit_demo.UNSEEN_START)
        if duty == [rare]:
            cd = np.full(cd.size, rare)
        part = day_waveform_part(ds, periods, cal)[0]
        old, new, total = verdicts(part, cal)
        tr = sim["truth"]
        ok = (tr["range"].values == 0) & cal.temperature_range.contains(ds["temperature"].values)
        ok &= (cd < 10) | ((cd >= res.duty_range[0]) & (cd < res.duty_range[1]))
        e = ds["b_sensor"].values[ok] - tr["b_sensor"].values[ok]
        print(f"  orbit, {name}: the day's part {part.round(3)} nT, its total "
              f"{total.round(3)}; warns before {old}, now {new}; truth inside T_RANGE and "
              f"D_RANGE {np.sqrt((e ** 2).mean(axis=0)).round(3)} nT against the stated "
              f"{np.round(m['total_nt'], 3)}", flush=True)


def saved(folders: list[Path]) -> None:
    """The rule on the saved runs' unseen days (rows with ``day_prediction``)."""
    n = n_old = n_new = 0
    for folder in folders:
        for row_file in sorted(folder.glob("row_*.pkl")):
            row = pickle.loads(row_file.read_bytes())
            if not row.get("day_prediction"):
                print(f"{row_file}: no day_prediction (saved before stop 38), skipped")
                continue
            res, _ = pickle.loads((folder / row_file.name.replace("row_", "fit_")).read_bytes())
            m = res.merit
            part = np.asarray(row["day_prediction"]["waveform_nt"], dtype=float)
            stated = np.asarray(m["waveform_nt"])
            beyond, total = exceeds_stated(part, stated, np.asarray(m["total_nt"]),
                                           float(m["goal_nt"]), WAVEFORM_FOLDS)
            old = bool(np.any(part > OLD_SLACK * stated))
            n, n_old, n_new = n + 1, n_old + old, n_new + bool(beyond.any())
            print(f"{folder.name}/{row_file.stem}: part {part} / stated {stated.round(4)} "
                  f"(largest {np.max(part / stated):.3f}x), total {total.round(4)} / stated "
                  f"{np.round(m['total_nt'], 4)}; warns before {old}, now {bool(beyond.any())}; "
                  f"truth {np.round(row['unseen_in_both_nt'], 3)}")
    print(f"{n} unseen days: {n_old} warned before, {n_new} now")


def main() -> None:
    """Run the constructed case or judge saved runs."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="Working folder of the constructed case.")
    ap.add_argument("--rare", type=int, default=28,
                    help="Centre (%%) of the duty bin the training sees in one block only.")
    ap.add_argument("--saved", type=Path, nargs="*", default=[],
                    help="messenger_fit_pulls.py --save folders to judge instead.")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="  calibrate: %(message)s")
    if args.saved:
        saved(args.saved)
    elif args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        constructed(args.out, args.rare)
    else:
        ap.error("give --out FOLDER (the constructed case) or --saved FOLDER ...")


if __name__ == "__main__":
    main()
