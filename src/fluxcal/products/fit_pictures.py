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

`fluxcal.products.fit_plots` draws them (matplotlib, the ``plot`` extra);
`fluxcal.products.fit_report.write_fit_report` writes them and the fit folder's
``index.html``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    law (outside it the curve is drawn but not constrained), one ``(lo, hi)`` or
    several intervals (`fluxcal.calibration.stated_ranges.StatedRanges.intervals`).
    ``name`` is the PNG stem.
    """

    name: str
    title: str
    xlabel: str
    ylabel: str
    axes: tuple[str, ...]
    caption: str
    points: Points | None = None
    curve: Curve | None = None
    fitted_range: tuple[float, float] | tuple[tuple[float, float], ...] | None = None


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
