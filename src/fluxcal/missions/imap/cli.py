"""``fluxcal imap ...``: IMAP MAG from raw packets or the team's L1A CSV to L1A/L1B products.

Declared in `fluxcal.missions.imap.mission.MISSION` (the registry builds ``fluxcal
imap``); errors are `FluxcalError` subclasses, which ``fluxcal.cli.main`` prints as one
line and turns into exit code 2, leaving nothing new in ``--out``.
"""

from __future__ import annotations

from pathlib import Path

import typer

from fluxcal import preflight
from fluxcal.cli_help import HelpGroup
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
