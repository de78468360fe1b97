"""What the MESSENGER in-flight fit holds with a stated width where the data do not decide.

Two parts of the tables can be held instead of fitted, each with a width that the
variance estimator's resamples draw from (so the stated errors and the figure of merit
count it):

* D0 of an axis, at the user's request (``--hold-d0``, `held_d0_values`): the start
  table's value or the user's, with the user's width or `fit_guards.HOLD_D0_DEFAULT_WIDTH`
  of the value (Table 3; docs/decisions/messenger_fit.md entries 15 and 18);
* the upper segment of an axis's temperature law (above its break T_m, eq. 3b) that no
  accepted interval determines (`held_upper_segments`): too few 5-C bins above the break
  hold accepted samples (`UPPER_SEGMENT_MIN_BINS`), or the fit's own bootstrap leaves its
  break or the sign of its slope change undetermined (`undetermined_upper`); its break
  and slope change are held at the start table's values with the widths
  `HOLD_BREAK_WIDTH_C` and `HOLD_SLOPE_CHANGE_WIDTH`, the upper line following the
  fitted lower one (eq. 4; entries 21 and 35).

`fluxcal.missions.messenger.fit.fit_variance_calibration` applies them; the guards
(`fluxcal.missions.messenger.fit_guards`) skip what is held and advise a hold where a
fitted D0 misses its goal.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3a, 3b, 4 and 5, Tables 2-3.
.. [2] docs/decisions/messenger_fit.md entries 15, 18, 21 and 35.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from fluxcal.errors import FluxcalError
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.fit_guards import HOLD_D0_DEFAULT_WIDTH, MAX_BREAK_ERROR_C
from fluxcal.missions.messenger.fit_merit import AXES
from fluxcal.missions.messenger.fit_variance import VarianceStatistics

__all__ = ["HOLD_BREAK_WIDTH_C", "HOLD_SLOPE_CHANGE_WIDTH", "HoldD0", "held_d0_values",
           "held_upper_segments", "undetermined_upper"]

#: The upper segment of an axis's law (above its break T_m, eq. 3b) counts as determined
#: when at least this many 5-C bins wholly above the break hold an interval's worth of
#: accepted samples (`VarianceSettings.min_samples`): the line is then seen over 10 C
#: (docs/decisions/messenger_fit.md entry 21); otherwise `held_upper_segments`.
UPPER_SEGMENT_MIN_BINS = 2
#: Widths (1 sigma) of a held upper segment: its slope change ``c = B1 - B0`` (fraction
#: of the held value) and its break T_m (C).  The simulated worlds' true tables change c
#: by -40 / +79 / +54 % from the seed's Table 2 and move the breaks by 4-6 C; at +30 C
#: the x truth lies 1.05 sigma from the held law with 100 %, 2.1 with 50 % (entry 21).
HOLD_SLOPE_CHANGE_WIDTH = 1.0
HOLD_BREAK_WIDTH_C = 5.0
#: Held D0: axes (base value, default width) or ``axis -> (value or None, width or None)``.
HoldD0 = tuple[str, ...] | Mapping[str, tuple[float | None, float | None]]


def held_d0_values(hold_d0: HoldD0, base: MessengerCalibration
                   ) -> dict[str, tuple[float, float]]:
    """``{axis: (value, width)}`` of the held D0 (``--hold-d0``; entry 18).

    ``hold_d0`` is a tuple of axes (the base value, the default width) or a mapping
    ``axis -> (value or None, width or None)``; a missing value is the base's, a missing
    width `HOLD_D0_DEFAULT_WIDTH` times the held value.

    Raises
    ------
    FluxcalError
        An axis other than x, y, z, a value or width that is not finite, or a negative
        width.
    """
    spec = dict(hold_d0) if isinstance(hold_d0, Mapping) else {a: (None, None) for a in hold_d0}
    if set(spec) - set(AXES):
        raise FluxcalError(f"--hold-d0 takes axes x, y, z, got {', '.join(spec)}")
    d0 = np.asarray(base.duty_cycle_d0, dtype=float)
    out = {}
    for a in AXES:
        if a not in spec:
            continue
        value, width = spec[a]
        value = float(d0[AXES.index(a)]) if value is None else float(value)
        width = HOLD_D0_DEFAULT_WIDTH * abs(value) if width is None else float(width)
        if not (np.isfinite(value) and np.isfinite(width) and width >= 0.0):
            raise FluxcalError(f"--hold-d0 {a}: the value and width must be finite and the "
                               f"width not negative, got {value} +- {width}")
        out[a] = (value, width)
    return out


def held_upper_segments(vstats: VarianceStatistics, start: MessengerCalibration,
                        force: Sequence[str] = ()
                        ) -> dict[str, dict[str, tuple[float, float]]]:
    """Upper segments (eq. 3b) that no accepted interval determines, held (entry 21).

    An axis's segment above its break T_m (of ``start``, the table the fit started
    from) is undetermined when fewer than `UPPER_SEGMENT_MIN_BINS` 5-C bins wholly
    above the break hold `VarianceSettings.min_samples` accepted samples (issue 34's
    Mercury orbit: the warm end seen only near periapsis, in intervals rejected as
    compressive), or when it is in ``force`` (`fit_variance_calibration`: the fit's
    own bootstrap left its break undetermined, an error above `MAX_BREAK_ERROR_C`, or
    its slope change's sign, an error above ``|c|``; `undetermined_upper`).
    Its break and its slope change ``c = B1 - B0`` are then held at
    ``start``'s values with the widths `HOLD_BREAK_WIDTH_C` and
    `HOLD_SLOPE_CHANGE_WIDTH` x ``|c|``; the upper line follows the fitted lower one
    (eq. 4).

    Returns
    -------
    dict
        ``axis -> {"Tm_c": (value, width), "slope_change": (value, width)}``.
    """
    law = fv.law_parameters(start)
    edges = fv.TEMPERATURE_EDGES_C
    seen = vstats.temperature_count >= fv.VarianceSettings().min_samples
    out = {}
    for j, a in enumerate(AXES):
        above = int(np.count_nonzero(seen & (edges[:-1] >= law[j, 3])))
        if above < UPPER_SEGMENT_MIN_BINS or a in force:
            out[a] = {"Tm_c": (float(law[j, 3]), HOLD_BREAK_WIDTH_C),
                      "slope_change": (float(law[j, 2]),
                                       HOLD_SLOPE_CHANGE_WIDTH * abs(float(law[j, 2])))}
    return out


def undetermined_upper(law: np.ndarray, b_law: np.ndarray, widening: float) -> np.ndarray:
    """Axes whose free upper segment (eq. 3b) the fit's own bootstrap leaves undetermined.

    An axis's upper segment is undetermined when its break's stated error (the
    resamples' spread times ``widening``, as stated) exceeds `MAX_BREAK_ERROR_C`
    (entry 21), or when its slope change ``c = B1 - B0``'s stated error exceeds
    ``|c|``: the data do not determine even the sign of the change (issue 34's 16-day
    Mercury orbit, seed 3507: x's B1 = -239 +- 683 counts/C against 3.3 true, 100-700
    nT off above T_m; docs/decisions/messenger_fit.md entry 35).  Either is then
    held by `held_upper_segments` (its ``force``), the fit solved again.

    Parameters
    ----------
    law : ndarray, shape (3, 4)
        The fitted ``(a, b, c, T_m)`` per axis (`fit_variance.law_parameters` form).
    b_law : ndarray, shape (n, 3, 4)
        The bootstrap's resamples of ``law`` (unwidened).
    widening : float
        The bootstrap's finite-sample widening (`fit_variance.VarianceSolution`).

    Returns
    -------
    ndarray of bool, shape (3,)

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3a, 3b, 4.
    """
    spread = widening * np.std(np.asarray(b_law, dtype=float), axis=0)
    c = np.abs(np.asarray(law, dtype=float)[:, 2])
    return ~(spread[:, 3] <= MAX_BREAK_ERROR_C) | ~(spread[:, 2] <= c)
