"""Day task for ``fluxcal batch messenger`` (one EDR day -> its CDR products).

Input folder layout (one file per stream and day, day = UTC day of the recorded time)::

    MAGSCI_YYYYDDD.csv   science samples
    MAGHTR_YYYYDDD.csv   heater bits (the previous day's file is read too, for the
                         5-change look-back of sec. 7, when present)
    MAGTMP_YYYYDDD.csv   sensor temperatures (previous and next day read when present)
    kernels.tm           meta-kernel (or ``--kernels``)

A day's products hold the science samples recorded in that UTC day, read from the
science files of the day before, the day and the day after (a stream across midnight may
be given as one day's files; `routes.csv_day_files`, `run.batch_day_rows`).

or, when the folder holds ``edr_mapping.toml`` (`routes.EDR_MAPPING`), archived MAG EDRs (PDS3
labels + tables, any sub-folders) read through that mapping
(`fluxcal.missions.messenger.edr.read_edr`; day D reads the science EDRs of D, the
header and LAC EDRs of D-1 and D, the status EDRs of D-1..D+1).

`simulate_days` writes this layout from the forward model (demos, tests, benchmarks).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import copy_meta_kernel, write_meta_kernel
from fluxcal.geometry.time import SclkKernel, et_to_utc, utc_to_et
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.options import (
    MessengerOptions,
)
from fluxcal.missions.messenger.routes import (
    MessengerRun,
    day_file,
)
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.paths import make_folder, move_into, temporary_affixes
from fluxcal.runs import driver

DAY_S = 86_400.0
#: Default science rate/range schedule inside each simulated day's science window
#: (fractions of the window): rate settings 10, 8, 6, 9, 10 (20, 5, 1, 10, 20 Hz).
WINDOW_RATES = ((0.0, 10), (0.45, 8), (0.55, 6), (0.62, 9), (0.7, 10))
WINDOW_COARSE = ((0.3, 0.38),)


def default_kernels(input_dir: Path, kernels: Path | None) -> Path:
    """Return ``kernels``, or the input folder's ``kernels.tm`` (the batch layout)."""
    return Path(kernels) if kernels else Path(input_dir) / "kernels.tm"


def make_day_task(input_dir: Path, out_dir: Path, **options) -> driver.DayTask:
    """Build the task for ``fluxcal batch messenger``: `MessengerRun` on the generic driver.

    Options: ``kernels`` (default ``<input>/kernels.tm``) and the fields of
    `MessengerOptions` (formats, calib, frames, averages, max_offset_step, quicklook,
    quicklook_frame, version); unknown options are ignored.  A day's manifest checksums
    its inputs, kernels and calibration tables (`MessengerRun.day_calibration`).
    """
    allowed = {f.name for f in dataclasses.fields(MessengerOptions)}
    # None is a value here (no sec. 13 check, the default quicklook frame), not "unset"
    opts = {k: v for k, v in options.items() if k in allowed}
    for key in ("formats", "frames", "averages", "version"):
        if opts.get(key) is None:
            opts.pop(key, None)
        elif key in ("formats", "frames", "averages"):
            opts[key] = tuple(opts[key])
    return driver.DayTask(MessengerRun(), Path(input_dir), Path(out_dir),
                          MessengerOptions(**opts),
                          default_kernels(input_dir, options.get("kernels")),
                          name="messenger")


def _runs(days: Sequence[_dt.date]) -> list[list[_dt.date]]:
    """Group sorted unique days into runs of consecutive days."""
    runs: list[list[_dt.date]] = []
    for day in sorted(set(days)):
        if runs and (day - runs[-1][-1]).days == 1:
            runs[-1].append(day)
        else:
            runs.append([day])
    return runs


