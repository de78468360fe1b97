"""The one-call Python API: calibrate a day or a run, open any product.

Each function returns xarray Datasets indexed by UTC ``time`` (``ds.sel(time=...)`` and
``ds.resample(time=...)`` work) with the exact TT2000 ``epoch`` beside it.  They are
reached as ``fluxcal.calibrate`` (any registered mission), its thin wrappers
``fluxcal.calibrate_messenger``, ``fluxcal.calibrate_rosetta``, ``fluxcal.calibrate_imap``,
and ``fluxcal.read_product``.  What `calibrate` returns has the names `read_product`
reads back from the products (docs/decisions/products.md, decision 72).

Examples
--------
>>> import fluxcal
>>> from pathlib import Path
>>> ds = fluxcal.read_product(Path("MAGMSOSCI12153_V01.cdf"))  # doctest: +SKIP
>>> ds["b"].sel(time=slice("2012-06-01T00:10", "2012-06-01T00:20"))  # doctest: +SKIP
>>> made = fluxcal.calibrate("messenger", {"science": ["MAG_science.csv"],
...     "heater": ["MAG_heater.csv"], "temperature": ["MAG_temperature.csv"]},
...     kernels="messenger.tm", frames=("mso",))  # doctest: +SKIP
>>> made["mso"]["b"].sel(b_component="B_X")  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.products.compare import load_product
from fluxcal.products.timeindex import with_time_index
from fluxcal.runs import registry


def read_product(path: str | Path) -> xr.Dataset:
    """Read any product: fluxcal's (TAB/LBL, CDF, netCDF, Zarr) or an archived table.

    A PDS3 table that a registered mission's archived-product reader accepts goes through
    it (`fluxcal.archive.products.read_archive_product`, which also reads fluxcal's own
    labels of those layouts); another table (a plugin's own layout) and the other formats
    through `fluxcal.products.read_fluxcal_product` (`fluxcal.products.compare.load_product`).
    The engine ``xr.open_dataset(path, engine="fluxcal")`` is this function.

    Raises
    ------
    fluxcal.errors.InputFormatError
        A file that is not a product (naming the file, row and column where it can).
    """
    return load_product(Path(path), registry.archived_readers())


def calibrate(mission: str, inputs: Any, **options: Any) -> dict[str, xr.Dataset]:
    """Calibrate a registered mission's inputs in one call; nothing is written.

    The mission's ``calibrate`` piece (`fluxcal.runs.contract.Mission`) found through
    the registry (`fluxcal.runs.registry.get`), so a plugin's mission works the same.

    Parameters
    ----------
    mission : str
        Registered mission name (``messenger``, ``rosetta``, ``imap``, a plugin's).
    inputs : object
        What the mission reads: MESSENGER ``{"science": files, "heater": files,
        "temperature": files}``; Rosetta one raw science file; IMAP packet files.
    **options
        The mission's options (`calibrate_messenger`, `calibrate_rosetta`,
        `calibrate_imap` list them).

    Returns
    -------
    dict of str -> xarray.Dataset
        Product kind (MESSENGER frame, Rosetta level, IMAP ``<mode>-<sensor>``) -> that
        full-resolution product's content, indexed by UTC ``time`` (in time order) with
        the exact TT2000 ``epoch``: the same variable and component names (and values)
        `read_product` reads back from the run's products (docs/decisions/products.md,
        decision 72).

    Raises
    ------
    fluxcal.errors.FluxcalError
        An unknown mission, one without a ``calibrate`` piece, or a bad input or option
        (the message names it).
    """
    piece = registry.get(mission).load("calibrate")
    made = piece(inputs, **options)
    return {name: _in_time_order(with_time_index(ds)) if "epoch" in ds.coords else ds
            for name, ds in made.items()}


def calibrate_messenger(
    science: Sequence[str | Path],
    heater: Sequence[str | Path],
    temperature: Sequence[str | Path],
    kernels: str | Path | Sequence[str | Path],
    *,
    frames: Sequence[str] = ("mso",),
    calib: str | Path | None = None,
) -> dict[str, xr.Dataset]:
    """Calibrate MESSENGER MAG streams (CSV files) in one call; nothing is written.

    ``calibrate("messenger", {"science": science, "heater": heater, "temperature":
    temperature}, kernels=kernels, frames=frames, calib=calib)`` (`calibrate`).

    Parameters
    ----------
    science, heater, temperature : sequence of path
        The three CSV streams (docs/formats/messenger.md).
    kernels : path or sequence of paths
        Meta-kernel or kernel files (SCLK, FK, SPK, CK).
    frames : sequence of str
        Frames of the products (``mso``, ``j2000``, ``mbf``, ``rtn``, ``sc``, ``vso``).
    calib : path, optional
        A calibration folder in place of the shipped tables.

    Returns
    -------
    dict of str -> xarray.Dataset
        Frame -> its full-resolution product's content, indexed by UTC ``time``:
        ``b`` (nT) on ``b_component`` (``B_X B_Y B_Z``; ``B_R B_T B_N`` in RTN),
        ``b_total``, ``met``, ``quality`` and the position, as `read_product` reads the
        product back.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-12.
    """
    return calibrate("messenger", {"science": science, "heater": heater,
                                   "temperature": temperature},
                     kernels=kernels, frames=frames, calib=calib)


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

    ``calibrate("rosetta", science, sensor=sensor, ...)`` (`calibrate`).

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
    return calibrate("rosetta", science, sensor=sensor, levels=levels, hk=hk, calib=calib,
                     kernels=kernels)


def calibrate_imap(inputs: Sequence[str | Path], *,
                   kernels: str | Path | Sequence[str | Path] | None = None,
                   level: str = "l1b", calib: str | Path | None = None,
                   xtce: str | Path | None = None) -> dict[str, xr.Dataset]:
    """Decode and calibrate IMAP MAG packet (or L1A CSV) files in one call.

    ``calibrate("imap", inputs, ...)`` (`calibrate`).  ``kernels``: the IMAP SCLK
    kernel; ``calib``: the team's calibration CDF (L1B); ``xtce``: the team's packet
    definition (default: the installed team package's).

    Returns
    -------
    dict of str -> xarray.Dataset
        ``"norm-mago"`` ... (``<mode>-<sensor>``): L1A counts or L1B nT, indexed by UTC
        ``time``.
    """
    return calibrate("imap", inputs, kernels=kernels, level=level, calib=calib, xtce=xtce)


def _in_time_order(ds: xr.Dataset) -> xr.Dataset:
    """Return ``ds`` sorted by ``epoch`` (stable), so that ``resample`` works.

    A run is in recorded order; its corrected times can step back where the latency
    changes with the rate (seed 000 sec. 5) and packets can overlap.
    """
    order = np.argsort(ds["epoch"].values, kind="stable")
    return ds if (order == np.arange(order.size)).all() else ds.isel(time=order)
