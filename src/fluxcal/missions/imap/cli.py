"""``fluxcal imap ...``: IMAP MAG from raw packets or the team's L1A CSV to L1A/L1B products.

Declared in `fluxcal.missions.imap.mission.MISSION` (the registry builds ``fluxcal
imap``); errors are `FluxcalError` subclasses, which ``fluxcal.cli.main`` prints as one
line and turns into exit code 2, leaving nothing new in ``--out``.
"""

from __future__ import annotations

from pathlib import Path

import typer

from fluxcal import preflight
from fluxcal.cli_help import HelpGroup, progress_display
from fluxcal.missions.imap.options import ImapOptions
from fluxcal.runs.options import with_options

app = typer.Typer(help="IMAP MAG pipeline commands.", no_args_is_help=True,
                  rich_markup_mode=None, cls=HelpGroup)


@app.callback()
def _group() -> None:
    """IMAP MAG pipeline commands."""


@app.command()
@with_options(ImapOptions)
def calibrate(
    inputs: list[Path] = typer.Option(
        ..., "--input", help="CCSDS MAG science packet file(s), or the team's L1A CSV "
        "layout MAGScience-<mode>-(<pri>,<sec>)-<n>s-<date>.csv; repeat for several."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    kernels: list[Path] | None = typer.Option(
        None, "--kernels", help="SCLK kernel or meta-kernel with the IMAP clock (-43) "
        "(default: the shipped imap_sclk_0036.tsc)."),
    options: ImapOptions = None,  # type: ignore[assignment] - from the command line
) -> None:
    """Decode, time and calibrate IMAP MAG vectors; one product per mode and sensor.

    Products are named imap_mag_<level>_<norm|burst>-<mago|magi>_<yyyymmdd>_v001.
    """
    from fluxcal.missions.imap.routes import ImapRun, default_kernels
    from fluxcal.runs import driver

    for path in inputs:
        preflight.existing_file(path, "--input")
    if options.calib is not None:
        preflight.existing_file(options.calib, "--calib")
    for path in kernels or []:
        preflight.existing_file(path, "--kernels")
    preflight.writable_folder(out, "--out")
    with progress_display() as progress:
        paths, n_vectors = driver.run(ImapRun(), tuple(inputs), kernels or default_kernels(),
                                      out, options, progress=progress)
    typer.echo(f"{options.level.upper()}: {n_vectors} vectors; {len(paths)} files in {out}")