def simulate_days(
    input_dir: Path,
    days: Sequence[_dt.date],
    seconds_per_day: float = 3600.0,
    *,
    rate_setting: int | None = None,
    solar_wind: str = "realistic",
) -> list[_dt.date]:
    """Simulate raw MAG telemetry for ``days`` in the layout of ``fluxcal batch messenger``.

    Each run of consecutive days is one forward-model simulation
    (`fluxcal.missions.messenger.simulate.simulate`) with continuous heater and
    temperature streams (so a day's look-back into the previous day's heater file is
    real) and science samples in the first ``seconds_per_day`` of every day (a short
    day; ``86400`` for whole days).  Inside each window the rate setting changes, the
    spacecraft turns +Y to the Sun over 20-60 % of the window (10-min slews), and the
    range goes coarse as in `WINDOW_RATES`/`WINDOW_COARSE` (or one ``rate_setting``
    throughout).  The streams are split by the UTC day of their recorded MET into
    ``MAG{SCI,HTR,TMP}_YYYYDDD.csv`` (heater and temperature start 20 min before the
    first day, in the previous day's files); the truth goes to
    ``truth/MAGTRUTH_YYYYDDD.csv``; one synthetic kernel set per run, all listed in
    ``kernels.tm``.

    Parameters
    ----------
    input_dir : Path
        Folder to write (created).
    days : sequence of datetime.date
        Days to simulate (any order; gaps allowed).
    seconds_per_day : float
        Length of each day's science window from 00:00 UTC (s), at most 86400.
    rate_setting : int, optional
        One Table 1 rate setting for all samples (e.g. 6 = 1 vector/s).
    solar_wind : {"realistic", "quiet"}
        The interplanetary field (`fluxcal.missions.messenger.simulate.SimulationConfig`).

    Returns
    -------
    list of datetime.date
        The days that received science data (sorted).
    """
    if not 0.0 < seconds_per_day <= DAY_S:
        raise ValueError(f"seconds_per_day must be in (0, 86400], got {seconds_per_day}")
    input_dir = Path(input_dir)
    make_folder(input_dir)
    kernel_files: list[Path] = []
    done: list[_dt.date] = []
    for run in _runs(days):
        start = f"{run[0]:%Y-%m-%d}T00:00:00"
        duration = (len(run) - 1) * DAY_S + seconds_per_day
        windows = [(k * DAY_S, k * DAY_S + seconds_per_day) for k in range(len(run))]
        config = SimulationConfig(start_utc=start, duration_s=duration, science_windows=windows,
                                  solar_wind=solar_wind)
        if rate_setting is not None:
            config.rate_segments = [(0.0, rate_setting)]
        else:
            config.rate_segments = [((w0 + f * seconds_per_day) / duration, r)
                                    for w0, _ in windows for f, r in WINDOW_RATES]
        config.coarse_intervals = [((w0 + a * seconds_per_day) / duration,
                                    (w0 + b * seconds_per_day) / duration)
                                   for w0, _ in windows for a, b in WINDOW_COARSE]
        sunward = [(w0 + 0.2 * seconds_per_day, w0 + 0.6 * seconds_per_day)
                   for w0, _ in windows]
        mk = write_messenger_like_kernels(input_dir / "kernels" / f"run_{run[0]:%Y%j}", start,
                                          duration + config.lead_s, plus_y_sunward=sunward)
        # the SCLK and frame kernels are the same for every run: list the first ones; the
        # dynamic frames' copies are left out (the runs load fluxcal's, `FRAME_KERNELS`)
        frames = {Path(p).name for p in FRAME_KERNELS.values()}
        listed = sorted(p for p in mk.parent.iterdir()
                        if p.suffix != ".tm" and p.name not in frames)
        kernel_files += listed if not kernel_files else [k for k in listed
                                                         if k.suffix in (".bsp", ".bc")]
        with KernelPool(mk, frames=FRAME_KERNELS):
            sclk = SclkKernel.from_pool(SPACECRAFT_ID)
            sim = simulate(config, load_calibration(start), sclk)
            first = run[0] - _dt.timedelta(days=1)
            edges = utc_to_et(np.array([f"{first + _dt.timedelta(days=k)}T00:00:00"
                                        for k in range(len(run) + 2)]))
            day_index = {k: np.searchsorted(edges, sclk.to_et(sim[k]["partition"].values,
                                                              sim[k]["met"].values),
                                            side="right") - 1
                         for k in ("science", "heater", "temperature")}
        dims = {"science": "time", "heater": "heater_time", "temperature": "temperature_time"}
        # fluxcal's own temporary name: only such a folder is ever removed (paths rule 4)
        prefix, suffix = temporary_affixes(input_dir / "simulation")
        tmp = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=input_dir))
        for k in range(len(run) + 1):
            day = first + _dt.timedelta(days=k)
            part = {key: sim[key].isel({dims[key]: day_index[key] == k}) for key in dims}
            part["truth"] = sim["truth"].isel(time=day_index["science"] == k)
            paths = write_inputs(part, tmp, stem=f"{day:%Y%j}")
            has_science = part["science"].sizes["time"] > 0
            for key, code in (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP")):
                if part[key].sizes[dims[key]] and (key != "science" or has_science):
                    move_into(paths[key], day_file(input_dir, code, day))
            if has_science:
                make_folder(input_dir / "truth")
                move_into(paths["truth"], input_dir / "truth" / f"MAGTRUTH_{day:%Y%j}.csv")
                done.append(day)
        shutil.rmtree(tmp, ignore_errors=True)
    write_meta_kernel(input_dir / "kernels.tm", kernel_files)
    return sorted(done)


#: The two days of the batch demo (a stretch across the midnight between them).
DEMO_DAYS = (_dt.date(2012, 6, 1), _dt.date(2012, 6, 2))


def _split_by_day(path: Path, stream: str, out_dir: Path, sclk) -> list[Path]:
    """Split a MESSENGER CSV (``partition,met,...``) into ``MAG<stream>_YYYYDDD.csv``."""
    lines = path.read_text().splitlines()
    header, rows = lines[0], np.array(lines[1:])
    pm = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1), ndmin=2)
    et = sclk.to_et(pm[:, 0].astype(int), pm[:, 1])
    days = np.array([u[:10] for u in et_to_utc(et, style="iso", digits=0)])
    written = []
    for day in np.unique(days):
        d = _dt.date.fromisoformat(str(day))
        dest = out_dir / f"MAG{stream}_{d:%Y%j}.csv"
        atomic_write_bytes(dest, "\n".join([header, *rows[days == day].tolist()]) + "\n", now=True)
        written.append(dest)
    return written


