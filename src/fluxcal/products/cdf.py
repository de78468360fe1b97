"""ISTP-compliant CDF products through cdflib.

* ``Epoch`` is ``CDF_TIME_TT2000`` written from the int64 ``epoch`` coordinate
  (read back to the nanosecond).
* Every variable along ``time`` is record-varying with ``DEPEND_0 = Epoch``; a vector
  variable ``(time, component)`` gets ``LABL_PTR_1`` pointing to the ``component``
  metadata variable (CDF_CHAR, not record-varying).
* Variable attributes: ISTP defaults and per-name entries from the YAML data file
  ``products/data/istp_variables.yaml`` (or the file passed as ``variable_yaml``),
  then the Dataset variable's attrs (``units`` -> ``UNITS``, ``description`` or
  ``long_name`` -> ``CATDESC``/``FIELDNAM``), which are also kept verbatim.
* Global attributes: ``products/data/istp_global.yaml``, then the Dataset attrs
  (containers JSON-encoded, see `fluxcal.products.attrs`), then ``label_extra``;
  ``Logical_file_id``, ``Generation_date``, ``Software_version`` and ``Parents``
  (input file names) are filled in.
* No compression: the bytes of the data records depend only on the values.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import cdflib
import numpy as np
import xarray as xr
import yaml
from cdflib.cdfwrite import CDF as CDFWriter

import fluxcal
from fluxcal.errors import InputFormatError
from fluxcal.products.atomic import atomic_path
from fluxcal.products.attrs import decode_value, encode_value
from fluxcal.products.columns import TIME_DIM
from fluxcal.products.provenance import creation_time

EPOCH = "Epoch"
DIMS_ATTR = "fluxcal_dims"
DTYPE_ATTR = "fluxcal_dtype"

# numpy dtype -> (CDF type name, FILLVAL, VALIDMIN, VALIDMAX)
_TYPES: dict[str, tuple[str, Any, Any, Any]] = {
    "float64": ("CDF_DOUBLE", -1.0e31, -1.0e30, 1.0e30),
    "float32": ("CDF_FLOAT", -1.0e31, -1.0e30, 1.0e30),
    "int64": ("CDF_INT8", -(2**63), -(2**63) + 1, 2**63 - 1),
    "int32": ("CDF_INT4", -(2**31), -(2**31) + 1, 2**31 - 1),
    "int16": ("CDF_INT2", -(2**15), -(2**15) + 1, 2**15 - 1),
    "int8": ("CDF_INT1", -128, -127, 127),
    "uint8": ("CDF_UINT1", 255, 0, 254),
    "uint16": ("CDF_UINT2", 65535, 0, 65534),
    "uint32": ("CDF_UINT4", 4294967295, 0, 4294967294),
    "bool": ("CDF_UINT1", 255, 0, 1),
}
_TYPE_NUM = {
    "CDF_DOUBLE": 45, "CDF_FLOAT": 44, "CDF_INT8": 8, "CDF_INT4": 4, "CDF_INT2": 2,
    "CDF_INT1": 1, "CDF_UINT1": 11, "CDF_UINT2": 12, "CDF_UINT4": 14, "CDF_CHAR": 51,
    "CDF_TIME_TT2000": 33,
}


@lru_cache(maxsize=8)
def _load_yaml(path: str | None, default: str) -> dict[str, Any]:
    if path is None:
        text = resources.files("fluxcal.products").joinpath("data", default).read_text()
    else:
        text = Path(path).read_text()
    data = yaml.safe_load(text) or {}
    if not isinstance(data, dict):
        raise InputFormatError("expected a mapping of attribute names", path=path or default)
    return data


def _cdf_attr(value: Any) -> Any:
    """Return a value in cdflib's attribute form (numbers with their CDF type)."""
    v = encode_value(value)
    if isinstance(v, str):
        return v if v else "json:" + json.dumps(v)  # cdflib cannot store ""
    if isinstance(v, int):
        return [v, "CDF_INT8"]
    return [v, "CDF_DOUBLE"]


def _typed(value: Any, cdf_type: str) -> Any:
    return [value, cdf_type] if cdf_type != "CDF_CHAR" else str(value)


def _tt2000(year: int) -> int:
    return int(cdflib.cdfepoch.compute_tt2000([year, 1, 1, 0, 0, 0, 0, 0, 0]))


