"""ISTP-compliant CDF products through cdflib.

* ``Epoch`` is ``CDF_TIME_TT2000`` written from the int64 ``epoch`` coordinate (read
  back to the nanosecond); ``MONOTON = INCREASE`` only when it is strictly increasing.
  A derived ``time`` index (`fluxcal.products.timeindex`) is not stored.
* Every variable along ``time`` is record-varying with ``DEPEND_0 = Epoch``.  An extra
  dimension ``d`` (``(time, d)``, e.g. vector components) gets ``DEPEND_1 = LABL_PTR_1 =
  d``, a CDF_CHAR ``metadata`` variable holding the coordinate's labels (so a mission
  names RTN components ``B_R B_T B_N`` through its coordinate).
* One attribute per meaning: the Dataset attrs with an ISTP meaning are stored under the
  ISTP name only (`ISTP_NAME`: ``units`` -> ``UNITS``, ``description`` -> ``CATDESC``,
  ``long_name`` -> ``LABLAXIS``, ``valid_min``/``valid_max`` -> ``VALIDMIN``/``VALIDMAX``,
  ``coordinate_system`` -> ``COORDINATE_SYSTEM``, ``var_type`` -> ``VAR_TYPE``) and
  `read_cdf` maps them back; other attrs are stored verbatim.  A variable with a
  ``frame`` attr and no ``coordinate_system`` gets ``COORDINATE_SYSTEM`` = its frame
  (the attribute pyspedas tags the frame with) and keeps ``frame``.
* Attribute values: the variable's attrs, then the per-name entries of the YAML table
  (``products/data/istp_variables.yaml`` or a mission's ``variable_yaml``), then its
  ``defaults``.  ``VALIDMIN``/``VALIDMAX`` are physical: the variable's
  ``valid_min``/``valid_max``, the table's entry, or the table's ``valid_range_by_units``
  for the variable's units; integers without one get their type's range (fill
  excluded); a float data or support variable without one is an error.
* NaN is written as ``FILLVAL`` (-1e31) and read back as NaN.  ``FILLVAL`` is the ISTP
  value of the variable's CDF type.
* ``VAR_TYPE`` ``data`` (default; quality flags too) get ``DISPLAY_TYPE time_series``
  and ``LABLAXIS`` (scalars) or ``LABL_PTR_1`` (vectors); ``FIELDNAM`` is the variable
  name (as spacepy's ISTP checks require).  String variables are ``metadata``.
* Global attributes: ``products/data/istp_global.yaml`` (or ``global_yaml``), then the
  Dataset attrs (containers JSON-encoded, see `fluxcal.products.attrs`), then
  ``label_extra``.  ``Logical_source`` defaults to the ISTP rule
  ``source_descriptor_datatype``; ``Logical_file_id`` is `istp_file_stem` of it, the UTC
  day of the median sample and ``Data_version``; ``Generation_date``,
  ``Software_version`` (from ``software_version``) and ``Parents`` are filled in.
* No compression: the bytes of the data records depend only on the values.
* Written through cdflib's public writer only (`cdflib.cdfwrite.CDF`: ``write_globalattrs``,
  ``write_var``), never its private methods (docs/decisions/products.md, decision 77).

References
----------
.. [1] ISTP/IACG Guidelines, global and variable attributes,
       https://spdf.gsfc.nasa.gov/istp_guide/gattributes.html, vattributes.html.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import cdflib
import numpy as np
import xarray as xr
import yaml
from cdflib.cdfwrite import CDF as CDFWriter
from cdflib.xarray import xarray_to_cdf

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import tt2000_to_datetime64
from fluxcal.products.atomic import atomic_path
from fluxcal.products.attrs import decode_value, encode_value
from fluxcal.products.columns import TIME_DIM
from fluxcal.products.provenance import creation_time, portable_attrs, portable_dataset
from fluxcal.products.timeindex import TIME_COORD, default_lsk, with_time_index
from fluxcal.version import software_version

EPOCH = "Epoch"
DIMS_ATTR = "fluxcal_dims"
DTYPE_ATTR = "fluxcal_dtype"

#: Dataset attribute -> ISTP variable attribute (one CDF attribute per meaning).
ISTP_NAME = {
    "units": "UNITS",
    "description": "CATDESC",
    "long_name": "LABLAXIS",
    "valid_min": "VALIDMIN",
    "valid_max": "VALIDMAX",
    "coordinate_system": "COORDINATE_SYSTEM",
    "var_type": "VAR_TYPE",
}
_FROM_ISTP = {v: k for k, v in ISTP_NAME.items()}
#: Dataset attribute -> ISTP global attribute.
ISTP_GLOBAL_NAME = {"software_version": "Software_version"}
_GLOBAL_FROM_ISTP = {v: k for k, v in ISTP_GLOBAL_NAME.items()}
#: Variable attributes the writer derives itself (never taken from a table or attrs).
_DERIVED = re.compile(r"^(FIELDNAM|FILLVAL|MONOTON|DEPEND_\d+|LABL_PTR_\d+)$")

# numpy dtype -> (CDF type name, ISTP FILLVAL, FORMAT)
_TYPES: dict[str, tuple[str, Any, str]] = {
    "float64": ("CDF_DOUBLE", -1.0e31, "E23.15"),
    "float32": ("CDF_FLOAT", -1.0e31, "E14.7"),
    "int64": ("CDF_INT8", -(2**63), "I20"),
    "int32": ("CDF_INT4", -(2**31), "I11"),
    "int16": ("CDF_INT2", -(2**15), "I6"),
    "int8": ("CDF_INT1", -128, "I4"),
    "uint8": ("CDF_UINT1", 255, "I3"),
    "uint16": ("CDF_UINT2", 65535, "I5"),
    "uint32": ("CDF_UINT4", 4294967295, "I10"),
    "bool": ("CDF_UINT1", 255, "I1"),
}
_TYPE_NUM = {
    "CDF_DOUBLE": 45, "CDF_FLOAT": 44, "CDF_INT8": 8, "CDF_INT4": 4, "CDF_INT2": 2,
    "CDF_INT1": 1, "CDF_UINT1": 11, "CDF_UINT2": 12, "CDF_UINT4": 14, "CDF_CHAR": 51,
    "CDF_TIME_TT2000": 33,
}
_TT2000_FILL = -(2**63)
_VERSION = re.compile(r"^[vV]?(\d+)$")


# ----------------------------------------------------------------------------------------
# ISTP names
# ----------------------------------------------------------------------------------------
def istp_logical_source(source_name: str, descriptor: str, data_type: str) -> str:
    """ISTP ``Logical_source``: the short forms (before ``>``) joined by ``_``, lower case.

    >>> istp_logical_source("SC1>Spacecraft One", "MAG>Magnetometer", "MSO-SCI>Full")
    'sc1_mag_mso-sci'
    """
    return "_".join(str(x).split(">")[0].strip() for x in
                    (source_name, descriptor, data_type)).lower()


def istp_file_stem(logical_source: str, date: Any, version: int | str) -> str:
    """ISTP file name without suffix: ``<logical_source>_<yyyymmdd>_v<NN>``.

    Parameters
    ----------
    logical_source : str
        The product's ``Logical_source`` (e.g. ``sc1_mag_mso-sci``).
    date : datetime.date, numpy.datetime64 or str
        The product's UTC day (``"2011-04-10"``, ``"20110410"`` or a date).
    version : int or str
        Data version: ``1``, ``"1"``, ``"01"`` or ``"v01"`` all give ``v01``; a string
        with more digits keeps its width (``"001"`` gives ``v001``).

    Returns
    -------
    str
        E.g. ``sc1_mag_mso-sci_20110410_v01``; the writer stores the same string as
        ``Logical_file_id``, so a CDF named ``<stem>.cdf`` passes the ISTP file-name checks.

    >>> istp_file_stem("sc1_mag_clc-ob", "2014-08-01", 1)
    'sc1_mag_clc-ob_20140801_v01'
    """
    if isinstance(date, str) and re.fullmatch(r"\d{8}", date):
        day = date
    else:
        day = str(np.datetime64(date, "D")).replace("-", "")
    m = _VERSION.match(str(version).strip())
    if m is None:
        raise InputFormatError(f"data version {version!r} is not a number (e.g. 1 or 'v01')",
                               field="Data_version")
    width = max(2, len(m.group(1)))
    return f"{logical_source}_{day}_v{int(m.group(1)):0{width}d}"


# ----------------------------------------------------------------------------------------
# writing
# ----------------------------------------------------------------------------------------
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


def _dtype_key(var: xr.Variable) -> str:
    """Key of `_TYPES` for a variable's dtype."""
    return "bool" if var.dtype.kind == "b" else str(var.dtype)


