"""netCDF (and Zarr, when installed) products through xarray.

The engine is the first installed of ``netCDF4``, ``h5netcdf`` (both netCDF-4, which
stores int64) and ``scipy`` (netCDF-3, always available here).  netCDF-3 has no
int64 and no containers in attributes, so before writing:

* an int64 variable whose values fit in int32 is stored as int32; one that does not
  (``epoch``, TT2000 ns ~ 1e17) is split into ``<name>__sec`` (floor seconds) and
  ``<name>__nsec`` (0..999 999 999), both int32, exact to the nanosecond until 2068;
* every attribute that is not a string or number is JSON-encoded (`fluxcal.products.attrs`);
* the original dtype and dims are recorded in ``fluxcal_dtype`` / ``fluxcal_split``
  attrs, so `read_netcdf` restores the Dataset exactly.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products.atomic import atomic_path
from fluxcal.products.attrs import decode_attrs, encode_attrs

_NS = 1_000_000_000
_I32 = np.iinfo(np.int32)
SPLIT_ATTR = "fluxcal_split"
DTYPE_ATTR = "fluxcal_dtype"


def netcdf_engine() -> str:
    """Return the xarray engine used for netCDF output (``netcdf4``, ``h5netcdf`` or ``scipy``)."""
    if importlib.util.find_spec("netCDF4") is not None:
        return "netcdf4"
    # h5netcdf writes only through h5py (its pyfive backend is read-only)
    if all(importlib.util.find_spec(m) is not None for m in ("h5netcdf", "h5py")):
        return "h5netcdf"
    return "scipy"


def zarr_available() -> bool:
    """Whether the optional ``zarr`` package is installed."""
    return importlib.util.find_spec("zarr") is not None


def encode_for_netcdf3(ds: xr.Dataset) -> xr.Dataset:
    """Pure: make ``ds`` storable in netCDF-3 (see module docstring); inverse `decode_netcdf3`."""
    out = xr.Dataset(attrs=encode_attrs(ds.attrs))
    for name, var in ds.variables.items():
        attrs = encode_attrs(var.attrs)
        values = var.values
        if values.dtype == np.int64 or values.dtype == np.uint64 or values.dtype == np.uint32:
            attrs[DTYPE_ATTR] = str(values.dtype)
            if values.size == 0 or (values.min() >= _I32.min and values.max() <= _I32.max):
                values = values.astype(np.int32)
            else:
                v = values.astype(np.int64)
                sec, nsec = np.divmod(v, _NS)
                if sec.min() < _I32.min or sec.max() > _I32.max:
                    raise InputFormatError(
                        f"int64 variable {name!r} exceeds +-2^31 s after splitting", field=name
                    )
                is_coord = name in ds.coords
                for suffix, part in (("__sec", sec), ("__nsec", nsec)):
                    v2 = xr.Variable(var.dims, part.astype(np.int32),
                                     {**attrs, SPLIT_ATTR: f"{name}|{int(is_coord)}"})
                    out[f"{name}{suffix}"] = v2
                continue
        elif values.dtype == np.bool_:
            attrs[DTYPE_ATTR] = "bool"
            values = values.astype(np.int8)
        elif values.dtype.kind == "U":
            attrs[DTYPE_ATTR] = "str"
        if name in ds.coords:
            out = out.assign_coords({name: xr.Variable(var.dims, values, attrs)})
        else:
            out[name] = xr.Variable(var.dims, values, attrs)
    return out


def decode_netcdf3(ds: xr.Dataset) -> xr.Dataset:
    """Inverse of `encode_for_netcdf3`."""
    out = xr.Dataset(attrs=decode_attrs(ds.attrs))
    done: set[str] = set()
    for name, var in ds.variables.items():
        attrs = dict(var.attrs)
        split = attrs.pop(SPLIT_ATTR, None)
        dtype = attrs.pop(DTYPE_ATTR, None)
        if split is not None:
            orig, is_coord = str(split).split("|")
            if orig in done:
                continue
            done.add(orig)
            sec = ds[f"{orig}__sec"].values.astype(np.int64)
            nsec = ds[f"{orig}__nsec"].values.astype(np.int64)
            values = (sec * _NS + nsec).astype(dtype or np.int64)
            new = xr.Variable(var.dims, values, decode_attrs(attrs))
            if is_coord == "1":
                out = out.assign_coords({orig: new})
            else:
                out[orig] = new
            continue
        values = var.values
        if dtype == "bool":
            values = values.astype(bool)
        elif dtype == "str":
            values = values.astype(str)
        elif dtype is not None:
            values = values.astype(dtype)
        new = xr.Variable(var.dims, values, decode_attrs(attrs))
        if name in ds.coords:
            out = out.assign_coords({name: new})
        else:
            out[name] = new
    return out


def write_netcdf(ds: xr.Dataset, path: Path) -> Path:
    """Write ``ds`` to ``path`` (``.nc``) atomically with the available engine."""
    path = Path(path)
    enc = encode_for_netcdf3(ds)
    for v in enc.variables.values():
        v.encoding = {"_FillValue": None} if v.dtype.kind == "f" else {}
    with atomic_path(path) as tmp:
        enc.to_netcdf(tmp, engine=netcdf_engine())
    return path


def read_netcdf(path: Path) -> xr.Dataset:
    """Read a fluxcal netCDF product back into a Dataset (exact inverse of `write_netcdf`)."""
    with xr.open_dataset(path, engine=netcdf_engine(), decode_times=False,
                         mask_and_scale=False) as f:
        return decode_netcdf3(f.load())


def write_zarr(ds: xr.Dataset, path: Path) -> Path:
    """Write ``ds`` as a Zarr store (directory) atomically; needs the ``zarr`` package."""
    if not zarr_available():
        raise InputFormatError("Zarr output needs the optional 'zarr' package", field="zarr")
    path = Path(path)
    enc = encode_for_netcdf3(ds)
    with atomic_path(path, directory=True) as tmp:
        enc.to_zarr(tmp, mode="w", zarr_format=2, consolidated=True)
    return path


def read_zarr(path: Path) -> xr.Dataset:
    """Read a fluxcal Zarr store back into a Dataset."""
    with xr.open_zarr(path, decode_times=False, mask_and_scale=False) as f:
        return decode_netcdf3(f.load())
