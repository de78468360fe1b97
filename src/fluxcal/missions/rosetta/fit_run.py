"""File driver of ``fluxcal rosetta fit``: raw science CSVs in, calibration files out.

The fits are in `fluxcal.missions.rosetta.fit`; this module reads the inputs, runs the
pipeline's LEVEL_A / LEVEL_B on them and writes what the fits return.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1.2 (science records), 4.2.3.3, 4.2.3.4,
   Appendix B.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.frames import rotate
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel, leapseconds, tt2000_to_et, tt2000_to_utc
from fluxcal.missions.rosetta import archive, calib, io, level_a, level_b
from fluxcal.missions.rosetta.calib import check_sensor
from fluxcal.missions.rosetta.fit import (
    DEFAULT_DEGREE,
    JUMP_BLOCK_S,
    JUMP_MAX_SIGMA,
    MODEL_BLOCK_S,
    fit_extended_model,
    reduce_offset_jumps,
    reduced_temperature,
    solve_offset_jumps,
    write_daily_model,
    write_offset_jump_table,
)
from fluxcal.missions.rosetta.fit_pictures import write_fit_pictures
from fluxcal.missions.rosetta.fit_variance import (
    ESTIMATORS,
    GOAL_NT,
    VarianceSettings,
    fit_extended_model_variance,
    fit_offset_jumps_variance,
)
from fluxcal.missions.rosetta.identity import FRAME_KERNELS
from fluxcal.missions.rosetta.level_c import FRAMES, SPACECRAFT_FRAME
from fluxcal.products.paths import make_folder
from fluxcal.products.provenance import portable_text
from fluxcal.textfile import read_text


def _portable(prov: dict) -> dict[str, str]:
    """Return the provenance with every path reduced to its file name."""
    return {key: portable_text(str(value)) for key, value in prov.items()}

def read_intervals_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read ``start_utc,end_utc`` rows (``#`` comments allowed; extra columns ignored).

    Raises
    ------
    InputFormatError
        Missing column or a time that is not ISO UTC, naming file, line and field.
    """
    path = Path(path)
    try:
        lines = read_text(path, "a CSV text file of intervals start_utc,end_utc").splitlines()
    except OSError as exc:
        raise InputFormatError(f"cannot read: {exc.strerror}", path=str(path)) from None
    numbered = [(i, s) for i, s in enumerate(lines, 1) if s.strip() and not s.startswith("#")]
    if not numbered:
        raise InputFormatError("no header line start_utc,end_utc", path=str(path))
    reader = csv.DictReader([s for _, s in numbered])
    for name in ("start_utc", "end_utc"):
        if name not in (reader.fieldnames or []):
            raise InputFormatError(f"missing column {name} (header {reader.fieldnames})",
                                   path=str(path), line=numbered[0][0], field=name)
    start, end = [], []
    for (line, _), row in zip(numbered[1:], reader, strict=True):
        for name, out in (("start_utc", start), ("end_utc", end)):
            try:
                out.append(str(np.datetime64(str(row[name]).strip(), "s")))
            except ValueError:
                raise InputFormatError(f"{row[name]!r} is not an ISO UTC time", path=str(path),
                                       line=line, field=name) from None
    if not start:
        raise InputFormatError("no intervals", path=str(path))
    return np.array(start), np.array(end)