def _inferred_dims(name: str, rec_vary: bool, ndim: int,
                   depends: Mapping[int, str]) -> tuple[str, ...]:
    """Dims `read_cdf` gives a variable from its ISTP attributes (one rule, both ways)."""
    if rec_vary:
        return (TIME_DIM, *[depends.get(i, f"{name}_dim{i}") for i in range(1, ndim)])
    if ndim == 1:
        return (name,)
    return tuple(f"{name}_dim{i}" for i in range(1, ndim + 1))


def _valid_range(name: str, var: xr.Variable, entry: Mapping[str, Any],
                 table: Mapping[str, Any], key: str) -> tuple[Any, Any] | None:
    """Physical (VALIDMIN, VALIDMAX) of a variable, see the module docstring."""
    a = var.attrs
    lo = a.get("valid_min", entry.get("VALIDMIN"))
    hi = a.get("valid_max", entry.get("VALIDMAX"))
    if (lo is None or hi is None) and np.dtype(var.dtype).kind == "f":
        units = str(a.get("units", entry.get("UNITS", ""))).strip()
        ranges = {**(_load_yaml(None, "istp_variables.yaml").get("valid_range_by_units") or {}),
                  **(table.get("valid_range_by_units") or {})}
        by_units = ranges.get(units)
        if by_units is not None:
            lo = by_units[0] if lo is None else lo
            hi = by_units[1] if hi is None else hi
    if key == "bool":
        return (0, 1) if lo is None or hi is None else (lo, hi)
    if np.dtype(var.dtype).kind in "iu":  # the type's range without the fill value
        info = np.iinfo(var.dtype)
        tmin, tmax = ((info.min + 1, info.max) if _TYPES[key][1] == info.min
                      else (info.min, info.max - 1))
        return (tmin if lo is None else max(int(lo), tmin),
                tmax if hi is None else min(int(hi), tmax))
    if lo is None or hi is None:
        return None
    return lo, hi


