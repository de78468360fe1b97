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
from fluxcal.products.cdf import istp_file_stem
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
        and the table keeps ``name``.
    version : int or str
        Data version of the ISTP file name.
    attrs : mapping
        Global attributes set after the provenance (``Logical_source``, ...).
    columns, label_extra, variable_yaml, global_yaml
        As `fluxcal.products.write_product`.
    inputs, calibration : optional
        What this product was made from when not the whole run's (a multi-sensor run):
        input files and calibration name -> path or version, for its provenance.
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


@dataclass(frozen=True)
class Quicklook:
    """A quicklook: ``<name>_<yyyymmdd>.png`` per UTC day of ``data``.

    ``field`` is the vector drawn, ``frame`` its frame's name in the titles
    (`fluxcal.products.quicklook.write_quicklooks`).
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


Declared = Product | Quicklook | File


def _content(item: Declared) -> xr.Dataset:
    return item.data() if callable(item.data) else item.data


def _day(value: Any) -> _dt.date:
    return _dt.date.fromisoformat(str(np.datetime64(value, "D")))


def dated(products: Iterable[Declared]) -> Iterable[Declared]:
    """Split every undated `Product` into one product per UTC day of its samples."""
    for item in products:
        if isinstance(item, (Quicklook, File)) or item.day is not None:
            yield item
            continue
        for day, part in split_days(_content(item), lsk=default_lsk()):
            day = _day(day)
            yield _replace(item, name=item.name.format(day=day), data=part, day=day)


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
        A product name that is not a plain file name.

    Notes
    -----
    Every file is written under a temporary name; the renames into place happen when
    every declared product is complete (`fluxcal.products.atomic.atomic_group`), so an
    error leaves no file of the call and an older product intact.
    """
    out_dir = Path(out_dir)
    make_folder(out_dir)
    written: list[Path] = []
    stale: list[Path] = []
    with atomic_group():
        for done, item in enumerate(dated(products), start=1):
            if only_day is not None and item.day is not None and item.day != only_day:
                continue
            if isinstance(item, File):
                path = _write_file(item, out_dir, stale)
                if item.listed and item.content is not None:
                    written.append(path)
                continue
            plain_name(item.name, what="product name")
            if isinstance(item, Quicklook):
                written += _write_quicklook(item, out_dir, only_day)
            else:
                written += _write_product(item, out_dir, provenance)
            if progress is not None:
                progress(item.name, done, 0)
    for path in stale:  # once every file of the group is in place
        path.unlink(missing_ok=True)
    return written


def _write_file(item: File, out_dir: Path, stale: list[Path]) -> Path:
    path = out_dir / item.path  # an absolute ``item.path`` stays itself
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
        written += write_product(ds, out_dir / stem, others, None, item.label_extra, **yaml)
    return written


def _write_quicklook(item: Quicklook, out_dir: Path, only_day: _dt.date | None) -> list[Path]:
    from fluxcal.products.quicklook import write_quicklooks  # matplotlib: when drawn

    ds = _content(item)
    if only_day is not None:
        days = [part for day, part in split_days(ds, lsk=default_lsk()) if _day(day) == only_day]
        if not days:
            return []
        ds = days[0]
    return write_quicklooks(ds, out_dir, item.name, field=item.field, frame=item.frame)
