"""``fluxcal plot``, ``compare`` and ``provenance``: commands on products of any mission."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from fluxcal.extras import require
from fluxcal.products.staging import owned_default
from fluxcal.runs import registry


def plot(
    product: Path = typer.Argument(..., exists=True, help="Product (.cdf, .nc or .TAB)."),
    out: Path | None = typer.Option(None, "--out", help="Folder for the PNGs "
                                    "(default: beside the product)."),
    spectrogram: bool = typer.Option(False, "--spectrogram",
                                     help="Also write a spectrogram PNG of the field."),
    field: str | None = typer.Option(None, "--field",
                                     help="Field variable to plot (default: the first "
                                          "B* vector in nT)."),
) -> None:
    """Render a quicklook PNG per day of a product.

    Without ``--out`` the PNGs go beside the product, and that folder is locked and
    owned as an ``--out`` would be (`fluxcal.products.staging.owned_default`).
    """
    from fluxcal.products.quicklook import epoch_from_table, save_png, write_quicklooks
    from fluxcal.products.spectrogram import spectrogram_figure
    from fluxcal.products.writer import read_fluxcal_product

    out_dir = out or product.parent
    with owned_default(out_dir):  # checked, locked, staged (as main does for an --out)
        ds = epoch_from_table(read_fluxcal_product(product))
        paths = write_quicklooks(ds, out_dir, product.stem, field=field)
        if spectrogram:
            paths.append(save_png(spectrogram_figure(ds, field),
                                  out_dir / f"{product.stem}_spec.png"))
    for p in paths:
        typer.echo(str(p))


def compare(
    product_a: Path = typer.Argument(..., help="Product A (.TAB/.LBL, .cdf, .nc or .zarr), "
                                     "e.g. an archived CDR."),
    product_b: Path = typer.Argument(..., help="Product B, e.g. fluxcal's reprocessing."),
    tolerance: str = typer.Option("0.01s", "--tolerance",
                                  help="Largest time difference of a matched pair "
                                       "(s, ms, us or ns; default 0.01s)."),
    out: Path | None = typer.Option(None, "--out", help="Folder for the difference plot "
                                    "(default: the current folder)."),
    force: bool = typer.Option(False, "--force", help="Compare even if the frames differ."),
) -> None:
    """Match two products in time; print A - B statistics per component and quality flag."""
    require("plot", "fluxcal compare (its difference plot)")  # before reading the products
    from fluxcal.products.compare import (
        compare as run_compare,
    )
    from fluxcal.products.compare import (
        format_report,
        load_product,
        parse_tolerance,
        write_difference_plot,
    )

    tol = parse_tolerance(tolerance)
    out_dir = out or Path.cwd()
    with owned_default(out_dir):  # the current folder: checked, locked, staged
        readers = registry.archived_readers()  # every registered mission's, passed down
        a, b = load_product(product_a, readers), load_product(product_b, readers)
        result = run_compare(a, b, tol, path_a=str(product_a), path_b=str(product_b),
                             force=force, readers=readers)
        png = write_difference_plot(result, out_dir)
    typer.echo(format_report(result))
    typer.echo(f"plot: {png}")


def provenance(
    product: Path = typer.Argument(..., exists=True, help="Product (.cdf, .nc, .zarr, "
                                   ".LBL or .TAB) written by fluxcal."),
    as_json: bool = typer.Option(False, "--json", help="Print the provenance as JSON."),
) -> None:
    """Print what a product was made from: inputs, calibration, kernels (name, SHA-256)."""
    from fluxcal.products.provenance_read import format_provenance, read_provenance

    prov = read_provenance(product)
    typer.echo(json.dumps(prov, indent=1, default=str) if as_json else format_provenance(prov))