def _var_attrs(name: str, var: xr.Variable, table: Mapping[str, Any], cdf_type: str,
               rec_vary: bool, depends: Mapping[int, str], is_dimension: bool = False,
               char_width: int = 1) -> dict[str, Any]:
    """ISTP attributes of one variable (values in cdflib's typed form)."""
    entry = table.get(name) or {}
    istp: dict[str, Any] = {}
    if rec_vary:
        istp.update(table.get("defaults", {}))
    istp.update(entry)
    custom: dict[str, Any] = {}
    for k, v in var.attrs.items():
        if v is None or (k in ("valid_min", "valid_max")):
            continue
        if k in ISTP_NAME:
            istp[ISTP_NAME[k]] = v
        elif k.isupper():
            istp[k] = v
        else:
            custom[k] = v
    if "COORDINATE_SYSTEM" not in istp and str(var.attrs.get("frame") or "").strip():
        # a variable's SPICE frame is its ISTP coordinate system (pyspedas tags it)
        istp["COORDINATE_SYSTEM"] = str(var.attrs["frame"]).strip()
    istp = {k: v for k, v in istp.items() if not _DERIVED.match(k)}
    if is_dimension:
        istp["VAR_TYPE"] = "support_data"
    elif cdf_type == "CDF_CHAR":
        istp["VAR_TYPE"] = "metadata"
    var_type = str(istp.setdefault("VAR_TYPE", "support_data"))
    istp["FIELDNAM"] = name
    if not str(istp.get("CATDESC", "")).strip():
        istp["CATDESC"] = name
    if not str(istp.get("UNITS", "")).strip():
        istp["UNITS"] = " "
    if var_type != "data":
        istp.pop("DISPLAY_TYPE", None)
    else:
        istp.setdefault("DISPLAY_TYPE", "time_series")
    if rec_vary:
        istp["DEPEND_0"] = EPOCH
    for i, dep in depends.items():
        istp[f"DEPEND_{i}"] = dep
        istp[f"LABL_PTR_{i}"] = label_name(dep)
    if depends:
        istp.pop("LABLAXIS", None)  # cdflib: not both LABLAXIS and LABL_PTR_1
    elif var_type != "metadata" and not str(istp.get("LABLAXIS", "")).strip():
        istp["LABLAXIS"] = name
    key = _dtype_key(var)
    out: dict[str, Any] = {}
    if cdf_type == "CDF_CHAR":
        istp["FORMAT"] = f"A{char_width}"
        istp.pop("VALIDMIN", None)
        istp.pop("VALIDMAX", None)
        out["FILLVAL"] = " "
    else:
        istp.setdefault("FORMAT", _TYPES[key][2])
        out["FILLVAL"] = _typed(_TYPES[key][1], cdf_type)
        rng = _valid_range(name, var, entry, table, key)
        if rng is None:
            if var_type in ("data", "support_data") and rec_vary and var.size:
                raise InputFormatError(
                    f"variable {name!r} (units {var.attrs.get('units')!r}) has no physical "
                    "valid range: give it valid_min/valid_max attrs or a VALIDMIN/VALIDMAX "
                    "entry in the ISTP variable table", field=name)
            istp.pop("VALIDMIN", None)
            istp.pop("VALIDMAX", None)
        else:
            istp.pop("VALIDMIN", None)
            istp.pop("VALIDMAX", None)
            cast = float if cdf_type in ("CDF_DOUBLE", "CDF_FLOAT") else int
            out["VALIDMIN"] = _typed(cast(rng[0]), cdf_type)
            out["VALIDMAX"] = _typed(cast(rng[1]), cdf_type)
    for k, v in istp.items():
        out[k] = _cdf_attr(v)
    for k, v in custom.items():
        out[k] = _cdf_attr(v)
    dims = tuple(map(str, var.dims))
    if dims != _inferred_dims(name, rec_vary, var.ndim, depends):
        out[DIMS_ATTR] = _cdf_attr(list(dims))
    if key == "bool":
        out[DTYPE_ATTR] = "bool"
    return out


