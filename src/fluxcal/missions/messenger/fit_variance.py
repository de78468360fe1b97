"""MESSENGER in-flight fit by variance minimisation of ``|B|`` (issue 21, estimator ``variance``).

The seed's estimators (sec. 7; `fluxcal.missions.messenger.fit`) take the offset as a
long-term average of the measured counts: they assume the field averages to zero over
each bin's samples.  A real solar wind does not (sectors, hour-long rotations): each bin
mean carries the field's own mean, tens of counts after days.  This estimator assumes
instead that the field's *magnitude* is nearly constant within short intervals while its
direction rotates (Alfvenic fluctuations, Davis and Smith 1968), and fits the *laws* of
the offset through that condition:

* the offset of every sample is the current model (Table 2 two-segment law of the
  sensor temperature, eq. 3-4; the duty-cycle offset ``D0 x relaxed duty cycle``, eq.
  5-6; the heater waveform, sec. 6) plus a correction linear in the parameters:
  per axis ``da + db T + dc max(0, T - T_m) - c dT_m [T > T_m] + dD0 R`` and, shared by
  the axes, ``D0 (dR/dtau dtau + dR/ddt ddt)`` (``R``: relaxed duty cycle, ppt);
* the corrected field ``B' = M (counts - offset)`` (eq. 8, nT) is split into intervals
  of ``interval_s``, selected as a whole, and each interval into segments of
  ``segment_s``; in each segment, ``|B' - M dO(t)| = const`` linearised is
  ``|B'| - u . M dO(t) = c_k`` (``u`` the unit vector of ``B'``): least squares over all
  samples of the accepted intervals, each segment's mean and trend removed (the
  Davis-Smith system with the offset parametrised by the seed's laws; the temperature
  moving inside an interval is in ``dO(t)``).  Short segments drop the slow compressive
  changes of ``|B|`` and keep the fast rotations (docs/decisions/messenger_fit.md
  entry 17);
* the break of each axis's law is also tried at `BREAK_SHIFTS_C` from the current
  one (one hinge column each; `solve_variance` keeps the shift of least residual):
  the linearised break step alone moves a distant break a fraction of the way per
  pass (entry 17); the columns' layout, the break choice and the bootstrap's resamples
  are `fluxcal.missions.messenger.fit_breaks`'s;
* intervals are accepted by the named criteria of `fluxcal.calibration.variance_offsets`
  (too_few_samples, ill_conditioned, small_fluctuations, compressive), evaluated on
  ``B'``; each rejected interval is kept with its reason;
* the normal equations are summed per bootstrap block (``block_s``) so that days merge
  exactly (map-reduce) and the errors come from a bootstrap over blocks;
* `fluxcal.missions.messenger.fit_passes.fit_days` repeats reduce-and-solve (Gauss-Newton):
  each pass re-linearises about the previous pass's tables.

The heater waveforms keep the phase-binned estimator of sec. 6 (it needs the field to
be uncorrelated with the heater phase, not zero-mean: a bin's mean level is removed).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 2-7, sec. 8 eq. 8.
.. [2] Davis, L. Jr. and Smith, E. J., EOS Trans. AGU 49, 257 (1968); Leinweber, H. K.
   et al., Meas. Sci. Technol. 19, 055104 (2008) (selection of pure rotations).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import reduce

import numpy as np
import xarray as xr

from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.relaxation import relaxed_offset, steady_state_offset
from fluxcal.calibration.segment_trends import (
    remove_segment_lines,
    segment_codes,
    segment_variance,
)
from fluxcal.calibration.solar_wind_offsets import (
    count_reasons,
)
from fluxcal.calibration.variance_offsets import (
    DEFAULT_MAX_COMPRESSIBILITY,
    DEFAULT_MIN_EIGENVALUE_RATIO,
    DEFAULT_MIN_RELATIVE_AMPLITUDE,
    interval_reasons,
)
from fluxcal.errors import FluxcalError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.fit_breaks import (
    BREAK_SHIFTS_C,
    N_PARAMETERS,
    PER_AXIS,
    break_layout,
    choice_shifts_c,
    choose_breaks,
    fit_columns,
    fixed_design_resamples,
    quantisation,
    refine_breaks,
    resample_fits,
    residual_sum,
    shift_column,
    solution_distance,
    wild_resamples,
    wild_weights,
)
from fluxcal.missions.messenger.fit_reduce import TAU_STEP, inside_intervals

__all__ = ["MIN_RANGE_SAMPLES", "MOMENT_COLUMNS", "MOMENT_EDGES_C", "TEMPERATURE_EDGES_C",
           "VarianceSettings", "VarianceStatistics", "apply_step", "apply_steps",
           "LAW_D0_SPLIT_WIDENING", "d0_field_balance", "law_values", "offset_moments",
           "reduce_variance", "resampling_units", "solve_variance", "widen_d0_along_field",
           "widen_law_d0_split", "law_d0_correlation", "split_widening_factor"]

#: Step of dt (s) for the derivative of the relaxed duty cycle in dt.
DELAY_STEP_S = 1.0
#: Edges (C) of the histogram of the accepted samples' temperatures (`fitted_range`).
TEMPERATURE_EDGES_C = np.arange(-100.0, 100.1, 5.0)
#: Edges (C) of the 1-C bins of every used sample's temperature, relaxed duty cycle and
#: its derivatives (`VarianceStatistics.offset_moments`, for `predicted_error`).
MOMENT_EDGES_C = np.arange(-100.0, 100.1, 1.0)
#: Columns of `VarianceStatistics.offset_moments`: sums per 1-C bin of 1, T, R, R^2,
#: r_tau, r_tau^2, R r_tau, r_dt, r_dt^2, R r_dt, r_tau r_dt (R: relaxed duty cycle,
#: ppt; r_tau, r_dt: its derivatives in tau and dt, ppt/s).
MOMENT_COLUMNS = ("n", "T", "R", "RR", "Rt", "RtRt", "RRt", "Rd", "RdRd", "RRd", "RtRd")
#: Fewest accepted samples in a 5-C bin for the bin to count as fitted: half an hour at
#: 1 Hz, two 900-s intervals (docs/decisions/messenger_fit.md entry 13).
MIN_RANGE_SAMPLES = 1800
#: Blocks beyond the free parameters needed for the bootstrap's error estimate.
MIN_SPARE_BLOCKS = 2
#: Most consecutive blocks resampled together (`solve_variance`): 12 h of 2-h blocks.
MAX_GROUP = 6
#: Residual bias of D0 along the field's mean direction, in units of D0's bootstrap error
#: along it, per unit of the field's one-sidedness (`d0_field_balance`): the part of D0's
#: error no resample of the blocks sees; added in quadrature as a stated error
#: (`widen_d0_along_field`).  2.0 while the regressors' direction carried the fitted heater
#: waveforms' error (docs/decisions/messenger_fit.md entry 28); 0.5 since it does not
#: (entry 31: Mercury orbit, 4 days, 12 realisations, +0.08 +- 0.21 at b 0.92-0.94).
D0_FIELD_BIAS_SIGMA = 0.5
#: In a wind with more than `fit_merit.ADVICE_MAX_COMPRESSIVE_SHARE` of its intervals
#: compressive, the part of each D0 axis's resampled error that trades with the law at the
#: regulated temperature (``|rho|`` of it, ``rho`` their correlation over the resamples) is
#: drawn once more, independently, with the law following it along the resamples' own
#: trade-off (`widen_law_d0_split`): there the heater-on samples pin the sum ``cT(-50 C)
#: + D0 R`` but not its split, and the bootstrap states the split short (law and D0 pulls
#: of opposite sign up to 2.9-3.0 on one axis, 5-%-compressive hard cruise at 4-8 days).
#: 1.0 doubles that part's variance: on 23 saved 4-16-day cruise fits (5 and 7 %
#: compressive) it takes the pulls' spread 1.12 / 1.01 (law / D0) to 0.95 / 0.78: the
#: largest value that keeps both within 0.7-1.5 (docs/decisions/messenger_fit.md entry
#: 52).
LAW_D0_SPLIT_WIDENING = 1.0


@dataclass(frozen=True)
class VarianceSettings:
    """Intervals, selection criteria and bootstrap blocks of the variance estimator.

    Attributes
    ----------
    interval_s : float
        Interval length (s) of the selection criteria (docs/decisions/messenger_fit.md
        entry 12 for 600 and 750 s).
    segment_s : float
        Segment length (s): ``|B|`` is taken constant within one up to a straight line
        in time (entry 17: with 60 s, 1.5 % of the rotations' power is left, and 0.011 %
        of a compressive part correlated over 5-60 min; 900 s, the interval, was the
        default before).
    min_samples : int
        ``too_few_samples`` below this many samples (a third of 15 min at 1 Hz).
    min_eigenvalue_ratio, min_relative_amplitude, max_compressibility : float
        ``ill_conditioned``, ``small_fluctuations``, ``compressive``
        (`fluxcal.calibration.variance_offsets` defaults; docs/decisions/
        solar_wind_offsets.md entry 4).
    block_s : float
        Bootstrap block (s): normal equations are kept per block; blocks much longer
        than the field's correlation time are nearly independent (2 h: the compressive
        ``|B|`` part is correlated up to an hour; docs/decisions/messenger_fit.md entry 13).
    detrend : bool
        Remove a straight line in time per segment (from ``|B'|`` and the regressors)
        instead of the mean only: the slow drift of ``|B|`` within a segment is then
        not taken for an offset.
    weighting : {"none", "inverse_variance"}
        ``inverse_variance``: each interval's samples weighted by ``1 / var(|B'|)`` of
        the interval (segment means and trends removed) at the linearisation point
        (floored at a tenth of the median), so that intervals with a strong compressive
        part count less.
    """

    interval_s: float = 900.0
    segment_s: float = 60.0
    min_samples: int = 300
    min_eigenvalue_ratio: float = DEFAULT_MIN_EIGENVALUE_RATIO
    min_relative_amplitude: float = DEFAULT_MIN_RELATIVE_AMPLITUDE
    max_compressibility: float = DEFAULT_MAX_COMPRESSIBILITY
    block_s: float = 7200.0
    detrend: bool = True
    weighting: str = "inverse_variance"


@dataclass
class VarianceStatistics:
    """Mergeable normal equations of the variance estimator, per bootstrap block.

    Attributes
    ----------
    normal : ndarray, shape (n_blocks, N_PARAMETERS, N_PARAMETERS)
    rhs : ndarray, shape (n_blocks, N_PARAMETERS)
    yy : ndarray, shape (n_blocks,)
        Sum of the squared interval-demeaned ``|B'|^2`` (nT^4), for the residual.
    samples : ndarray, shape (n_blocks,)
    block_start : ndarray, shape (n_blocks,)
        ET of each block's start.
    interval_start : ndarray, shape (n_intervals,)
        ET of every interval's start (accepted and rejected).
    reason : ndarray of str, shape (n_intervals,)
        ``""`` for accepted intervals, else the first failed criterion.
    temperature_count : ndarray, shape (len(TEMPERATURE_EDGES_C) - 1,)
        Accepted samples per 5-C bin of the sensor temperature (`fitted_range`).
    segments : int
        Segments of the accepted intervals (one constant each).
    offset_moments : ndarray, shape (len(MOMENT_EDGES_C) - 1, len(MOMENT_COLUMNS))
        Sums per 1-C bin over every used sample (accepted or not) of the quantities the
        offset's error depends on (`MOMENT_COLUMNS`): the distribution of temperatures
        and duty cycles a recalibrated day of these data sees (`predicted_error`).
    field_sum : ndarray, shape (n_blocks, 4)
        Per block, over the accepted samples, the sums of ``w^2 R^2 B'/|B'|`` (3, the
        field's unit vector, sensor axes) and of ``w^2 R^2`` (``w`` the interval weight,
        ``R`` the relaxed duty cycle): the field's mean direction weighted as D0's
        information (`d0_field_balance`, docs/decisions/messenger_fit.md entry 28).
    """

    normal: np.ndarray = field(default_factory=lambda: np.zeros((0, N_PARAMETERS,
                                                                 N_PARAMETERS)))
    rhs: np.ndarray = field(default_factory=lambda: np.zeros((0, N_PARAMETERS)))
    yy: np.ndarray = field(default_factory=lambda: np.zeros(0))
    samples: np.ndarray = field(default_factory=lambda: np.zeros(0))
    block_start: np.ndarray = field(default_factory=lambda: np.zeros(0))
    interval_start: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reason: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype="<U24"))
    temperature_count: np.ndarray = field(
        default_factory=lambda: np.zeros(TEMPERATURE_EDGES_C.size - 1))
    segments: int = 0
    offset_moments: np.ndarray = field(
        default_factory=lambda: np.zeros((MOMENT_EDGES_C.size - 1, len(MOMENT_COLUMNS))))
    field_sum: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))

    def merge(self, other: VarianceStatistics) -> VarianceStatistics:
        """Return the statistics of both (blocks of the same start are summed)."""
        starts = np.concatenate([self.block_start, other.block_start])
        uniq, inv = np.unique(starts, return_inverse=True)
        n_self = self.block_start.size
        # each side's blocks are distinct (unique starts), so adding one side at a time by
        # index sums what np.add.at sums, in its order: (0 + self's) + other's, bit for bit
        # (entry 54); np.add.at itself where a side repeats a start
        by_side = (np.unique(inv[:n_self]).size == n_self
                   and np.unique(inv[n_self:]).size == inv.size - n_self)

        def add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            out = np.zeros((uniq.size, *np.shape(a)[1:]))
            if by_side:
                out[inv[:n_self]] += a
                out[inv[n_self:]] += b
            else:
                np.add.at(out, inv, np.concatenate([a, b]))
            return out

        return VarianceStatistics(
            normal=add(self.normal, other.normal), rhs=add(self.rhs, other.rhs),
            yy=add(self.yy, other.yy), samples=add(self.samples, other.samples),
            block_start=uniq,
            interval_start=np.concatenate([self.interval_start, other.interval_start]),
            reason=np.concatenate([self.reason, other.reason]).astype("<U24"),
            temperature_count=self.temperature_count + other.temperature_count,
            segments=self.segments + other.segments,
            offset_moments=self.offset_moments + other.offset_moments,
            field_sum=add(*(_per_block(x.field_sum, x.block_start.size, 4)
                            for x in (self, other))))

    @staticmethod
    def merge_all(parts: Sequence[VarianceStatistics]) -> VarianceStatistics:
        """Return ``reduce(VarianceStatistics.merge, parts)``, bit for bit, in one pass.

        Each part's blocks go into one array once, instead of the growing merged arrays
        being copied at every step of the fold (the merge tree's last, largest merge:
        docs/decisions/messenger_fit.md entry 54).  A block is summed in the
        fold's order, ``((0 + first) + second) + ...``: adding 0 again to a sum that
        already had 0 added changes no bit.  A part that repeats a start is folded.
        """
        parts = list(parts)
        if len(parts) < 3:
            return reduce(VarianceStatistics.merge, parts)
        uniq, inv = np.unique(np.concatenate([x.block_start for x in parts]),
                              return_inverse=True)
        cuts = np.cumsum([0, *(x.block_start.size for x in parts)])
        idx = [inv[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
        if any(np.unique(i).size != i.size for i in idx):
            return reduce(VarianceStatistics.merge, parts)

        def add(arrays: list[np.ndarray]) -> np.ndarray:
            out = np.zeros((uniq.size, *np.shape(arrays[0])[1:]))
            for i, a in zip(idx, arrays, strict=True):
                out[i] += a
            return out

        def column(name: str) -> list[np.ndarray]:
            return [getattr(x, name) for x in parts]

        return VarianceStatistics(
            normal=add(column("normal")), rhs=add(column("rhs")), yy=add(column("yy")),
            samples=add(column("samples")), block_start=uniq,
            interval_start=np.concatenate(column("interval_start")),
            reason=np.concatenate(column("reason")).astype("<U24"),
            temperature_count=reduce(np.add, column("temperature_count")),
            segments=sum(x.segments for x in parts),
            offset_moments=reduce(np.add, column("offset_moments")),
            field_sum=add([_per_block(x.field_sum, x.block_start.size, 4) for x in parts]))

    def rejections(self) -> dict[str, int]:
        """Return ``{reason: count}`` of the rejected intervals."""
        return count_reasons(self.reason)

    def fitted_range(self, min_samples: int = MIN_RANGE_SAMPLES) -> tuple[float, float]:
        """Return the temperature range (C) over which the data constrain the law.

        From the lower edge of the first to the upper edge of the last 5-C bin holding
        at least ``min_samples`` accepted samples; ``(nan, nan)`` when none does.  The
        law is stated (fit_report, Table 2 header) and verified over this range only.
        """
        full = np.flatnonzero(self.temperature_count >= min_samples)
        if full.size == 0:
            return float("nan"), float("nan")
        return float(TEMPERATURE_EDGES_C[full[0]]), float(TEMPERATURE_EDGES_C[full[-1] + 1])


def _per_block(values: np.ndarray, blocks: int, width: int) -> np.ndarray:
    """``values`` with one row per block; statistics built without them: zeros."""
    values = np.asarray(values, dtype=float).reshape(-1, width)
    return values if values.shape[0] == blocks else np.zeros((blocks, width))


def _relaxed(et: np.ndarray, changes, cal: MessengerCalibration, tau: float,
             delay: float) -> np.ndarray:
    """Relaxed duty cycle (ppt) at ``et`` for ``tau`` and ``delay`` (eq. 6a-6f, D0 = 1)."""
    rel = cal.constants["relaxation"]
    target = steady_state_offset(changes.duty_cycle_ppt, np.ones(1),
                                 float(rel["min_duty_cycle_ppt"]))
    return relaxed_offset(et, changes.time, target, tau=tau, delay=delay,
                          look_back=int(rel["look_back"]),
                          look_back_s=float(rel["look_back_s"]))[:, 0]


def offset_moments(temp_c: np.ndarray, r: np.ndarray, dr_tau: np.ndarray,
                   dr_dt: np.ndarray) -> np.ndarray:
    """Return the sums of `MOMENT_COLUMNS` per 1-C bin of ``temp_c`` (`MOMENT_EDGES_C`)."""
    cols = (np.ones_like(temp_c), temp_c, r, r * r, dr_tau, dr_tau * dr_tau, r * dr_tau,
            dr_dt, dr_dt * dr_dt, r * dr_dt, dr_tau * dr_dt)
    idx = np.searchsorted(MOMENT_EDGES_C, temp_c, side="right") - 1
    ok = (idx >= 0) & (idx < MOMENT_EDGES_C.size - 1)
    nb = MOMENT_EDGES_C.size - 1
    return np.column_stack([np.bincount(idx[ok], c[ok], nb) for c in cols])


def law_parameters(cal: MessengerCalibration) -> np.ndarray:
    """Per axis ``(a, b, c, T_m)`` of the total Table 2 law: ``a + b T + c max(0, T - T_m)``."""
    coeff = np.asarray(cal.offset_coefficients(), dtype=float)  # A0, B0, A1, B1
    c = coeff[:, 3] - coeff[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        tm = np.where(c != 0, (coeff[:, 0] - coeff[:, 2]) / np.where(c != 0, c, 1.0), 0.0)
    return np.column_stack([coeff[:, 0], coeff[:, 1], c, tm])


def reduce_variance(
    science: xr.Dataset,
    heater: xr.Dataset,
    temperature: xr.Dataset,
    sclk: SclkKernel,
    cal: MessengerCalibration,
    intervals: np.ndarray | None = None,
    settings: VarianceSettings | None = None,
) -> VarianceStatistics:
    """Reduce one chunk's raw streams to the variance estimator's normal equations.

    Parameters
    ----------
    science, heater, temperature : xarray.Dataset
        Raw streams (`fluxcal.missions.messenger.readers`), as for
        `fluxcal.missions.messenger.fit_reduce.reduce_day`.
    sclk : SclkKernel
    cal : MessengerCalibration
        Current estimate of every term (the linearisation point).
    intervals : ndarray, shape (k, 2), optional
        Solar-wind intervals (ET); None: all samples.
    settings : VarianceSettings, optional

    Returns
    -------
    VarianceStatistics

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 2-7, sec. 8 eq. 8.
    """
    s = settings or VarianceSettings()
    out = VarianceStatistics()
    if int(science.sizes.get("time", 0)) == 0:
        return out
    ds = levels.correct_time(science, cal, sclk)
    et_all = ds["et"].values
    keep = ((et_all >= levels._date_et(cal, "heater_mode_v10")) & (ds["range"].values == 0)
            & inside_intervals(et_all, intervals))
    if not keep.any():
        return out
    ds = ds.isel(time=np.flatnonzero(keep))
    et = ds["et"].values
    counts = ds["counts"].values.astype(float)
    periods, changes = levels.find_heater_periods(heater, cal, sclk)
    heat = levels.correct_heater_signal(ds, periods, cal)
    temp_c = levels.interpolate_temperature(
        et, levels.aux_times_et(temperature, sclk), temperature["temperature_c"].values)
    offset = levels.offset_model(et, temp_c, changes, cal)
    m = np.asarray(cal.matrices[0], dtype=float)  # fine range, eq. 8
    b = (counts - offset - heat["heater_signal"].values) @ m.T
    # the regressors' direction from the field before the fitted heater waveform is
    # subtracted: a direction that carried the table's error would share it with |B'|,
    # and that shared error biases D0 along the field (even in the error; entry 31)
    b_dir = (counts - offset) @ m.T
    rel = cal.constants["relaxation"]
    tau, delay = float(rel["tau_s"]), float(rel["delay_s"])
    r = _relaxed(et, changes, cal, tau, delay)
    dr_tau = (_relaxed(et, changes, cal, tau * (1.0 + TAU_STEP), delay) - r) / (tau * TAU_STEP)
    dr_dt = (_relaxed(et, changes, cal, tau, delay + DELAY_STEP_S) - r) / DELAY_STEP_S
    valid = np.all(np.isfinite(b), axis=1) & np.isfinite(temp_c)
    if not valid.any():
        return out
    sel = np.flatnonzero(valid)
    et, b, b_dir, temp_c, r, dr_tau, dr_dt = (x[sel] for x in (et, b, b_dir, temp_c, r, dr_tau,
                                                                dr_dt))
    out.offset_moments = offset_moments(temp_c, r, dr_tau, dr_dt)
    mag = np.sqrt(np.einsum("ij,ij->i", b, b))
    label = np.floor(et / s.interval_s).astype(np.int64)
    labels, codes = np.unique(label, return_inverse=True)
    k = labels.size
    reason = interval_reasons(b, codes, k, min_samples=s.min_samples,
                              min_eigenvalue_ratio=s.min_eigenvalue_ratio,
                              min_relative_amplitude=s.min_relative_amplitude,
                              max_compressibility=s.max_compressibility)
    out.interval_start = labels * s.interval_s
    out.reason = reason
    ok = (reason == "")[codes]
    if not ok.any():
        return out
    codes = codes[ok]
    out.temperature_count = np.histogram(temp_c[ok], TEMPERATURE_EDGES_C)[0].astype(float)
    b, b_dir, temp_c, r, dr_tau, dr_dt, et, mag = (x[ok] for x in (b, b_dir, temp_c, r, dr_tau,
                                                                   dr_dt, et, mag))
    unit = b / mag[:, None]  # the field's direction (nT, sensor axes), for `field_sum`
    # M^T of the unit vector per sample: d|B'| / d(offset counts) = -u (the |B| form: the
    # regressors are direction cosines, independent of the compressive |B| changes;
    # the |B|^2 form's regressors carry them and bias the along-field offset)
    u = (b_dir / np.linalg.norm(b_dir, axis=1)[:, None]) @ m
    law = law_parameters(cal)
    d0 = np.asarray(cal.duty_cycle_d0, dtype=float)
    cols = []
    for j in range(3):
        above = temp_c > law[j, 3]
        basis = (np.ones_like(temp_c), temp_c, np.where(above, temp_c - law[j, 3], 0.0),
                 above.astype(float), r)
        cols += [u[:, j] * f for f in basis]
    for j in range(3):
        cols += [u[:, j] * np.maximum(0.0, temp_c - (law[j, 3] + d)) for d in BREAK_SHIFTS_C]
    cols.append((u @ d0) * dr_tau)
    cols.append((u @ d0) * dr_dt)
    x = np.column_stack(cols)
    y = mag
    # the mean (and trend) per segment (`segment_trends`, as Rosetta's); the weights
    # below per interval
    interval_codes = codes
    codes, k = segment_codes(et, interval_codes, labels * s.interval_s, s.segment_s)
    out.segments = k
    xy = remove_segment_lines(np.column_stack([x, y]), codes, k, et, line=s.detrend)
    x, y = np.ascontiguousarray(xy[:, :-1]), xy[:, -1]
    w2 = np.ones_like(y)
    if s.weighting == "inverse_variance":
        ki = labels.size
        n_i = np.bincount(interval_codes, minlength=ki)
        var_i = np.nan_to_num(segment_variance(y, interval_codes, ki))
        floor = 0.1 * np.median(var_i[n_i > 0])
        w = 1.0 / np.sqrt(np.maximum(var_i, floor))
        x *= w[interval_codes, None]
        y = y * w[interval_codes]
        w2 = w[interval_codes] ** 2
    block = np.floor(et / s.block_s).astype(np.int64)
    starts, bcode = np.unique(block, return_inverse=True)
    nb = starts.size
    out.normal = np.zeros((nb, N_PARAMETERS, N_PARAMETERS))
    out.rhs = np.zeros((nb, N_PARAMETERS))
    out.yy = np.bincount(bcode, y * y, nb)
    out.samples = np.bincount(bcode, minlength=nb).astype(float)
    info = w2 * r * r
    out.field_sum = np.column_stack([np.bincount(bcode, info * unit[:, j], nb) for j in range(3)]
                                    + [np.bincount(bcode, info, nb)])
    bounds = np.searchsorted(bcode, np.arange(nb + 1)) if np.all(np.diff(bcode) >= 0) else None
    for i in range(nb):  # bootstrap blocks (a few per day), each one matrix product
        if bounds is not None:
            xi, yi = x[bounds[i]:bounds[i + 1]], y[bounds[i]:bounds[i + 1]]
        else:
            xi, yi = x[bcode == i], y[bcode == i]
        out.normal[i] = xi.T @ xi
        out.rhs[i] = xi.T @ yi
    out.block_start = starts * s.block_s
    return out


@dataclass
class VarianceSolution:
    """One Gauss-Newton step of the variance estimator and its bootstrap.

    Attributes
    ----------
    step : ndarray, shape (N_PARAMETERS,)
        Correction to the linearisation point (see module docstring for the order).
    boot : ndarray, shape (n_bootstrap, N_PARAMETERS)
        The step re-solved on blocks resampled with replacement, each with its own break
        choices (``boot_shift``) and held D0 drawn from its width (not yet widened:
        ``widening``).
    chi2 : float
        Residual sum of squares (weighted).
    dof : int
        Samples minus parameters minus segments.
    break_shift : ndarray, shape (3,)
        Per axis, the break shift (C, one of `BREAK_SHIFTS_C`) taken instead of the
        linearised step, or 0 (`apply_step`).
    boot_shift : ndarray, shape (n_bootstrap, 3)
        ``break_shift`` of every resample (chosen again on the resampled blocks).
    boot_dither : ndarray, shape (n_bootstrap, 3)
        Per resample and axis, where in the cell of its chosen shift its break lies (C
        from the shift; 0 where the break was kept), to be added to the resampled breaks
        (`fit.fit_variance_calibration`): with ``refine_resamples`` (`solve_variance`,
        the default) or ``refine``, where its own data put it (`refine_breaks`), plus
        the solution's own distance (`solution_distance`) where the solution took a
        shift and stays on it; else drawn uniformly over the half-ways to the
        neighbouring shifts (`quantisation`, entry 27).
    widening : float
        ``sqrt(n / (n - p))`` (``n`` resampled units, ``p`` free parameters): the
        finite-sample correction of the pairs bootstrap, to be applied to the spread of
        the resamples' parameters about their mean (`fit.fit_variance_calibration`).
    break_offset : ndarray, shape (3,)
        With ``refine`` (`solve_variance`), per axis, where in the cell of
        ``break_shift`` the data put the break (C from the shift, `refine_breaks`);
        else 0.  To be added to the stepped break (the fit leaves ``refine`` off).
    """

    step: np.ndarray
    boot: np.ndarray
    chi2: float
    dof: int
    break_shift: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boot_shift: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    widening: float = 1.0
    boot_dither: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    break_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))


def resampling_units(a: np.ndarray, v: np.ndarray, yy: np.ndarray,
                     p_free: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the bootstrap's resampling units: runs of ``k`` consecutive blocks summed.

    ``k`` the largest that leaves ``2 p_free`` units, at most `MAX_GROUP` (entry 13: the
    error is correlated over hours); `solve_variance`'s units, and the units whose scores
    scale `fit_break_profile.profile_break_errors`' threshold.  Returns the units' ``a``,
    ``v``, ``yy``.
    """
    nb = a.shape[0]
    k = int(min(MAX_GROUP, max(1, nb // (2 * p_free))))
    if k == 1:
        return a, v, yy
    group = np.arange(nb) // k
    n_units = int(group[-1]) + 1
    a_g, v_g = np.zeros((n_units, *a.shape[1:])), np.zeros((n_units, v.shape[1]))
    yy_g = np.zeros(n_units)
    np.add.at(a_g, group, a)
    np.add.at(v_g, group, v)
    np.add.at(yy_g, group, yy)
    return a_g, v_g, yy_g


def solve_variance(stats: VarianceStatistics, fit_delay: bool = True,
                   n_bootstrap: int = 200, seed: int = 0,
                   hold_d0: tuple[int, ...] = (),
                   law: np.ndarray | None = None,
                   held_step: np.ndarray | None = None,
                   held_width: np.ndarray | None = None,
                   held: Mapping[int, tuple[float, float]] | None = None,
                   map_rows: Callable[[Callable, list[tuple]], list] | None = None,
                   n_blocks: int = 1,
                   fixed_design: bool = False,
                   refine: bool = False,
                   refine_resamples: bool = True,
                   bootstrap: str = "pairs",
                   ) -> VarianceSolution:
    """Solve the summed normal equations; bootstrap over blocks for the errors.

    Parameters
    ----------
    stats : VarianceStatistics
    fit_delay : bool
        Solve for dt too (else its step is 0).
    n_bootstrap : int
        Resamples of the blocks (with replacement).
    seed : int
        Seed of the resampling.
    hold_d0 : tuple of int
        Axes (0, 1, 2) whose D0 is held (not fitted; the user's choice where the data
        do not determine it, ``--hold-d0``).
    law : ndarray, shape (3, 4), optional
        The linearisation point's ``(a, b, c, T_m)`` per axis (`law_parameters`): the
        breaks are then also tried at `BREAK_SHIFTS_C` inside the data's range
        (``stats.fitted_range`` of `VarianceSettings.min_samples` per 5-C bin;
        `choose_breaks`), in the solution and again in every resample, each shifted
        resample's break placed inside its shift's cell on its own data
        (``refine_resamples``) or drawn over the cell (`quantisation`); None: the
        linearised step only.
    held_step : ndarray, shape (3,), optional
        D0 step of each held axis (the held value minus the linearisation point's);
        default 0 (the base value kept).
    held_width : ndarray, shape (3,), optional
        Standard error of each held D0: every resample draws the held value from a
        normal distribution of this width, so that it propagates into every other
        parameter's error (issue 34); default 0.
    held : mapping, optional
        Any other held parameter: column (`PER_AXIS` layout) -> ``(step, width)``, the
        same way as a held D0 (not fitted, the step to the held value, every resample
        drawing it from a normal distribution of ``width``).  An axis whose break
        column (``-c dT_m``) is held keeps its break: no shift is tried for it
        (`fit_holds.held_upper_segments`, docs/decisions/messenger_fit.md entry 21).
    map_rows : callable, optional
        ``map_rows(resample_fits, [args, ...])`` -> the results in order: the resamples'
        break choices and fits (`resample_fits`, their breaks placed in their cells
        there too where they are refined) in ``n_blocks`` blocks of rows, e.g. on the
        Dask workers, idle while the client fits (`fit_passes.fit_days`); the rows are
        independent, so the numbers are those of one block (issue 34, item 7).  None:
        here, in one block.
    n_blocks : int
        Blocks of resamples given to ``map_rows``.
    fixed_design : bool
        Resample the units' scores with the whole data's normal matrix kept
        (`fixed_design_resamples`) instead of the units' normal equations (the pairs
        bootstrap, the default; docs/decisions/messenger_fit.md entry 41).
    refine : bool
        Place each break moved to a shift inside its cell on its own data
        (`refine_breaks`), in the solution and in every resample.  Off: it changes the
        passes' path, and the 4-day late-peak orbit (seed 3401) then ends with every
        upper segment held (entry 42).
    refine_resamples : bool
        `refine_breaks` in the resamples only (the default): the solution stays at its
        grid point (the passes' path is that of the uniform draw), and where the solution
        itself took a shift, the distance from its grid point to where its own data put
        the break is counted in every resample's break (`solution_distance`, variance
        ``d^2``).  False (and ``refine`` False): every moved resample's break drawn
        uniformly over its cell (`quantisation`, entry 27), the default before entry
        47 (which measured both on the late-peak orbit: T_m pull spreads 0.39 / 0.39
        / 0.47 -> 0.46 / 0.42 / 0.63, no pull beyond 3 added, the fitted tables the same).
    bootstrap : {"pairs", "wild", "wild-webb"}
        ``"pairs"`` (the default): the units resampled with replacement, their normal
        equations summed.  ``"wild"``: the wild cluster bootstrap (`wild_resamples`),
        each unit's residual about the solution times a Rademacher weight (``"wild-webb"``:
        Webb's six-point weights, `wild_weights`), the design kept; each resample chooses
        its breaks again in a world whose truth is the solution.  Opt-in
        (docs/decisions/messenger_fit.md entry 50); not with ``fixed_design``.

    Returns
    -------
    VarianceSolution
        ``boot`` holds the resamples' steps (each with its own break choices and held
        draws); ``widening`` is ``sqrt(n / (n - p))`` (``n`` resampled units, ``p``
        free parameters). The units are runs of ``k`` consecutive blocks, ``k`` the
        largest that leaves ``2 p`` units, at most `MAX_GROUP` (2 h on 2-4 days, 10 h
        on 16 days).

    Raises
    ------
    FluxcalError
        ``n <= p + MIN_SPARE_BLOCKS``: too few blocks for an error estimate; an unknown
        ``bootstrap``, or a wild one with ``fixed_design``.
    """
    wild = {"pairs": None, "wild": "rademacher", "wild-webb": "webb"}
    if bootstrap not in wild or (wild[bootstrap] and fixed_design):
        raise FluxcalError(f"solve_variance: bootstrap {bootstrap!r}: give one of "
                           f"{sorted(wild)} (a wild one without fixed_design)")
    base_free = np.ones(N_PARAMETERS, dtype=bool)
    base_free[-1] = fit_delay
    step_h = np.zeros(3) if held_step is None else np.asarray(held_step, dtype=float)
    width_h = np.zeros(3) if held_width is None else np.asarray(held_width, dtype=float)
    columns = {j * PER_AXIS + 4: (float(step_h[j]), float(width_h[j])) for j in hold_d0}
    columns.update(held or {})
    fixed_h = np.zeros(N_PARAMETERS)
    for col, (value, _) in columns.items():
        base_free[col] = False
        fixed_h[col] = value
    a, v, yy_b = stats.normal, stats.rhs, stats.yy
    nb = a.shape[0]
    choice: tuple[int, ...] = (-1, -1, -1)
    total_a, total_v, yy = a.sum(axis=0), v.sum(axis=0), float(stats.yy.sum())
    # the shifts reach as far as the data do (5-C bins with an interval's worth of
    # accepted samples, the range `fit_guards.break_refusal` judges a break by), not only the
    # stated range: a break seen only in a few short warm peaks lies above the stated
    # range, where the linearised step alone stalls on its bumpy residual and a
    # resample without those peaks cannot move it at all (stated +- 0.04-0.5 C while
    # 0.5-5 C off, issue 34; docs/decisions/messenger_fit.md entry 27)
    data_range = stats.fitted_range(VarianceSettings().min_samples)
    slope = law[:, 2] if law is not None else np.zeros(3)
    if law is not None:
        choice = choose_breaks(total_a, total_v, yy, base_free, law, data_range,
                               fixed=fixed_h)
    free, fixed = break_layout(choice, base_free, slope)
    p_free = int(free.sum())
    if nb <= p_free + MIN_SPARE_BLOCKS:
        raise FluxcalError(
            f"variance estimator: {nb} bootstrap blocks of {VarianceSettings().block_s / 3600:g}"
            f" h hold accepted intervals, need more than {p_free + MIN_SPARE_BLOCKS} for the "
            f"errors of {p_free} parameters; give more days of solar wind")
    # resampling units as long as the days allow (entry 13: the error is correlated over
    # hours): consecutive blocks grouped k at a time, k the largest that keeps 2 p units,
    # at most MAX_GROUP blocks (12 h of 2-h blocks)
    a, v, yy_b = resampling_units(a, v, yy_b, p_free)
    nb = a.shape[0]
    step = fit_columns(total_a, total_v, free, fixed + fixed_h)
    chi2 = float(residual_sum(total_a, total_v, yy, step))
    rng = np.random.default_rng(seed)
    if wild[bootstrap]:  # every unit's residual about the solution, weighted (entry 50)
        a_r, v_r, yy_r = wild_resamples(wild_weights(n_bootstrap, nb, rng, wild[bootstrap]),
                                        a, v, yy_b, total_a, step)
    else:
        picks = np.stack([np.bincount(rng.integers(0, nb, nb), minlength=nb)
                          for _ in range(n_bootstrap)]).astype(float)
        if fixed_design:  # the units' scores resampled, the whole data's design kept
            a_r, v_r, yy_r = fixed_design_resamples(picks, a, v, total_a, total_v, yy, step)
        else:
            a_r, v_r, yy_r = np.einsum("rb,bij->rij", picks, a), picks @ v, picks @ yy_b
    held_r = np.broadcast_to(fixed_h, (n_bootstrap, N_PARAMETERS)).copy()
    if columns:
        cols = sorted(columns)
        draws = rng.standard_normal((n_bootstrap, len(cols)))
        # each column scaled to unit spread: the table states the width held (entry 63)
        draws /= np.maximum(np.std(draws, axis=0), 1e-12)
        held_r[:, cols] += draws * np.array([columns[c][1] for c in cols])
    # a moved break placed inside its cell on its own data, in every resample (with the
    # resamples: on Dask on the workers, entry 54)
    refined = law is not None and (refine or refine_resamples)
    if map_rows is None:
        boot_choice, boot, refined_offset = resample_fits(a_r, v_r, yy_r, held_r, base_free,
                                                          law, data_range, refined)
    else:  # blocks of resamples elsewhere (the rows are independent: the same numbers)
        cuts = np.array_split(np.arange(n_bootstrap), max(1, min(n_blocks, n_bootstrap)))
        parts = map_rows(resample_fits, [(a_r[c], v_r[c], yy_r[c], held_r[c], base_free,
                                          law, data_range, refined) for c in cuts if c.size])
        boot_choice, boot, refined_offset = (np.concatenate(x) for x in zip(*parts,
                                                                            strict=True))
    boot_offset, offset = quantisation(boot_choice, rng), np.zeros(3)
    if refined:
        boot_offset = refined_offset
        if max(choice) >= 0:
            steps, offsets = refine_breaks(total_a[None], total_v[None], np.array([yy]),
                                           fixed_h[None], base_free, law,
                                           np.array([choice]), step[None], data_range)
            if refine:
                step, offset = steps[0], offsets[0]  # chi2 stays the grid solution's
            else:  # the solution kept at its grid point: its distance counted instead
                boot_offset = boot_offset + solution_distance(offsets[0], n_bootstrap, rng)
    dof = int(stats.samples.sum()) - p_free - stats.segments
    return VarianceSolution(step=step, boot=boot, chi2=chi2, dof=dof,
                            break_shift=choice_shifts_c(np.asarray(choice)),
                            boot_shift=choice_shifts_c(boot_choice),
                            boot_dither=boot_offset,
                            widening=float(np.sqrt(nb / (nb - p_free))),
                            break_offset=offset)


def apply_step(cal: MessengerCalibration, step: np.ndarray, max_tau_shift: float = 0.3,
               max_break_shift_c: float = 10.0,
               break_shift: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Return the stepped law ``(a, b, c, T_m)`` per axis, D0, tau and dt.

    The break moves by ``-(step on [T > T_m]) / c``, at most ``max_break_shift_c`` per
    step, or, on an axis with a nonzero ``break_shift`` (`solve_variance`), to the
    shifted break with the slope change fitted there; tau by at most ``max_tau_shift``
    of itself (the linearisation's range).
    """
    law, d0, tau, dt = apply_steps(
        cal, np.asarray(step, dtype=float).reshape(1, -1), max_tau_shift, max_break_shift_c,
        None if break_shift is None else np.asarray(break_shift, dtype=float).reshape(1, 3))
    return law[0], d0[0], float(tau[0]), float(dt[0])


def apply_steps(cal: MessengerCalibration, steps: np.ndarray, max_tau_shift: float = 0.3,
                max_break_shift_c: float = 10.0, break_shifts: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return `apply_step` of every row of ``steps`` (n, `N_PARAMETERS`), stacked.

    The law (n, 3, 4), D0 (n, 3), tau (n,) and dt (n,); ``break_shifts`` (n, 3): each
    row's break shifts (default none).  The same arithmetic element by element as one
    row at a time (the bootstrap's resamples at once, instead of a Python call per
    resample; issue 34, item 7).
    """
    law0 = law_parameters(cal)
    st = np.asarray(steps, dtype=float)
    n = st.shape[0]
    law = np.broadcast_to(law0, (n, 3, 4)).copy()
    d0 = np.broadcast_to(np.asarray(cal.duty_cycle_d0, dtype=float), (n, 3)).copy()
    shifts = np.zeros((n, 3)) if break_shifts is None else np.asarray(break_shifts,
                                                                       dtype=float)
    for j in range(3):
        da, db, dc, dstep, dd0 = st[:, PER_AXIS * j:PER_AXIS * (j + 1)].T
        c = law0[j, 2]
        law[:, j, 0] += da
        law[:, j, 1] += db
        d0[:, j] += dd0
        moved = np.flatnonzero(shifts[:, j] != 0.0)
        kept = np.flatnonzero(shifts[:, j] == 0.0)
        k = np.array([BREAK_SHIFTS_C.index(float(x)) for x in shifts[moved, j]], dtype=int)
        law[moved, j, 2] = st[moved, shift_column(j, k)]
        law[moved, j, 3] += shifts[moved, j]
        dtm = -dstep[kept] / c if c != 0 else np.zeros(kept.size)
        law[kept, j, 2] += dc[kept]
        law[kept, j, 3] += np.clip(dtm, -max_break_shift_c, max_break_shift_c)
    rel = cal.constants["relaxation"]
    tau = float(rel["tau_s"])
    tau_new = tau + np.clip(st[:, -2], -max_tau_shift * tau, max_tau_shift * tau)
    dt_new = float(rel["delay_s"]) + st[:, -1]
    return law, d0, tau_new, dt_new


def d0_field_balance(stats: VarianceStatistics) -> tuple[np.ndarray, float]:
    """Return the field's mean direction weighted as D0's information, and its length.

    ``sum(w^2 R^2 u) / sum(w^2 R^2)`` over the accepted samples (`VarianceStatistics.
    field_sum`): a length near 1 means the field kept one sense (polarity) while the
    heater regulated, near 0 both senses equally.

    Returns
    -------
    direction : ndarray, shape (3,)
        Unit vector (sensor axes, nT); zeros when there is no information.
    balance : float
        The length, 0..1.
    """
    total = np.asarray(stats.field_sum, dtype=float).reshape(-1, 4).sum(axis=0)
    if total[3] <= 0:
        return np.zeros(3), 0.0
    mean = total[:3] / total[3]
    length = float(np.linalg.norm(mean))
    return (mean / length if length > 0 else np.zeros(3)), length


def widen_d0_along_field(b_d0: np.ndarray, d0: np.ndarray, matrix: np.ndarray,
                         direction: np.ndarray, balance: float, free: np.ndarray,
                         seed: int = 34) -> tuple[np.ndarray, float, float]:
    """Add D0's unresampled error along the field's mean direction to the resamples.

    Each resample's D0 (counts/ppt) moves along ``M^-1 direction`` (so that its field
    equivalent ``M D0`` moves along ``direction``) by a normal draw of standard deviation
    ``D0_FIELD_BIAS_SIGMA x balance x s``, ``s`` the resamples' own spread of ``M D0``
    along ``direction`` (about ``d0``); axes not ``free`` (held) do not move.  The draws
    are independent of every other parameter, as the measured bias is (entry 28).

    Parameters
    ----------
    b_d0 : ndarray, shape (n, 3)
        Resampled D0 (already widened by ``sqrt(n / (n - p))``).
    d0 : ndarray, shape (3,)
        The solution.
    matrix : ndarray, shape (3, 3)
        Eq. 8's fine-range matrix (nT per count).
    direction, balance
        `d0_field_balance`.
    free : ndarray of bool, shape (3,)
        Axes whose D0 is fitted.
    seed : int

    Returns
    -------
    b_d0 : ndarray, shape (n, 3)
    along : float
        ``s`` (nT per ppt).
    added : float
        The added standard deviation (nT per ppt).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 5-6 (D0), sec. 8 eq. 8.
    """
    b_d0 = np.asarray(b_d0, dtype=float)
    m = np.asarray(matrix, dtype=float)
    along = float(np.sqrt(np.mean((((b_d0 - d0) @ m.T) @ direction) ** 2)))
    added = D0_FIELD_BIAS_SIGMA * float(balance) * along
    if added == 0.0 or not np.any(free):
        return b_d0, along, 0.0
    step = np.where(free, np.linalg.solve(m, direction), 0.0)
    draws = np.random.default_rng(seed).standard_normal(b_d0.shape[0])
    draws *= added / max(float(np.std(draws)), 1e-12)  # exactly the stated spread
    return b_d0 + draws[:, None] * step[None, :], along, added


def widen_law_d0_split(b_law: np.ndarray, b_d0: np.ndarray, t_ref: float,
                       free: np.ndarray, law_free: np.ndarray, seed: int = 35
                       ) -> tuple[np.ndarray, np.ndarray, dict[str, list[float]]]:
    """Widen each D0 axis and the law at ``t_ref`` along the split the data cannot make.

    Per axis ``j`` whose D0 is ``free``: ``s`` the resamples' D0 about their mean,
    ``L`` their law at ``t_ref`` (the regulated temperature, eq. 2), ``rho`` the
    correlation of ``L`` and ``s`` (`law_d0_correlation`) and ``beta`` the law's
    parameters ``(a, b, c)`` regressed on ``s`` over the resamples (``c`` only where
    ``law_free``: a held upper segment keeps its draws; ``T_m`` never).  Each
    resample's D0 moves by a draw ``eta`` of standard deviation ``LAW_D0_SPLIT_WIDENING
    x |rho| x sd(s)`` and its law by ``beta x eta``: the sum ``L + R D0`` that the
    heater-on samples pin keeps its spread where the trade-off is the sum's (``beta``
    at ``t_ref``, ``beta_L = cov(L, s) / var(s)``, equal to ``-R``; otherwise its
    variance grows by ``(beta_L + R)^2`` times the draws'), while D0 and the law at
    ``t_ref`` apart widen by ``sqrt(1 + (lambda rho)^2)`` and ``sqrt(1 + lambda^2
    rho^4)`` (``lambda`` = `LAW_D0_SPLIT_WIDENING`).  The draws are made orthogonal
    (over the resamples) to ``1``, ``s`` and ``L``, and scaled to exactly that spread,
    so that these hold exactly below every break.
    docs/decisions/messenger_fit.md entry 52.

    Parameters
    ----------
    b_law : ndarray, shape (n, 3, 4)
        Resampled laws ``(a, b, c, T_m)`` per axis.
    b_d0 : ndarray, shape (n, 3)
        Resampled D0 (counts/ppt).
    t_ref : float
        The regulated temperature (C).
    free : ndarray of bool, shape (3,)
        Axes whose D0 is fitted (a held axis keeps its draws: they are the user's).
    law_free : ndarray of bool, shape (3,)
        Axes whose upper segment is fitted.
    seed : int

    Returns
    -------
    b_law, b_d0 : ndarray
    added : dict
        ``rho`` and ``added_counts_per_ppt`` (the draws' standard deviation) per axis
        (0 where nothing was added).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 2-5 (the law, D0 R).
    """
    b_law = np.array(b_law, dtype=float)
    b_d0 = np.array(b_d0, dtype=float)
    n = b_d0.shape[0]
    draws = np.random.default_rng(seed).standard_normal((n, 3))
    dev_d0, dev_law = _split_deviations(b_law, b_d0, t_ref)
    rho = np.where(free, _split_correlation(dev_d0, dev_law), 0.0)
    added = np.zeros(3)
    for j in range(3):
        if rho[j] == 0.0:
            continue
        s, el = dev_d0[j], dev_law[j]
        var = float(np.mean(s ** 2))
        beta = (s[:, None] * (b_law[:, j, :] - b_law[:, j, :].mean(axis=0))).mean(axis=0) / var
        beta[3] = 0.0
        if not law_free[j]:
            beta[2] = 0.0
        x = np.column_stack([np.ones(n), s, el])
        eta = draws[:, j] - x @ np.linalg.lstsq(x, draws[:, j], rcond=None)[0]
        added[j] = LAW_D0_SPLIT_WIDENING * abs(rho[j]) * np.sqrt(var)
        eta *= added[j] / max(float(np.sqrt(np.mean(eta ** 2))), 1e-300)
        b_d0[:, j] += eta
        b_law[:, j, :] += eta[:, None] * beta[None, :]
    return b_law, b_d0, {"rho": rho.tolist(), "added_counts_per_ppt": added.tolist()}


def law_d0_correlation(b_law: np.ndarray, b_d0: np.ndarray, t_ref: float) -> np.ndarray:
    """Return ``rho`` per axis: the resamples' correlation of D0 with the law at ``t_ref``.

    The ``rho`` by which `widen_law_d0_split` widens the split (the same bits: both take
    it from `_split_deviations`), for `split_widening_factor` where the split is not
    widened (docs/decisions/messenger_fit.md entries 52, 60).  0 on an axis whose D0 or
    law does not vary over the resamples, or with fewer than 4 of them.

    Parameters
    ----------
    b_law, b_d0, t_ref
        As `widen_law_d0_split`.

    Returns
    -------
    ndarray, shape (3,)
    """
    return _split_correlation(*_split_deviations(b_law, b_d0, t_ref))


def _split_deviations(b_law: np.ndarray, b_d0: np.ndarray, t_ref: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Return the resamples' D0 and law at ``t_ref`` about their means, each ``(3, n)``.

    Each axis recentred on its own (a column's mean), as entry 52's widening first
    computed it: `widen_law_d0_split` and `law_d0_correlation` share these bits.
    ``b_law, b_d0, t_ref`` as `widen_law_d0_split`.
    """
    b_d0 = np.asarray(b_d0, dtype=float)
    at_ref = law_values(b_law, np.array([float(t_ref)]))[:, 0, :]               # (n, 3)
    dev_d0 = np.array([b_d0[:, j] - b_d0[:, j].mean() for j in range(3)])
    dev_law = np.array([at_ref[:, j] - at_ref[:, j].mean() for j in range(3)])
    return dev_d0, dev_law


def _split_correlation(dev_d0: np.ndarray, dev_law: np.ndarray) -> np.ndarray:
    """Return ``rho`` per axis from `_split_deviations` (`law_d0_correlation`).

    0 where either does not vary, or with fewer than 4 resamples.
    """
    rho = np.zeros(3)
    if dev_d0.shape[1] < 4:
        return rho
    for j in range(3):
        s, el = dev_d0[j], dev_law[j]
        if np.ptp(s) == 0.0 or np.ptp(el) == 0.0:
            continue
        rho[j] = float(np.mean(s * el) / np.sqrt(np.mean(s ** 2) * np.mean(el ** 2)))
    return rho


def split_widening_factor(rho: np.ndarray | float) -> np.ndarray:
    """Return entry 52's widening of D0 along the law-D0 split: ``sqrt(1 + (lambda rho)^2)``.

    ``lambda`` = `LAW_D0_SPLIT_WIDENING`, ``rho`` = `law_d0_correlation`: the factor by
    which `widen_law_d0_split` widens a free D0's stated error (docs/decisions/
    messenger_fit.md entry 52); `fit_guards.d0_goal_refusal` widens the width it advises
    for this fit's own D0 by it where the split is not stated (entry 60).
    """
    return np.sqrt(1.0 + (LAW_D0_SPLIT_WIDENING * np.asarray(rho, dtype=float)) ** 2)


def law_to_table(law: np.ndarray) -> np.ndarray:
    """Convert ``(a, b, c, T_m)`` per axis to Table 2's total ``(A0, B0, A1, B1)`` (eq. 4)."""
    a, b, c, tm = law.T
    return np.column_stack([a, b, a - c * tm, b + c])


def law_values(law: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Return the law ``a + b T + c max(0, T - T_m)`` (counts) at temperatures ``t``.

    ``law`` of shape ``(..., 3, 4)``; the result ``(..., len(t), 3)`` (eq. 3a, 3b, 4).
    """
    law = np.asarray(law, dtype=float)
    t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
    a, b, c, tm = (law[..., None, :, i] for i in range(4))
    return a + b * t + c * np.maximum(0.0, t - tm)


def law_at(law: np.ndarray, t: float) -> np.ndarray:
    """Return the law's offset (counts) per axis at temperature ``t``."""
    return two_segment_offset(np.array([t]), law_to_table(law))[0]
