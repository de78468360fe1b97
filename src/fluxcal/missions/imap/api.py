"""IMAP's piece of the one-call API (`fluxcal.calibrate`, ``Mission.calibrate``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import xarray as xr

from fluxcal.missions.imap.chain import process


def calibrate(
    inputs: Sequence[str | Path],
    *,
    kernels: str | Path | Sequence[str | Path] | None = None,
    level: str = "l1b",
    calib: str | Path | None = None,
    xtce: str | Path | None = None,
) -> dict[str, xr.Dataset]:
    """Decode and calibrate IMAP MAG packet (or L1A CSV) files; nothing is written.

    Parameters
    ----------
    inputs : sequence of path
        Packet files, or files in the team's L1A CSV layout.
    kernels : path or sequence of paths
        The IMAP SCLK kernel (`fluxcal.missions.imap.chain.process`).
    level : {"l1a", "l1b"}
    calib : path, optional
        The team's calibration CDF (L1B).
    xtce : path, optional
        The team's packet definition (default: the installed team package's).

    Returns
    -------
    dict of str -> xarray.Dataset
        ``"<mode>-<sensor>"`` (``norm-mago`` ..., the descriptor of the product's name)
        -> L1A counts or L1B nT.
    """
    if isinstance(kernels, (str, Path)):
        kernels = [kernels]
    out = process([Path(p) for p in inputs], level=level,
                  calib=None if calib is None else Path(calib),
                  kernels=None if kernels is None else [Path(k) for k in kernels],
                  xtce=None if xtce is None else Path(xtce))
    return {f"{mode}-{sensor}": ds for (mode, sensor), ds in out.items()}
