"""``fluxcal rosetta clean``: disturbance-removal levels F, G, H-L from earlier products.

File I/O around the pure level functions of `fluxcal.missions.rosetta.cleaning_levels`:
read earlier-level products (``.cdf``, ``.nc`` or ``.TAB``), run one level, write
``RPCMAG_<yyyymmdd>_CL<level>_<sensor>`` tables and ISTP-named
``rosetta_rpcmag_cl<level>-<sensor>_<yyyymmdd>_v01`` CDF, netCDF or Zarr
(`clean_products`), plus a before/after spectrogram PNG for H and a before/after
time-series PNG for K, declared (`CleanRun`) and written by the generic driver with the
provenance.

Registration (in ``fluxcal/cli.py``)::

    from fluxcal.missions.rosetta import clean_cli
    rosetta_cli.app.command("clean")(clean_cli.clean)

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.7-4.13.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.extras import require
from fluxcal.missions.rosetta.identity import FRAME_KERNELS
from fluxcal.missions.rosetta.options import check_average
from fluxcal.products.paths import plain_name
from fluxcal.runs.options import with_config
from fluxcal.textfile import read_text

if TYPE_CHECKING:  # numpy and xarray load inside the functions: not for 'fluxcal --help'
    import numpy as np
    import xarray as xr

    from fluxcal.products.declared import Declared, Product

log = logging.getLogger(__name__)

CLEAN_LEVELS = ("F", "G", "H", "I", "J", "K", "L")
#: Levels each cleaned level is made from (seed 003 sec. 4.7-4.13); F and G here are
#: the heater-disturbance paths (from B and C they are made by ``calibrate``).
SOURCE_LEVELS = {
    "F": ("K",),
    "G": ("L",),
    "H": ("C", "L"),
    "I": ("H",),
    "J": ("G", "I"),
    "K": ("B",),
    "L": ("K",),
}
#: Level whose product columns (seed tables) a cleaned level reuses.
_COLUMNS_LIKE = {"F": "F", "G": "G", "H": "C", "I": "G", "J": "G", "K": "B", "L": "C"}
#: Global attributes that describe one written file and must not be inherited.
_PER_FILE_ATTRS = (
    "Logical_source",
    "Logical_file_id",
    "Generation_date",
    "Parents",
    "LEVEL",
    "SENSOR",
    "command_line",
    "creation_time",
)


@dataclass
class CleanResult:
    """Datasets made by `clean_files` and the files written."""

    levels: dict[str, xr.Dataset] = field(default_factory=dict)
    paths: list[Path] = field(default_factory=list)


def _columns(level: str, ds: xr.Dataset) -> list:
    from fluxcal.missions.rosetta.products import product_columns

    cols = product_columns(_COLUMNS_LIKE[level])
    present = set(ds.data_vars) | set(ds.coords) | {"time_utc"}
    return [c for c in cols if c.name in present]


def _day(epoch: np.ndarray, lsk) -> str:
    import numpy as np

    from fluxcal.geometry.time import tt2000_to_utc

    return str(tt2000_to_utc(np.asarray(epoch[:1]), digits=0, lsk=lsk)[0])[:10].replace("-", "")


#: What each cleaned level holds (RO-IGEP-TR0028 sec. 4.9-4.13): the long part of its
#: ISTP ``Data_type`` and its ``Logical_source_description``.
CLEAN_DESCRIPTION = {
    "H": "reaction-wheel and LAP lines removed",
    "I": "LEVEL_H averaged",
    "J": "two-sensor PCA residual field",
    "K": "heater disturbance removed",
    "L": "LEVEL_K rotated into the output frame",
}


def clean_logical_source(level: str, sensor: str) -> tuple[str, str]:
    """ISTP ``Data_type`` and ``Logical_source`` of a cleaned level H-L of one sensor.

    ``Data_type`` is ``CL<level>-<sensor>>LEVEL_<level> <what it holds>``, so that the
    ISTP rule ``Logical_source = source_descriptor_datatype`` (short forms, lower case)
    gives ``rosetta_rpcmag_cl<level>-<sensor>``, the name family of the calibrated
    levels: each level has its own ``Logical_source`` and file names
    ``rosetta_rpcmag_clh-ob_20140801_v01.cdf`` (docs/decisions/products.md).

    Examples
    --------
    >>> clean_logical_source("H", "OB")
    ('CLH-OB>LEVEL_H reaction-wheel and LAP lines removed', 'rosetta_rpcmag_clh-ob')
    """
    level, sensor = level.upper(), sensor.upper()
    data_type = f"CL{level}-{sensor}>LEVEL_{level} {CLEAN_DESCRIPTION[level]}"
    return data_type, f"rosetta_rpcmag_cl{level}-{sensor}".lower()


def clean_products(
    ds: xr.Dataset,
    *,
    level: str,
    sensor: str,
    formats: Sequence[str] = ("tab", "cdf"),
    lsk=None,
) -> Product:
    """Declare one cleaned level of one sensor (one day; `fluxcal.products.declared`).

    The table is ``RPCMAG_<yyyymmdd>_CL<level>_<sensor>.TAB`` (+ label); CDF, netCDF and
    Zarr have the ISTP names of the calibrated levels,
    ``rosetta_rpcmag_cl<level>-<sensor>_<yyyymmdd>_v01``, with the level's own
    ``Logical_source`` and ``Data_type`` (`clean_logical_source`) and the Rosetta ISTP
    attribute files.  The input's provenance is kept as ``parent_*`` attributes.
    """
    import datetime as _dt

    from fluxcal.geometry.time import tt2000_to_utc
    from fluxcal.missions.rosetta.products import DATA_VERSION, istp_yaml
    from fluxcal.products.declared import Product  # numpy: not for 'fluxcal --help'

    epoch = ds["epoch"].values
    if epoch.size == 0:
        raise FluxcalError(f"LEVEL_{level} {sensor}: no vectors to write")
    part = ds.assign(time_utc=("time", tt2000_to_utc(epoch, digits=6, lsk=lsk), {"units": "UTC"}))
    attrs = {k: v for k, v in part.attrs.items() if k not in _PER_FILE_ATTRS}
    for key in ("inputs", "calibration", "kernels"):
        if key in attrs:
            attrs[f"parent_{key}"] = attrs.pop(key)
    part.attrs = attrs
    data_type, source = clean_logical_source(level, sensor)
    day = _day(epoch, lsk)
    return Product(f"RPCMAG_{day}_CL{level}_{sensor}", part,
                   _dt.date(int(day[:4]), int(day[4:6]), int(day[6:])), tuple(formats),
                   logical_source=source, version=DATA_VERSION,
                   columns=_columns(level, part),
                   label_extra={"LEVEL": f"LEVEL_{level}", "SENSOR": sensor}, **istp_yaml(),
                   attrs={"Data_type": data_type, "Logical_source": source,
                          "Data_version": str(DATA_VERSION),
                          "Logical_source_description": f"Rosetta RPC-MAG LEVEL_{level}, "
                                                        f"{CLEAN_DESCRIPTION[level.upper()]}"})


@dataclass(frozen=True)
class CleanRun:
    """The products of one cleaning level (`fluxcal.runs.driver.write`: provenance, one group).

    ``before`` is the input the before/after PNG compares with (H, K; ``None``: no PNG).
    """

    level: str
    formats: tuple[str, ...]
    before: xr.Dataset | None = None
    lsk: object = None

    def products(self, made: dict[str, xr.Dataset], options: object = None) -> Iterator[Declared]:
        """Declare each sensor's cleaned level, then the before/after PNG."""
        from fluxcal.missions.rosetta.products import level_products
        from fluxcal.products.declared import File

        for tag, ds in made.items():
            if self.level in ("F", "G"):
                # the same products (archive names, columns) as F/G from B/C
                yield from level_products(ds.assign_attrs(sensor=tag), self.formats,
                                          lsk=self.lsk)
            else:
                yield clean_products(ds, level=self.level, sensor=tag, formats=self.formats,
                                     lsk=self.lsk)
        if self.before is not None:
            sensor, after = next(iter(made.items()))
            title = f"RPC-MAG {sensor} LEVEL_{self.level}"
            plotter = plot_spectrogram if self.level == "H" else plot_timeseries
            yield File(f"RPCMAG_{_day(after['epoch'].values, self.lsk)}_CL{self.level}_"
                       f"{sensor}.png",
                       lambda path: plotter(self.before, after, path, title))

    def calibration(self, made: object, options: object = None) -> dict:
        """Return no calibration: a cleaning level is made from products and side tables."""
        return {}


