"""Spectrogram figures (``fluxcal plot --spectrogram``, cleaning levels' plots).

Kept apart from `fluxcal.products.quicklook` so that a run that draws a quicklook or the
offset report's figure does not import ``scipy.signal`` (0.8 s of CPU on the 2-core VM,
most of it scipy's docstring processing; docs/decisions/products.md, decision 52).
"""

from __future__ import annotations

from fluxcal.extras import guard

try:  # the plot extra, as `fluxcal.products.quicklook`
    import matplotlib.dates as mdates
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
except ImportError as _exc:
    raise guard("plot", "spectrograms", _exc) from _exc

import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from scipy.signal import spectrogram  # noqa: E402

from fluxcal.errors import InputFormatError  # noqa: E402
from fluxcal.products.quicklook import (  # noqa: E402
    component_label,
    date_axis,
    day_start_ns,
    field_variable,
)


def spectrogram_axes(ax, t_seconds: np.ndarray, signal: np.ndarray, fs: float,
                     nperseg: int = 256, label: str = "", norm=None) -> object:
    """Draw a power spectrogram of ``signal`` (sampled at ``fs`` Hz) on ``ax``.

    Used where cleaning levels ran (spectral line removal): power in nT^2/Hz, log
    colour scale.  ``signal`` must be evenly sampled (see `uniform_runs`).  Returns
    the QuadMesh (for a colour bar).
    """
    if len(signal) < nperseg:
        raise InputFormatError(f"spectrogram needs at least nperseg={nperseg} samples, "
                               f"got {len(signal)}", field=label or "signal")
    f, t, sxx = spectrogram(np.asarray(signal, float), fs=fs, nperseg=nperseg)
    mesh = ax.pcolormesh(t_seconds[0] + t, f, np.log10(sxx + 1e-30), shading="auto",
                         norm=norm)
    ax.set_ylabel("Frequency (Hz)")
    ax.set_xlabel("Time (s)")
    if label:
        ax.set_title(label, fontsize=9, loc="left")
    return mesh


#: Relative change of the sample spacing that starts a new evenly sampled run: rate
#: changes are factors of 2 or more and gaps longer still, while time-tag jitter of a
#: few per cent must not cut a run.
RATE_TOLERANCE = 0.25


def uniform_runs(t_seconds: np.ndarray, tolerance: float = RATE_TOLERANCE) -> list[slice]:
    """Split sample times into runs of (nearly) constant spacing.

    A run ends where the spacing differs from the run's previous spacing by more than
    ``tolerance`` (relative): a change of vector rate (filter mode) or a gap.  Each run
    is a slice of the samples; consecutive runs share no sample.
    """
    t = np.asarray(t_seconds, float)
    if t.size < 3:
        return [slice(0, t.size)]
    dt = np.diff(t)
    change = np.abs(dt[1:] - dt[:-1]) > tolerance * np.minimum(dt[1:], dt[:-1])
    # a change between spacing k and k+1 puts sample k+2 into a new run
    cuts = np.flatnonzero(change) + 2
    edges = np.r_[0, cuts, t.size]
    edges = np.unique(edges)
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def spectrogram_figure(ds: xr.Dataset, variable: str | None = None, fs: float | None = None,
                       nperseg: int = 256) -> Figure:
    """One spectrogram panel per component of a vector variable (default: the field).

    The time axis is UTC, from each sample's own time: a day whose
    vector rate changes (or that has gaps) is drawn as one spectrogram per evenly
    sampled run (`uniform_runs`) at its own rate, placed at its real times, with one
    colour scale; runs shorter than ``nperseg`` are left blank; UTC date ticks
    (`date_axis`).  ``fs`` forces one rate
    for the whole series (evenly sampled data only).
    """
    name = variable or field_variable(ds)
    epoch = ds["epoch"].values.astype(np.int64)
    if epoch.size == 0:
        raise InputFormatError("spectrogram of an empty product", field="epoch")
    start, date = day_start_ns(int(epoch[0]))
    t = (epoch - start) / 1e9
    day0 = float(mdates.date2num(np.datetime64(date, "ns")))
    runs = [slice(0, t.size)] if fs is not None else uniform_runs(t)
    runs = [r for r in runs if r.stop - r.start >= nperseg]
    if not runs:
        raise InputFormatError(f"spectrogram needs an evenly sampled run of at least "
                               f"nperseg={nperseg} samples", field=name)
    data = ds[name].values.astype(float)
    rates = [fs or 1.0 / float(np.median(np.diff(t[r]))) for r in runs]
    specs = {(k, j): spectrogram(data[r, j], fs=f, nperseg=nperseg)
             for k, (r, f) in enumerate(zip(runs, rates, strict=True))
             for j in range(data.shape[1])}
    logs = {key: np.log10(sxx + 1e-30) for key, (_, _, sxx) in specs.items()}
    lo = min(float(np.percentile(v, 1)) for v in logs.values())  # one colour scale
    hi = max(float(v.max()) for v in logs.values())
    norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    fig = Figure(figsize=(11, 2.4 * data.shape[1] + 0.8), dpi=100, layout="constrained")
    axes = fig.subplots(data.shape[1], 1, sharex=True, squeeze=False)[:, 0]
    comps = [str(c) for c in ds[ds[name].dims[1]].values] if ds[name].dims[1] in ds.coords \
        else [str(j) for j in range(data.shape[1])]
    for j, ax in enumerate(axes):
        for k, r in enumerate(runs):
            f, tt, _ = specs[(k, j)]
            x = day0 + (t[r][0] + tt) / 86_400.0  # matplotlib date numbers (days)
            mesh = ax.pcolormesh(x, f, logs[(k, j)], shading="auto", norm=norm)
        ax.set_ylabel("Frequency (Hz)")
        ax.set_title(f"{component_label(comps[j])} ({name})", fontsize=9, loc="left")
        ax.set_ylim(0, max(rates) / 2)
        fig.colorbar(mesh, ax=ax, label="log10 PSD (nT$^2$/Hz)")
    date_axis(axes[-1])
    if len(set(np.round(rates, 6))) > 1:
        fig.suptitle(f"{len(runs)} evenly sampled runs, "
                     f"{min(rates):g}-{max(rates):g} Hz", fontsize=9)
    return fig
