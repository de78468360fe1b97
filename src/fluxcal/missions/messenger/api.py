"""MESSENGER's piece of the one-call API (`fluxcal.calibrate`, ``Mission.calibrate``).

`calibrate` returns each frame's full-resolution product content (`products.product_dataset`):
the names and components `fluxcal.read_product` reads back from the run's products
(``b`` on ``b_component`` ``B_X B_Y B_Z``, or ``B_R B_T B_N`` in RTN; docs/decisions/products.md,
decision 72).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger.options import MessengerOptions
from fluxcal.missions.messenger.products import order_day, product_dataset
from fluxcal.missions.messenger.routes import CsvSource, MessengerRun

#: The streams of ``inputs`` (docs/formats/messenger.md).
STREAMS = ("science", "heater", "temperature")


def _paths(value: str | Path | Sequence[str | Path]) -> tuple[Path, ...]:
    return (Path(value),) if isinstance(value, (str, Path)) else tuple(map(Path, value))


def calibrate(
    inputs: Mapping[str, str | Path | Sequence[str | Path]],
    *,
    kernels: str | Path | Sequence[str | Path],
    frames: Sequence[str] = ("mso",),
    calib: str | Path | None = None,
) -> dict[str, xr.Dataset]:
    """Calibrate MESSENGER MAG CSV streams; return each frame's product content.

    Parameters
    ----------
    inputs : mapping
        ``{"science": files, "heater": files, "temperature": files}``: the three CSV
        streams (docs/formats/messenger.md), a path or a sequence of paths each.
    kernels : path or sequence of paths
        Meta-kernel or kernel files (SCLK, FK, SPK, CK).
    frames : sequence of str
        Product frames (``mso``, ``j2000``, ``mbf``, ``rtn``, ``sc``, ``vso``).
    calib : path, optional
        A calibration folder in place of the shipped tables.

    Returns
    -------
    dict of str -> xarray.Dataset
        Frame -> the full-resolution product's variables (``met``, ``b``, ``b_total``,
        ``quality``, the position), in time order, duplicates dropped as the products do.

    Raises
    ------
    fluxcal.errors.InputFormatError
        A stream missing from ``inputs`` or one it does not know.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-12.
    """
    unknown = sorted(set(inputs) - set(STREAMS))
    missing = [s for s in STREAMS if s not in inputs]
    if unknown or missing:
        raise InputFormatError(f"inputs: expected the streams {', '.join(STREAMS)} "
                               f"(missing: {', '.join(missing) or 'none'}; unknown: "
                               f"{', '.join(unknown) or 'none'})", field="inputs")
    run = MessengerRun()
    options = MessengerOptions(frames=tuple(frames), formats=("cdf",),
                               calib=None if calib is None else Path(calib))
    run.check(options)
    source = CsvSource(*(_paths(inputs[s]) for s in STREAMS))
    with KernelPool(kernels, frames=run.frame_kernels):
        raw, _ = run.read(source, options)
        ds, _cal = run.calibrate(raw, options, None)
        del raw
        ordered, _report = order_day(ds, frames)
        return {frame: product_dataset(ordered, frame) for frame in frames}
