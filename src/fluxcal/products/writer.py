"""One writer interface for every product format, and the matching readers."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.products.atomic import atomic_group
from fluxcal.products.format_names import FORMATS
from fluxcal.products.timeindex import epoch_from_table, has_table_time, with_time_index

if TYPE_CHECKING:
    import xarray as xr

    from fluxcal.products.columns import Column

SUFFIX = {"tab": ".TAB", "cdf": ".cdf", "nc": ".nc", "zarr": ".zarr"}


def write_product(
    ds: xr.Dataset,
    stem: Path,
    formats: Sequence[str] = ("tab", "cdf"),
    columns: Sequence[Column] | None = None,
    label_extra: Mapping[str, Any] | None = None,
    *,
    variable_yaml: Path | None = None,
    global_yaml: Path | None = None,
    cdf_stem: Path | None = None,
) -> list[Path]:
    """Write one product in several formats; return the paths written.

    Parameters
    ----------
    ds : xarray.Dataset
        Dimension ``time``, int64 TT2000 coordinate ``epoch``, vectors on
        ``("time", "component")``, ``units`` attrs, provenance in ``attrs`` (see
        `fluxcal.products.provenance.provenance_attrs`).
    stem : Path
        Output path without suffix, e.g. ``out/MAGMSOSCI24001``.
    formats : sequence of str
        Any of ``"tab"`` (``stem.TAB`` + ``stem.LBL``), ``"cdf"`` (``stem.cdf``),
        ``"nc"`` (``stem.nc``), ``"zarr"`` (``stem.zarr``, needs the zarr package).
    columns : sequence of Column, optional
        Table columns (TAB only); default: every time variable, exact formats.
    label_extra : mapping, optional
        Extra keywords for the label and extra CDF global attributes.
    variable_yaml, global_yaml : Path, optional
        Mission ISTP attribute files replacing ``products/data/istp_*.yaml``.
    cdf_stem : Path, optional
        Path without suffix of the CDF when it is not ``stem``, e.g.
        ``out / istp_file_stem(logical_source, day, version)`` for ISTP file names.

    Returns
    -------
    list of Path
        Every file (or store) written, in the order of ``formats``.

    Raises
    ------
    InputFormatError
        Unknown format, or a dataset the format cannot hold.

    Notes
    -----
    Every file is written under a temporary name in the same folder; only when all
    formats are complete are they renamed into place (`atomic_group`).  If any
    format fails, no file of this call appears (an older product stays intact).
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise InputFormatError(f"unknown product format(s) {unknown}; expected {FORMATS}",
                               field="formats")
    stem = Path(stem)
    written: list[Path] = []
    with atomic_group():  # all formats complete, or none renamed into place
        for fmt in formats:  # each format's module is imported when first used
            if fmt == "tab":
                from fluxcal.products.tab import write_tab

                written += write_tab(ds, stem, columns, label_extra)
            elif fmt == "cdf":
                from fluxcal.products.cdf import write_cdf

                written.append(write_cdf(ds, _with(Path(cdf_stem or stem), "cdf"), label_extra,
                                         variable_yaml, global_yaml))
            elif fmt == "nc":
                from fluxcal.products.netcdf import write_netcdf

                written.append(write_netcdf(ds, _with(stem, "nc")))
            else:
                from fluxcal.products.netcdf import write_zarr

                written.append(write_zarr(ds, _with(stem, "zarr")))
    return written


def _with(stem: Path, fmt: str) -> Path:
    return stem.with_name(stem.name + SUFFIX[fmt])


#: Suffix -> (module of `fluxcal.products`, reader function), imported when first used:
#: a CDF-only run loads neither pvl nor the table writer.
READERS: dict[str, tuple[str, str]] = {
    ".tab": ("tab", "read_tab"),
    ".lbl": ("tab", "read_tab"),
    ".cdf": ("cdf", "read_cdf"),
    ".nc": ("netcdf", "read_netcdf"),
    ".zarr": ("netcdf", "read_zarr"),
}


def read_fluxcal_product(path: Path) -> xr.Dataset:
    """Read any fluxcal product (format from the suffix) into a Dataset.

    Internal: the one public reader is `fluxcal.read_product` (which also reads the
    archive's tables).  The Dataset has the indexed UTC ``time`` coordinate beside the
    exact ``epoch`` (`fluxcal.products.timeindex.with_time_index`) whenever it has
    ``epoch``; a table's ``epoch`` is made from its UTC columns (``time_utc``, or year,
    day of year, hour, minute, second: `fluxcal.products.timeindex.epoch_from_table`).
    """
    path = Path(path)
    source = READERS.get(path.suffix.lower())
    if source is None:
        raise InputFormatError(f"unknown product suffix {path.suffix!r}; expected one of "
                               f"{sorted(READERS)}", path=str(path))
    reader = getattr(import_module(f"fluxcal.products.{source[0]}"), source[1])
    if path.suffix.lower() == ".lbl":
        path = path.with_suffix(".TAB")
    try:
        ds = reader(path)
    except (FluxcalError, FileNotFoundError, PermissionError):
        raise
    except Exception as exc:  # noqa: BLE001 - e.g. MemoryError from a corrupt size field
        # a truncated or foreign file breaks the format library in many ways (the
        # cause stays chained: ``fluxcal --debug`` shows it)
        raise InputFormatError(
            f"not a readable {path.suffix.lstrip('.').upper()} product ({type(exc).__name__}: "
            f"{' '.join(str(exc).split())[:200]}); give a product written by fluxcal",
            path=str(path)) from exc
    if "epoch" not in ds.coords and "epoch" not in ds and has_table_time(ds):
        ds = epoch_from_table(ds)
    return with_time_index(ds) if "epoch" in ds.coords else ds