def fit_files(
    science: Path | Sequence[Path],
    sensor: str,
    out: Path,
    *,
    hk_file: Path | None = None,
    calib_dir: Path | None = None,
    kernels: Path | None = None,
    primary: str = "OB",
    degree: int = DEFAULT_DEGREE,
    block_s: float | None = None,
    jumps: bool = False,
    intervals: Path | None = None,
    max_sigma: float | None = JUMP_MAX_SIGMA,
    boom: str = "deployed",
    alignment_from_kernels: bool = False,
    estimator: str = "variance",
    goal: float | None = None,
) -> list[Path]:
    """Run ``fluxcal rosetta fit`` on one or more raw science files of one sensor.

    Without ``jumps``: one daily extended-temperature file per UTC day of the telemetry
    time (the day the pipeline applies it to, `extended_model.utc_days`), fitted on the
    ground-calibrated LEVEL_A of that day (daily files in ``calib_dir`` are not applied:
    the fit is of the residual after the ground calibration; docs/decisions/rosetta_fit.md
    decision 3).  A day must be in one file.  With ``jumps``: LEVEL_B of each file as
    ``rosetta calibrate`` makes it (daily files of ``calib_dir`` applied, *no* jump
    table), rotated to CSEQ with the loaded kernels and reduced to blocks; the blocks of
    all files are fitted together per interval of ``intervals`` (CSV ``start_utc,end_utc``)
    or, by default, of the jump table (``calib_dir`` or fluxcal's) rows that overlap the
    data; written as ``RPCMAG_OFFSET_JUMPS.csv`` (decision 4).

    ``hk_file`` is read (checked) and recorded as an input; the temperatures come from
    the science records' thermistor words (sec. 4.1.2), at the vector rate.

    ``estimator`` names what the fit assumes about the field (issue 21): ``"variance"``
    (default; `fluxcal.missions.rosetta.fit_variance`: rotations at nearly constant
    ``|B|`` within intervals of ``block_s``, default 1200 s, nothing about the mean
    field; no attitude needed for the jumps) or ``"zero-mean"`` (the seed's criteria:
    the day's field, or the CSEQ ``B_z``, averages to zero).  A variance fit whose error
    exceeds ``max_sigma`` (nT) is refused, and so is one whose figure of merit (the
    predicted error of a recalibrated day, or twice a jump's error) exceeds ``goal`` (nT;
    default `fit_variance.GOAL_NT`, 0.2 nT; a larger value is written into the file).

    Returns
    -------
    list of Path
        Files written.

    Raises
    ------
    FluxcalError
        Every input, calibration and fit error (naming file, line, field, day, interval).
    """
    files = [Path(science)] if isinstance(science, (str, Path)) else [Path(s) for s in science]
    if not files:
        raise FluxcalError("no science file given (--input)")
    sensor = check_sensor(sensor)
    out = Path(out)
    if estimator not in ESTIMATORS:
        raise FluxcalError(f"estimator {estimator!r}: choose one of {', '.join(ESTIMATORS)}")
    variance = estimator == "variance"
    vset = VarianceSettings(**({"interval_s": block_s} if block_s else {}),
                            **({"max_sigma": max_sigma} if max_sigma is not None else {}),
                            **({"goal": goal} if goal is not None else {}))
    if jumps and kernels is None and not variance:
        raise FluxcalError("--jumps needs --kernels (attitude and comet for the CSEQ frame; "
                           "--estimator variance needs none)")
    with KernelPool(kernels, frames=FRAME_KERNELS) as pool:
        lsk = leapseconds()
        sclk = SclkKernel.from_pool(io.SCLK_ID) if kernels is not None else None
        cal = calib.load_ground_calibration(sensor, calib_dir)
        shifts = calib.load_time_shift_table(calib_dir)
        nominal = calib.load_nominal_conversion(calib_dir)
        raws = [archive.read_science(f, sensor, sclk=sclk, lsk=lsk) for f in files]
        if hk_file is not None:
            archive.read_hk(hk_file, sclk=sclk, lsk=lsk)
        prov = {
            "inputs": " ".join(str(p) for p in [*files, hk_file] if p is not None),
            "ground calibration": cal.source,
            "kernels": " ".join(str(k) for k in pool.loaded) if kernels is not None else "LSK",
        }
        make_folder(out)
        if not jumps:
            pieces, seen = [], {}
            for path, raw in zip(files, raws, strict=True):
                day_index, days, _ = level_a.utc_days(raw["epoch"].values, lsk)
                for d, day in enumerate(days):  # loop over days
                    sel = np.flatnonzero(day_index == d)
                    if sel.size == 0:
                        continue
                    if day in seen:
                        raise FluxcalError(
                            f"{path}: records of {day} are also in {seen[day]}; give each "
                            "day's records in one file (one fit per day, sec. 4.2.3.3)"
                        )
                    seen[day] = path
                    pieces.append((day, raw.isel(time=sel)))
            fits = []
            for day, part in pieces:
                a = level_a.level_a(part, cal, shifts, nominal, primary=primary, lsk=lsk)
                if variance:
                    fits.append(fit_extended_model_variance(
                        a, reduced_temperature(a, cal), degree=degree, settings=vset, day=day))
                else:
                    fits.append(fit_extended_model(
                        a, reduced_temperature(a, cal), degree=degree,
                        block_s=block_s or MODEL_BLOCK_S, day=day))
            written = [write_daily_model(f, out, provenance=_portable(prov)) for f in fits]
            write_fit_pictures(fits, out)
            return written
        return [_fit_jumps(files, raws, sensor, out, cal, shifts, nominal, prov,
                           calib_dir=calib_dir, primary=primary, block_s=block_s or JUMP_BLOCK_S,
                           intervals=intervals, max_sigma=max_sigma, boom=boom,
                           alignment_from_kernels=alignment_from_kernels, lsk=lsk,
                           variance=vset if variance else None)]