def _payload(name: str, var: xr.Variable) -> tuple[str, int, Any]:
    """CDF type, element count and data of a variable (NaN -> FILLVAL).

    The data is in a form cdflib's public `write_var` takes: a numpy array of the
    variable's type (cdflib copies it into bytes), ASCII text as one ``bytes`` of
    NUL-padded fixed-width strings (the bytes cdflib makes of a list of strings, without
    a Python string per value), other text as a list of str.
    """
    if var.dtype.kind in "US":
        try:  # ASCII text as fixed-width bytes, no Python list
            data = np.ascontiguousarray(var.values).astype("S").reshape(-1)
        except UnicodeEncodeError:
            data = None
        if data is not None and (var.dtype.kind == "U" or not (  # U: ASCII already
                data.size and data.view(np.uint8).max() >= 0x80)):
            nelem = max(1, int(np.char.str_len(data).max(initial=1)))
            if data.dtype.itemsize != nelem:
                data = data.astype(f"S{nelem}")
            return "CDF_CHAR", nelem, data.tobytes()
    if var.dtype.kind in "USO":
        data = var.values.astype(str)
        nelem = max(1, max((len(s) for s in data.ravel().tolist()), default=1))
        return "CDF_CHAR", nelem, data.ravel().tolist()
    key = _dtype_key(var)
    if key not in _TYPES:
        raise InputFormatError(f"dtype {var.dtype} has no CDF type", field=name)
    values = var.values
    if key == "bool":
        values = values.astype(np.uint8)
    elif values.dtype.kind == "f" and values.size and not (
            values.min() > values.dtype.type(_TYPES[key][1])):
        # one pass (no temporary) clears the usual case: every value above the fill
        # value -1e31 of the variable's type and no NaN (a NaN makes the minimum NaN)
        fill = values.dtype.type(_TYPES[key][1])
        if np.any(values == fill):
            raise InputFormatError(
                f"variable {name!r} holds the fill value {float(fill)!r}, which a reader "
                "takes for a missing value", field=name)
        nan = np.isnan(values)
        if nan.any():
            values = np.where(nan, fill, values)
    return _TYPES[key][0], 1, values  # cdflib makes its own C-ordered copy


