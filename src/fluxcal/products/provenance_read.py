"""Reading a product's provenance back: `read_provenance` and its text form.

The records are written by `fluxcal.products.provenance` (``inputs``, ``calibration``,
``kernels`` by file name and SHA-256, ``command_line``); ``fluxcal provenance FILE`` prints
`format_provenance` of `read_provenance` (or its JSON with ``--json``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cdflib
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products.attrs import decode_attrs
from fluxcal.products.label import decode_attributes, find_objects, read_label
from fluxcal.products.netcdf import netcdf_engine
from fluxcal.products.paths import check_pointers

#: Global attributes a provenance summary shows, beside the provenance records.
SUMMARY_KEYS = ("Logical_file_id", "Logical_source", "Data_type", "Parents", "software",
                "software_version", "creation_time", "command_line")


def read_provenance(path: Path | str) -> dict[str, Any]:
    """Read the provenance of any fluxcal product: CDF, netCDF, Zarr or PDS3 label/table.

    Only the attributes are read (not the data) for CDF, netCDF and Zarr.

    Returns
    -------
    dict
        ``product`` (the file name), the `SUMMARY_KEYS` present, ``inputs``,
        ``calibration`` and ``kernels`` (records of name, SHA-256, version).

    Raises
    ------
    fluxcal.errors.InputFormatError
        An unknown suffix, or a file that is not a readable product.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    try:
        if suffix == ".cdf":
            raw = cdflib.CDF(str(p)).globalattsget()
            attrs = {k: (v if k == "Parents" else v[0] if isinstance(v, list) and len(v) == 1
                         else v) for k, v in raw.items()}
            attrs["Parents"] = [str(x) for x in raw.get("Parents", [])]
            if "Software_version" in attrs:
                attrs.setdefault("software_version", attrs.pop("Software_version"))
        elif suffix in (".nc", ".zarr"):
            opened = (xr.open_zarr(p, decode_times=False) if suffix == ".zarr" else
                      xr.open_dataset(p, engine=netcdf_engine(), decode_times=False))
            with opened as f:
                attrs = dict(f.attrs)
        elif suffix in (".lbl", ".tab"):
            label_path = p.with_suffix(".LBL") if suffix == ".tab" else p
            label = read_label(label_path)
            check_pointers(label, label_path)  # no pointer out of the label's folder
            found = find_objects(label, "DATASET_ATTRIBUTES")
            attrs = decode_attributes(found[0]) if found else {}
            if label.get("PRODUCT_CREATION_TIME") not in (None, "N/A"):
                attrs["creation_time"] = str(label["PRODUCT_CREATION_TIME"])
            attrs.setdefault("Logical_file_id", str(label.get("PRODUCT_ID", p.stem)))
        else:
            raise InputFormatError(f"unknown product suffix {p.suffix!r}; expected .cdf, .nc, "
                                   ".zarr, .LBL or .TAB", path=str(p))
    except (InputFormatError, FileNotFoundError, PermissionError):
        raise
    except Exception as exc:  # noqa: BLE001 - a foreign or truncated file breaks the readers
        raise InputFormatError(f"not a readable product ({type(exc).__name__}: "
                               f"{' '.join(str(exc).split())[:200]})", path=str(p)) from exc
    attrs = decode_attrs({k: (v.item() if hasattr(v, "item") and getattr(v, "ndim", 1) == 0
                              else v) for k, v in attrs.items()})
    out: dict[str, Any] = {"product": p.name}
    for key in SUMMARY_KEYS:
        if attrs.get(key) not in (None, "", []):
            out[key] = attrs[key]
    out["inputs"] = list(attrs.get("inputs") or [])
    out["calibration"] = dict(attrs.get("calibration") or {})
    out["kernels"] = list(attrs.get("kernels") or [])
    return out


def format_provenance(prov: Mapping[str, Any]) -> str:
    """Return a readable summary of `read_provenance`'s result (one file per line)."""

    def rec(r: Mapping[str, Any]) -> str:
        sha = str(r.get("sha256", ""))
        parts = [f"sha256 {sha}" if sha else "", f"version {r['version']}"
                 if r.get("version") else ""]
        return "  ".join(x for x in parts if x)

    lines = [f"product: {prov.get('product', '')}"]
    for key in SUMMARY_KEYS:
        if key in prov and key != "Parents":
            lines.append(f"{key}: {prov[key]}")
    if prov.get("Parents"):
        lines.append("Parents: " + ", ".join(map(str, prov["Parents"])))
    inputs = prov.get("inputs") or []
    lines.append(f"inputs ({len(inputs)}):")
    lines += [f"  {r.get('name', '?'):<40} {rec(r)}" for r in inputs]
    cal = prov.get("calibration") or {}
    lines.append(f"calibration ({len(cal)}):")
    # a table's role (e.g. "ground"), where it differs from its file name
    lines += [f"  {r.get('name', name):<40} {rec(r)}"
              + (f"  ({name})" if r.get("name", name) != name else "") for name, r in cal.items()]
    kernels = prov.get("kernels") or []
    lines.append(f"kernels ({len(kernels)}):")
    lines += [f"  {r.get('name', '?'):<40} {rec(r)}" for r in kernels]
    return "\n".join(lines)