def _fit_jumps(files, raws, sensor, out, cal, shifts, nominal, prov, *, calib_dir, primary,
               block_s, intervals, max_sigma, boom, alignment_from_kernels, lsk,
               variance=None) -> Path:
    """Run the ``--jumps`` branch of `fit_files` (kernels loaded); return the table path."""
    models = calib.find_daily_offset_models(calib_dir, sensor)
    alignment = None if alignment_from_kernels else calib.load_alignment(calib_dir)
    levels_b = []
    for raw in raws:  # loop over files
        a = level_a.level_a(raw, cal, shifts, nominal, daily_models=models, primary=primary,
                            lsk=lsk)
        levels_b.append(level_b.level_b(a, alignment, None, boom=boom, lsk=lsk))
    if intervals is not None:
        start, end = read_intervals_csv(intervals)
        prov["intervals"] = str(intervals)
    else:
        table = calib.load_offset_jump_table(calib_dir)
        ends = np.concatenate([b["epoch"].values[[0, -1]] for b in levels_b]).astype(np.int64)
        first, last = (np.datetime64(str(s)[:19], "s")
                       for s in tt2000_to_utc(np.array([ends.min(), ends.max()]), digits=0,
                                              lsk=lsk))
        s_all, e_all = table.start_utc.astype("M8[s]"), table.end_utc.astype("M8[s]")
        use = (e_all > first) & (s_all <= last)
        if not use.any():
            raise FluxcalError(
                f"{files[0]}: no interval of {table.source} overlaps the data "
                f"({first} .. {last}); give --intervals CSV"
            )
        start, end = table.start_utc[use], table.end_utc[use]
        prov["intervals"] = table.source
    if variance is not None:
        epoch = np.concatenate([b["epoch"].values.astype(np.int64) for b in levels_b])
        b_sc = np.concatenate([b["b"].values for b in levels_b])
        order = np.argsort(epoch, kind="stable")
        fit = fit_offset_jumps_variance(epoch[order], b_sc[order], start, end, sensor=sensor,
                                        settings=variance, lsk=lsk)
        prov["goal"] = (f"{variance.goal:g} nT (twice each jump's error)" + (
            "" if variance.goal <= GOAL_NT else
            f" (ACCEPTED ABOVE THE DEFAULT GOAL {GOAL_NT:g} nT by --goal)"))
        prov["alignment"] = levels_b[0].attrs["alignment"]
        prov["daily models"] = ", ".join(m.source for m in models.values()) or "none"
        return _with_pictures(fit, out, write_offset_jump_table(
            [fit], Path(out) / calib.JUMPS_FILE, provenance=_portable(prov)))
    blocks = []
    for b in levels_b:
        epoch = b["epoch"].values.astype(np.int64)
        _, rotation = rotate(b["b"].values, tt2000_to_et(epoch, lsk), SPACECRAFT_FRAME,
                             FRAMES["CSEQ"], return_matrices=True)
        blocks.append(reduce_offset_jumps(epoch, b["b"].values, rotation, start, end,
                                          block_s=block_s, lsk=lsk))
    fit = solve_offset_jumps(blocks, start, end, sensor=sensor, max_sigma=max_sigma)
    prov["alignment"] = levels_b[0].attrs["alignment"]
    prov["daily models"] = ", ".join(m.source for m in models.values()) or "none"
    return _with_pictures(fit, out, write_offset_jump_table(
        [fit], Path(out) / calib.JUMPS_FILE, provenance=_portable(prov)))


def _with_pictures(fit, out: Path, table: Path) -> Path:
    """Draw the jump fit's picture and the folder's index beside ``table``; return it."""
    write_fit_pictures([fit], out)
    return table
