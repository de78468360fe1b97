"""Quicklook plots: one PNG per day with field components, magnitude and context.

Panels, top to bottom (a panel is drawn only when the Dataset has its variable):

1. the three field components (the first vector variable in nT, preferring ``B*``);
2. the field magnitude, on a log scale when it spans more than a factor of 20 (a
   Mercury orbit of seed 000: periapsis and the rest both readable);
3. applied offsets (seed 000; a vector variable whose name starts with ``offset``);
4. temperatures (seed 003; variables named ``temperature*``/``T_*`` in degC or K);
5. quality flags (``quality*``/``flag*``), as categories: one tick per value seen
   (named by CF ``flag_values``/``flag_meanings`` when given) when there are few;
6. spacecraft distance (``distance`` with its ``label`` attr, e.g. "Sun distance" in
   AU, or the norm of a ``position*`` vector in km).

The time axis is UTC with matplotlib date ticks (`matplotlib.dates.AutoDateLocator`,
`matplotlib.dates.ConciseDateFormatter`: ``03:00``, ``06:00`` ... under the date), from
the int64 TT2000 ``epoch`` with cdflib (no SPICE needed).  The legend names the field
components as the product does (``B_R B_T B_N``, ``B_X B_Y B_Z``); every axis label
carries the variable's units; a linear value axis never prints an offset or a power of
ten (a nearly constant distance reads ``30.000``, not ``1e-11+3e1``).  Long days are
reduced for drawing by a min/max envelope per pixel column, so every excursion stays
visible.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from fluxcal.extras import guard

try:  # the plot extra: a core install (no matplotlib) stops here, in one line
    import matplotlib
except ImportError as _exc:
    raise guard("plot", "quicklooks and figures", _exc) from _exc

matplotlib.use("Agg")

import cdflib  # noqa: E402
import matplotlib.dates as mdates  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import ScalarFormatter  # noqa: E402

from fluxcal.errors import InputFormatError  # noqa: E402
from fluxcal.products.atomic import atomic_path  # noqa: E402
from fluxcal.products.attrs import variable_units  # noqa: E402
from fluxcal.products.timeindex import default_lsk, epoch_from_table  # noqa: E402, F401

log = logging.getLogger(__name__)

NS_PER_HOUR = 3_600 * 1_000_000_000
MAX_POINTS = 4000  # envelope bins per panel (about the pixel width of the figure)
COLORS = ("tab:blue", "tab:green", "tab:red")


def _find(ds: xr.Dataset, prefixes: Sequence[str], vector: bool | None = None,
          units: Sequence[str] | None = None) -> list[str]:
    out = []
    for name in ds.data_vars:
        n = str(name)
        var = ds[name]
        if var.dims[:1] != ("time",):
            continue
        if not any(n.lower().startswith(p.lower()) for p in prefixes):
            continue
        if vector is not None and (var.ndim == 2) != vector:
            continue
        if units is not None and variable_units(var) not in units:
            continue
        if var.dtype.kind not in "iufb":
            continue
        out.append(n)
    return out


def field_variable(ds: xr.Dataset) -> str:
    """Name of the field vector to plot: a ``B*`` vector in nT, else any nT vector."""
    for cands in (_find(ds, ["B"], vector=True, units=["nT"]),
                  _find(ds, [""], vector=True, units=["nT"]), _find(ds, ["B"], vector=True)):
        if cands:
            return cands[0]
    raise InputFormatError("no field vector variable (dims (time, component), units nT) "
                           f"in the dataset; have {sorted(map(str, ds.data_vars))}")


def envelope(x: np.ndarray, y: np.ndarray, bins: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Min/max envelope of ``y`` in at most ``bins`` equal-count bins (vectorized), for drawing.

    Every sample belongs to a bin, the last (shorter) bin included, so a spike in
    the last samples of a product is drawn like one anywhere else.  Each bin gives
    two points at its first ``x``: its minimum and its maximum (NaN ignored; an
    all-NaN bin gives NaN, a gap in the line).

    Parameters
    ----------
    x : numpy.ndarray
        Abscissa (numbers or datetime64), one per sample.
    y : numpy.ndarray
        Values, one per sample.
    bins : int
        Most bins (about the pixel width of the figure).

    Returns
    -------
    tuple of numpy.ndarray
        ``(xs, ys)`` of ``2 * ceil(n / ceil(n / bins))`` points, or ``x`` and ``y``
        unchanged when they are no longer than ``2 * bins`` already.
    """
    n = len(y)
    if n <= 2 * bins:
        return x, y
    per = -(-n // bins)  # ceil: at most `bins` bins cover all n samples
    starts = np.arange(0, n, per)
    yf = np.asarray(y, dtype=float)
    lo = np.fmin.reduceat(yf, starts)  # fmin/fmax skip NaN
    hi = np.fmax.reduceat(yf, starts)
    xs = np.repeat(np.asarray(x)[starts], 2)
    ys = np.column_stack([lo, hi]).ravel()
    return xs, ys


def day_start_ns(epoch0: int) -> tuple[int, str]:
    """TT2000 of 00:00 UTC of the day containing ``epoch0``, and that date as text."""
    y, mo, d = (int(v) for v in cdflib.cdfepoch.breakdown_tt2000(int(epoch0))[:3])
    start = int(cdflib.cdfepoch.compute_tt2000([y, mo, d, 0, 0, 0, 0, 0, 0]))
    return start, f"{y:04d}-{mo:02d}-{d:02d}"


def quicklook_figure(ds: xr.Dataset, title: str = "", frame: str | None = None,
                     field: str | None = None) -> Figure:
    """Build the quicklook figure of ``ds`` (no I/O).

    Parameters
    ----------
    ds : xarray.Dataset
        A product with int64 ``epoch`` along ``time`` and a field vector in nT.
    title : str
        Figure title (e.g. the product name).
    frame : str, optional
        Frame name for the axis labels (default: the field variable's or the
        dataset's ``frame`` attr, the dataset's ``COORDINATE_SYSTEM``, or the suffix
        of the variable name, e.g. ``B_mso`` -> ``mso``).
    field : str, optional
        The field vector to plot (default: `field_variable`), e.g. ``"b_mso"`` when the
        dataset holds the field in several frames.
    """
    if "epoch" not in ds.coords and "epoch" not in ds:
        raise InputFormatError("quicklook needs the int64 'epoch' coordinate", field="epoch")
    epoch = ds["epoch"].values.astype(np.int64)
    if epoch.size == 0:
        raise InputFormatError("quicklook of an empty product", field="epoch")
    start, date = day_start_ns(int(np.median(epoch)))
    times = utc_times(epoch, start, date)
    bname = field or field_variable(ds)
    if bname not in ds or ds[bname].ndim != 2:
        raise InputFormatError(f"field {bname!r} is not a (time, component) variable of the "
                               "dataset", field=bname)
    b = ds[bname].values.astype(float)
    frame = frame or str(
        ds[bname].attrs.get("frame")
        or ds.attrs.get("frame")
        or ds.attrs.get("COORDINATE_SYSTEM")
        or (bname.split("_", 1)[-1] if "_" in bname else "")
    )
    comps = [str(c) for c in ds[ds[bname].dims[1]].values] if ds[bname].dims[1] in ds.coords \
        else ["x", "y", "z"]
    panels: list[tuple[str, object]] = [("components", None), ("magnitude", None)]
    offsets = _find(ds, ["offset"], vector=True)
    temps = _find(ds, ["temperature", "T_", "temp"], vector=False, units=["degC", "K", "C"])
    quality = _find(ds, ["quality", "flag"])
    pos = _find(ds, ["position"], vector=True, units=["km"])
    dist = _find(ds, ["distance", "r_km", "range"], vector=False, units=["km", "AU", "au"])
    if offsets:
        panels.append(("offsets", offsets[0]))
    if temps:
        panels.append(("temperature", temps))
    if quality:
        panels.append(("quality", quality[0]))
    if dist:
        panels.append(("distance", dist[0]))
    elif pos:
        panels.append(("position", pos[0]))
    fig = Figure(figsize=(11, 2.0 * len(panels) + 1.0), dpi=100)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (kind, arg) in zip(axes, panels, strict=True):
        if kind == "components":
            for j in range(b.shape[1]):
                ax.plot(*envelope(times, b[:, j]), lw=0.6, color=COLORS[j % 3],
                        label=component_label(comps[j]))
            units = variable_units(ds[bname]) or "nT"
            ax.set_ylabel(f"B {frame} ({units})".replace("  ", " "))
            ax.legend(loc="upper right", fontsize=8, ncol=3)
        elif kind == "magnitude":
            m = np.linalg.norm(b, axis=1)
            ax.plot(*envelope(times, m), lw=0.6, color="k")
            ax.set_ylabel(f"|B| ({variable_units(ds[bname]) or 'nT'})")
            if _wide_range(m):
                ax.set_yscale("log")
        elif kind == "offsets":
            o = ds[arg].values.astype(float)
            for j in range(o.shape[1]):
                ax.plot(*envelope(times, o[:, j]), lw=0.8, color=COLORS[j % 3],
                        label=f"{comps[j] if j < len(comps) else j}")
            ax.set_ylabel(f"{arg} ({variable_units(ds[arg])})")
            ax.legend(loc="upper right", fontsize=8, ncol=3)
        elif kind == "temperature":
            for name in arg:
                ax.plot(*envelope(times, ds[name].values.astype(float)), lw=0.8, label=name)
            ax.set_ylabel(f"T ({variable_units(ds[arg[0]])})")
            ax.legend(loc="upper right", fontsize=8)
        elif kind == "quality":
            _quality_panel(ax, times, ds[arg])
            ax.set_ylabel(f"{arg}")
        elif kind == "distance":
            ax.plot(*envelope(times, ds[arg].values.astype(float)), lw=0.8, color="tab:brown")
            ax.set_ylabel(f"{ds[arg].attrs.get('label', 'distance')} ({variable_units(ds[arg])})")
        else:
            r = np.linalg.norm(ds[arg].values.astype(float), axis=1)
            ax.plot(*envelope(times, r), lw=0.8, color="tab:brown")
            ax.set_ylabel("distance (km)")
        ax.grid(alpha=0.3)
        plain_numbers(ax)
    date_axis(axes[-1])
    fig.suptitle(title or f"{bname} {date}")
    fig.align_ylabels(axes)
    return fig


def utc_times(epoch: np.ndarray, day_start: int, date: str) -> np.ndarray:
    """UTC ``datetime64[ns]`` of TT2000 ``epoch`` for plotting, from 00:00 UTC of ``date``.

    ``day_start`` is the TT2000 of that midnight (`day_start_ns`): a sample's UTC is the
    date plus its nanoseconds since then, exact within the day (a leap second at its end
    puts the 1 s after it 1 s late on the axis).

    Examples
    --------
    >>> import numpy as np
    >>> start, date = day_start_ns(0)
    >>> str(utc_times(np.array([start + 3_600_000_000_000]), start, date)[0])
    '2000-01-01T01:00:00.000000000'
    """
    return np.datetime64(date, "ns") + (np.asarray(epoch, np.int64) - day_start).astype("m8[ns]")


def plot_times(epoch: np.ndarray) -> np.ndarray:
    """Return UTC ``datetime64[ns]`` of TT2000 ``epoch`` for a time axis (`utc_times`)."""
    epoch = np.asarray(epoch, np.int64)
    start, date = day_start_ns(int(epoch[0])) if epoch.size else (0, "2000-01-01")
    return utc_times(epoch, start, date)


def date_axis(ax) -> None:
    """UTC date ticks on ``ax``'s time axis (`matplotlib.dates.ConciseDateFormatter`).

    Ticks at round times (``00:05``, ``06:00``, ...) with the date written once beneath;
    the axis label is ``Time (UTC)``.
    """
    locator = mdates.AutoDateLocator(minticks=4, maxticks=10)
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    ax.set_xlabel("Time (UTC)")


def component_label(component: str) -> str:
    """Legend name of a field component: ``B_R`` stays, ``x`` becomes ``B_X``.

    >>> [component_label(c) for c in ("B_R", "x", "Bz")]
    ['B_R', 'B_X', 'Bz']
    """
    c = str(component).strip()
    return c if len(c) > 1 and c[0] in "Bb" else f"B_{c.upper()}"


#: A linear value axis whose data span less than this fraction of their magnitude (or
#: than `FLAT_ABSOLUTE`) is widened to ``value * (1 +- FLAT_RELATIVE)``: a constant drawn
#: on a readable scale, not rounding noise magnified.
FLAT_RELATIVE = 1e-6
FLAT_ABSOLUTE = 1e-9


def plain_numbers(ax) -> None:
    """Value-axis ticks as plain numbers: no offset text, no ``1e..`` multiplier.

    A nearly constant line (a comet distance of 30 km +- 1e-11) would otherwise be
    labelled ``1e-11+3e1``; its axis is widened (`FLAT_RELATIVE`) before.  Log axes
    (their own formatter) are left as they are.
    """
    if ax.get_yscale() != "linear" or not isinstance(ax.yaxis.get_major_formatter(),
                                                      ScalarFormatter):
        return
    ys = [np.asarray(line.get_ydata(), float) for line in ax.get_lines()]
    ys = [y[np.isfinite(y)] for y in ys if y.size]
    ys = [y for y in ys if y.size]
    if ys:
        lo, hi = min(float(y.min()) for y in ys), max(float(y.max()) for y in ys)
        mid = 0.5 * (lo + hi)
        if hi - lo < max(FLAT_RELATIVE * abs(mid), FLAT_ABSOLUTE):
            pad = max(FLAT_RELATIVE * 1e3 * abs(mid), 1e-3)
            ax.set_ylim(mid - pad, mid + pad)
    ax.ticklabel_format(axis="y", style="plain", useOffset=False)


#: ``|B|`` spanning more than this ratio (1st to 99th percentile) is drawn on a log scale.
LOG_RATIO = 20.0
#: A quality variable with at most this many distinct values is drawn as categories.
MAX_CATEGORIES = 16


def _wide_range(m: np.ndarray) -> bool:
    """Whether ``m`` (>= 0) spans more than `LOG_RATIO` between its 1st and 99th percentile."""
    good = m[np.isfinite(m) & (m > 0)]
    if good.size < 2:
        return False
    lo, hi = np.percentile(good, [1.0, 99.0])
    return bool(hi > LOG_RATIO * lo)


def _quality_panel(ax, times: np.ndarray, var: xr.DataArray) -> None:
    """Draw a quality flag as categories (one tick per value seen), else as a line."""
    q = var.values
    values, index = np.unique(q, return_inverse=True)
    if values.size > MAX_CATEGORIES or q.dtype.kind == "f":
        ax.step(*envelope(times, q.astype(float)), lw=0.8, where="post", color="tab:purple")
        return
    names = {}
    flag_values = np.atleast_1d(var.attrs.get("flag_values", []))
    meanings = str(var.attrs.get("flag_meanings", "")).split()
    if len(meanings) == flag_values.size:
        names = {int(v): m for v, m in zip(flag_values, meanings, strict=True)}
    ax.plot(*envelope(times, index.astype(float)), ls="none", marker="|", ms=6,
            color="tab:purple")
    ax.set_yticks(np.arange(values.size))
    ax.set_yticklabels([names.get(int(v), str(int(v))) for v in values], fontsize=7)
    ax.set_ylim(-0.5, values.size - 0.5)


def save_png(fig: Figure, path: Path) -> Path:
    """Save ``fig`` as PNG atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path


#: An edge day holding less than this span of data ...
EDGE_SPAN_NS = 30 * 60 * 1_000_000_000
#: ... and fewer samples than this fraction of its neighbour's is drawn with it.
EDGE_FRACTION = 0.10


def _day_keys(epoch: np.ndarray) -> np.ndarray:
    parts = np.asarray(cdflib.cdfepoch.breakdown_tt2000(epoch)).reshape(-1, 9)
    return parts[:, 0] * 10000 + parts[:, 1] * 100 + parts[:, 2]


def split_days(ds: xr.Dataset) -> list[tuple[str, xr.Dataset]]:
    """Split ``ds`` at UTC midnights: ``[(yyyymmdd, day_ds), ...]``, one per UTC day.

    A first or last day holding under 30 min of data and under 10 % of its
    neighbour's samples is drawn with that neighbour (and named by it): a daily
    product whose first samples fall a few seconds before midnight (e.g. seed 000's
    days defined by the recorded time, before the latency correction) gives one PNG,
    while a run over several days gives one PNG per day, however short it is.
    """
    epoch = ds["epoch"].values.astype(np.int64)
    if epoch.size == 0:
        return []
    key = _day_keys(epoch)
    # day boundaries (epoch is in time order): start index of each day's run
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    bounds = list(np.r_[starts, epoch.size])
    names = [int(key[i]) for i in starts]

    def small(i: int, j: int) -> bool:  # run i is a small edge beside run j
        n_i, n_j = bounds[i + 1] - bounds[i], bounds[j + 1] - bounds[j]
        span = int(epoch[bounds[i + 1] - 1]) - int(epoch[bounds[i]])
        return span < EDGE_SPAN_NS and n_i < EDGE_FRACTION * n_j

    if len(names) > 1 and small(len(names) - 1, len(names) - 2):
        del bounds[-2], names[-1]
    if len(names) > 1 and small(0, 1):
        del bounds[1], names[0]
    return [(f"{k:08d}", ds.isel(time=slice(a, b)))
            for k, a, b in zip(names, bounds[:-1], bounds[1:], strict=True)]


def write_quicklooks(ds: xr.Dataset, out_dir: Path, stem: str, field: str | None = None,
                     frame: str | None = None) -> list[Path]:
    """Write ``<out_dir>/<stem>_<yyyymmdd>.png`` for every UTC day in ``ds``.

    This is the quicklook option of the pipelines: call it with the calibrated day
    Dataset (which may hold ``offset`` or ``temperature`` variables that the archived
    product does not) and the field in the chosen frame (``field=``, ``frame=``).
    """
    paths = []
    for day, sub in split_days(ds):
        fig = quicklook_figure(sub, title=f"{stem} {day}", frame=frame, field=field)
        paths.append(save_png(fig, Path(out_dir) / f"{stem}_{day}.png"))
        plt.close(fig)
    return paths
