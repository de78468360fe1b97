"""``fluxcal rosetta ...`` commands and ``fluxcal simulate rosetta``.

``calibrate`` and ``simulate`` follow "RO-IGEP-TR0028 Rosetta RPC-MAG calibration"
(sec. 3-4.8); the cleaning commands are added here by the cleaning issue.

References
----------
.. [1] RO-IGEP-TR0028 Rosetta RPC-MAG calibration (seed 003), sec. 4.1 (calibration
   files), 4.3.1 (alignment).
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import typer

from fluxcal import preflight
from fluxcal.cli_help import HelpGroup
from fluxcal.errors import InputFormatError
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.runs.display_cli import compilation_notice, progress_display, status_display
from fluxcal.runs.options import with_config, with_options

#: Levels computed from LEVEL_B, i.e. through the sensor-to-spacecraft alignment.
ALIGNED_LEVELS = frozenset("BCFG")


def warn_placeholder_alignment(calib_dir: Path | None) -> bool:
    """Warn on stderr when the alignment in use is fluxcal's placeholder identity.

    The shipped ``RPCMAG_SC_ALIGN.TXT`` is marked ``PLACEHOLDER``: the measured
    URF -> spacecraft rotations (RO-IGEP-TR0028 sec. 4.3.1) are not public.  Every run
    that uses it says so here (the products say so in their ``alignment`` attribute and
    label).  Returns whether it warned.
    """
    from fluxcal.missions.rosetta import calib

    alignment = calib.load_alignment(calib_dir)
    if alignment.placeholder:
        typer.echo(
            f"fluxcal: warning: the alignment {alignment.source} is fluxcal's PLACEHOLDER "
            "identity, not the measured sensor-to-spacecraft rotation (RO-IGEP-TR0028 "
            "sec. 4.3.1): LEVEL_B, C, F, G directions are only as good as that; give "
            "--calib FOLDER holding the real RPCMAG_SC_ALIGN.TXT, or "
            "--alignment-from-kernels", err=True)
    return alignment.placeholder

def describe_daily_model(path: Path) -> str:
    """One line: where a written daily model was fitted and its stated curve error."""
    from fluxcal.missions.rosetta import calib

    model = calib.read_daily_offset_model(path)
    if model.temperature_range is None or model.curve_sigma is None:
        return "no fitted range or curve error recorded"
    lo, hi = model.temperature_range
    return (f"fitted on T~ {lo:.2f} .. {hi:.2f} C; curve error (1 sigma, largest over "
            "that range) x y z " + " ".join(f"{v:.3f}" for v in model.curve_sigma) + " nT; "
            "'rosetta calibrate' warns about vectors outside the range")


app = typer.Typer(help="Rosetta pipeline commands.", no_args_is_help=True,
                  rich_markup_mode=None, cls=HelpGroup)


@app.command()
@with_options(RosettaOptions)
def calibrate(
    science: Path = typer.Option(
        ..., "--input", "--science", help="Raw science of one sensor (RO-IGEP-TR0028 sec. "
        "4.1.2): a CSV file, or the archive's EDITED products (a folder searched "
        "recursively, or one .LBL)."
    ),
    sensor: str = typer.Option(..., "--sensor", help="OB or IB."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    hk: Path | None = typer.Option(
        None, "--hk", help="Raw HK (RO-IGEP-TR0028 sec. 4.1.1), converted to HK LEVEL_A: a CSV "
        "file, or EDITED HK products (folder or .LBL)."
    ),
    kernels: Path | None = typer.Option(
        None, "--kernels", help="Meta-kernel (SCLK -226, CK, SPK): times from OBT; needed for C, G."
    ),
    stitch_state: Path | None = typer.Option(
        None,
        "--stitch-state",
        help="JSON file carrying the midnight-stitching state from one day's run to the next.",
    ),
    options: RosettaOptions = None,  # type: ignore[assignment] - from the command line
) -> None:
    """Calibrate raw RPC-MAG telemetry into LEVEL_A, B, C, E, F, G products.

    Follows "RO-IGEP-TR0028 Rosetta RPC-MAG calibration" sec. 4.1-4.8.
    """
    from fluxcal.missions.rosetta.products import parse_levels
    from fluxcal.missions.rosetta.routes import FILE_LEVELS, run_files

    calib = options.calib
    check_raw_source(science, "--input")
    if hk is not None:
        check_raw_source(hk, "--hk")
    if calib is not None:
        preflight.existing_folder(calib, "--calib")
    if kernels is not None:
        preflight.existing_file(kernels, "--kernels")
    preflight.writable_folder(out, "--out")
    level_list = parse_levels(",".join(options.levels or FILE_LEVELS))
    summary = {}

    def count(levels) -> None:
        a = levels.sensors[0].levels["A"]
        summary.update(n=a.sizes["time"], dropped=a.attrs["n_dropped_quality"])

    with compilation_notice(), progress_display("rosetta calibrate") as progress:
        paths = run_files(science, sensor, out, hk=hk, kernels=kernels, options=options,
                          state_file=stitch_state, on_calibrated=count, progress=progress)
    if ALIGNED_LEVELS & set(level_list) and not options.alignment_from_kernels:
        warn_placeholder_alignment(calib)
    typer.echo(f"{summary['n']} vectors calibrated ({summary['dropped']} dropped for "
               f"quality); {len(paths)} files in {out}")


@app.command()
@with_config(exclude=("science", "sensor", "out", "hk", "kernels", "intervals"))
def fit(
    science: list[Path] = typer.Option(
        ..., "--input", "--science", help="Raw science of one sensor (RO-IGEP-TR0028 sec. "
        "4.1.2): a CSV, or EDITED archive products (folder or .LBL); repeat for several "
        "files (days)."
    ),
    sensor: str = typer.Option(..., "--sensor", help="OB or IB."),
    out: Path = typer.Option(..., "--out", help="Folder for the fitted calibration files."),
    hk: Path | None = typer.Option(
        None, "--hk", help="Raw HK CSV (checked and recorded; temperatures come from the "
        "science records)."
    ),
    calib: Path | None = typer.Option(
        None, "--calib", help="Folder with calibration files overriding fluxcal's defaults."
    ),
    kernels: Path | None = typer.Option(
        None, "--kernels", help="Meta-kernel (SCLK -226, CK, SPK); needed with --jumps "
        "--estimator zero-mean."
    ),
    primary: str = typer.Option("OB", "--primary", help="Primary sensor (time-shift table)."),
    degree: int = typer.Option(3, "--degree", help="Degree of the daily polynomial (0-5)."),
    block: float | None = typer.Option(
        None, "--block-seconds", help="Interval length of the variance fit (s; default "
        "1200); with --estimator zero-mean the block length (default 1800)."
    ),
    jumps: bool = typer.Option(
        False, "--jumps", help="Fit the post-hibernation offset jumps (sec. 4.2.3.4, "
        "Appendix B) instead of the daily temperature model."
    ),
    intervals: Path | None = typer.Option(
        None, "--intervals", help="--jumps: CSV start_utc,end_utc of the intervals "
        "(default: those of the jump table that overlap the data)."
    ),
    max_sigma: float = typer.Option(
        1.0, "--max-sigma", help="Refuse a jump (and, with --estimator variance, a daily "
        "curve anywhere over the day's temperatures) known worse than this (nT)."
    ),
    goal: float = typer.Option(
        0.2, "--goal", help="--estimator variance: refuse a daily curve whose predicted error "
        "of the recalibrated day (twice the rms of its stated error over the day), or a jump "
        "whose twice its error, exceeds this (nT; the goal 0.2 nT). A larger value accepts a "
        "worse table and is written into it."
    ),
    boom: str = typer.Option("deployed", "--boom", help="Boom state: deployed or stowed."),
    alignment_from_kernels: bool = typer.Option(
        False, "--alignment-from-kernels",
        help="--jumps: URF -> s/c from the frames kernel instead of RPCMAG_SC_ALIGN.TXT.",
    ),
    estimator: str = typer.Option(
        "variance", "--estimator",
        help="What the fit assumes about the field. 'variance' (default): rotations at "
        "nearly constant |B| within --block-seconds intervals (default 1200 s), nothing about "
        "the mean field; needs no --kernels for --jumps; refused above --max-sigma. "
        "'zero-mean': the seed's criteria, the day's field (or the CSEQ B_z) averages to "
        "zero; a mean field goes into the offsets.",
    ),
) -> None:
    """Derive calibration files from flight data (RO-IGEP-TR0028 sec. 4.2.3.3, 4.2.3.4).

    Writes the daily RPCMAG_<yymmdd>_006_CALIB_<sensor>.TXT files (or, with --jumps,
    RPCMAG_OFFSET_JUMPS.csv) that 'fluxcal rosetta calibrate --calib OUT' reads.
    """
    from fluxcal.missions.rosetta.fit_run import fit_files

    for path in science:
        check_raw_source(path, "--input")
    if hk is not None:
        check_raw_source(hk, "--hk")
    if calib is not None:
        preflight.existing_folder(calib, "--calib")
    if kernels is not None:
        preflight.existing_file(kernels, "--kernels")
    if intervals is not None:
        preflight.plain_text_file(intervals, "--intervals")
    if not 0 <= degree <= 5:
        raise InputFormatError(f"{degree}: the daily files hold degrees 0 to 5", field="--degree")
    if block is not None and not 0 < block <= 86_400:
        raise InputFormatError(f"{block:g} s: give a block length above 0 s and at most "
                               "86400 s (one day)", field="--block-seconds")
    if not 0 < max_sigma < float("inf"):
        raise InputFormatError(f"{max_sigma:g} nT: give a finite limit above 0 nT",
                               field="--max-sigma")
    if estimator not in ("zero-mean", "variance"):
        raise InputFormatError(f"{estimator}: choose zero-mean or variance", field="--estimator")
    if not 0 < goal < float("inf"):
        raise InputFormatError(f"{goal:g} nT: give a finite goal above 0 nT", field="--goal")
    preflight.writable_folder(out, "--out")
    paths = fit_files(
        science, sensor, out, hk_file=hk, calib_dir=calib, kernels=kernels, primary=primary,
        degree=degree, block_s=block, jumps=jumps, intervals=intervals, max_sigma=max_sigma,
        boom=boom,
        alignment_from_kernels=alignment_from_kernels, estimator=estimator, goal=goal,
    )
    for path in paths:
        typer.echo(str(path))
        if not jumps:
            typer.echo("  " + describe_daily_model(path))
    typer.echo(f"pictures and report of the fit: {Path(out) / 'index.html'}")


@app.command("list-calibration")
def list_calibration(
    calib: Path | None = typer.Option(None, "--calib", help="User calibration folder over "
                                      "fluxcal's files (default: $FLUXCAL_CALIBRATION_DIR)."),
) -> None:
    """List the calibration files a run would use (*), then the ones they hide."""
    from fluxcal.calibration.store import describe, user_folder
    from fluxcal.missions.rosetta.calib import calibration_store, refuse_unread_archive_files

    refuse_unread_archive_files(user_folder(calib))
    store = calibration_store(calib)
    for line in describe(store.tables(), len(store.names)):
        typer.echo(line)


def simulate(
    out: Path = typer.Option(Path("rosetta-sim"), "--out", help="Folder for the simulated inputs."),
    start: str = typer.Option("2014-08-01T00:00:00", "--start", help="First time stamp (UTC)."),
    hours: float = typer.Option(1.0, "--hours", help="Length of the simulation (h); with "
                                "--layout batch, the length of each day's data."),
    rate: float = typer.Option(20.0, "--rate", help="Vector rate (Hz)."),
    primary: str = typer.Option("OB", "--primary", help="Primary sensor."),
    seed: int = typer.Option(0, "--seed", help="Random seed (bad-quality vectors, the "
                             "realistic field)."),
    layout: str = typer.Option(
        "files", "--layout",
        help="files: the inputs of 'fluxcal rosetta calibrate'; batch: the input folder of "
        "'fluxcal batch rosetta' (<out>/<yyyymmdd>/science_OB.csv ..., kernels.tm, calib/; "
        "docs/formats/rosetta.md); archive: archive-style EDITED products "
        "(<out>/DATA/EDITED/<yyyy>/<MON>/<OB|IB|HK>/*.LBL/.TAB, CALIB/, kernels.tm), input "
        "of both."),
    days: int = typer.Option(1, "--days", min=1, max=366,
                             help="--layout batch: number of consecutive days."),
    field: str = typer.Option(
        "realistic", "--field",
        help="The known field: realistic (default): a 3-nT solar wind with a daily mean "
        "(about 2.5 nT along a sector direction) and Alfvenic rotations dB/B ~ 0.55 with "
        "an f^-5/3 spectrum from 12 h to 2 s, 3 % compressive; quiet: slow deterministic "
        "waves of tens of nT (the field before issue 21)."),
) -> None:
    """Write simulated raw Rosetta telemetry, calibration files and kernels from a known field."""
    check_simulation_options(start, hours, rate, primary)
    if field not in ("realistic", "quiet"):
        raise InputFormatError(f"{field!r}: choose realistic or quiet", field="--field")
    if layout not in ("files", "batch", "archive"):
        raise InputFormatError(f"{layout!r}: choose files, batch or archive", field="--layout")
    preflight.writable_folder(out, "--out")
    with compilation_notice(), status_display(f"simulating {hours:g} h of Rosetta RPC-MAG"):
        _simulate(out, start, hours, rate, primary, seed, layout, days, field)


def _simulate(out: Path, start: str, hours: float, rate: float, primary: str, seed: int,
              layout: str, days: int, field: str) -> None:
    """``fluxcal simulate rosetta`` once its options are checked."""
    if layout == "archive":
        simulate_archive_layout(out, start, hours, rate, primary, seed, field)
        return
    if layout == "batch":
        folders = simulate_batch_layout(out, start, hours, rate, primary, seed, days, field)
        typer.echo(f"{len(folders)} day folders in {out}; run: fluxcal batch rosetta "
                   f"--input {out} --start {folders[0].name[:4]}-{folders[0].name[4:6]}-"
                   f"{folders[0].name[6:]} --end {folders[-1].name[:4]}-"
                   f"{folders[-1].name[4:6]}-{folders[-1].name[6:]} --out OUT")
        return
    from fluxcal.missions.rosetta.simulate import write_simulation

    paths = write_simulation(
        out, start_utc=start, hours=hours, rate_hz=rate, primary=primary, seed=seed,
        field=field)
    for name, path in paths.items():
        typer.echo(f"{name}: {path}")


def check_raw_source(path: Path, option: str) -> None:
    """Check a raw input before anything runs: a CSV file, or EDITED products (folder, .LBL).

    Raises
    ------
    FluxcalError
        Naming the option: a missing folder or file, a CSV that is not plain text.
    """
    from fluxcal.missions.rosetta.archive import is_archive_source

    if Path(path).is_dir():
        preflight.existing_folder(path, option)
    elif is_archive_source(path):
        preflight.existing_file(path, option)
    else:
        preflight.plain_text_file(path, option)


def simulate_archive_layout(out: Path, start: str, hours: float, rate: float, primary: str,
                            seed: int, field: str = "realistic") -> None:
    """Write the simulation as archive-style EDITED products and say how to calibrate them.

    `fluxcal.missions.rosetta.simulate.write_simulation` with ``layouts=("archive",)``:
    ``<out>/DATA/EDITED/...``, ``<out>/CALIB`` (archived names), kernels, truth CSVs.
    """
    from fluxcal.missions.rosetta.simulate import write_simulation

    paths = write_simulation(out, start_utc=start, hours=hours, rate_hz=rate,
                             primary=primary, seed=seed, layouts=("archive",), field=field)
    for name, path in paths.items():
        typer.echo(f"{name}: {path}")
    edited, day = paths["archive"], start[:10]
    typer.echo(f"run: fluxcal rosetta calibrate --input {edited} --hk {edited} --sensor OB "
               f"--calib {paths['calib']} --kernels {out / 'kernels.tm'} --out OUT; or: "
               f"fluxcal batch rosetta --input {out} --start {day} --end {day} --out OUT")


def simulate_batch_layout(out: Path, start: str, hours: float, rate: float, primary: str,
                          seed: int, days: int, field: str = "realistic") -> list[Path]:
    """Write ``days`` simulated days in the input layout of ``fluxcal batch rosetta``.

    Each day holds ``hours`` of both sensors from ``start``'s time of day
    (`fluxcal.missions.rosetta.batch_task.simulate_days`, with kernels and each day's
    truth); a day's data must end before midnight (a day folder holds its UTC day).

    Raises
    ------
    InputFormatError
        If a day's data would cross midnight, or ``primary`` is not OB (the batch
        simulation uses OB as primary sensor).
    """
    from fluxcal.missions.rosetta.batch_task import simulate_days

    t0 = _dt.datetime.fromisoformat(start)
    seconds_of_day = t0.hour * 3600 + t0.minute * 60 + t0.second
    if seconds_of_day + hours * 3600.0 > 86_400 - 1200:  # 1200 s: the filter time shifts
        raise InputFormatError(
            f"{hours} h from {t0.time()} reaches within 20 min of midnight; with --layout "
            "batch each day's data must stay in its UTC day (time shifts of up to 1024 s): "
            "start earlier or shorten --hours", field="--hours")
    if primary.upper() != "OB":
        raise InputFormatError("--layout batch simulates OB as the primary sensor",
                               field="--primary")
    dates = [t0.date() + _dt.timedelta(days=k) for k in range(days)]
    return simulate_days(out, dates, start_time=t0.strftime("%H:%M:%S"),
                         minutes=hours * 60.0, rate_hz=rate, seed=seed, kernels=True,
                         truth=True, field=field)


def check_simulation_options(start: str, hours: float, rate: float, primary: str) -> None:
    """Check ``fluxcal simulate rosetta``'s options before anything is written.

    Raises
    ------
    InputFormatError
        Naming the option: a start that is not ISO UTC, a non-positive or longer than
        31-day length, a rate outside (0, 1000] Hz, a primary other than OB/IB.
    """
    try:
        _dt.datetime.fromisoformat(start)
    except ValueError:
        raise InputFormatError(f"{start!r} is not an ISO UTC time such as "
                               "2014-08-01T00:00:00", field="--start") from None
    if not 0.0 < hours <= 31 * 24:
        raise InputFormatError(f"{hours} h: give a length above 0 and at most 744 h (31 days)",
                               field="--hours")
    if not 0.0 < rate <= 1000.0:
        raise InputFormatError(f"{rate} Hz: give a vector rate above 0 and at most 1000 Hz",
                               field="--rate")
    if primary.upper() not in ("OB", "IB"):
        raise InputFormatError(f"{primary!r}: the primary sensor is OB or IB", field="--primary")