def _spec(name: str, cdf_type: str, nelem: int, shape: tuple[int, ...],
          rec_vary: bool) -> dict[str, Any]:
    return {"Variable": name, "Data_Type": _TYPE_NUM[cdf_type], "Num_Elements": nelem,
            "Rec_Vary": rec_vary, "Dim_Sizes": list(shape), "Compress": 0}


def _tt2000(year: int) -> int:
    return int(cdflib.cdfepoch.compute_tt2000([year, 1, 1, 0, 0, 0, 0, 0, 0]))


def _epoch_attrs(epoch: xr.Variable, table: Mapping[str, Any]) -> dict[str, Any]:
    v = epoch.values
    istp: dict[str, Any] = dict(table.get(EPOCH) or {})
    for k, val in epoch.attrs.items():
        if k in ISTP_NAME:
            istp[ISTP_NAME[k]] = val
        elif k.isupper():
            istp[k] = val
    istp = {k: val for k, val in istp.items() if not _DERIVED.match(k)
            and k not in ("VALIDMIN", "VALIDMAX", "DISPLAY_TYPE", "DEPEND_0")}
    istp.update(FIELDNAM=EPOCH, VAR_TYPE="support_data", FORMAT=istp.get("FORMAT", "I20"))
    istp.setdefault("CATDESC", "Time tag of the sample, TT2000 nanoseconds since J2000")
    istp.setdefault("UNITS", "ns")
    istp.setdefault("LABLAXIS", EPOCH)
    if bool(np.all(v[1:] > v[:-1])):
        istp["MONOTON"] = "INCREASE"
    out = {k: _cdf_attr(val) for k, val in istp.items()}
    out["FILLVAL"] = [_TT2000_FILL, "CDF_TIME_TT2000"]
    out["VALIDMIN"] = [_tt2000(1990), "CDF_TIME_TT2000"]
    out["VALIDMAX"] = [_tt2000(2100), "CDF_TIME_TT2000"]
    return out


def label_name(dim: str) -> str:
    """Name of the CDF_CHAR label variable (``LABL_PTR_i``) of an extra dimension."""
    return f"{dim}_label"


def _label_attrs(name: str, dim: str, width: int) -> dict[str, Any]:
    return {"FIELDNAM": name, "CATDESC": f"Labels of the {dim} dimension",
            "VAR_TYPE": "metadata", "FORMAT": f"A{width}", "FILLVAL": " ", "DEPEND_1": dim}


