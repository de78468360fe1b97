"""Pictures of a calibration fit and its ``index.html``: what a scientist looks at first.

A fit (offsets of a fluxgate against temperature, duty cycle, time) is described here as
plain arrays, independent of the instrument; a mission's adapter builds them from its
fit result.  Four kinds of picture (issue 34, item 6):

* `Panel`: measured values with their errors against a variable (temperature, duty
  cycle, lag), one subplot per axis, with the fitted law (sampled) and its 1-sigma band
  where given, and the range over which the data determine the law shaded;
* `Pulls`: the residuals of the measured values about the law divided by their errors,
  as histograms beside the unit normal (spread ~1 when the errors are honest);
* `Rejections`: the intervals the fit did not use, by reason, on a UTC time line.

`write_fit_report` draws them (matplotlib, the ``plot`` extra: `fluxcal.products.fit_plots`)
into the fit's output folder and writes that folder's ``index.html`` with the run-report
machinery of the calibration runs (`fluxcal.products.html_report.write_run_report`):
pictures with a caption saying what each shows, the text reports, every file of the
folder linked relatively (those already in place and those the run still stages).
Without matplotlib the index is written without pictures and the returned note says,
in one line, that they need ``fluxcal[plot]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fluxcal.extras import available
from fluxcal.products.atomic import ungrouped
from fluxcal.products.html_report import run_products, write_run_report

#: The one line a fit prints when matplotlib is missing.
NO_PLOT_NOTE = "fit pictures need matplotlib: install fluxcal[plot] (the index lists the tables)"


@dataclass(frozen=True)
class Points:
    """Measured values with their standard errors: ``x`` (n,), ``y`` and ``err`` (n, n_axes).

    ``model`` (n, n_axes) is what the fit expects each value to be, when that is not the
    law at ``x`` (a bin mean modelled as the law averaged over the bin's samples); the
    residuals drawn are ``y - model`` (default: the law interpolated at ``x``).
    """

    x: np.ndarray
    y: np.ndarray
    err: np.ndarray | None = None
    label: str = "measured"
    model: np.ndarray | None = None


@dataclass(frozen=True)
class Curve:
    """A fitted law sampled at ``x`` (m,): ``y`` (m, n_axes), 1-sigma ``band`` or None."""

    x: np.ndarray
    y: np.ndarray
    band: np.ndarray | None = None
    label: str = "fitted law"


@dataclass(frozen=True)
class Panel:
    """One picture: a subplot per axis of ``points`` and ``curve`` against ``xlabel``.

    ``fitted_range`` (x units) is shaded: the range over which the data determine the
    law (outside it the curve is drawn but not constrained).  ``name`` is the PNG stem.
    """

    name: str
    title: str
    xlabel: str
    ylabel: str
    axes: tuple[str, ...]
    caption: str
    points: Points | None = None
    curve: Curve | None = None
    fitted_range: tuple[float, float] | None = None


@dataclass(frozen=True)
class Pulls:
    """Pulls ``(measured - law) / error`` per named group (e.g. ``"temperature x"``)."""

    name: str
    title: str
    caption: str
    values: dict[str, np.ndarray]


@dataclass(frozen=True)
class Rejections:
    """Intervals of the fit on a UTC time line: ``start`` (datetime64), ``reason``.

    ``reason`` is ``""`` for an accepted interval (drawn on its own row), else why it
    was left out.
    """

    name: str
    title: str
    caption: str
    start: np.ndarray
    reason: np.ndarray


Picture = Panel | Pulls | Rejections


def pull_values(points: Points, law: np.ndarray) -> np.ndarray:
    """Return ``(points.y - law) / points.err`` where both are finite and ``err > 0``.

    ``law`` is the law at ``points.x``, shape of ``points.y``; the result is flat (the
    finite pulls of every axis in order).
    """
    if points.err is None:
        return np.zeros(0)
    y, err = np.asarray(points.y, float), np.asarray(points.err, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        pulls = (y - np.asarray(law, float)) / err
    return pulls[np.isfinite(pulls) & (err > 0)]


def write_fit_report(out: Path, pictures: Sequence[Picture], title: str
                     ) -> tuple[list[Path], str]:
    """Draw ``pictures`` into ``out`` (PNG) and write ``out/index.html``.

    Parameters
    ----------
    out : Path
        The fit's output folder (its tables already written).
    pictures : sequence of Panel, Pulls, Rejections
        What to draw, in page order.
    title : str
        Page title.

    Returns
    -------
    list of Path
        The pictures and the index written.
    str
        `NO_PLOT_NOTE` when matplotlib is missing (no picture drawn), else ``""``.
    """
    out = Path(out)
    written: list[Path] = []
    note = ""
    if available("plot"):
        from fluxcal.products.fit_plots import draw_picture  # the plot extra

        written = [draw_picture(p, out / f"{p.name}.png") for p in pictures]
    else:
        note = NO_PLOT_NOTE
    captions = {f"{p.name}.png": p.caption for p in pictures}
    with ungrouped():  # what is in the folder already (tables some fits rename at once)
        files = {f.rel: f for f in run_products(out)}
    files.update({f.rel: f for f in run_products(out)})  # and what the run stages
    index = write_run_report(out, title, [files[k] for k in sorted(files)],
                             captions=captions, no_figures=note or "This fit drew no picture.")
    return written + ([index] if index is not None else []), note
