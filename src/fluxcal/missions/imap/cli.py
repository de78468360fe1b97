"""``fluxcal imap ...``: IMAP MAG from raw packets or the team's L1A CSV to L1A/L1B products.

Declared in `fluxcal.missions.imap.mission.MISSION` (the registry builds ``fluxcal
imap``); errors are `FluxcalError` subclasses, which ``fluxcal.cli.main`` prints as one
line and turns into exit code 2, leaving nothing new in ``--out``.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import typer

from fluxcal import preflight
from fluxcal.cli_help import HelpGroup
from fluxcal.errors import InputFormatError
from fluxcal.missions.imap.levels_cli import register as _register_levels
from fluxcal.missions.imap.options import ImapOptions
from fluxcal.runs.display_cli import compilation_notice, progress_display
from fluxcal.runs.options import with_options

app = typer.Typer(help="IMAP MAG pipeline commands.", no_args_is_help=True,
                  rich_markup_mode=None, cls=HelpGroup)


_register_levels(app)  # imap l1c, imap l2


@app.callback()
def _group() -> None:
    """IMAP MAG pipeline commands."""


@app.command()
@with_options(ImapOptions)
def calibrate(
    inputs: list[Path] = typer.Option(
        ..., "--input", help="CCSDS MAG science packet file(s), compressed or not, or "
        "files in the team's L1A CSV layout (told apart by content); repeat for several."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    kernels: list[Path] | None = typer.Option(
        None, "--kernels", help="SCLK kernel or meta-kernel with the IMAP clock (-43), "
        "e.g. the team's imap_sclk_0036.tsc (needed: fluxcal ships none)."),
    options: ImapOptions = None,  # type: ignore[assignment] - from the command line
) -> None:
    """Decode, time and calibrate IMAP MAG vectors; one product per mode and sensor.

    Products are named imap_mag_<level>_<norm|burst>-<mago|magi>_<yyyymmdd>_v001.
    """
    from fluxcal.missions.imap.routes import ImapRun
    from fluxcal.missions.imap.sources import sclk_kernels
    from fluxcal.runs import driver

    for path in inputs:
        preflight.existing_file(path, "--input")
    for path, name in ((options.calib, "--calib"), (options.xtce, "--xtce")):
        if path is not None:
            preflight.existing_file(path, name)
    for path in kernels or []:
        preflight.existing_file(path, "--kernels")
    preflight.writable_folder(out, "--out")
    with compilation_notice(), progress_display("imap calibrate") as progress:
        paths, n_vectors = driver.run(ImapRun(), tuple(inputs), sclk_kernels(kernels), out,
                                      options, progress=progress)
    typer.echo(f"{options.level.upper()}: {n_vectors} vectors; {len(paths)} files in {out}")


def simulate(
    out: Path = typer.Option(Path("imap-sim"), "--out", help="Folder for the simulated inputs."),
    start: str = typer.Option("2025-10-17T00:00:00", "--start",
                              help="First packet time (UTC, ISO 8601)."),
    hours: float = typer.Option(1.0, "--hours", min=0.01, max=24.0,
                                help="Normal-mode data per day (h, 2 + 2 vectors/s)."),
    burst_minutes: float = typer.Option(
        5.0, "--burst-minutes", min=0.0, max=1440.0,
        help="Burst-mode data in the middle of each day (min, 64 + 8 vectors/s); 0: none."),
    days: int = typer.Option(1, "--days", min=1, max=366, help="Consecutive days."),
    widths: str = typer.Option(
        "0,16,18,13", "--widths",
        help="Compression widths W cycled every 4 packets, comma-separated; 0 is "
        "uncompressed (e.g. 0 for uncompressed packets only)."),
    range_changes: bool = typer.Option(
        True, "--range-changes/--no-range-changes",
        help="Change range inside every third packet (primary from its middle vector, "
        "secondary over its first half)."),
    seed: int = typer.Option(0, "--seed", help="Random seed of the realistic field."),
) -> None:
    """Write simulated IMAP MAG science packets from a known field, with the truth.

    Also writes fluxcal's own simulated SCLK kernel, calibration CDF and XTCE packet
    description (not the IMAP team's files) and prints the command that calibrates them.
    """
    try:
        width_list = tuple(int(w) for w in widths.split(","))
    except ValueError:
        width_list = ()
    if not width_list or any(w != 0 and not 4 <= w <= 20 for w in width_list):
        raise InputFormatError(f"{widths!r}: give comma-separated widths, 0 (uncompressed) "
                               "or 4..20 (narrower ones cannot hold a range's counts)",
                               field="--widths")
    try:
        _dt.datetime.fromisoformat(start)
    except ValueError as exc:
        raise InputFormatError(f"{start!r} is not an ISO 8601 time", field="--start") from exc
    preflight.writable_folder(out, "--out")
    from fluxcal.missions.imap.simulate import write_simulation

    paths = write_simulation(out, start_utc=start, hours=hours, burst_minutes=burst_minutes,
                             days=days, widths=width_list, range_changes=range_changes,
                             seed=seed)
    for name, path in paths.items():
        typer.echo(f"{name}: {path}")
    typer.echo(f"run: fluxcal imap calibrate --input {paths['packets']} --kernels "
               f"{paths['kernels']} --calib {paths['calib']} --xtce {paths['xtce']} --out OUT")
