"""The pictures of a ``rosetta fit`` (`fluxcal.products.fit_pictures`) from its fits.

* each daily extended-temperature model (`DailyModelFit`): the fitted offset curve
  ``P(T~)`` of sec. 4.2.3.3 per axis against the reduced temperature, with its 1-sigma
  band from the fit covariance (`DailyModelFit.offset_sigma`) and the temperature range
  of the day's data shaded (outside it the curve is not determined);
* the Appendix B offset jumps (`OffsetJumpFit`): each interval's fitted offset with
  its standard error at the interval's UTC start.

The Rosetta fits keep neither per-interval offsets nor the rejected intervals' times
(only their counts by reason, in the daily file's header), so no pulls or time line
are drawn for them.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3, Appendix B.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fluxcal.missions.rosetta.fit import DailyModelFit, OffsetJumpFit
from fluxcal.products.fit_pictures import Curve, Panel, Picture, Points
from fluxcal.products.fit_report import write_fit_report

log = logging.getLogger(__name__)

AXES = ("x", "y", "z")
#: Points on the drawn curve.
N_CURVE = 201
#: The curve is drawn this fraction of the data's temperature range beyond each end.
MARGIN = 0.15


def daily_panel(fit: DailyModelFit) -> Panel:
    """Return the offset curve of one day with its band, the data's temperature range shaded."""
    lo, hi = (float(v) for v in fit.temperature_range)
    pad = max(MARGIN * (hi - lo), 1.0)
    grid = np.linspace(lo - pad, hi + pad, N_CURVE)
    day = str(np.datetime64(fit.day, "D"))
    return Panel(f"fit_{day}_{fit.sensor}", f"{fit.sensor} {day}: offset curve (sec. 4.2.3.3)",
                 "reduced temperature T~ (C)", "offset (nT)", AXES,
                 f"{fit.sensor} {day}: the fitted offset polynomial P(T~) of degree "
                 f"{fit.degree} ({fit.estimator} estimator) with its 1-sigma band from the fit "
                 "covariance; shaded: the temperatures of the day's data, where the curve is "
                 "determined", None,
                 Curve(grid, fit.offset(grid), fit.offset_sigma(grid), "fitted curve"),
                 (lo, hi))


def jump_panel(fit: OffsetJumpFit) -> Panel:
    """Return the Appendix B offsets of each interval at its UTC start, with their errors."""
    start = np.asarray(fit.start_utc).astype("datetime64[s]")
    return Panel(f"fit_jumps_{fit.sensor}", f"{fit.sensor}: offsets per interval (Appendix B)",
                 "interval start (UTC)", "offset (nT)", AXES,
                 f"{fit.sensor}: the fitted offset of each interval in s/c coordinates with its "
                 f"standard error ({fit.estimator} estimator), at the interval's start",
                 Points(start, np.asarray(fit.jumps, float), np.asarray(fit.sigma, float),
                        "interval offsets"))


def pictures(fits: Sequence[DailyModelFit | OffsetJumpFit]) -> list[Picture]:
    """Return one picture per fit, in order."""
    return [daily_panel(f) if isinstance(f, DailyModelFit) else jump_panel(f) for f in fits]


def write_fit_pictures(fits: Sequence[DailyModelFit | OffsetJumpFit], out: Path
                       ) -> list[Path]:
    """Draw the pictures of ``fits`` into ``out``, write its ``index.html``, return them.

    Without matplotlib: the index only, and one warning line that the pictures need
    ``fluxcal[plot]``.
    """
    written, note = write_fit_report(out, pictures(fits), f"fluxcal rosetta fit: "
                                     f"{Path(out).name}")
    if note:
        log.warning("%s", note)
    return written
