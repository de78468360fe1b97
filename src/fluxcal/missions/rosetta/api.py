"""Rosetta's piece of the one-call API (`fluxcal.calibrate`, ``Mission.calibrate``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import xarray as xr

from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.routes import calibrate_levels


def _path(value: str | Path | None) -> Path | None:
    return None if value is None else Path(value)


def calibrate(
    inputs: str | Path,
    *,
    sensor: str,
    levels: Sequence[str] = ("A", "B"),
    hk: str | Path | None = None,
    calib: str | Path | None = None,
    kernels: str | Path | None = None,
) -> dict[str, xr.Dataset]:
    """Calibrate one RPC-MAG sensor's raw file; return each level's product content.

    The registry's piece behind `fluxcal.calibrate_rosetta` (parameters there, with
    ``inputs`` its ``science``).  Each level's dataset holds the variables of its
    products (``b`` on ``component`` ``x y z``, ...); the products add ``time_utc`` (the
    UTC text of ``epoch``); the coordinate ``mode_segment`` that splits the tables by
    filter mode is not returned, as no product holds it.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1-4.8.
    """
    made = calibrate_levels(Path(inputs), sensor, hk=_path(hk), kernels=_path(kernels),
                            options=RosettaOptions(calib=_path(calib), levels=tuple(levels)))
    return {name: ds.drop_vars("mode_segment", errors="ignore") for name, ds in made.items()}
