"""``fluxcal imap ...``: IMAP MAG from raw packets or the team's L1A CSV to L1A/L1B products.

Declared in `fluxcal.missions.imap.mission.MISSION` (the registry builds ``fluxcal
imap``); errors are `FluxcalError` subclasses, which ``fluxcal.cli.main`` prints as one
line and turns into exit code 2, leaving nothing new in ``--out``.
"""

from __future__ import annotations

from pathlib import Path

import typer

from fluxcal.cli_help import HelpGroup

app = typer.Typer(help="IMAP MAG pipeline commands.", no_args_is_help=True,
                  rich_markup_mode=None, cls=HelpGroup)


@app.callback()
def _group() -> None:
    """IMAP MAG pipeline commands."""


@app.command()
def calibrate(
    inputs: list[Path] = typer.Option(
        ..., "--input", help="CCSDS MAG science packet file(s), or the team's L1A CSV "
        "layout MAGScience-<mode>-(<pri>,<sec>)-<n>s-<date>.csv; repeat for several."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    calib: Path | None = typer.Option(
        None, "--calib", help="L1B calibration CDF (default: the shipped "
        "imap_calibration_mag_20240229_v01.cdf)."),
    kernels: list[Path] | None = typer.Option(
        None, "--kernels", help="SCLK kernel or meta-kernel with the IMAP clock (-43) "
        "(default: the shipped imap_sclk_0036.tsc)."),
    level: str = typer.Option("l1b", "--level", help="l1a (counts) or l1b (nT)."),
    formats: str = typer.Option("cdf", "--formats", help="Product formats: cdf,nc,tab,zarr."),
    quicklook: bool = typer.Option(False, "--quicklook", help="Also write a PNG quicklook "
                                   "per mode, sensor and UTC day (L1B)."),
) -> None:
    """Decode, time and calibrate IMAP MAG vectors; one product per mode and sensor.

    Products are named imap_mag_<level>_<norm|burst>-<mago|magi>_<yyyymmdd>_v001.
    """
    from fluxcal import preflight
    from fluxcal.missions.imap.calibration import DEFAULT_CALIBRATION
    from fluxcal.missions.imap.packets import data_file
    from fluxcal.missions.imap.pipeline import DEFAULT_SCLK, process, write_products
    from fluxcal.products.provenance import provenance_attrs

    for path in inputs:
        preflight.existing_file(path, "--input")
    if calib is not None:
        preflight.existing_file(calib, "--calib")
    for path in kernels or []:
        preflight.existing_file(path, "--kernels")
    preflight.writable_folder(out, "--out")
    datasets = process(inputs, level=level, calib=calib, kernels=kernels or None)
    cal_file = calib or data_file(DEFAULT_CALIBRATION)
    prov = provenance_attrs(inputs, {"imap_mag_l1b": cal_file} if level == "l1b" else {},
                            kernels or [data_file(DEFAULT_SCLK)])
    paths = write_products(datasets, out, [f.strip() for f in formats.split(",") if f.strip()],
                           prov, quicklook=quicklook)
    counts = ", ".join(f"{m}-{s} {ds.sizes['time']}" for (m, s), ds in datasets.items())
    typer.echo(f"{level.upper()} vectors: {counts}; {len(paths)} files in {out}")
