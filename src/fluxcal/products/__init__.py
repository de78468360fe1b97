"""Products: writers and readers of every output format, provenance, quicklooks, batch.

Writing a product
-----------------
>>> import numpy as np, xarray as xr
>>> from pathlib import Path
>>> from fluxcal.products import Column, write_product, read_fluxcal_product, provenance_attrs
>>> ds = xr.Dataset(
...     {"B_mso": (("time", "component"), np.zeros((2, 3)), {"units": "nT"}),
...      "quality": ("time", np.array([0, 1]), {"units": "1"})},
...     coords={"epoch": ("time", np.array([0, 50_000_000], dtype=np.int64)),
...             "component": ["x", "y", "z"]},
...     attrs=provenance_attrs(inputs=[], command_line="doctest"))
>>> cols = [Column("epoch", "I20", "ns", "TT2000"),   # FORTRAN formats, as in the label
...         Column("B_mso", "F10.3", label="b{c}"),      # -> columns bx, by, bz
...         Column("quality", "I2")]
>>> import tempfile
>>> out = Path(tempfile.mkdtemp())
>>> paths = write_product(ds, out / "MAGMSOSCI24001", formats=("tab", "cdf"), columns=cols)
>>> [p.name for p in paths]
['MAGMSOSCI24001.TAB', 'MAGMSOSCI24001.LBL', 'MAGMSOSCI24001.cdf']
>>> (out / "MAGMSOSCI24001.TAB").read_text().splitlines()[1]
'            50000000      0.000      0.000      0.000  1'
>>> read_fluxcal_product(out / "MAGMSOSCI24001.cdf")["epoch"].values.tolist()
[0, 50000000]

Column naming
-------------
A `Column` whose ``name`` is a vector variable ``(time, component)`` expands to one
column per component, named ``f"{name}_{c}"`` (``B_mso_x``, ``B_mso_y``,
``B_mso_z``), or ``label.format(c=c)`` when ``label`` is given (``label="b{c}"`` ->
``bx by bz``).  ``Column("B_mso", "F9.3", component="z")`` prints one component
only.  Any variable or coordinate along ``time`` may be a column, including
``epoch`` (printed ``I20`` it round-trips to the nanosecond) and string variables
(e.g. pre-formatted UTC; no whitespace inside a value).

Formats: ``tab`` (fixed-width ``.TAB`` + PDS3 ``.LBL``, via pvl), ``cdf`` (ISTP, ``Epoch`` TT2000),
``nc`` (netCDF via xarray), ``zarr`` (if the zarr package is installed).  All writes
are atomic.  See ``docs/formats/products.md``.
"""

from importlib import import_module
from typing import Any

#: Public name -> module that defines it; imported on first use (PEP 562), so that
#: the command line and the ``fluxcal --help`` listing do not load xarray,
#: cdflib and pvl.
_SOURCE = {
    "FORMATS": "writer",
    "Column": "columns",
    "netcdf_engine": "netcdf",
    "provenance_attrs": "provenance",
    "read_cdf": "cdf",
    "read_netcdf": "netcdf",
    "read_fluxcal_product": "writer",
    "read_tab": "tab",
    "read_zarr": "netcdf",
    "sha256_file": "provenance",
    "write_cdf": "cdf",
    "write_netcdf": "netcdf",
    "write_product": "writer",
    "write_tab": "tab",
    "write_zarr": "netcdf",
    "zarr_available": "netcdf",
}
#: Public modules (imported on first use): the API reference's pages of this package.
_MODULES = ("atomic", "attrs", "cdf", "columns", "compare", "format_names", "label", "netcdf",
            "provenance", "provenance_read", "quicklook", "tab", "timeindex", "writer")
__all__ = [
    "FORMATS",
    "Column",
    "netcdf_engine",
    "provenance_attrs",
    "read_cdf",
    "read_netcdf",
    "read_fluxcal_product",
    "read_tab",
    "read_zarr",
    "sha256_file",
    "write_cdf",
    "write_netcdf",
    "write_product",
    "write_tab",
    "write_zarr",
    "zarr_available",
    *_MODULES,
]


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return import_module(f"{__name__}.{name}")
    module = _SOURCE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_SOURCE, *_MODULES})
