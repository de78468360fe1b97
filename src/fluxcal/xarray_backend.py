"""The xarray backend ``engine="fluxcal"``: open any product fluxcal reads with xarray.

Registered under the entry-point group ``xarray.backends`` (``pyproject.toml``), so::

    import xarray as xr
    ds = xr.open_dataset("messenger_mag_mso-sci_20120601_v01.cdf", engine="fluxcal")
    days = xr.open_mfdataset("out/SYNTH_*_v01.cdf", engine="fluxcal", combine="by_coords")

Formats: fluxcal's products (PDS3 ``.TAB``/``.LBL``, ISTP ``.cdf``, ``.nc``, ``.zarr``) and
the archived calibrated tables of every registered mission (`fluxcal.read_product`, the
one reader behind this engine).  Each dataset is indexed by the UTC ``time`` coordinate
beside the exact TT2000 ``epoch``, so ``open_mfdataset`` over a folder of days joins them
in time.  Without ``engine=``, xarray picks this engine for ``.cdf``, ``.tab`` and
``.lbl`` files (`FluxcalBackendEntrypoint.guess_can_open`); netCDF and Zarr stay with
xarray's own engines unless ``engine="fluxcal"`` is given.

The whole product is read into memory (the products are daily files); ``chunks=``
still makes Dask arrays of it.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from xarray.backends import BackendEntrypoint

import fluxcal

#: Suffixes this engine claims when xarray guesses (netCDF and Zarr have xarray's own).
GUESSED_SUFFIXES = (".cdf", ".tab", ".lbl")


class FluxcalBackendEntrypoint(BackendEntrypoint):
    """xarray backend for fluxcal's products and archived calibrated tables."""

    description = ("fluxcal products (PDS3 TAB/LBL, ISTP CDF, netCDF, Zarr) and archived "
                   "magnetometer tables, indexed by UTC time")
    open_dataset_parameters = ("filename_or_obj", "drop_variables")

    def open_dataset(self, filename_or_obj: Any, *,
                     drop_variables: str | Iterable[str] | None = None) -> Any:
        """Return the product as `fluxcal.read_product` reads it, less ``drop_variables``.

        Raises
        ------
        fluxcal.errors.InputFormatError
            A file that is not a product (naming the file, row and column where it can).
        """
        # through ``fluxcal.read_product`` (PEP 562, imported on first use): xarray imports
        # every installed backend's module when it lists its engines, and fluxcal's
        # readers (and missions) are not light
        ds = fluxcal.read_product(Path(os.fspath(filename_or_obj)))
        if drop_variables:
            names = [drop_variables] if isinstance(drop_variables, str) else drop_variables
            ds = ds.drop_vars(list(names), errors="ignore")
        return ds

    def guess_can_open(self, filename_or_obj: Any) -> bool:
        """Return True for a path ending in ``.cdf``, ``.tab`` or ``.lbl``."""
        try:
            suffix = Path(os.fspath(filename_or_obj)).suffix.lower()
        except TypeError:
            return False
        return suffix in GUESSED_SUFFIXES
