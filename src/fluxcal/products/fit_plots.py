"""Draw the pictures of a fit (`fluxcal.products.fit_pictures`) with matplotlib.

The ``plot`` extra: a core install stops at the guarded import below in one line
(`fluxcal.extras.guard`).  Each picture becomes one PNG written atomically
(`fluxcal.products.quicklook.save_png`); time axes are UTC
(`fluxcal.products.quicklook.date_axis`).
"""

from __future__ import annotations

from pathlib import Path

from fluxcal.extras import guard

try:  # the plot extra
    import matplotlib
except ImportError as _exc:
    raise guard("plot", "fit pictures", _exc) from _exc

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from fluxcal.products.fit_pictures import Panel, Picture, Pulls, Rejections  # noqa: E402
from fluxcal.products.quicklook import COLORS, date_axis, save_png  # noqa: E402

#: Bins of the pull histograms (pulls beyond +-PULL_LIMIT are counted in the edge bins).
PULL_LIMIT = 5.0


def panel_figure(panel: Panel) -> Figure:
    """One subplot per axis: points with error bars, the law, its band, the fitted range.

    The first ``len(panel.axes)`` subplots (`matplotlib.figure.Figure.axes`) are these;
    the law's line is the first line of each, its data exactly ``panel.curve.x`` and
    ``panel.curve.y[:, j]``.  When the law has a band, a second column shows the points'
    residuals about the law (``points.model``, else the law interpolated on its samples)
    inside the band around zero:
    a band of 0.1 nT on a law spanning hundreds is invisible in the first column.
    """
    n = len(panel.axes)
    c, p = panel.curve, panel.points
    residuals = c is not None and c.band is not None
    fig = plt.figure(figsize=(12 if residuals else 8, 2.4 * n + 0.8))
    grid = fig.add_gridspec(n, 2 if residuals else 1, width_ratios=[3, 2] if residuals else [1])
    left = [fig.add_subplot(grid[0, 0])]
    left += [fig.add_subplot(grid[j, 0], sharex=left[0]) for j in range(1, n)]
    right = [fig.add_subplot(grid[j, 1], sharex=left[0]) for j in range(n)] if residuals else []
    for j, (ax, name) in enumerate(zip(left, panel.axes, strict=True)):
        color = COLORS[j % len(COLORS)]
        if c is not None:
            ax.plot(c.x, c.y[:, j], color=color, lw=1.4, label=c.label, zorder=3)
            if c.band is not None:
                ax.fill_between(c.x, c.y[:, j] - c.band[:, j], c.y[:, j] + c.band[:, j],
                                color=color, alpha=0.25, lw=0, label="1-sigma band")
        if p is not None:
            err = None if p.err is None else p.err[:, j]
            ax.errorbar(p.x, p.y[:, j], yerr=err, fmt="o", ms=3, color="k", lw=0.8,
                        label=p.label)
        ax.set_ylabel(f"{name}\n{panel.ylabel}")
        if residuals:
            r = right[j]
            r.fill_between(c.x, -c.band[:, j], c.band[:, j], color=color, alpha=0.25, lw=0,
                           label="law's 1-sigma band")
            r.axhline(0.0, color=color, lw=1.0)
            if p is not None and np.asarray(p.x).size:
                res = p.y[:, j] - (np.interp(p.x, c.x, c.y[:, j]) if p.model is None
                                   else p.model[:, j])
                r.errorbar(p.x, res, yerr=None if p.err is None else p.err[:, j], fmt="o",
                           ms=3, color="k", lw=0.8, label="measured - law")
            r.set_ylabel(f"{name} - law\n{panel.ylabel}")
        for a in (ax, *([right[j]] if residuals else [])):
            if panel.fitted_range is not None:
                spans = ([panel.fitted_range] if np.ndim(panel.fitted_range) == 1
                         else panel.fitted_range)
                for k, (lo, hi) in enumerate(s for s in spans if all(np.isfinite(s))):
                    a.axvspan(lo, hi, color="0.93", zorder=0,
                              label=None if k else "range the data determine")
            a.grid(alpha=0.3)
    left[0].legend(fontsize=7, loc="best")
    if residuals:
        right[0].legend(fontsize=7, loc="best")
        right[-1].set_xlabel(panel.xlabel)
    if p is not None and np.asarray(p.x).dtype.kind == "M":
        date_axis(left[-1])
    left[-1].set_xlabel(panel.xlabel)
    fig.suptitle(panel.title)
    fig.tight_layout()
    return fig


def pulls_figure(pulls: Pulls) -> Figure:
    """Histograms of each group's pulls with the unit normal scaled to their count."""
    n = max(len(pulls.values), 1)
    fig, axs = plt.subplots(1, n, figsize=(3.2 * n + 0.8, 3.2), squeeze=False)
    edges = np.linspace(-PULL_LIMIT, PULL_LIMIT, 21)
    grid = np.linspace(-PULL_LIMIT, PULL_LIMIT, 201)
    for ax, (name, values) in zip(axs[0], pulls.values.items(), strict=False):
        v = np.clip(np.asarray(values, float), -PULL_LIMIT, PULL_LIMIT)
        ax.hist(v, bins=edges, color="tab:blue", alpha=0.7)
        width = edges[1] - edges[0]
        ax.plot(grid, v.size * width * np.exp(-0.5 * grid**2) / np.sqrt(2 * np.pi),
                color="k", lw=1, label="unit normal")
        spread = f"{np.std(values):.2f}" if v.size > 1 else "-"
        ax.set_title(f"{name}: n {v.size}, spread {spread}", fontsize=9)
        ax.set_xlabel("pull")
    axs[0, 0].set_ylabel("count")
    axs[0, 0].legend(fontsize=7)
    fig.suptitle(pulls.title)
    fig.tight_layout()
    return fig


def rejections_figure(rej: Rejections) -> Figure:
    """One row per reason (accepted first), a tick at each interval's UTC start."""
    reason = np.asarray(rej.reason).astype(str)
    start = np.asarray(rej.start, "datetime64[ns]")
    names = sorted(set(reason.tolist()), key=lambda r: (r != "", r))
    fig, ax = plt.subplots(figsize=(9, 0.45 * max(len(names), 1) + 1.8))
    for k, name in enumerate(names):
        sel = reason == name
        ax.plot(start[sel], np.full(int(sel.sum()), k), ls="none", marker="|", ms=12,
                color="tab:green" if name == "" else "tab:red")
    ax.set_yticks(range(len(names)))
    ax.set_yticklabels([f"{name or 'accepted'} ({int((reason == name).sum())})"
                        for name in names], fontsize=8)
    ax.set_ylim(-0.7, len(names) - 0.3)
    if start.size:
        date_axis(ax)
        if start.min() == start.max():  # one time: an hour around it, not years
            ax.set_xlim(start.min() - np.timedelta64(1, "h"), start.max() + np.timedelta64(1, "h"))
    ax.set_title(rej.title)
    fig.tight_layout()
    return fig


def draw_picture(picture: Picture, path: Path) -> Path:
    """Draw ``picture`` and save it as PNG at ``path`` (atomically)."""
    if isinstance(picture, Panel):
        fig = panel_figure(picture)
    elif isinstance(picture, Pulls):
        fig = pulls_figure(picture)
    else:
        fig = rejections_figure(picture)
    try:
        return save_png(fig, path)
    finally:
        plt.close(fig)
