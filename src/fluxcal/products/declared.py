"""Products declared by a mission, written by the runner (docs/guide/plugins.md).

A mission says *what* its products are: a `Product` per file set (its name, its UTC
day, its content or a function making it, its formats, table columns and label
keywords), a `Quicklook` per picture or a `File` (a figure of its own, a state the next
run starts from).  `write_declared` does the rest once for every mission: the UTC day
split of undated products, the ISTP file names, the provenance attributes, the writers
and the all-or-nothing write group.

A mission's declarations may be a generator: each product is made only when the one
before it has been written, so a memory-bound mission (twenty frames and averages of a
20 Hz day) holds one product's arrays at a time.

A mission may also declare a `Refused` product (a day that failed its validation): the
other products are written, then the refusal is raised.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fluxcal.errors import FluxcalError
from fluxcal.geometry.days import split_days
from fluxcal.products.atomic import atomic_group, atomic_path, atomic_write_bytes
from fluxcal.products.attrs import encode_attrs
from fluxcal.products.cdf import istp_file_stem, write_cdf_as_is
from fluxcal.products.paths import make_folder, plain_name
from fluxcal.products.timeindex import default_lsk
from fluxcal.products.writer import write_product

if TYPE_CHECKING:
    import xarray as xr

    from fluxcal.products.columns import Column

#: ``provenance(product) -> attrs``: the provenance attributes of a product
#: (`fluxcal.products.provenance.provenance_attrs` of what it was made from).
Provenance = Callable[["Product"], Mapping[str, Any]]
#: ``progress(description, done, total)``; ``total`` is 0 while unknown.
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class Product:
    """One product: one call of `fluxcal.products.write_product`.

    Parameters
    ----------
    name : str
        File name without suffix.  With ``day=None`` it may hold ``{day}`` (a
        `datetime.date`, e.g. ``"GT_{day:%Y%m%d}"``): the runner splits ``data`` by UTC
        day (`fluxcal.geometry.days.split_days`) and writes one product per day.
    data : xarray.Dataset or callable
        The content, or a function of no argument returning it (made when written).
    day : datetime.date, optional
        The product's UTC day (a batch day writes only its own day's products).
    formats : tuple of str
        Product formats (`fluxcal.products.format_names.FORMATS`).
    logical_source : str, optional
        ISTP ``Logical_source``: the formats but ``tab`` are then named
        ``<logical_source>_<yyyymmdd>_v<version>`` (`fluxcal.products.cdf.istp_file_stem`)
        and the table keeps ``name``; their global attributes ``Logical_source`` and
        ``Data_version`` are these unless the data or ``attrs`` set them (the CDF's
        ``Logical_file_id`` is then its file name).
    version : int or str
        Data version of the ISTP file name.
    attrs : mapping
        Global attributes set after the provenance (``Logical_source``, ...).
    columns, label_extra, variable_yaml, global_yaml
        As `fluxcal.products.write_product`.
    inputs, calibration : optional
        What this product was made from when not the whole run's (a multi-sensor run):
        input files and calibration name -> path or version, for its provenance.
    layout : callable, optional
        ``layout(day_data, provenance) -> dataset``: the product has a CDF layout of its
        own (an archive's variable names, dimensions and ISTP attributes), made from each
        UTC day's data and its provenance attributes (an archive's ``Parents``, say) and
        written as it is (`fluxcal.products.cdf.write_cdf_as_is`; ``formats`` must be
        ``("cdf",)``); the provenance, JSON-encoded (`fluxcal.products.attrs`), and
        ``attrs`` follow its own global attributes.
    """

    name: str
    data: xr.Dataset | Callable[[], xr.Dataset]
    day: _dt.date | None = None
    formats: tuple[str, ...] = ("tab", "cdf")
    logical_source: str | None = None
    version: int | str = 1
    attrs: Mapping[str, Any] = field(default_factory=dict)
    columns: Sequence[Column] | None = None
    label_extra: Mapping[str, Any] | None = None
    variable_yaml: Path | None = None
    global_yaml: Path | None = None
    inputs: tuple[Path, ...] | None = None
    calibration: Mapping[str, Any] | None = None
    layout: Callable[[xr.Dataset, Mapping[str, Any]], xr.Dataset] | None = None


@dataclass(frozen=True)
class Quicklook:
    """A quicklook: ``<name>_<yyyymmdd>.png`` per UTC day of ``data``.

    ``field`` is the vector drawn, ``frame`` its frame's name in the titles
    (`fluxcal.products.quicklook.write_quicklooks`).  With ``day`` the data is the
    mission's day as it is (a batch day does not cut it at the UTC midnights).
    """

    name: str
    data: xr.Dataset | Callable[[], xr.Dataset]
    field: str = "b"
    frame: str | None = None
    day: _dt.date | None = None


@dataclass(frozen=True)
class File:
    """A file written with the products that is not one (no provenance, no ISTP name).

    A picture the mission draws itself, or a state the next run starts from.

    Parameters
    ----------
    path : Path or str
        Relative to the product folder, or absolute (a file the user named).
    content : bytes, str, callable or None
        The bytes (text as UTF-8), or ``write(path)`` writing the file at the temporary
        path it is given; ``None`` removes an older file at ``path`` once the products
        are in place (a state that no longer holds).
    day : datetime.date, optional
        As `Product.day` (a batch day writes only its own day's files).
    listed : bool
        Among the paths `write_declared` returns (a picture); a state is not.
    """

    path: Path | str
    content: bytes | str | Callable[[Path], Any] | None
    day: _dt.date | None = None
    listed: bool = True


@dataclass(frozen=True)
class Refused:
    """A product the mission refuses to write (a day that failed its validation).

    The other declared products are written; then ``error`` is raised (several
    refusals: one error of the first one's class, their messages joined by ``"; "``).
    """

    error: FluxcalError
    day: _dt.date | None = None


Declared = Product | Quicklook | File | Refused


def _content(item: Product | Quicklook) -> Any:
    return item.data() if callable(item.data) else item.data


def _day(value: Any) -> _dt.date:
    return _dt.date.fromisoformat(str(np.datetime64(value, "D")))


def dated(products: Iterable[Declared]) -> Iterable[Declared]:
    """Split every undated `Product` into one product per UTC day of its samples."""
    for item in products:
        if isinstance(item, Product) and item.day is None:
            for day, part in split_days(_content(item), lsk=default_lsk()):
                day = _day(day)
                yield _replace(item, name=item.name.format(day=day), data=part, day=day)
        else:
            yield item
        del item  # not held while the next declaration is made (memory)


def _replace(item: Product, **changes: Any) -> Product:
    return Product(**{**item.__dict__, **changes})


def write_declared(
    products: Iterable[Declared],
    out_dir: Path,
    provenance: Provenance,
    *,
    only_day: _dt.date | None = None,
    progress: Progress | None = None,
) -> list[Path]:
    """Write declared products, all or nothing; return the paths written.

    Parameters
    ----------
    products : iterable of Product, Quicklook or File
        The mission's declarations, in writing order (a generator is consumed lazily).
    out_dir : Path
        Product folder (inside the run's ``--out``; `fluxcal.products.paths`).
    provenance : callable
        ``provenance(product) -> attrs``, set on each product before its own ``attrs``.
    only_day : datetime.date, optional
        Write only that day's products (a batch day); quicklooks are drawn for it only.
    progress : callable, optional
        ``progress(description, done, 0)`` after each product.

    Raises
    ------
    FluxcalError
        A product name that is not a plain file name; a `Refused` product's error, after
        the others are written.

    Notes
    -----
    Every file is written under a temporary name; the renames into place happen when
    every declared product is complete (`fluxcal.products.atomic.atomic_group`), so an
    error leaves no file of the call and an older product intact.
    """
    out_dir = Path(out_dir)
    make_folder(out_dir)
    written: list[Path] = []
    refused: list[FluxcalError] = []
    stale: list[Path] = []
    done = 0
    with atomic_group():
        for item in dated(products):  # (not enumerate: its tuple would hold the item)
            done += 1
            if only_day is None or item.day is None or item.day == only_day:
                if isinstance(item, Refused):
                    refused.append(item.error)
                elif isinstance(item, File):
                    path = _write_file(item, out_dir, stale)
                    if item.listed and item.content is not None:
                        written.append(path)
                else:
                    written += _write_item(item, out_dir, provenance, only_day)
                    if progress is not None:
                        progress(item.name, done, 0)
            del item  # not held while the next declaration is made (memory)
    for path in stale:  # once every file of the group is in place
        path.unlink(missing_ok=True)
    if refused:
        if len(refused) == 1:
            raise refused[0]
        raise type(refused[0])("; ".join(map(str, refused)))
    return written


def _write_item(item: Product | Quicklook, out_dir: Path, provenance: Provenance,
                only_day: _dt.date | None) -> list[Path]:
    plain_name(item.name, what="product name")
    if isinstance(item, Quicklook):
        return _write_quicklook(item, out_dir, only_day)
    return _write_product(item, out_dir, provenance)


def _write_file(item: File, out_dir: Path, stale: list[Path]) -> Path:
    if not Path(item.path).is_absolute():  # a folder of the products' own, never ``..``
        for part in Path(item.path).parts:
            plain_name(part, what="file name")
    path = out_dir / item.path  # an absolute ``item.path`` (a file the user named) stays
    if item.content is None:
        stale.append(path)
    elif callable(item.content):
        with atomic_path(path) as tmp:
            item.content(tmp)
    else:
        atomic_write_bytes(path, item.content)
    return path


def _write_product(item: Product, out_dir: Path, provenance: Provenance) -> list[Path]:
    ds = _content(item)
    if item.layout is not None:
        return [_write_laid_out(item, ds, out_dir, provenance(item))]
    ds = ds.copy(deep=False)
    ds.attrs = {**ds.attrs, **provenance(item), **item.attrs}
    yaml = {"variable_yaml": item.variable_yaml, "global_yaml": item.global_yaml}
    if item.logical_source is None:
        return write_product(ds, out_dir / item.name, item.formats, item.columns,
                             item.label_extra, **yaml)
    if item.day is None:
        raise FluxcalError(f"{item.name}: an ISTP-named product needs its day")
    written: list[Path] = []
    if "tab" in item.formats:
        written += write_product(ds, out_dir / item.name, ("tab",), item.columns,
                                 item.label_extra, **yaml)
    others = tuple(f for f in item.formats if f != "tab")
    if others:
        stem = istp_file_stem(item.logical_source, item.day, item.version)
        istp = {"Logical_source": item.logical_source, "Data_version": item.version}
        ds = ds.assign_attrs({k: v for k, v in istp.items() if k not in ds.attrs})
        written += write_product(ds, out_dir / stem, others, None, item.label_extra, **yaml)
    return written


def _write_laid_out(item: Product, ds: xr.Dataset, out_dir: Path,
                    provenance: Mapping[str, Any]) -> Path:
    """Write a product with a layout of its own (`Product.layout`): a CDF, as it is."""
    if tuple(item.formats) != ("cdf",):
        raise FluxcalError(f"{item.name}: a product with a layout of its own is a CDF "
                           f"only (formats {', '.join(item.formats)})")
    laid = item.layout(ds, provenance).copy(deep=False)
    laid.attrs = {**laid.attrs, **encode_attrs(provenance), **item.attrs}
    return write_cdf_as_is(laid, out_dir / f"{item.name}.cdf")


def _write_quicklook(item: Quicklook, out_dir: Path, only_day: _dt.date | None) -> list[Path]:
    from fluxcal.products.quicklook import write_quicklooks  # matplotlib: when drawn

    ds = _content(item)
    if only_day is not None and item.day is None:  # a dated quicklook: drawn as declared
        days = [part for day, part in split_days(ds, lsk=default_lsk()) if _day(day) == only_day]
        if not days:
            return []
        ds = days[0]
    return write_quicklooks(ds, out_dir, item.name, field=item.field, frame=item.frame)