def _var_attrs(name: str, var: xr.DataArray, table: Mapping[str, Any], cdf_type: str,
               record_varying: bool) -> dict[str, Any]:
    attrs: dict[str, Any] = {}
    if record_varying:
        attrs.update(table.get("defaults", {}))
    attrs.update(table.get(name, {}))
    attrs["FIELDNAM"] = str(var.attrs.get("long_name", attrs.get("FIELDNAM") or name))[:30]
    desc = var.attrs.get("description", var.attrs.get("long_name"))
    attrs["CATDESC"] = str(desc or attrs.get("CATDESC") or name)
    if "units" in var.attrs:
        attrs["UNITS"] = str(var.attrs["units"]) or " "
    if record_varying and cdf_type != "CDF_CHAR":
        _, fill, vmin, vmax = _TYPES[_dtype_key(var)]
        attrs.setdefault("FILLVAL", fill)
        attrs.setdefault("VALIDMIN", vmin)
        attrs.setdefault("VALIDMAX", vmax)
        attrs.setdefault("FORMAT", "E14.6" if cdf_type in ("CDF_DOUBLE", "CDF_FLOAT") else "I20")
    elif record_varying:
        attrs.setdefault("FILLVAL", " ")
        attrs.setdefault("FORMAT", f"A{max(1, var.dtype.itemsize // 4)}")
    if var.ndim == 2 and record_varying:
        attrs["LABL_PTR_1"] = str(var.dims[1])
    out: dict[str, Any] = {}
    for k, v in attrs.items():
        out[k] = _typed(v, cdf_type) if k in ("FILLVAL", "VALIDMIN", "VALIDMAX") else \
            _cdf_attr(v)
    for k, v in var.attrs.items():  # verbatim copy for an exact round trip
        out[k] = _cdf_attr(v)
    out[DIMS_ATTR] = _cdf_attr(list(var.dims))
    out[DTYPE_ATTR] = str(var.dtype) if var.dtype.kind not in "US" else "str"
    return out


def _dtype_key(var: xr.DataArray) -> str:
    """Key of `_TYPES` for a variable's dtype."""
    return "bool" if var.dtype == np.bool_ else str(var.dtype)


def _spec(name: str, var: xr.DataArray, record_varying: bool) -> tuple[dict[str, Any], Any]:
    shape = var.shape[1:] if record_varying else var.shape
    if var.dtype.kind in "USO":
        data = var.values.astype(str)
        nelem = max(1, max((len(s) for s in data.ravel().tolist()), default=1))
        cdf_type = "CDF_CHAR"
        payload: Any = data.ravel().tolist()
    else:
        key = _dtype_key(var)
        if key not in _TYPES:
            raise InputFormatError(f"dtype {var.dtype} has no CDF type", field=name)
        cdf_type = _TYPES[key][0]
        nelem = 1
        payload = np.ascontiguousarray(var.values.astype(np.uint8) if key == "bool"
                                       else var.values)
    spec = {
        "Variable": name,
        "Data_Type": _TYPE_NUM[cdf_type],
        "Num_Elements": nelem,
        "Rec_Vary": record_varying,
        "Dim_Sizes": list(shape),
        "Compress": 0,
    }
    return spec, (cdf_type, payload)


def write_cdf(
    ds: xr.Dataset,
    path: Path,
    label_extra: Mapping[str, Any] | None = None,
    variable_yaml: Path | None = None,
    global_yaml: Path | None = None,
) -> Path:
    """Write ``ds`` as an ISTP CDF at ``path`` (atomically) and return ``path``.

    Raises
    ------
    InputFormatError
        If ``ds`` has no int64 ``epoch`` coordinate along ``time`` or a variable has a
        dtype with no CDF type.
    """
    path = Path(path)
    if "epoch" not in ds.coords or ds["epoch"].dims != (TIME_DIM,) or ds["epoch"].dtype != np.int64:
        raise InputFormatError("a CDF product needs an int64 'epoch' coordinate along 'time'",
                               field="epoch")
    vtable = _load_yaml(None if variable_yaml is None else str(variable_yaml),
                        "istp_variables.yaml")
    gtable = _load_yaml(None if global_yaml is None else str(global_yaml), "istp_global.yaml")
    gattrs: dict[str, Any] = dict(gtable)
    gattrs.update(ds.attrs)
    gattrs.update(label_extra or {})
    gattrs.setdefault("Logical_source", path.stem)
    gattrs["Logical_file_id"] = path.stem
    created = str(ds.attrs.get("creation_time") or creation_time())
    gattrs["Generation_date"] = created[:10].replace("-", "")
    gattrs["Software_version"] = str(ds.attrs.get("software_version", fluxcal.__version__))
    parents = [r.get("name", "") for r in ds.attrs.get("inputs", []) or []]
    globals_cdf: dict[str, dict[int, Any]] = {
        k: {0: _cdf_attr(v)} for k, v in gattrs.items() if v is not None
    }
    if parents:
        globals_cdf["Parents"] = {i: f"CDF>{p}" for i, p in enumerate(parents)}
    with atomic_path(path) as tmp:
        cdf = CDFWriter(tmp, cdf_spec={"Majority": "Row_major", "Checksum": False})
        try:
            cdf.write_globalattrs(globals_cdf)
            epoch = ds["epoch"]
            eattrs = _var_attrs(EPOCH, epoch, vtable, "CDF_TIME_TT2000", True)
            eattrs["FILLVAL"] = [-(2**63), "CDF_TIME_TT2000"]
            eattrs["VALIDMIN"] = [_tt2000(1990), "CDF_TIME_TT2000"]
            eattrs["VALIDMAX"] = [_tt2000(2100), "CDF_TIME_TT2000"]
            eattrs["FORMAT"] = "I20"
            eattrs.pop("DEPEND_0", None)
            eattrs.pop("LABL_PTR_1", None)
            eattrs["DISPLAY_TYPE"] = "no_plot"
            spec = {"Variable": EPOCH, "Data_Type": 33, "Num_Elements": 1, "Rec_Vary": True,
                    "Dim_Sizes": [], "Compress": 0}
            cdf.write_var(spec, var_attrs=eattrs,
                          var_data=np.ascontiguousarray(epoch.values) if epoch.size else None)
            names = [n for n in ds.variables if n not in ("epoch", TIME_DIM)]
            for name in names:
                var = ds[name].variable
                da = xr.DataArray(var)
                rv = var.dims[:1] == (TIME_DIM,)
                if not rv and TIME_DIM in var.dims:
                    raise InputFormatError(f"variable {name!r} has 'time' not first: {var.dims}",
                                           field=str(name))
                spec, (cdf_type, payload) = _spec(str(name), da, rv)
                attrs = _var_attrs(str(name), da, vtable, cdf_type, rv)
                if not rv:
                    attrs["VAR_TYPE"] = "metadata" if cdf_type == "CDF_CHAR" else "support_data"
                    attrs.pop("DEPEND_0", None)
                empty = da.size == 0
                cdf.write_var(spec, var_attrs=attrs, var_data=None if empty else payload)
        finally:
            cdf.close()
    return path


