"""Guards of the MESSENGER in-flight fit: a table the data do not support is refused.

A fitted table is written only when each parameter lies in its physical range and the
data determine it (`check_fit`, run by `fluxcal.missions.messenger.fit_passes.fit_days` after
every pass for tau's range and after the last pass for everything); each refusal is
one line naming the parameter, its value and stated error, the allowed range or goal
and the data (or the option) that would settle it:

* tau within `TAU_RANGE_FACTOR` of the shipped 872 s (sec. 7) and, on the final pass,
  its relative error within `TAU_ERROR_GOAL` (`tau_goal_refusal`, whose size in nT is
  `tau_goal_cost_nt`; docs/decisions/messenger_fit.md entries 9 and 43);
* an adopted heater delay dt inside `DELAY_RANGE_S` (entry 9);
* per axis, a fitted (not held) D0 of the shipped sign within `D0_RANGE_FACTOR` of it
  (Table 3; entries 9 and 15) and its relative error within `D0_ERROR_GOAL` where that
  goal binds (`d0_goal_refusal`, `d0_goal_cost_nt`, `D0_GOAL_BINDS_BELOW`; entry 38),
  else (x, y, which the figure of merit holds) within `MAX_RELATIVE_ERROR` (entries 9
  and 38); the refusal advises a hold with a width (``--hold-d0``,
  `HOLD_D0_DEFAULT_WIDTH`; entries 18 and 26);
* the break temperature T_m of each free law segment inside the temperatures of the
  data and known to `MAX_BREAK_ERROR_C` (`break_refusal`, also asked before the
  convergence refusal; Table 2, eq. 3a/3b; entries 13, 18 and 21,
  docs/decisions/messenger_fit_verification.md section 15).

The figure of merit's own refusals (the predicted error of a recalibrated day, the
compressive share) are `fluxcal.missions.messenger.fit_merit`'s.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 2-7 (tau = 872 s, eq. 6),
   Tables 2-3; sec. 8 eq. 8.
.. [2] docs/decisions/messenger_fit.md entries 9, 13, 15, 18, 21, 26, 38 and 43.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger import fit_merit
from fluxcal.missions.messenger import fit_variance as fv
from fluxcal.missions.messenger.calibration_data import MessengerCalibration, load_calibration
from fluxcal.missions.messenger.fit_merit import AXES
from fluxcal.missions.messenger.fit_reduce import usable_bins

#: `fluxcal.missions.messenger.fit.FitResult` (not imported: `fit` imports this module,
#: and tests/test_layers.py counts an import under ``TYPE_CHECKING`` as a cycle too).
FitResult = Any

__all__ = ["D0_ERROR_GOAL", "OWN_HOLD_SPLIT_MAX_SHARE", "TAU_ERROR_GOAL", "break_refusal",
           "check_fit", "d0_goal_cost_nt", "d0_goal_refusal", "tau_goal_cost_nt",
           "tau_goal_refusal"]

#: Guards (`check_fit`; docs/decisions/messenger_fit.md, entry 9): a fitted tau must lie
#: within this factor of the shipped 872 s, D0 keep the shipped sign and lie within this
#: factor of it, an adopted dt within `DELAY_RANGE_S`, the break temperature inside the
#: heater-off data and known to `MAX_BREAK_ERROR_C`; tau needs a relative standard
#: error within `TAU_ERROR_GOAL`, a fitted D0 one within `D0_ERROR_GOAL` (x, y where the
#: figure of merit holds them: below `MAX_RELATIVE_ERROR`).
TAU_RANGE_FACTOR = 2.0
D0_RANGE_FACTOR = 3.0
DELAY_RANGE_S = (0.0, 50.0)
MAX_BREAK_ERROR_C = 10.0
MAX_RELATIVE_ERROR = 0.3
#: Goal for a fitted D0 (issue 34: "D0 and tau within 5 %"): `check_fit` refuses an axis
#: whose stated relative error (1 sigma) exceeds it (docs/decisions/messenger_fit.md entry
#: 38: the 16-day Mercury orbit states 1.8-3.7 % on z, the written hard-cruise tables
#: 12-16 %; 5 % on z is 0.009-0.014 nT over the fitted days, on x or y 0.10-0.13 nT).
D0_ERROR_GOAL = 0.05
#: The D0 goal binds an axis where its 5 % costs less than this share of the figure of
#: merit's default goal (`d0_goal_cost_nt`; entry 38): z (0.009-0.014 nT) and not x, y
#: (0.094-0.13 nT), whose stated errors the figure of merit itself holds near 5 %.
D0_GOAL_BINDS_BELOW = 0.5
#: Goal for the fitted tau (issue 34: "D0 and tau within 5 %"): `check_fit` refuses a tau
#: whose stated relative error (1 sigma) exceeds it (`tau_goal_refusal`; docs/decisions/
#: messenger_fit.md entry 43: the 16-day Mercury orbit states 0.35-0.86 %, 5 % of
#: tau is 0.012-0.023 nT over the fitted days, so the figure of merit never holds it).
TAU_ERROR_GOAL = 0.05
#: Largest compressive share at which a D0 refusal advises the fit's own value where the
#: law-D0 split is stated (`d0_goal_refusal`, entry 52): the 5-%-compressive hard
#: cruise (0.26-0.33) is where its own-value tables were measured to meet their stated
#: errors; in the 7-% cruise (0.48-0.50) a fit kept the law z 3.5 of its widened band off.
OWN_HOLD_SPLIT_MAX_SHARE = 1.0 / 3.0
#: The data that constrain tau (the refusals of `check_fit` name them).
_TAU_DATA = ("more duty-cycle changes (heater regulating, steps of several %), or "
             "solar-wind intervals where the field does not mask the steps")
#: Default width of a held D0, as a fraction of the held value (``--hold-d0 z`` without
#: ``+-WIDTH``; docs/decisions/messenger_fit.md entry 18).
HOLD_D0_DEFAULT_WIDTH = 0.5
#: A day inside the shipped tables' validity, to load them as the guards' reference.
_SHIPPED_DAY = "2010-01-01"


@functools.lru_cache(maxsize=1)
def _shipped() -> MessengerCalibration:
    return load_calibration(_SHIPPED_DAY)


def check_fit(result: FitResult, reference: MessengerCalibration | None = None, *,
              final: bool = True) -> None:
    """Refuse a fit whose parameters are outside their physical range or undetermined.

    Checks, in this order (the first failure is raised): tau within
    `TAU_RANGE_FACTOR` of the reference and its relative error within
    `TAU_ERROR_GOAL` (`tau_goal_refusal`); an adopted dt inside `DELAY_RANGE_S`; per axis, D0 of the
    reference's sign, within `D0_RANGE_FACTOR` of it, relative error within
    `D0_ERROR_GOAL` (`d0_goal_refusal`; a held axis is judged by `fit_merit`); the
    break temperature T_m inside the mean temperatures of the filled heater-off bins and
    known to `MAX_BREAK_ERROR_C`.

    Parameters
    ----------
    result : FitResult
    reference : MessengerCalibration, optional
        The physical reference (default: the shipped tables, seed 000 Table 3 and
        tau = 872 s of sec. 7).
    final : bool
        False for an intermediate pass: only tau's range is checked (tau steers the next
        reduction's decay cut and look-back; the other parameters may still be on their
        way from a far-off start, entry 9).

    Raises
    ------
    FitRefusedError
        One line: the parameter, its value and error, the allowed range and the data
        that would constrain it.
    """
    ref = reference if reference is not None else _shipped()
    tau_ref = float(ref.constants["relaxation"]["tau_s"])
    r = result.relaxation
    lo, hi = tau_ref / TAU_RANGE_FACTOR, tau_ref * TAU_RANGE_FACTOR
    if not (lo <= r.tau <= hi):
        raise FitRefusedError(
            f"relaxation time (sec. 7): fitted tau = {r.tau:.0f} +- {r.tau_err:.0f} s lies "
            f"outside {lo:.0f}..{hi:.0f} s ({TAU_RANGE_FACTOR:g}x the shipped {tau_ref:.0f} s)"
            f"; not written. Needs {_TAU_DATA}")
    if not final:
        return
    cause = tau_goal_refusal(r.tau, r.tau_err, cost_nt=float(np.max(tau_goal_cost_nt(result))))
    if cause:  # the 5 % goal (entry 43)
        raise FitRefusedError(cause)
    if result.delay_fitted and not (DELAY_RANGE_S[0] <= r.dt <= DELAY_RANGE_S[1]):
        raise FitRefusedError(
            f"heater delay (sec. 7): fitted dt = {r.dt:.1f} +- {r.dt_err:.1f} s lies outside "
            f"{DELAY_RANGE_S[0]:g}..{DELAY_RANGE_S[1]:g} s (half a heater period); not "
            f"written. Needs more heater on/off transitions, or hold it (--hold-delay)")
    d0_ref = np.asarray(ref.duty_cycle_d0, dtype=float)
    compressive = (fit_merit.compressive_share(result.variance.reason)
                   if result.variance is not None else (0, 0))
    split = bool((getattr(result, "d0_field", None) or {}).get("law_d0_split"))
    rho = _own_hold_rho(result, compressive, split)
    what_d0 = "more heater-regulated samples over a wider range of duty cycles"
    cost = d0_goal_cost_nt(result)
    # NaN (no moments): the goal binds
    binds = ~(cost >= D0_GOAL_BINDS_BELOW * fit_merit.ERROR_GOAL_NT)
    for a, f, ref_j in zip(AXES, result.duty, d0_ref, strict=True):
        if a in result.held_d0:  # the user's value and width (`fit_merit` judges them)
            continue
        ratio = f.slope / ref_j if ref_j != 0 else np.inf
        if not (1.0 / D0_RANGE_FACTOR <= ratio <= D0_RANGE_FACTOR):
            raise FitRefusedError(
                f"duty-cycle law (sec. 7, Table 3): fitted D0 {a} = {f.slope:.4g} +- "
                f"{f.slope_err:.2g} counts/ppt is {ratio:.2g}x the shipped {ref_j:.4g} "
                f"(allowed: same sign, 1/{D0_RANGE_FACTOR:g}..{D0_RANGE_FACTOR:g}x); not "
                f"written. Needs {what_d0}, or hold it with a stated width "
                f"({_hold_d0_advice(a)})")
        if binds[AXES.index(a)]:  # the 5 % goal (entry 38)
            cause = d0_goal_refusal(a, f.slope, f.slope_err, cost_nt=cost[AXES.index(a)],
                                    compressive=compressive, split_stated=split,
                                    split_rho=float(rho[AXES.index(a)]))
            if cause:
                raise FitRefusedError(cause)
        elif not (np.isfinite(f.slope_err)
                  and f.slope_err <= MAX_RELATIVE_ERROR * abs(f.slope)):
            raise FitRefusedError(
                f"duty-cycle law (sec. 7, Table 3): fitted D0 {a} = {f.slope:.4g} +- "
                f"{f.slope_err:.2g} counts/ppt, a relative error above "
                f"{MAX_RELATIVE_ERROR:.0%}; not written. Needs {what_d0}, or hold it with a "
                f"stated width ({_hold_d0_advice(a)})")
    cause = break_refusal(result)
    if cause:
        raise FitRefusedError(cause)


def _own_hold_rho(result: FitResult, compressive: tuple[int, int],
                  split_stated: bool) -> np.ndarray:
    """Return per axis the ``rho`` by whose split factor an own-value hold is widened.

    `fit_variance.law_d0_correlation` over the fit's resamples (``result.bootstrap``) at
    the regulated temperature, where any judged interval was compressive and the fit
    does not state the split already (``split_stated``: its D0 error carries the factor,
    entry 52); else 0 (factor 1).  `d0_goal_refusal`, entry 60.
    """
    boot = getattr(result, "bootstrap", None) or {}
    if compressive[0] <= 0 or split_stated or "law" not in boot or "d0" not in boot:
        return np.zeros(3)
    return fv.law_d0_correlation(boot["law"], boot["d0"],
                                 result.calibration.reference_temperature_c)


def d0_goal_cost_nt(result: FitResult, goal: float = D0_ERROR_GOAL) -> np.ndarray:
    """Return the rms (nT) over the fitted samples of a D0 error of ``goal`` on each axis.

    Per sensor axis j: ``goal |D0_j| sqrt(sum R^2 / n) max_i |M_ij|``, the figure of
    merit's D0 part (`fit_merit.predicted_error`) for that error on axis j alone, on the
    output axis it reaches most (``R`` the relaxed duty cycle in ppt, eq. 5-6, over
    every used sample of the fitted days, `VarianceStatistics.offset_moments`; ``M``
    eq. 8's fine matrix).  `check_fit` holds an axis to `D0_ERROR_GOAL` where this is below
    `D0_GOAL_BINDS_BELOW` of the figure of merit's default goal (z: 0.009-0.014 nT);
    where it is above (x, y: 0.094-0.134 nT) the figure of merit's D0 part alone holds the
    stated error to ``5 % x goal / cost`` (entry 38).  NaN without the variance
    estimator's moments (the zero-mean estimator states no figure of merit: the goal
    then binds every axis).

    References
    ----------
    Seed 000 sec. 7, eq. 5-6 and Table 3; sec. 8, eq. 8.
    """
    m = np.abs(np.asarray(result.calibration.matrices[0], dtype=float))
    d0 = np.abs(np.asarray(result.calibration.duty_cycle_d0, dtype=float))
    return goal * d0 * _moment_rms(result, "RR") * m.max(axis=0)


def _moment_rms(result: FitResult, square: str) -> float:
    """Return sqrt(sum ``square`` / n) over every used sample of the fitted days.

    ``square`` names a column of `VarianceStatistics.offset_moments` (``RR``: the rms
    relaxed duty cycle, ``RtRt``: the rms of its tau derivative); NaN without the
    variance estimator's moments or samples.
    """
    v = result.variance
    if v is None:
        return np.nan
    mom = np.asarray(v.offset_moments, dtype=float)
    cols = fv.MOMENT_COLUMNS
    n = mom[:, cols.index("n")].sum()
    if not n > 0:
        return np.nan
    return float(np.sqrt(max(mom[:, cols.index(square)].sum(), 0.0) / n))


def tau_goal_cost_nt(result: FitResult, goal: float = TAU_ERROR_GOAL) -> np.ndarray:
    """Return the rms (nT) over the fitted samples of a tau error of ``goal`` per output axis.

    Per output axis i: ``goal tau sqrt(sum R_tau^2 / n) |sum_j M_ij D0_j|``, the figure of
    merit's tau part (`fit_merit.predicted_error`, whose ``dO = D0 R_tau dtau``) for a
    relative tau error of ``goal`` alone (``R_tau`` the derivative of the relaxed duty
    cycle eq. 6 with respect to tau, ppt/s, over every used sample of the fitted days,
    `VarianceStatistics.offset_moments`; ``M`` eq. 8's fine matrix).  5 % of tau is
    0.012-0.023 nT in the measured worlds (entry 43).  NaN without the variance
    estimator's moments.

    References
    ----------
    Seed 000 sec. 7, eq. 5-6 (tau) and Table 3; sec. 8, eq. 8.
    """
    m = np.asarray(result.calibration.matrices[0], dtype=float)
    md0 = np.abs(m @ np.asarray(result.calibration.duty_cycle_d0, dtype=float))
    return goal * float(result.relaxation.tau) * _moment_rms(result, "RtRt") * md0


def tau_goal_refusal(tau: float, error: float, goal: float = TAU_ERROR_GOAL,
                     cost_nt: float = np.nan) -> str:
    """Return why a fitted tau misses its goal, else ``""`` (`check_fit`; entry 43).

    A tau whose stated relative error ``error / tau`` (1 sigma) exceeds ``goal``
    (`TAU_ERROR_GOAL`, issue 34's "tau within 5 %") is not written: the data do not pin
    it to the goal.  The message names tau, its error in s and %, the goal (and its size
    in nT when known), and what to do: more duty-cycle changes, intervals where the field
    does not mask the steps, or more days, with the factor ``(error / tau / goal)^2`` of
    days at which the error would reach the goal if it falls as 1/sqrt(days) (measured in
    the Mercury orbit: that or faster; in the hard cruise wind, 5 % compressive, slower:
    3.6-10.8 % at 4 days, 4.1-6.5 % at 8, 1.8-4.7 % at 16).  No option is advised: tau
    cannot be held, and the figure of merit's ``--error-goal`` does not judge it.

    Parameters
    ----------
    tau, error : float
        The fitted relaxation time and its stated error (s, seed 000 sec. 7).
    goal : float
        Largest relative error written.
    cost_nt : float
        `tau_goal_cost_nt` on its largest axis (stated in the message when finite).

    References
    ----------
    Seed 000 sec. 7 (tau = 872 s, eq. 6); issue 34, "Done when".
    """
    beyond = _beyond_goal(tau, error, goal, cost_nt)
    if beyond is None:
        return ""
    rel, size = beyond
    more = (f" (in a calm wind the error falls about as 1/sqrt(days) or faster: about "
            f"{(rel / goal) ** 2:.1f}x the days fitted; in a compressive one it falls slower)"
            if np.isfinite(rel) else "")
    return (f"relaxation time (sec. 7): fitted tau = {tau:.0f} +- {error:.0f} s, a relative "
            f"error above the {goal:.0%} goal ({rel:.1%}{size}; entry 43); not "
            f"written. Needs {_TAU_DATA}, or more days{more}")


def d0_goal_refusal(axis: str, value: float, error: float,
                    goal: float = D0_ERROR_GOAL, cost_nt: float = np.nan,
                    compressive: tuple[int, int] = (0, 0), split_stated: bool = False,
                    split_rho: float = 0.0) -> str:
    """Return why a fitted D0 misses its goal, else ``""`` (`check_fit`; entry 38).

    A fitted D0 whose stated relative error ``error / |value|`` (1 sigma) exceeds ``goal``
    (`D0_ERROR_GOAL`, issue 34's "D0 within 5 %") is not written: the data do not pin
    it to the goal.  The message names the axis, the stated error and the goal, and
    what to do: more data, or hold the axis with a stated width (``--hold-d0``), either
    this fit's own value and error (the table then states the axis held, beyond the
    goal; the predicted-error guard judges its width) or the start table's value.  This
    fit's own value is not advised where more than
    `fit_merit.ADVICE_MAX_COMPRESSIVE_SHARE` of the judged intervals were compressive
    (entry 49): there the fitted D0 and law are each less determined along the field than
    stated (only their sum is, entry 48), and a table holding the fit's own D0 at its
    stated width missed it by 2.8 widths; where the fit states that split
    (``split_stated``: `fit_variance.widen_law_d0_split` widened its D0 and law, entry
    52) up to `OWN_HOLD_SPLIT_MAX_SHARE` compressive, where its own-value tables met
    their stated errors (the same 8 days: 2.15 widths), it is advised again.  Below that
    share, in a wind with any compressive interval, the fit states no split, and its own
    D0 is biased along the law-D0 trade-off by the compressive part (seed 4311, 4-day
    hard cruise at 24.2 %: the held table 3.24 widths off): the advised width is the
    stated error times entry 52's factor for D0, ``sqrt(1 + (lambda rho)^2)``
    (`fit_variance.split_widening_factor`, ``rho`` = ``split_rho``; entry 60).

    Parameters
    ----------
    axis : str
        ``x``, ``y`` or ``z``.
    value, error : float
        The fitted D0 and its stated error (counts/ppt, seed 000 Table 3).
    goal : float
        Largest relative error written.
    cost_nt : float
        `d0_goal_cost_nt` of the axis (stated in the message when finite).
    compressive : tuple of int
        ``(compressive, judged)`` interval counts (`fit_merit.compressive_share`).
    split_stated : bool
        The fit's D0 and law carry the split's widening (``FitResult.d0_field``'s
        ``law_d0_split``).
    split_rho : float
        The correlation over the fit's resamples of this axis's D0 with the law at the
        regulated temperature (`fit_variance.law_d0_correlation`; 0 where the split is
        stated or no interval was compressive: `check_fit`).

    References
    ----------
    Seed 000 sec. 7, eq. 5 and Table 3 (D0); issue 34, "Done when".
    """
    beyond = _beyond_goal(value, error, goal, cost_nt)
    if beyond is None:
        return ""
    rel, size = beyond
    # this fit's own value as a hold only with an error to hold it with, and not in a
    # compressive wind (entry 49)
    n_comp, judged = compressive
    limit = (OWN_HOLD_SPLIT_MAX_SHARE if split_stated
             else fit_merit.ADVICE_MAX_COMPRESSIVE_SHARE)
    if fit_merit.compressive_wind(n_comp, judged) and n_comp > limit * judged:
        own = (f"(not this fit's own value: {n_comp} of {judged} intervals compressive, "
               f"above {limit:.0%}, where its stated error does not cover D0 along the "
               f"field; entries 49, 52) ")
    elif np.isfinite(error) and value != 0:
        factor = float(fv.split_widening_factor(split_rho))
        widened = (f" widened {factor:.2f}x along the law-D0 split the {n_comp} compressive "
                   f"intervals leave (rho {split_rho:+.2f}; entries 52, 60)"
                   if factor > 1.0 else "")
        own = (f"--hold-d0 {axis}={value:.4g}+-{_up_to_two_digits(error * factor):.2g} "
               f"(this fit's value and error{widened}, rounded up: the table states D0 "
               f"{axis} held, beyond the goal), or ")
    else:
        own = ""
    return (f"duty-cycle law (sec. 7, Table 3): fitted D0 {axis} = {value:.4g} +- "
            f"{error:.2g} counts/ppt, a relative error above the {goal:.0%} goal "
            f"({rel:.1%}{size}; entry 38); not written. Needs more heater-regulated "
            f"samples over a wider range of duty cycles (more days: the error falls about "
            f"as 1/sqrt(days)), or hold it with a stated width: {own}"
            f"{_hold_d0_advice(axis)}")


def _beyond_goal(value: float, error: float, goal: float,
                 cost_nt: float) -> tuple[float, str] | None:
    """Return ``(|error / value|, the goal's size in nT as text)`` beyond ``goal``, else None.

    Beyond: the stated error exceeds ``goal`` of ``|value|``, is not finite, or ``value``
    is 0 (`d0_goal_refusal`, `tau_goal_refusal`).
    """
    rel = abs(error / value) if value != 0 else np.inf
    if np.isfinite(error) and rel <= goal:
        return None
    return rel, (f", the goal {cost_nt:.3f} nT rms over the fitted days"
                 if np.isfinite(cost_nt) else "")


def _up_to_two_digits(x: float) -> float:
    """``x`` rounded up to two significant digits (an advised width never narrower)."""
    if not (np.isfinite(x) and x > 0):
        return x
    step = 10.0 ** (np.floor(np.log10(x)) - 1)
    return float(np.ceil(round(x / step, 9)) * step)


def _hold_d0_advice(axis: str) -> str:
    """Return the ``--hold-d0`` a D0 refusal advises, to type as it is (entry 26)."""
    return (f"--hold-d0 {axis}: the start table's D0, its width "
            f"{HOLD_D0_DEFAULT_WIDTH:.0%} of the value, entry 18; or {axis}=VALUE+-WIDTH "
            "from a better source")


def break_refusal(result: FitResult, *, error: bool = True) -> str:
    """Return why a break temperature is not determined by the data, else ``""``.

    The break T_m of an axis outside the temperatures of the data (the variance
    estimator's accepted intervals, 5-C bins with an interval's worth of samples; else
    the filled heater-off bins), or (``error``) known worse than `MAX_BREAK_ERROR_C`
    (`check_fit`).  The first is asked before the convergence refusal too: a law whose
    upper line no data reach does not settle, and the cause is the missing temperatures,
    not the passes (issue 34's Mercury orbit, docs/decisions/messenger_fit_verification.md
    section 15).
    """
    t = result.stats.temperature
    ok = usable_bins(t)
    # the variance estimator's data: 5-C bins holding an interval's worth of accepted
    # samples (the law is stated over the narrower `fitted_range`; a break just beyond it
    # can still be determined to a fraction of a degree, entry 13)
    span = (result.variance.fitted_range(fv.VarianceSettings().min_samples)
            if result.variance is not None else (np.nan, np.nan))
    if np.all(np.isfinite(span)):
        t_lo, t_hi = span
        data = "temperatures of the accepted intervals"
        what_t = ("solar-wind intervals at sensor temperatures on both sides of the break "
                  "(heater-off runs)")
    elif ok.any():
        t_mean = t.mean()[ok, 3]
        t_lo, t_hi = float(np.nanmin(t_mean)), float(np.nanmax(t_mean))
        data = "heater-off data"
        what_t = "heater-off samples over a wider temperature range around the break"
    if (np.all(np.isfinite(span)) or ok.any()) and result.temperature:
        for a, f in zip(AXES, result.temperature, strict=True):
            if a in result.held_upper:  # held with its width (`held_upper_segments`)
                continue
            if not (t_lo <= f.x_m <= t_hi):
                return (f"temperature law (sec. 7, Table 2): fitted break T_m {a} = "
                        f"{f.x_m:.1f} +- {f.x_m_err:.2g} C lies outside the {data} "
                        f"({t_lo:.1f}..{t_hi:.1f} C); not written. Needs {what_t}")
            if error and not (np.isfinite(f.x_m_err) and f.x_m_err <= MAX_BREAK_ERROR_C):
                return (f"temperature law (sec. 7, Table 2): fitted break T_m {a} = "
                        f"{f.x_m:.1f} +- {f.x_m_err:.2g} C, an error above "
                        f"{MAX_BREAK_ERROR_C:g} C; not written. Needs {what_t}")
    return ""