def simulate_messenger_days(input_dir: Path, duration_s: float = 1800.0,
                            start: _dt.datetime | None = None,
                            rate_setting: int | None = None) -> list[_dt.date]:
    """Simulate MESSENGER MAG telemetry; write the batch input layout (one file per day).

    By default ``duration_s`` centred on the midnight between the two demo days.  With
    ``rate_setting`` (Table 1, e.g. 6 = 1 vector/s) the whole stretch uses that rate
    (long benchmark stretches).  Returns the UTC days that received science data.
    """
    input_dir = Path(input_dir)
    work = input_dir / "simulation"
    if start is None:
        start = _dt.datetime.combine(DEMO_DAYS[1], _dt.time()) - _dt.timedelta(
            seconds=duration_s / 2)
    start_utc = start.strftime("%Y-%m-%dT%H:%M:%S")
    config = SimulationConfig(start_utc=start_utc, duration_s=duration_s)
    if rate_setting is not None:
        config.rate_segments = [(0.0, rate_setting)]
    mk = write_messenger_like_kernels(work / "kernels", start_utc,
                                      duration_s + 2 * config.lead_s,
                                      plus_y_sunward=[(0.25 * duration_s, 0.45 * duration_s)])
    with KernelPool(mk, frames=FRAME_KERNELS):
        sim = simulate(config, load_calibration(start_utc), SclkKernel.from_pool(SPACECRAFT_ID))
    paths = {"kernels": mk, **write_inputs(sim, work / "inputs")}
    with KernelPool(paths["kernels"], frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        days = []
        for key, stream in (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP")):
            written = _split_by_day(Path(paths[key]), stream, input_dir, sclk)
            if key == "science":
                days = [_dt.datetime.strptime(p.stem[-7:], "%Y%j").date() for p in written]
    copy_meta_kernel(paths["kernels"], input_dir / "kernels.tm")  # paths relative to it
    return days
