"""The one-call Python API: calibrate a day or a run, open any product.

Each function returns xarray Datasets indexed by UTC ``time`` (``ds.sel(time=...)`` and
``ds.resample(time=...)`` work) with the exact TT2000 ``epoch`` beside it.  They are
reached as ``fluxcal.calibrate_messenger``, ``fluxcal.calibrate_rosetta``,
``fluxcal.calibrate_imap`` and ``fluxcal.read_product``.

Examples
--------
>>> import fluxcal
>>> from pathlib import Path
>>> ds = fluxcal.read_product(Path("MAGMSOSCI12153_V01.cdf"))  # doctest: +SKIP
>>> ds["b"].sel(time=slice("2012-06-01T00:10", "2012-06-01T00:20"))  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.imap.pipeline import process
from fluxcal.missions.messenger.levels import frame_variables
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.missions.messenger.routes import CsvSource, MessengerRun
from fluxcal.missions.rosetta.options import RosettaOptions
from fluxcal.missions.rosetta.routes import calibrate_levels
from fluxcal.products.compare import load_product
from fluxcal.products.timeindex import with_time_index
from fluxcal.runs import registry


def read_product(path: str | Path) -> xr.Dataset:
    """Read any product: fluxcal's (TAB/LBL, CDF, netCDF, Zarr) or an archived table.

    A PDS3 table that a registered mission's archived-product reader accepts goes through
    it (`fluxcal.archive.products.read_product`, which also reads fluxcal's own labels
    of those layouts); another table (a plugin's own layout) and the other formats
    through `fluxcal.products.read_product` (`fluxcal.products.compare.load_product`).
    The engine ``xr.open_dataset(path, engine="fluxcal")`` is this function.

    Raises
    ------
    fluxcal.errors.InputFormatError
        A file that is not a product (naming the file, row and column where it can).
    """
    return load_product(Path(path), registry.archived_readers())


def calibrate_messenger(
    science: Sequence[str | Path],
    heater: Sequence[str | Path],
    temperature: Sequence[str | Path],
    kernels: str | Path | Sequence[str | Path],
    *,
    frames: Sequence[str] = ("mso",),
    calib: str | Path | None = None,
) -> xr.Dataset:
    """Calibrate MESSENGER MAG streams (CSV files) in one call; nothing is written.

    Parameters
    ----------
    science, heater, temperature : sequence of path
        The three CSV streams (docs/formats/messenger.md).
    kernels : path or sequence of paths
        Meta-kernel or kernel files (SCLK, FK, SPK, CK).
    frames : sequence of str
        Frames of the field to return (``mso``, ``j2000``, ``mbf``, ``rtn``, ``sc``,
        ``vso``): one variable ``b_<frame>`` (nT) and its position variable each.
    calib : path, optional
        A calibration folder in place of the shipped tables.

    Returns
    -------
    xarray.Dataset
        Indexed by UTC ``time`` (in time order); ``b_<frame>`` per frame, positions,
        ``quality`` and the applied offsets, as the products hold them.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-12.
    """
    run = MessengerRun()
    options = MessengerOptions(frames=tuple(frames), formats=("cdf",),
                               calib=None if calib is None else Path(calib))
    run.check(options)
    source = CsvSource(tuple(map(Path, science)), tuple(map(Path, heater)),
                       tuple(map(Path, temperature)))
    with KernelPool(kernels, frames=run.frame_kernels):
        raw, _ = run.read(source, options)
        ds, _cal = run.calibrate(raw, options, None)
        del raw
        for frame in frames:
            ds = ds.assign(frame_variables(ds, frame))
    return _in_time_order(with_time_index(ds))


def calibrate_rosetta(
    science: str | Path,
    sensor: str,
    *,
    levels: Sequence[str] = ("A", "B"),
    hk: str | Path | None = None,
    calib: str | Path | None = None,
    kernels: str | Path | None = None,
) -> dict[str, xr.Dataset]:
    """Calibrate one Rosetta RPC-MAG sensor's raw file in one call; nothing is written.

    Parameters
    ----------
    science : path
        Raw science CSV, or the archive's EDITED products (folder or ``.LBL``).
    sensor : {"OB", "IB"}
    levels : sequence of str
        Levels to make (A, B, C, E, F, G; C and G need ``kernels``).
    hk, calib, kernels : path, optional
        Raw HK, a calibration folder, a meta-kernel (as ``fluxcal rosetta calibrate``).

    Returns
    -------
    dict of str -> xarray.Dataset
        Each level made (and ``HK`` with ``hk``), indexed by UTC ``time``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1-4.8.
    """
    made = calibrate_levels(Path(science), sensor, hk=None if hk is None else Path(hk),
                            kernels=None if kernels is None else Path(kernels),
                            options=RosettaOptions(calib=None if calib is None else Path(calib),
                                                   levels=tuple(levels)))
    return {name: _in_time_order(with_time_index(ds)) if "epoch" in ds.coords else ds
            for name, ds in made.items()}


def calibrate_imap(inputs: Sequence[str | Path], *, kernels: str | Path | Sequence[str | Path],
                   level: str = "l1b", calib: str | Path | None = None,
                   xtce: str | Path | None = None
                   ) -> dict[tuple[str, str], xr.Dataset]:
    """Decode and calibrate IMAP MAG packet (or L1A CSV) files in one call.

    ``kernels``: the IMAP SCLK kernel; ``calib``: the team's calibration CDF (L1B);
    ``xtce``: the team's packet definition (default: the installed team package's).
    fluxcal ships none of them (`fluxcal.missions.imap.sources`).

    Returns
    -------
    dict of (mode, sensor) -> xarray.Dataset
        ``("norm", "mago")`` ...: L1A counts or L1B nT, indexed by UTC ``time``.
    """
    out = process([Path(p) for p in inputs], level=level,
                  calib=None if calib is None else Path(calib),
                  kernels=[Path(kernels)] if isinstance(kernels, (str, Path))
                  else [Path(k) for k in kernels],
                  xtce=None if xtce is None else Path(xtce))
    return {key: _in_time_order(with_time_index(ds)) for key, ds in out.items()}


def _in_time_order(ds: xr.Dataset) -> xr.Dataset:
    """Return ``ds`` sorted by ``epoch`` (stable), so that ``resample`` works.

    A run is in recorded order; its corrected times can step back where the latency
    changes with the rate (seed 000 sec. 5) and packets can overlap.
    """
    order = np.argsort(ds["epoch"].values, kind="stable")
    return ds if (order == np.arange(order.size)).all() else ds.isel(time=order)