def _product_day(epoch: np.ndarray) -> np.datetime64:
    """UTC day of the median sample (the day a daily product is named after)."""
    mid = np.partition(epoch, epoch.size // 2)[epoch.size // 2]
    return tt2000_to_datetime64(np.array([mid]), default_lsk())[0].astype("M8[D]")


def _global_attrs(ds: xr.Dataset, path: Path, label_extra: Mapping[str, Any] | None,
                  gtable: Mapping[str, Any]) -> dict[str, dict[int, Any]]:
    gattrs: dict[str, Any] = dict(gtable)
    for k, v in ds.attrs.items():
        gattrs[ISTP_GLOBAL_NAME.get(k, k)] = v
    for k, v in (label_extra or {}).items():
        gattrs[ISTP_GLOBAL_NAME.get(k, k)] = v
    if not gattrs.get("Logical_source"):
        gattrs["Logical_source"] = istp_logical_source(
            gattrs.get("Source_name", "fluxcal"), gattrs.get("Descriptor", "mag"),
            gattrs.get("Data_type", "l2"))
    epoch = ds["epoch"].values
    if epoch.size:
        gattrs["Logical_file_id"] = istp_file_stem(gattrs["Logical_source"],
                                                   _product_day(epoch),
                                                   gattrs.get("Data_version", 1))
    else:
        gattrs["Logical_file_id"] = path.stem
    created = str(ds.attrs.get("creation_time") or creation_time())
    gattrs["Generation_date"] = created[:10].replace("-", "")
    gattrs.setdefault("Software_version", software_version())
    parents = istp_parents(r.get("name", "") for r in ds.attrs.get("inputs", []) or [])
    out: dict[str, dict[int, Any]] = {
        k: {0: _cdf_attr(v)} for k, v in gattrs.items() if v is not None and k != "Parents"
    }
    if parents:
        out["Parents"] = dict(enumerate(parents))
    return out


def istp_parents(names: Iterable[str]) -> list[str]:
    """ISTP ``Parents`` entries of a product's input files (one per file, in order).

    ISTP defines the entry of a parent CDF as ``CDF>logical_file_id`` [1]_ (the file
    name without ``.cdf``); a parent in another format (CSV, PDS3 label or table, CCSDS
    packets, a mapping file) is named by its file name, suffix included, with no
    ``CDF>`` (it is no CDF).  Empty names are left out.

    Examples
    --------
    >>> istp_parents(["imap_mag_l1a_norm-mago_20250206_v001.cdf", "RPCMAG_RAW_OB.csv"])
    ['CDF>imap_mag_l1a_norm-mago_20250206_v001', 'RPCMAG_RAW_OB.csv']

    References
    ----------
    .. [1] ISTP Metadata Guidelines, global attribute ``Parents``,
           https://spdf.gsfc.nasa.gov/istp_guide/gattributes.html.
    """
    out = []
    for name in names:
        name = Path(str(name)).name
        if not name:
            continue
        out.append(f"CDF>{name[:-4]}" if name.lower().endswith(".cdf") else name)
    return out


def write_cdf(
    ds: xr.Dataset,
    path: Path,
    label_extra: Mapping[str, Any] | None = None,
    variable_yaml: Path | None = None,
    global_yaml: Path | None = None,
) -> Path:
    """Write ``ds`` as an ISTP CDF at ``path`` (atomically) and return ``path``.

    Parameters
    ----------
    ds : xarray.Dataset
        Dimension ``time`` with the int64 TT2000 coordinate ``epoch``; a ``time`` index
        (`fluxcal.products.timeindex.with_time_index`) may be present and is not stored.
    path : Path
        The ``.cdf`` file; name it ``istp_file_stem(...) + ".cdf"`` for ISTP file names.
    label_extra : mapping, optional
        Extra global attributes (override the Dataset attrs).
    variable_yaml, global_yaml : Path, optional
        Mission ISTP tables replacing ``products/data/istp_*.yaml``.

    Raises
    ------
    InputFormatError
        If ``ds`` has no int64 ``epoch`` along ``time``, a variable has a dtype with no
        CDF type, a float variable holds the fill value -1e31, a data or support
        variable has no physical valid range, or an extra dimension's coordinate is not
        a set of string labels.
    """
    path = Path(path)
    if "epoch" not in ds.coords or ds["epoch"].dims != (TIME_DIM,) or ds["epoch"].dtype != np.int64:
        raise InputFormatError("a CDF product needs an int64 'epoch' coordinate along 'time'",
                               field="epoch")
    ds = portable_dataset(ds)  # no folder of this machine in the product
    label_extra = portable_attrs(label_extra or {})
    vtable = _load_yaml(None if variable_yaml is None else str(variable_yaml),
                        "istp_variables.yaml")
    gtable = _load_yaml(None if global_yaml is None else str(global_yaml), "istp_global.yaml")
    globals_cdf = _global_attrs(ds, path, label_extra, gtable)
    epoch = ds["epoch"].variable
    names = [str(n) for n in ds.variables if n not in ("epoch", TIME_COORD)]
    coord_of: dict[str, xr.Variable] = {}  # extra dimension -> its string labels
    for name in names:
        var = ds[name].variable
        if TIME_DIM in var.dims[1:]:
            raise InputFormatError(f"variable {name!r} has 'time' not first: {var.dims}",
                                   field=name)
        for d in map(str, var.dims[1:] if var.dims[:1] == (TIME_DIM,) else ()):
            if d in ds.variables and ds[d].dtype.kind not in "US":
                raise InputFormatError(
                    f"dimension {d!r} of {name!r}: its coordinate must hold string labels "
                    f"(got {ds[d].dtype})", field=d)
            if label_name(d) in ds.variables:
                raise InputFormatError(f"variable name {label_name(d)!r} is reserved for the "
                                       f"labels of dimension {d!r}", field=label_name(d))
            coord_of[d] = ds[d].variable if d in ds.variables else xr.Variable(
                (d,), np.array([f"{d}{i}" for i in range(ds.sizes[d])]))
    extra = [(d, v) for d, v in coord_of.items() if d not in ds.variables]
    with atomic_path(path) as tmp:
        cdf = CDFWriter(tmp, cdf_spec={"Majority": "Row_major", "Checksum": False})
        try:
            cdf.write_globalattrs(globals_cdf)
            spec = _spec(EPOCH, "CDF_TIME_TT2000", 1, (), True)
            cdf.write_var(spec, var_attrs=_epoch_attrs(epoch, vtable),
                          var_data=np.ascontiguousarray(epoch.values) if epoch.size else None)
            for d, lab in coord_of.items():
                text = lab.values.astype(str)
                width = max(1, max(map(len, text.tolist()), default=1))
                cdf.write_var(_spec(label_name(d), "CDF_CHAR", width, text.shape, False),
                              var_attrs=_label_attrs(label_name(d), d, width),
                              var_data=text.tolist())
            for name, var in [*extra, *((n, ds[n].variable) for n in names)]:
                rv = var.dims[:1] == (TIME_DIM,)
                depends = {i: str(d) for i, d in enumerate(var.dims[1:], 1)} if rv else {}
                cdf_type, nelem, payload = _payload(name, var)
                attrs = _var_attrs(name, var, vtable, cdf_type, rv, depends,
                                   is_dimension=name in coord_of, char_width=nelem)
                shape = var.shape[1:] if rv else var.shape
                cdf.write_var(_spec(name, cdf_type, nelem, shape, rv), var_attrs=attrs,
                              var_data=None if var.size == 0 else payload)
        finally:
            cdf.close()
    return path


# ----------------------------------------------------------------------------------------
# reading
# ----------------------------------------------------------------------------------------
def read_cdf(path: Path) -> xr.Dataset:
    """Read a CDF into a Dataset (``Epoch`` -> int64 ``epoch``, with a ``time`` index).

    ISTP attributes with a Dataset meaning come back under the Dataset name
    (`ISTP_NAME` reversed: ``UNITS`` -> ``units`` ...); the derived ones (``FIELDNAM``,
    ``FILLVAL``, ``DEPEND_i``, ``LABL_PTR_i``, ``MONOTON``) are dropped; any other is
    kept as stored.  Float values equal to ``FILLVAL`` become NaN.  For a CDF written
    by other ISTP software the time variable is ``Epoch``, else the CDF_TIME_TT2000
    variable most data variables name in ``DEPEND_0`` (e.g. ``epoch``); the variables
    with that ``DEPEND_0`` are read with dims ``("time", <DEPEND_i or LABL_PTR_i>...)``,
    record-varying variables on another time base are left out.
    """
    path = Path(path)
    cdf = cdflib.CDF(str(path))
    info = cdf.cdf_info()
    names = list(info.zVariables) + list(info.rVariables)
    data_vars: dict[str, xr.Variable] = {}
    coords: dict[str, xr.Variable] = {}
    n_epoch = 0
    all_raw = {n: {k: _plain_attr(v) for k, v in cdf.varattsget(n).items()} for n in names}
    time_var = _time_variable(cdf, names, all_raw)
    # label variables of a dimension that has its own DEPEND_i variable are derived
    derived_labels = {str(a[f"LABL_PTR_{i}"]) for a in all_raw.values() for i in range(1, 10)
                      if a.get(f"LABL_PTR_{i}") and a.get(f"DEPEND_{i}")
                      and a[f"LABL_PTR_{i}"] != a[f"DEPEND_{i}"]}
    for name in names:
        if name in derived_labels:
            continue
        vinfo = cdf.varinq(name)
        raw = all_raw[name]
        dims = raw.pop(DIMS_ATTR, None)
        dtype = raw.pop(DTYPE_ATTR, None)
        fill = raw.get("FILLVAL")
        depends = {i: str(raw.get(f"DEPEND_{i}") or raw.get(f"LABL_PTR_{i}"))
                   for i in range(1, len(vinfo.Dim_Sizes) + 1)
                   if raw.get(f"DEPEND_{i}") or raw.get(f"LABL_PTR_{i}")}
        foreign_skip = vinfo.Rec_Vary and raw.get("DEPEND_0") != time_var and name != time_var
        attrs = {_FROM_ISTP.get(k, k): ("" if v == " " else v) for k, v in raw.items()
                 if not _DERIVED.match(k)}
        nrec = vinfo.Last_Rec + 1 if vinfo.Rec_Vary else 1
        is_char = vinfo.Data_Type_Description == "CDF_CHAR"
        if vinfo.Rec_Vary and nrec == 0:
            values = np.zeros([0, *vinfo.Dim_Sizes], dtype=str if is_char else None)
        else:
            values = np.asarray(cdf.varget(name))
        if name == time_var:
            values = values.astype(np.int64).reshape(-1)
            n_epoch = values.size
            coords["epoch"] = xr.Variable((TIME_DIM,), values, attrs)
            continue
        if dims is None:
            if foreign_skip:
                continue
            dims = _inferred_dims(name, bool(vinfo.Rec_Vary),
                                  len(vinfo.Dim_Sizes) + int(bool(vinfo.Rec_Vary)), depends)
        dims = tuple(dims)
        if is_char:
            values = np.asarray(values, dtype=str)
        elif dtype == "bool":
            values = values.astype(bool)
        elif values.dtype.kind == "f" and fill is not None and values.size:
            values = np.where(values == values.dtype.type(fill), np.nan, values)
        shape = (nrec, *vinfo.Dim_Sizes) if vinfo.Rec_Vary else tuple(vinfo.Dim_Sizes)
        var = xr.Variable(dims, values.reshape(shape), attrs)
        if dims == (name,) and not vinfo.Rec_Vary:
            coords[name] = var
        else:
            data_vars[name] = var
    gattrs = {}
    for k, v in cdf.globalattsget().items():
        key = _GLOBAL_FROM_ISTP.get(k, k)
        if k == "Parents":
            gattrs[key] = [str(x) for x in (v if isinstance(v, list) else [v])]
        else:
            gattrs[key] = _plain_attr(v[0] if isinstance(v, list) and len(v) == 1 else v)
    ds = xr.Dataset(data_vars, coords=coords, attrs=gattrs)
    if n_epoch and ds.sizes.get(TIME_DIM, n_epoch) != n_epoch:
        raise InputFormatError("Epoch and data variables differ in length", path=str(path))
    return with_time_index(ds) if "epoch" in ds.coords else ds


def _time_variable(cdf: Any, names: list[str], raw: Mapping[str, Mapping[str, Any]]) -> str:
    """``Epoch``, else the CDF_TIME_TT2000 variable most often named in ``DEPEND_0``."""
    if EPOCH in names:
        return EPOCH
    named = [str(a.get("DEPEND_0")) for a in raw.values() if a.get("DEPEND_0")]
    tt2000 = [n for n in set(named) if n in names
              and cdf.varinq(n).Data_Type_Description == "CDF_TIME_TT2000"]
    return max(sorted(tt2000), key=named.count) if tt2000 else EPOCH


def _plain_attr(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        v = v.tolist()
        if isinstance(v, list) and len(v) == 1:
            v = v[0]
    if isinstance(v, list) and len(v) == 1:
        v = v[0]
    return decode_value(v)


__all__ = ["ISTP_NAME", "istp_file_stem", "istp_logical_source", "istp_parents", "read_cdf",
           "write_cdf"]


def write_cdf_as_is(ds: xr.Dataset, path: Path) -> Path:
    """Write a dataset already in a CDF layout of its own at ``path`` (atomically).

    For a product that keeps an archive's variable names, dimensions and ISTP
    attributes as the dataset holds them (record dimension ``epoch``): cdflib's xarray
    writer with its ISTP checks [1]_, no fluxcal attribute table and no renaming
    (`write_cdf` writes fluxcal's own layout).  Global attribute values must be
    strings, numbers or lists of them (`fluxcal.products.attrs.encode_attrs`).

    References
    ----------
    .. [1] cdflib, ``cdflib.xarray.xarray_to_cdf``,
           https://cdflib.readthedocs.io/en/latest/api/cdflib.xarray.xarray_to_cdf.html.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        xarray_to_cdf(ds, str(tmp), istp=True, terminate_on_warning=False,
                      auto_fix_depends=False, record_dimensions=["epoch"])
    return path
