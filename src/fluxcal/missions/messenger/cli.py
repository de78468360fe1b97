"""``fluxcal messenger edr2cdr``, ``fluxcal messenger fit`` and ``fluxcal simulate messenger``."""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import typer

from fluxcal.cli_help import HelpGroup
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.preflight import plain_text_file
from fluxcal.runs.display_cli import compilation_notice, progress_display, status_display
from fluxcal.runs.options import with_config, with_options

app = typer.Typer(help="Messenger pipeline commands.", no_args_is_help=True,
                  rich_markup_mode=None, cls=HelpGroup)


@app.command("edr2cdr")
@with_options(MessengerOptions)
def edr2cdr(
    sci: list[Path] = typer.Option([], "--input", "--sci", help="Science CSV file(s)."),
    heater: list[Path] = typer.Option([], "--heater", help="Heater-bit CSV file(s)."),
    temperature: list[Path] = typer.Option([], "--temperature", help="Temperature CSV file(s)."),
    edr: Path = typer.Option(None, "--edr", help="Folder of archived MAG EDRs (PDS3 labels "
                             "+ tables), instead of --input/--heater/--temperature; needs "
                             "--mapping."),
    mapping: Path = typer.Option(None, "--mapping", help="EDR column mapping (TOML; template: "
                                 "fluxcal/missions/messenger/data/edr_mapping_template.toml)."),
    kernels: list[Path] = typer.Option(..., "--kernels", help="Meta-kernel or kernel files."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    options: MessengerOptions = None,  # type: ignore[assignment] - from the command line
) -> None:
    """Calibrate MESSENGER MAG EDR streams into CDR products.

    Follows MESSENGER MAG EDR-to-CDR Processing, sec. 5-13.
    """
    from fluxcal.missions.messenger.routes import CsvSource, EdrSource, run_source
    from fluxcal.missions.messenger.run import prepare_formats

    prepare_formats(options.formats)  # both routes: before any EDR or CSV is read
    _check_input_style(sci, heater, temperature, edr, mapping)
    for option, paths in (("--input", sci), ("--heater", heater), ("--temperature", temperature)):
        for path in paths:  # before any work: not compressed, a data line after the header
            plain_text_file(path, option, header_lines=1)
    if options.calib is not None:
        check_calibration_folder(options.calib)
    source = EdrSource(edr, mapping) if edr is not None else CsvSource(
        tuple(sci), tuple(heater), tuple(temperature))
    with compilation_notice(), progress_display("edr2cdr") as progress:
        written = run_source(source, kernels, out, options, progress)
    typer.echo(f"wrote {len(written)} files to {out}")


@app.command("list-calibration")
def list_calibration(
    calib: Path | None = typer.Option(None, "--calib", help="User calibration folder over "
                                      "the packaged tables (default: $FLUXCAL_CALIBRATION_DIR)."),
    day: str | None = typer.Option(None, "--day", help="UTC day the tables must cover "
                                   "(default: the highest version of each)."),
) -> None:
    """List the calibration tables a run would use (*), then every other version."""
    from fluxcal.calibration.store import describe
    from fluxcal.missions.messenger.calibration_data import calibration_store

    store = calibration_store(calib)
    for line in describe(store.tables(day), len(store.names)):
        typer.echo(line)


def check_calibration_folder(folder: Path) -> None:
    """Refuse a ``--calib`` that is not a folder holding every calibration table.

    Every table is read here, before any data: a table that is not text, TOML or CSV
    fails now, in one line naming its file.

    Raises
    ------
    FluxcalError
        Naming the folder and the missing tables, or the first unreadable table.
    """
    from fluxcal.missions.messenger.calibration_data import TABLE_NAMES, read_tables

    folder = Path(folder)
    if not folder.is_dir():
        raise FluxcalError(f"{folder}: --calib must be a folder of calibration tables")
    missing = [n for n in TABLE_NAMES if not any(folder.glob(f"{n}_v*.*"))]
    if missing:
        raise FluxcalError(f"{folder}: --calib lacks the table(s) {', '.join(missing)} "
                           "(<name>_v<version>.csv|toml; docs/formats/calibration.md)")
    read_tables(folder)  # every table readable, before any data are read


@app.command("fit")
@with_config(exclude=("sci", "heater", "temperature", "kernels", "input_dir", "days",
                      "intervals", "out"))
def fit(
    sci: list[Path] = typer.Option([], "--input", "--sci", help="Science CSV file(s)."),
    heater: list[Path] = typer.Option([], "--heater", help="Heater-bit CSV file(s)."),
    temperature: list[Path] = typer.Option([], "--temperature",
                                           help="Temperature CSV file(s)."),
    kernels: list[Path] = typer.Option([], "--kernels", help="Meta-kernel or kernel files "
                                       "(default with --input-dir: <input-dir>/kernels.tm)."),
    input_dir: Path | None = typer.Option(
        None, "--input-dir", help="Input folder in the layout of 'fluxcal batch messenger' "
        "(MAGSCI_YYYYDDD.csv ...); one reduction per day."),
    days: str = typer.Option(
        "", "--days", help="With --input-dir: FIRST:LAST (ISO dates, inclusive) or a comma "
        "list; default: every day with a science file."),
    intervals: Path | None = typer.Option(
        None, "--intervals", help="CSV of solar-wind intervals 'start,stop' (ISO UTC); "
        "default: all data."),
    out: Path = typer.Option(..., "--out", help="Calibration folder to write."),
    calib: Path | None = typer.Option(
        None, "--calib", help="Starting/base calibration folder (default: shipped tables)."),
    passes: int = typer.Option(12, "--passes", min=1, max=20,
                               help="Most reduce-and-fit passes."),
    fit_delay: bool = typer.Option(True, "--fit-delay/--hold-delay",
                                   help="Fit the heater delay dt, or hold the base value."),
    scheduler: str = typer.Option(
        "serial", "--scheduler", help="'serial' (this process), 'local' (a local Dask "
        "cluster of --workers processes) or the address of a running Dask scheduler."),
    workers: int = typer.Option(2, "--workers", min=1, help="Workers of the local cluster."),
    temperature_law: str = typer.Option(
        "distribution", "--temperature-law", help="'distribution': each 10-C bin modelled "
        "as the law averaged over its samples' temperatures (unbiased at the break); "
        "'binned-mean': the seed's law at the bins' mean temperatures."),
    estimator: str = typer.Option(
        "variance", "--estimator", help="'variance' (default): |B| least variable within "
        "1-min segments of selected 15-min intervals, which assumes rotations at nearly "
        "constant |B| (Alfvenic solar wind) and nothing about the mean field; "
        "'zero-mean': the seed's long-term averages, which assume the field averages to "
        "zero over each bin's samples (a quiet field, e.g. the demo's). Temperature law, "
        "D0, tau and dt; the waveforms are phase-binned either way."),
    hold_d0: str = typer.Option(
        "", "--hold-d0", help="Comma list of AXIS[=VALUE][+-WIDTH] (x, y, z; counts/ppt): "
        "the duty-cycle coefficient D0 of these axes is held at VALUE (default: the base "
        "table's) with the stated WIDTH (default: half the value), which enters every "
        "other stated error (variance estimator): for an axis whose D0 the data do not "
        "determine, which the fit otherwise refuses; the report marks it held."),
    error_goal: float | None = typer.Option(
        None, "--error-goal", help="Largest predicted rms error (nT) of a day recalibrated "
        "with the fitted tables (default 0.1); the fit refuses above it. A larger value "
        "accepts a worse table and is written into every table header."),
    max_compressive_share: float | None = typer.Option(
        None, "--max-compressive-share", help="Largest share of the judged 15-min intervals "
        "rejected as compressive (default 0.5); the fit refuses above it. A larger value is "
        "written into every table header."),
) -> None:
    """Fit the offset and heater calibration tables to flight data (solar wind).

    Temperature law (Table 2 form), duty-cycle law (Table 3 form), relaxation time and
    heater delay (by default from the variance of the field magnitude in short
    intervals; or from the seed's long-term averages, sec. 7), heater waveforms (Tables
    6-8 form, phase-binned, sec. 6), as in MESSENGER MAG EDR-to-CDR Processing; writes
    a folder for 'edr2cdr --calib'.
    """
    from fluxcal.missions.messenger.fit_cli import run_fit

    if calib is not None:
        check_calibration_folder(calib)
    with compilation_notice(), progress_display("fit") as progress:
        text = run_fit(sci=sci, heater=heater, temperature=temperature, kernels=kernels,
                       input_dir=input_dir, days=days, intervals=intervals, out=out,
                       calib=calib, passes=passes, fit_delay=fit_delay, scheduler=scheduler,
                       workers=workers, progress=progress, temperature_law=temperature_law,
                       estimator=estimator, hold_d0=hold_d0, error_goal=error_goal,
                       max_compressive_share=max_compressive_share)
    typer.echo(text)


def _check_input_style(sci: list[Path], heater: list[Path], temperature: list[Path],
                       edr: Path | None, mapping: Path | None) -> None:
    """Exactly one input style: the three CSV streams, or --edr with --mapping."""
    csv = bool(sci or heater or temperature)
    if edr is not None and csv:
        raise InputFormatError("give either --edr/--mapping or --input/--heater/--temperature, "
                               "not both", field="--edr")
    if edr is None:
        if mapping is not None:
            raise InputFormatError("--mapping goes with --edr DIR", field="--mapping")
        for option, paths in (("--input", sci), ("--heater", heater),
                              ("--temperature", temperature)):
            if not paths:
                raise InputFormatError(f"missing {option} (or give --edr DIR --mapping FILE)",
                                       field=option)
        return
    if mapping is None:
        raise InputFormatError("--edr needs --mapping FILE (template: "
                               "fluxcal/missions/messenger/data/edr_mapping_template.toml)",
                               field="--mapping")
    if not edr.is_dir():
        raise InputFormatError(f"{edr}: not a folder of EDR labels and tables", field="--edr")
    if not mapping.is_file():
        raise InputFormatError(f"{mapping}: no such mapping file", field="--mapping")


def simulate(
    out: Path = typer.Option(Path("messenger-sim"), "--out", help="Output folder."),
    start: str = typer.Option("2012-06-01T00:00:00", help="Start (ISO UTC)."),
    duration: float = typer.Option(7200.0, help="Length (s); with --layout batch, the "
                                   "length of each day's science from 00:00 UTC (<= 86400)."),
    layout: str = typer.Option(
        "files", "--layout",
        help="files: the inputs of 'fluxcal messenger edr2cdr'; batch: the input folder of "
        "'fluxcal batch messenger' (<out>/MAGSCI_YYYYDDD.csv, MAGHTR_..., MAGTMP_..., "
        "kernels.tm; docs/formats/messenger.md); edr: archive-style EDRs (PDS3 labels + "
        "tables, two versions a day) with their mapping, for 'edr2cdr --edr --mapping'."),
    days: int = typer.Option(1, "--days", min=1, max=366,
                             help="--layout batch: number of consecutive days."),
    field: str = typer.Option(
        "realistic", "--field",
        help="The interplanetary field added to Mercury's dipole: realistic (default): "
        "an 18-nT solar wind with Alfvenic rotations dB/B ~ 0.55 (f^-5/3 spectrum from "
        "12 h to 2 s), 3 % compressive, sectors of 1-3 days; quiet: a uniform (12, -8, 5) "
        "nT MSO (the field before issue 21)."),
) -> None:
    """Write simulated raw Messenger telemetry and kernels from a known field."""
    if layout not in ("files", "batch", "edr"):
        raise InputFormatError(f"{layout!r}: choose files, batch or edr", field="--layout")
    if field not in ("realistic", "quiet"):
        raise InputFormatError(f"{field!r}: choose realistic or quiet", field="--field")
    check_simulation_options(start, duration)
    if layout == "edr":
        from fluxcal.missions.messenger.edr_write import simulate_edr_layout

        with compilation_notice(), status_display("simulating MESSENGER EDRs"):
            paths = simulate_edr_layout(out, start, duration, solar_wind=field)
        for key, path in paths.items():
            typer.echo(f"{key}: {path}")
        return
    if layout == "batch":
        written = simulate_batch_layout(out, start, duration, days, field)
        typer.echo(f"{len(written)} days in {out}; run: fluxcal batch messenger --input {out} "
                   f"--start {written[0]} --end {written[-1]} --out OUT")
        return
    from fluxcal.missions.messenger.demo import simulate_to_dir

    with compilation_notice(), status_display(f"simulating {duration:.0f} s of MESSENGER "
                                              "telemetry and kernels"):
        paths = simulate_to_dir(out, start, duration, solar_wind=field)
    for key, path in paths.items():
        typer.echo(f"{key}: {path}")


#: Longest ``fluxcal simulate messenger --duration`` (s): one day (about 1.7 M vectors at
#: 20 Hz); more days with ``--layout batch --days N``.
MAX_DURATION_S = 86_400.0


def check_simulation_options(start: str, duration: float) -> None:
    """Check ``fluxcal simulate messenger``'s ``--start`` and ``--duration`` up front.

    Raises
    ------
    InputFormatError
        Naming the option: a start that is not an ISO UTC time (without a UTC offset),
        a length that is not above 0 s and at most `MAX_DURATION_S`.
    """
    try:
        t0 = _dt.datetime.fromisoformat(start)
    except ValueError:
        t0 = None
    if t0 is None or t0.tzinfo is not None:
        raise InputFormatError(f"{start!r} is not an ISO UTC time such as "
                               "2012-06-01T00:00:00", field="--start")
    if not 0.0 < duration <= MAX_DURATION_S:
        raise InputFormatError(f"{duration:g} s: give a length above 0 s and at most "
                               f"{MAX_DURATION_S:.0f} s (one day; more days: --layout batch "
                               "--days N)", field="--duration")


def simulate_batch_layout(out: Path, start: str, duration: float, days: int,
                          field: str = "realistic") -> list:
    """Write ``days`` simulated days in the input layout of ``fluxcal batch messenger``.

    Each day holds ``duration`` s of science from 00:00 UTC
    (`fluxcal.missions.messenger.batch_task.simulate_days`, with kernels, the previous
    day's heater and temperature lead, and each day's truth).

    Raises
    ------
    InputFormatError
        If ``start`` is not a midnight or ``duration`` is not in (0, 86400] s.
    """
    from fluxcal.missions.messenger.batch_task import DAY_S, simulate_days

    try:
        t0 = _dt.datetime.fromisoformat(start)
    except ValueError:
        raise InputFormatError(f"{start!r}: expected an ISO UTC time such as "
                               "2012-06-01T00:00:00", field="--start") from None
    if t0.time() != _dt.time(0):
        raise InputFormatError(f"{start!r}: with --layout batch each day's science starts at "
                               "00:00 UTC: give a date or a midnight", field="--start")
    if not 0.0 < duration <= DAY_S:
        raise InputFormatError(f"{duration}: with --layout batch the length of each day's "
                               "science must be in (0, 86400] s", field="--duration")
    dates = [t0.date() + _dt.timedelta(days=k) for k in range(days)]
    return simulate_days(out, dates, seconds_per_day=duration, solar_wind=field)
