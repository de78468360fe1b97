"""Shared pieces of the MESSENGER level modules: components, spacecraft id, variables, dates."""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.geometry import compiled
from fluxcal.geometry.time import utc_to_et
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.identity import SPACECRAFT_ID

COMPONENT = ["x", "y", "z"]
#: NAIF id of MESSENGER and its clock (`fluxcal.missions.messenger.identity`).
SC_ID = SPACECRAFT_ID


def _vector(values: np.ndarray, units: str, description: str) -> xr.Variable:
    return xr.Variable(("time", "component"), values, {"units": units, "description": description})


def _scalar(values: np.ndarray, units: str, description: str) -> xr.Variable:
    return xr.Variable(("time",), values, {"units": units, "description": description})


def _date_et(cal: MessengerCalibration, key: str) -> float:
    return float(utc_to_et(np.array([str(cal.date(key))]))[0])


def _apply(m: np.ndarray, v: np.ndarray, transpose: bool = False) -> np.ndarray:
    """``out[i] = M[i] @ v[i]`` (or ``M[i].T @ v[i]``); a single matrix applies to all."""
    if m.shape[0] == 1:  # one fixed matrix: a compiled pass over the vectors

        out = np.empty(v.shape)
        compiled.apply_matrix(np.ascontiguousarray(m[0].T if transpose else m[0]),
                              np.ascontiguousarray(v, dtype=float), out)
        return out
    return np.einsum("nji,nj->ni" if transpose else "nij,nj->ni", m, v)


def _unit_rows(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` divided by their norms."""
    return v / np.sqrt(np.einsum("ij,ij->i", v, v))[:, None]