def read_cdf(path: Path) -> xr.Dataset:
    """Read a fluxcal CDF back into a Dataset (``Epoch`` -> int64 ``epoch`` coordinate).

    Variables keep every attribute of the file (ISTP ones included); dataset attrs are
    the decoded global attributes.  For a CDF written by other ISTP software (no
    ``fluxcal_dims`` attributes), the variables with ``DEPEND_0 = Epoch`` are read with
    dims ``("time", <LABL_PTR_i or DEPEND_i>...)``; ``Epoch`` must be CDF_TIME_TT2000.
    """
    path = Path(path)
    cdf = cdflib.CDF(str(path))
    info = cdf.cdf_info()
    names = list(info.zVariables) + list(info.rVariables)
    data_vars: dict[str, xr.Variable] = {}
    coords: dict[str, xr.Variable] = {}
    n_epoch = 0
    for name in names:
        vinfo = cdf.varinq(name)
        raw_attrs = cdf.varattsget(name)
        attrs = {k: _plain_attr(v) for k, v in raw_attrs.items()}
        dims = attrs.pop(DIMS_ATTR, None)
        dtype = attrs.pop(DTYPE_ATTR, None)
        nrec = vinfo.Last_Rec + 1 if vinfo.Rec_Vary else 1
        if vinfo.Rec_Vary and nrec == 0:
            shape = [0, *vinfo.Dim_Sizes]
            values = np.zeros(shape, dtype=_np_dtype(dtype))
        else:
            values = np.asarray(cdf.varget(name))
        if name == EPOCH:
            values = values.astype(np.int64).reshape(-1)
            n_epoch = values.size
            coords["epoch"] = xr.Variable((TIME_DIM,), values, attrs)
            continue
        if dims is None:  # a CDF not written by fluxcal: infer dims from ISTP attributes
            if not (vinfo.Rec_Vary and attrs.get("DEPEND_0") == EPOCH):
                continue
            extra = [str(attrs.get(f"LABL_PTR_{i + 1}") or attrs.get(f"DEPEND_{i + 1}")
                         or f"{name}_dim{i + 1}") for i in range(len(vinfo.Dim_Sizes))]
            dims = [TIME_DIM, *extra]
            if vinfo.Data_Type_Description == "CDF_CHAR":
                dtype = "str"
        dims = tuple(dims)
        if dtype == "str":
            values = np.asarray(values, dtype=str)
        elif dtype is not None:
            values = values.astype(_np_dtype(dtype))
        if vinfo.Rec_Vary:
            values = values.reshape((nrec, *vinfo.Dim_Sizes))
        else:
            values = values.reshape(tuple(vinfo.Dim_Sizes))
        var = xr.Variable(dims, values, attrs)
        if dims == (name,) and not vinfo.Rec_Vary:
            coords[name] = var
        else:
            data_vars[name] = var
    gattrs = {}
    for k, v in cdf.globalattsget().items():
        if k == "Parents":
            gattrs[k] = [str(x) for x in (v if isinstance(v, list) else [v])]
        else:
            gattrs[k] = _plain_attr(v[0] if isinstance(v, list) and len(v) == 1 else v)
    ds = xr.Dataset(data_vars, coords=coords, attrs=gattrs)
    if n_epoch and ds.sizes.get(TIME_DIM, n_epoch) != n_epoch:
        raise InputFormatError("Epoch and data variables differ in length", path=str(path))
    return ds


def _np_dtype(dtype: str | None) -> np.dtype:
    if dtype in (None, "str"):
        return np.dtype(str)
    return np.dtype(dtype)


def _plain_attr(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        v = v.tolist()
        if isinstance(v, list) and len(v) == 1:
            v = v[0]
    if isinstance(v, list) and len(v) == 1:
        v = v[0]
    return decode_value(v)
