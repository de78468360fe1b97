"""Offset-smoothness report of a calibrated day: text summary and figure (sec. 13).

The text is always written; the figure (PNG) when the run's formats include
`REPORT_FIGURE`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13 "Validation".
"""

from __future__ import annotations

import datetime as _dt
import io
from functools import partial
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.extras import require
from fluxcal.geometry.time import et_to_utc
from fluxcal.missions.messenger.defects import span_records
from fluxcal.missions.messenger.levels import offset_step_report
from fluxcal.products.declared import File


def load_figure_support() -> None:
    """Import matplotlib's figure module; for a run to call before it makes any data.

    Importing matplotlib raises and catches pyparsing errors whose tracebacks keep
    every calling frame alive in reference cycles; imported from inside `report_figure`,
    those frames would hold the day's whole Dataset until a full collection of the
    garbage collector (212 MB at 20 Hz).  A run that writes the figure therefore
    imports it first (`fluxcal.missions.messenger.run.prepare_formats`); `report_figure`
    imports it itself when nobody did.  Without the ``plot`` extra it raises
    `~fluxcal.errors.MissingExtraError` (one line, exit 2, nothing read or written).
    """
    require("plot", "--formats png (the offset report figure)")
    import fluxcal.products.quicklook  # noqa: F401 - matplotlib, behind the plot extra's guard


def report_text(ds: xr.Dataset, threshold_counts: float | None,
                report: dict | None = None) -> str:
    """Return the step report as text: largest step per axis, where, and the threshold.

    ``report`` is `offset_step_report` of ``ds`` when the caller has it already (e.g.
    from `levels.validate_offsets`); it is computed otherwise.  A day with defect spans
    (`fluxcal.missions.messenger.defects`, issue 23) gets a second table, one line per
    span: ``cause,flag,action,stream,start_utc,end_utc,seconds,samples``
    (`read_defect_spans` reads it back).
    """
    rep = offset_step_report(ds) if report is None else report
    lines = ["# MESSENGER MAG offset smoothness (MESSENGER MAG EDR-to-CDR Processing, sec. 13)",
             f"# threshold_counts: {threshold_counts}", "axis,largest_step_counts,utc"]
    for axis, item in rep.items():
        utc = et_to_utc(np.array([item["et"]]))[0]
        lines.append(f"{axis},{item['step_counts']:.6f},{utc}")
    spans = span_records(ds)
    if spans:
        lines += [DEFECT_HEADER, ",".join(DEFECT_COLUMNS)]
        lines += [",".join(str(s[k]) for k in DEFECT_COLUMNS) for s in spans]
    return "\n".join(lines) + "\n"


#: The report's defect table: its title line and columns.
DEFECT_HEADER = "# defect spans (issue 23; docs/formats/messenger.md, \"Defect flag\")"
DEFECT_COLUMNS = ("cause", "flag", "action", "stream", "start", "end", "seconds", "samples")


def read_defect_spans(path: Path) -> list[dict]:
    """Return the defect spans a day report (`report_text`) lists ([] when none).

    Each span: ``cause``, ``flag`` (int), ``action``, ``stream``, ``start``/``end``
    (UTC), ``seconds`` (float), ``samples`` (int).
    """
    lines = Path(path).read_text().splitlines()
    if DEFECT_HEADER not in lines:
        return []
    rows = lines[lines.index(DEFECT_HEADER) + 2:]
    out = []
    for row in rows:
        if not row.strip():
            continue
        span: dict = dict(zip(DEFECT_COLUMNS, row.split(","), strict=True))
        span["flag"], span["samples"] = int(span["flag"]), int(span["samples"])
        span["seconds"] = float(span["seconds"])
        out.append(span)
    return out


def report_files(ds: xr.Dataset, name: str, threshold_counts: float | None,
                 report: dict | None = None, day: _dt.date | None = None, *,
                 figure: bool = True) -> list[File]:
    """Declare ``name.txt`` (`report_text`) and, with ``figure``, ``name.png`` (`report_figure`).

    ``report``: the day's `offset_step_report`, when already computed (`report_text`);
    the figure is drawn when written (`fluxcal.products.declared.write_declared`).
    """
    files = [File(f"{name}.txt", report_text(ds, threshold_counts, report), day)]
    if figure:
        files.append(File(f"{name}.png", partial(_save_figure, ds), day))
    return files


def _save_figure(ds: xr.Dataset, path: Path) -> None:
    """Write `report_figure` at ``path`` (the declared file's temporary)."""
    Path(path).write_bytes(report_figure(ds))


def report_figure(ds: xr.Dataset) -> bytes:
    """Return the PNG of the applied offsets versus time (fine-range counts, per axis)."""
    # the plot extra's module, imported only when a figure is asked for
    from fluxcal.products.quicklook import Figure, date_axis, plot_times

    times = plot_times(ds["epoch"].values)  # UTC date ticks (issue 25 item 6)
    fig = Figure(figsize=(8, 6))
    axes = fig.subplots(3, 1, sharex=True)
    step = max(1, times.size // 20000)
    for j, axis in enumerate("xyz"):
        axes[j].plot(times[::step], ds["offset"].values[::step, j], lw=0.8)
        axes[j].set_ylabel(f"offset {axis} (counts)")
    date_axis(axes[-1])
    fig.suptitle("Applied thermal offsets (fine-range counts)")
    png = io.BytesIO()
    fig.savefig(png, dpi=80, format="png")
    return png.getvalue()
