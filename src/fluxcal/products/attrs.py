"""Encoding of attribute values for formats that only hold strings and numbers.

netCDF, Zarr, CDF and the text label hold strings, numbers and (for some) lists of
numbers.  fluxcal's dataset attributes also carry lists and dicts (provenance).  Any
value that is not a ``str``, ``int``, ``float`` or ``bool`` is stored as the string
``"json:" + json.dumps(value, sort_keys=True)``; `decode_value` reverses it, so
``decode_value(encode_value(v)) == v`` for every JSON-representable ``v``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np

JSON_PREFIX = "json:"


def encode_value(value: Any) -> str | int | float:
    """Return ``value`` as a string or number (JSON with a prefix for containers)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, (str, int, float)):
        return value
    if isinstance(value, np.ndarray):
        value = value.tolist()
    return JSON_PREFIX + json.dumps(value, sort_keys=True, default=str)


def decode_value(value: Any) -> Any:
    """Inverse of `encode_value`."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str) and value.startswith(JSON_PREFIX):
        return json.loads(value[len(JSON_PREFIX) :])
    return value


def encode_attrs(attrs: Mapping[str, Any]) -> dict[str, str | int | float]:
    """Encode every value of ``attrs`` with `encode_value` (``None`` values are dropped)."""
    return {str(k): encode_value(v) for k, v in attrs.items() if v is not None}


def decode_attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    """Decode every value of ``attrs`` with `decode_value`."""
    return {str(k): decode_value(v) for k, v in attrs.items()}


def variable_units(var: Any) -> str:
    """Return a variable's ``units`` attr, else its ISTP ``UNITS``, stripped (``""``: neither).

    Used by `fluxcal.products.compare` and `fluxcal.products.quicklook` alike.
    """
    return str(var.attrs.get("units", var.attrs.get("UNITS", ""))).strip()