def read_intervals(path: Path, lsk=None) -> list[tuple[int, int, str]]:
    """Read disturbed intervals ``start_utc,stop_utc,label`` (method 2 of LEVEL_K).

    Raises
    ------
    InputFormatError
        Wrong header or field count, unparsable time, or stop <= start (names the line).
    """
    import numpy as np

    from fluxcal.geometry.time import utc_to_tt2000

    path = Path(path)
    if not path.is_file():
        raise InputFormatError("interval file not found", path=str(path))
    out: list[tuple[int, int, str]] = []
    header = ("start_utc", "stop_utc", "label")
    seen = False
    with io.StringIO(read_text(path, "a CSV text file"), newline="") as fh:
        for lineno, row in enumerate(csv.reader(fh), start=1):
            cells = [c.strip() for c in row]
            if not cells or not "".join(cells) or cells[0].startswith("#"):
                continue
            if not seen:
                if tuple(c.lower() for c in cells) != header:
                    raise InputFormatError(
                        f"header {','.join(cells)!r}; expected {','.join(header)!r}",
                        path=str(path),
                        line=lineno,
                    )
                seen = True
                continue
            if len(cells) != 3:
                raise InputFormatError(
                    f"{len(cells)} fields; expected 3", path=str(path), line=lineno
                )
            try:
                t0, t1 = utc_to_tt2000(np.array(cells[:2]), lsk)
            except InputFormatError as exc:
                raise InputFormatError(str(exc), path=str(path), line=lineno) from None
            if t1 <= t0:
                raise InputFormatError(
                    "stop_utc must be after start_utc", path=str(path), line=lineno,
                    field="stop_utc",
                )  # fmt: skip
            out.append((int(t0), int(t1), cells[2]))
    if not out:
        raise InputFormatError("no intervals", path=str(path))
    return out


def read_heater_states(path: Path, lsk=None) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Read a heater-state series ``time_utc,<heater>,<heater>,...`` (0 = off, 1 = on).

    The first stage of method 2 (seed 003 sec. 4.12.2) as a time series, e.g. from
    `fluxcal.cleaning.heater_states.states_from_steps` on ROMAP data or from lander
    housekeeping; `fluxcal.cleaning.heater_states.intervals_from_states` turns it
    into the labelled intervals.

    Returns
    -------
    epoch : ndarray (n,) int64
        TT2000 ns.
    states : ndarray (n, k) bool
    names : list of str
        Heater names from the header.

    Raises
    ------
    InputFormatError
        Wrong header, field count, unparsable time or state (names the line).
    """
    import numpy as np

    from fluxcal.geometry.time import utc_to_tt2000

    path = Path(path)
    if not path.is_file():
        raise InputFormatError("heater-state file not found", path=str(path))
    names: list[str] | None = None
    times: list[str] = []
    rows: list[list[bool]] = []
    with io.StringIO(read_text(path, "a CSV text file"), newline="") as fh:
        for lineno, row in enumerate(csv.reader(fh), start=1):
            cells = [c.strip() for c in row]
            if not cells or not "".join(cells) or cells[0].startswith("#"):
                continue
            if names is None:
                if cells[0].lower() != "time_utc" or len(cells) < 2 or not all(cells[1:]):
                    raise InputFormatError(
                        f"header {','.join(cells)!r}; expected time_utc,<heater>,...",
                        path=str(path), line=lineno,
                    )  # fmt: skip
                names = cells[1:]
                continue
            if len(cells) != len(names) + 1:
                raise InputFormatError(
                    f"{len(cells)} fields; expected {len(names) + 1}", path=str(path), line=lineno
                )
            bad = [c for c in cells[1:] if c not in ("0", "1")]
            if bad:
                raise InputFormatError(
                    f"state {bad[0]!r} is not 0 or 1", path=str(path), line=lineno
                )
            times.append(cells[0])
            rows.append([c == "1" for c in cells[1:]])
    if names is None or not rows:
        raise InputFormatError("no heater states", path=str(path))
    try:
        epoch = utc_to_tt2000(np.array(times), lsk).astype(np.int64)
    except InputFormatError as exc:
        raise InputFormatError(str(exc), path=str(path), field="time_utc") from None
    if epoch.size > 1 and np.any(np.diff(epoch) <= 0):
        raise InputFormatError("time_utc must increase", path=str(path), field="time_utc")
    return epoch, np.array(rows, dtype=bool), names


def plot_spectrogram(before: xr.Dataset, after: xr.Dataset, path: Path, title: str) -> Path:
    """Before/after dynamic spectra (trace PSD) of the longest cleaned mode, as PNG."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.dates as mdates
    import matplotlib.pyplot as plt

    from fluxcal.cleaning.spectral_lines import dynamic_spectrum
    from fluxcal.missions.rosetta.cleaning_levels import _groups
    from fluxcal.products.quicklook import date_axis, plot_times

    groups = _groups(before)
    _, idx = max(groups, key=lambda g: g[1].size)
    epoch = before["epoch"].values[idx]
    dt = np.diff(epoch) / 1e9
    fs = 1.0 / float(np.median(dt[dt > 0])) if idx.size > 2 else 1.0
    length = int(min(1024, idx.size))
    if length < 16:
        raise FluxcalError(f"too few vectors ({idx.size}) for a spectrogram")
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True, constrained_layout=True)
    for ax, ds, name in ((axes[0], before, "before"), (axes[1], after, "after")):
        b = ds["b"].values[idx]
        psd = 0.0
        for c in range(3):
            starts, freqs, p = dynamic_spectrum(b[:, c], fs, window_length=length)
            psd = psd + p
        x = mdates.date2num(plot_times(epoch[starts + length // 2]))
        mesh = ax.pcolormesh(
            x, freqs[1:], np.log10(np.maximum(psd[:, 1:].T, 1e-12)), shading="nearest"
        )
        ax.set_ylabel("frequency (Hz)")
        ax.set_title(f"{title}: {name} line removal")
        fig.colorbar(mesh, ax=ax, label="log10 trace PSD (nT^2/Hz)")
    date_axis(axes[1])
    return _save(fig, path)


def plot_timeseries(before: xr.Dataset, after: xr.Dataset, path: Path, title: str) -> Path:
    """Before (grey) / after (colour) components, as PNG (min/max envelope of every sample)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fluxcal.products.quicklook import component_label, date_axis, envelope, plot_times

    epoch = before["epoch"].values
    hours = plot_times(epoch)
    hours_after = plot_times(after["epoch"].values)
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True, constrained_layout=True)
    for c, ax in enumerate(axes):
        ax.plot(*envelope(hours, before["b"].values[:, c]), color="0.6", lw=0.6,
                label="before")
        ax.plot(*envelope(hours_after, after["b"].values[:, c]), color="C1", lw=0.6,
                label="after")
        ax.set_ylabel(f"{component_label('xyz'[c])} (nT)")
    axes[0].legend(loc="upper right")
    axes[0].set_title(title)
    date_axis(axes[-1])
    return _save(fig, path)


def _save(fig, path: Path) -> Path:
    """Save ``fig`` as PNG at ``path`` (a declared file's temporary: `CleanRun`)."""
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        fig.savefig(path, dpi=100, format="png")
    finally:
        plt.close(fig)
    return path


def _read(path: Path, lsk=None) -> xr.Dataset:
    """Read a level product; a table (no ``epoch`` column) gets ``epoch`` from TIME.UTC."""
    import numpy as np

    from fluxcal.geometry.time import utc_to_tt2000
    from fluxcal.products import read_fluxcal_product

    path = Path(path)
    if not path.exists():
        raise InputFormatError("input product not found", path=str(path))
    ds = read_fluxcal_product(path)
    if "b" not in ds:
        raise InputFormatError(
            "not an RPC-MAG level product: no 'b' (BX, BY, BZ) variable", path=str(path)
        )
    if "epoch" not in ds:
        if "time_utc" not in ds:
            raise InputFormatError("product has neither epoch nor TIME.UTC", path=str(path))
        epoch = utc_to_tt2000(np.asarray(ds["time_utc"].values, dtype=str), lsk)
        ds = ds.assign_coords(epoch=("time", epoch.astype(np.int64), {"units": "ns"}))
    return ds


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file (a link or another spelling included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one does not exist: reported when it is read
        return Path(a).resolve() == Path(b).resolve()


def _check_two_sensors(inputs: Sequence[Path], data: Sequence[xr.Dataset]) -> None:
    """Refuse LEVEL_J inputs that are not the OB product then the IB product.

    The sensor is the product's own ``SENSOR`` attribute: a product labelled IB made
    from OB data (residuals all 0) must never be written.

    Raises
    ------
    InputFormatError
        Naming the input and its option: a product of the wrong sensor, or of none.
    """
    for path, ds, want, option in zip(inputs, data, ("OB", "IB"), ("--input", "--input-ib"),
                                      strict=True):
        have = str(ds.attrs.get("sensor", ds.attrs.get("SENSOR", ""))).strip().upper()
        if have != want:
            what = f"the {have} sensor's product" if have else "a product with no SENSOR"
            raise InputFormatError(f"is {what}; LEVEL_J takes the OB product as --input "
                                   "and the IB product as --input-ib", path=str(path),
                                   field=option)


def clean_files(
    level: str,
    inputs: Sequence[Path],
    out: Path,
    *,
    wheels: Path | None = None,
    lap_lines_hz: Sequence[float] = (),
    bandwidth_hz: float | None = None,
    seed: int = 0,
    intervals: Path | None = None,
    heater_states: Path | None = None,
    kernels: Path | None = None,
    average_s: float = 1.0,
    step_s: float | None = None,
    max_gap_samples: float = 2.0,
    formats: Sequence[str] = ("tab", "cdf"),
    plot: bool = True,
    pca_estimator: str = "robust",
    heater_direction: Sequence[float] | None = None,
) -> CleanResult:
    """Run one cleaning level on earlier-level product files and write the products.

    Parameters mirror the ``clean`` command's options.

    Raises
    ------
    FluxcalError
        Unknown level, wrong number of inputs, missing kernels for L, H with neither
        wheels nor LAP lines (it would change nothing), and every input error.
    """
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import leapseconds
    from fluxcal.missions.rosetta import cleaning_levels as cl
    from fluxcal.missions.rosetta.reaction_wheels import read_reaction_wheels
    from fluxcal.runs import driver

    level = level.strip().upper()
    if pca_estimator not in ("robust", "common-mode", "projection"):
        raise FluxcalError(f"--pca-estimator {pca_estimator}: choose robust, common-mode or "
                           "projection")
    if level not in CLEAN_LEVELS:
        raise FluxcalError(f"unknown level {level!r}; choose one of {','.join(CLEAN_LEVELS)}")
    need = 2 if level == "J" else 1
    if len(inputs) != need:
        raise FluxcalError(
            f"LEVEL_{level} needs {need} input product(s) "
            + ("(--input OB, --input-ib IB)" if need == 2 else "(--input)")
        )
    if level == "J" and _same_file(*inputs):
        raise InputFormatError("is given as both --input (OB) and --input-ib (IB); LEVEL_J "
                               "needs the two sensors' products", path=str(inputs[1]),
                               field="--input-ib")
    if level == "L" and kernels is None:
        raise FluxcalError("LEVEL_L needs SPICE kernels: pass --kernels META (SCLK, CK, SPK)")
    if level == "H" and wheels is None and not len(lap_lines_hz):
        raise FluxcalError(
            "LEVEL_H removes reaction-wheel and LAP lines and none were given: pass --wheels "
            "CSV and/or --lap-lines HZ[,HZ...]"
        )
    if bandwidth_hz is not None and not 0 < bandwidth_hz < float("inf"):
        raise FluxcalError(f"--bandwidth {bandwidth_hz:g}: the replaced band width must be a "
                           "finite number > 0 Hz")
    if step_s is not None and not 0 < step_s < float("inf"):
        raise FluxcalError(f"--step {step_s:g}: the grid step must be a finite number > 0 s")
    if not 0 <= max_gap_samples < float("inf"):
        raise FluxcalError(f"--max-gap {max_gap_samples:g}: give a finite number of sample "
                           "intervals >= 0")
    negative = [f for f in lap_lines_hz if not 0 < f < float("inf")]
    if negative:
        raise FluxcalError(f"--lap-lines {negative[0]:g}: a line frequency must be a finite "
                           "number > 0 Hz")
    if level == "K" and intervals is not None and heater_states is not None:
        raise FluxcalError("give either --intervals or --heater-states, not both")
    if level in ("F", "G", "I"):
        check_average(average_s)
    result = CleanResult()
    out = Path(out)
    with KernelPool(kernels, frames=FRAME_KERNELS) as pool:
        lsk = leapseconds()
        # the small side tables first: a defect there is reported before the products load
        table = read_reaction_wheels(wheels, lsk) if level == "H" and wheels is not None \
            else None
        spans = read_intervals(intervals, lsk) if level == "K" and intervals is not None \
            else None
        states = read_heater_states(heater_states, lsk) \
            if level == "K" and heater_states is not None else None
        data = [_read(p, lsk) for p in inputs]
        for path, ds in zip(inputs, data, strict=True):
            have = str(ds.attrs.get("level", "")).upper()
            if have and have not in SOURCE_LEVELS[level]:
                raise InputFormatError(
                    f"is a LEVEL_{have} product; LEVEL_{level} is made from LEVEL_"
                    + " or LEVEL_".join(SOURCE_LEVELS[level]),
                    path=str(path),
                )
        if level == "J":
            _check_two_sensors(inputs, data)
        used_inputs: list[Path] = list(inputs)
        src = data[0]
        # a name from the input's metadata becomes part of file names (paths rule 3)
        sensor = plain_name(src.attrs.get("sensor", src.attrs.get("SENSOR", "OB")),
                            what="SENSOR", path=str(inputs[0]))
        if level == "H":
            if wheels is not None:
                used_inputs.append(Path(wheels))
            made = {
                sensor: cl.level_h(src, table, lap_lines_hz, bandwidth_hz=bandwidth_hz, seed=seed)
            }
        elif level == "I":
            made = {sensor: cl.level_i(src, average_s, lsk=lsk)}
        elif level == "F":
            made = {sensor: cl.level_f(src, average_s, lsk=lsk)}
        elif level == "G":
            made = {sensor: cl.level_g(src, average_s, lsk=lsk)}
        elif level == "J":
            made = cl.level_j(data[0], data[1], step_s=step_s, max_gap_samples=max_gap_samples,
                              estimator=pca_estimator)
        elif level == "K":
            if spans is not None:
                used_inputs.append(Path(intervals))
                made = {sensor: cl.level_k_assisted(src, spans)}
            elif states is not None:
                from fluxcal.cleaning.heater_states import intervals_from_states

                used_inputs.append(Path(heater_states))
                made = {sensor: cl.level_k_assisted(src, intervals_from_states(*states))}
            else:
                made = {sensor: cl.level_k(src, heater_direction=heater_direction)}
        else:
            made = {sensor: cl.level_l(src, lsk=lsk)}
        result.levels.update(made)
        run = CleanRun(level, tuple(formats), src if plot and level in ("H", "K") else None,
                       lsk)
        result.paths = driver.write(run, made, out, None, inputs=used_inputs,
                                    kernel_list=[Path(str(k)) for k in pool.loaded])
    return result


def _floats(text: str, option: str) -> list[float]:
    try:
        return [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise typer.BadParameter(f"expected comma-separated Hz values, got {text!r}",
                                 param_hint=option) from None  # fmt: skip


def _direction(text: str) -> list[float] | None:
    if not text.strip():
        return None
    try:
        values = [float(t) for t in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not any(values):
        raise typer.BadParameter(f"expected a non-zero vector X,Y,Z, got {text!r}",
                                 param_hint="--heater-direction")
    return values


@with_config(exclude=("input", "input_ib", "out", "wheels", "intervals", "heater_states",
                      "kernels"))
def clean(
    level: str = typer.Option(..., "--level", help="Level to make: F, G, H, I, J, K or L."),
    input: list[Path] = typer.Option(  # noqa: A002 - the option's natural name
        ...,
        "--input",
        help="Earlier-level product (.cdf/.nc/.TAB): K for F, L for G, C or L for H, H for I, "
        "B for K, K for L; for J the OB product (G or I).",
    ),
    input_ib: Path | None = typer.Option(None, "--input-ib", help="J only: the IB product."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    wheels: Path | None = typer.Option(
        None, "--wheels", help="H: reaction wheel CSV time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz."
    ),
    lap_lines: str = typer.Option("", "--lap-lines", help="H: fixed LAP lines, e.g. 2.5,4.1 (Hz)."),
    bandwidth: float | None = typer.Option(
        None, "--bandwidth", help="H: replaced band width in Hz (default 0.06 Hz at 20 Hz)."
    ),
    seed: int = typer.Option(0, "--seed", help="H: seed of the substituted noise."),
    intervals: Path | None = typer.Option(
        None, "--intervals", help="K: ROMAP intervals CSV start_utc,stop_utc,label (method 2)."
    ),
    heater_states: Path | None = typer.Option(
        None,
        "--heater-states",
        help="K: heater-state CSV time_utc,<heater>,... of 0/1 (method 2, stage 1).",
    ),
    kernels: Path | None = typer.Option(
        None, "--kernels", help="Meta-kernel (SCLK, CK, SPK); needed for L."
    ),
    average: float = typer.Option(1.0, "--average", help="F, G, I: averaging interval (s)."),
    step: float | None = typer.Option(
        None, "--step", help="J: regular common time grid step (s); default the OB tags."
    ),
    max_gap: float = typer.Option(
        2.0, "--max-gap", help="J: longest gap bridged by interpolation (sample intervals)."
    ),
    pca_estimator: str = typer.Option(
        "robust", "--pca-estimator",
        help="J: robust (default; noise variances from the high-passed series), common-mode "
        "(from the series themselves) or projection (literal principal components).",
    ),
    heater_direction: str = typer.Option(
        "", "--heater-direction",
        help="K: direction X,Y,Z (s/c frame) of the heater field when on, where the data "
        "cannot tell which level is heater-off (a constant current seen 'on' first).",
    ),
    formats: str = typer.Option("tab,cdf", "--formats",
                                help="Product formats: tab, cdf, nc, zarr."),
    no_plot: bool = typer.Option(False, "--no-plot", help="Skip the before/after PNG (H, K)."),
) -> None:
    """Remove s/c disturbances: LEVEL_H (wheel/LAP lines), I, J (PCA), K, L (heaters), F, G."""
    inputs = list(input) + ([input_ib] if input_ib is not None else [])
    if not no_plot and level.upper() in ("H", "K"):  # before any input is read
        require("plot", f"the before/after PNG of LEVEL_{level.upper()} (or --no-plot)")
    result = clean_files(
        level,
        inputs,
        out,
        wheels=wheels,
        lap_lines_hz=_floats(lap_lines, "--lap-lines"),
        bandwidth_hz=bandwidth,
        seed=seed,
        intervals=intervals,
        heater_states=heater_states,
        kernels=kernels,
        average_s=average,
        step_s=step,
        max_gap_samples=max_gap,
        formats=[f.strip() for f in formats.split(",") if f.strip()],
        plot=not no_plot,
        pca_estimator=pca_estimator,
        heater_direction=_direction(heater_direction),
    )
    for tag, ds in result.levels.items():
        typer.echo(f"LEVEL_{level.upper()} {tag}: {ds.sizes['time']} vectors")
    typer.echo(f"{len(result.paths)} files in {out}")
