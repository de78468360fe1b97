"""Per-day sufficient statistics for the in-flight MESSENGER MAG calibration fit.

`reduce_day` turns one day (or any chunk) of raw streams into a `DayStatistics`: binned
sums of the fine-range counts in sensor axes, each corrected by the *current* estimate
of the other calibration terms, for the four analyses of sec. 6 and 7:

1. ``temperature``: heater off (duty cycle in force below 100 ppt, no powered heater
   period), counts minus the heater signal, in 10 C bins of the sensor temperature
   (value columns x, y, z, the temperature itself, whose bin mean is the abscissa of
   the fit, the relaxed duty cycle `relaxed_duty`, whose mean times D0 is the
   duty-cycle offset still decaying after the heater stopped, and its derivative in tau);
   ``temperature_fine`` keeps the same samples' temperature distribution in 0.25-C
   sub-bins nested in the 10-C bins (count and mean temperature), so that the fit can
   model each bin as the average of the law over its samples (docs/decisions/
   messenger_fit.md, entry 8);
2. ``duty``: inside heater periods with a duty cycle of at least 100 ppt, counts minus
   the temperature variation ``cT(T) - cT(-50 C)`` and the heater signal, in 40-ppt (4 %)
   bins of the duty cycle the offset has relaxed to (`relaxed_duty`; columns x, y, z, that
   duty cycle and its derivative in tau), so that the line through ``cT(-50 C)`` has the
   slope ``D0``;
3. ``epoch``: the 1200-s superposed epoch (-200 s .. +1000 s) of the duty-cycle changes
   of the model residual (counts minus the whole current offset model; the relaxed duty
   cycle and its derivative in tau as columns 4, 5) times each change's ``delta`` (change
   of the eq. 5 steady-state duty cycle, ppt), and ``delta**2`` over the same lags
   (``epoch_weight``): their ratio is the least-squares response to a unit step, positive
   and negative steps combined (sec. 7's normalised epoch, each step weighted by its
   size squared, i.e. by the inverse variance of its normalised values);
4. ``waveform``: per duty-cycle bin 12..40 % of the heater period, counts minus the
   current offsets ``cT(T) + Delta(t)`` against seconds since the heater-bit rising
   edge (100 bins of 1 s centred on 0..99 s; columns x, y, z, the phase and the
   weights of the eight duty-cycle columns in the pipeline's interpolation at the
   period's duty cycle, which `fluxcal.missions.messenger.fit_waveforms` unmixes).

Everything is a `fluxcal.calibration.binned_stats.BinnedMoments`, so days merge exactly
(`DayStatistics.merge`) and a month runs as a map-reduce (`fluxcal.missions.messenger.fit_passes`).

Only fine-range samples after MAG FSW V10 (2007-03-09) inside the solar-wind intervals
enter (docs/decisions/messenger_fit.md).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (superposed epoch of the heater
   cycle, 4 % duty-cycle bins, centres 12-40 %), sec. 7 (10 C bins, heater off; 4 %
   duty-cycle bins; the 1200-s epoch starting 200 s before each change), eq. 2-7.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.calibration.binned_stats import BinnedMoments, phase_binned, superposed_epoch
from fluxcal.calibration.heater_error import duty_bin_index
from fluxcal.calibration.heater_signal import heater_waveform, period_index
from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.relaxation import relaxed_offset, steady_state_offset
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel, datetime64_to_tt2000, tt2000_to_et
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.textfile import read_text

__all__ = ["DayStatistics", "FitSettings", "read_intervals", "reduce_day"]


#: Relative step of tau for the derivative of the relaxed duty cycle (``slope`` columns).
TAU_STEP = 0.01
#: Fewest samples in a bin for it to enter a fit (the variance needs two; a bin mean of
#: a few samples of a 5-nT field is noise, its sqrt(N) weight makes it harmless).
MIN_BIN_SAMPLES = 2


@dataclass(frozen=True)
class FitSettings:
    """Bins of the four analyses (sec. 6, 7).

    Attributes
    ----------
    temperature_edges_c : tuple of float
        10 C bins (sec. 7), centred on multiples of 10 C.
    duty_edges_ppt : tuple of float
        4 % (40 ppt) bins of the duty cycle in force from 10 % (eq. 5b threshold) up.
    lag_edges_s : tuple of float
        Superposed-epoch lag bins, -200 s .. +1000 s (sec. 7), 5 s wide (resolves dt).
    waveform_bins_percent : tuple of float
        Duty-cycle bin centres of the heater waveform (12..40 %, 4 % wide; sec. 6).
    phase_bins : int
        Phase bins over the 100-s heater period (1 s, centred on 0..99 s, Tables 6-8).
    max_relaxed_off_ppt : float
        Heater-off samples enter the temperature law once the duty cycle their offset has
        relaxed to is below this (the decaying term then weighs little on cT).
    temperature_sub_bin_c : float
        Width of the sub-bins of ``temperature_fine`` (must divide the 10-C bins).
    min_step_ppt : float
        Least change of the steady-state duty cycle entering the epoch (1 %: a step
        carries weight ``delta**2``, so small ones add little either way).
    """

    temperature_edges_c: tuple[float, ...] = tuple(np.arange(-105.0, 106.0, 10.0))
    duty_edges_ppt: tuple[float, ...] = tuple(np.arange(100.0, 1001.0, 40.0))
    lag_edges_s: tuple[float, ...] = tuple(np.arange(-200.0, 1001.0, 5.0))
    waveform_bins_percent: tuple[float, ...] = (12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 36.0, 40.0)
    phase_bins: int = 100
    min_step_ppt: float = 10.0
    max_relaxed_off_ppt: float = 50.0
    temperature_sub_bin_c: float = 0.25

    def temperature_fine_edges(self) -> np.ndarray:
        """Sub-bin edges of ``temperature_fine``, nested in ``temperature_edges_c``."""
        edges = np.asarray(self.temperature_edges_c, dtype=float)
        h = float(self.temperature_sub_bin_c)
        steps = np.diff(edges) / h
        if h <= 0 or not np.allclose(steps, np.round(steps), rtol=0, atol=1e-9):
            raise InputFormatError(f"temperature sub-bins of {h} C do not divide the "
                                   "temperature bins", field="temperature_sub_bin_c")
        return np.concatenate([edges[:1], *[e0 + h * np.arange(1, int(round(k)) + 1)
                                            for e0, k in zip(edges[:-1], steps, strict=True)]])


@dataclass
class DayStatistics:
    """Mergeable sufficient statistics of one or more days (see module docstring).

    Attributes
    ----------
    temperature, duty, epoch : BinnedMoments
        Analyses 1-3 (``epoch`` holds the residual columns times each change's step).
    epoch_weight : BinnedMoments
        The squared steps over the same lags: ``epoch.mean() / epoch_weight.mean()`` is
        the least-squares response to a unit step (sec. 7's normalised epoch).
    waveform : list of BinnedMoments
        Analysis 4, one per waveform duty-cycle bin.
    waveform_folds : list of list of BinnedMoments
        Analysis 4 split into `WAVEFORM_FOLDS` folds by the 30-min block of each sample
        (block index modulo the folds): the waveforms refitted without each fold state
        the waveform's error (docs/decisions/messenger_fit.md entries 19, 29, 34).
    temperature_fine : BinnedMoments
        The temperature-law samples in 0.25-C sub-bins; its one value column is the
        temperature (count and mean temperature per sub-bin).
    heater_off : BinnedMoments
        Every heater-off sample (duty cycle in force below 100 ppt, no powered period) in
        the 10-C bins, before the cut on the decaying duty-cycle offset
        (``max_relaxed_off_ppt``); its one value column is the relaxed duty cycle.  Only
        for the error message of the temperature law (`fluxcal.missions.messenger.fit`),
        which must tell a lack of heater-off data from a decay that has not ended.
    n_samples : dict
        Sample counts: ``total``, ``used`` (fine, V10, inside intervals), ``coarse``,
        ``outside_intervals``, ``before_v10``; ``events`` (duty-cycle changes in the
        epoch) and ``events_positive``; ``heater_on_beyond_bins`` (heater-on samples
        whose period's duty cycle lies in no ``waveform`` bin: outside every D_RANGE).
    inputs : dict
        Input file name -> sha256 (provenance).
    days : list of str
        Days (or chunk labels) reduced.
    """

    temperature: BinnedMoments
    duty: BinnedMoments
    epoch: BinnedMoments
    waveform: list[BinnedMoments]
    epoch_weight: BinnedMoments | None = None
    temperature_fine: BinnedMoments | None = None
    heater_off: BinnedMoments | None = None
    waveform_folds: list[list[BinnedMoments]] | None = None
    n_samples: dict[str, int] = field(default_factory=dict)
    inputs: dict[str, str] = field(default_factory=dict)
    days: list[str] = field(default_factory=list)

    @classmethod
    def empty(cls, settings: FitSettings | None = None) -> DayStatistics:
        """Return statistics of no data (the identity of `merge`)."""
        s = settings or FitSettings()
        return cls(
            temperature=BinnedMoments.empty(s.temperature_edges_c, 6, label="temperature",
                                            units="degC", value_units="counts"),
            duty=BinnedMoments.empty(s.duty_edges_ppt, 5, label="duty cycle", units="ppt",
                                     value_units="counts"),
            epoch=BinnedMoments.empty(s.lag_edges_s, 5, label="lag", units="s",
                                      value_units="counts per ppt"),
            waveform=[BinnedMoments.empty(_phase_edges(s), 4 + len(s.waveform_bins_percent),
                                          label="phase", units="s",
                                          value_units="counts")
                      for _ in s.waveform_bins_percent],
            epoch_weight=BinnedMoments.empty(s.lag_edges_s, 1, label="lag", units="s",
                                             value_units="ppt^2"),
            temperature_fine=_empty_fine(s.temperature_fine_edges()),
            heater_off=_empty_off(s.temperature_edges_c),
        )

    def __post_init__(self) -> None:
        if self.epoch_weight is None:
            self.epoch_weight = BinnedMoments.empty(self.epoch.edges, 1, label="lag",
                                                    units="s", value_units="ppt^2")
        if self.temperature_fine is None:
            edges = self.temperature.edges
            self.temperature_fine = _empty_fine(FitSettings(
                temperature_edges_c=tuple(edges)).temperature_fine_edges())
        if self.heater_off is None:
            self.heater_off = _empty_off(self.temperature.edges)
        if self.waveform_folds is None:
            self.waveform_folds = [[BinnedMoments.empty(w.edges, w.n_comp, label="phase",
                                                        units="s", value_units="counts")
                                    for w in self.waveform] for _ in range(WAVEFORM_FOLDS)]

    def merge(self, other: DayStatistics) -> DayStatistics:
        """Return the statistics of both (bins must agree)."""
        keys = set(self.n_samples) | set(other.n_samples)
        return DayStatistics(
            temperature=self.temperature.merge(other.temperature),
            duty=self.duty.merge(other.duty),
            epoch=self.epoch.merge(other.epoch),
            waveform=[a.merge(b) for a, b in zip(self.waveform, other.waveform, strict=True)],
            epoch_weight=self.epoch_weight.merge(other.epoch_weight),
            temperature_fine=self.temperature_fine.merge(other.temperature_fine),
            heater_off=self.heater_off.merge(other.heater_off),
            waveform_folds=[[a.merge(b) for a, b in zip(ha, hb, strict=True)]
                            for ha, hb in zip(self.waveform_folds, other.waveform_folds,
                                              strict=True)],
            n_samples={k: self.n_samples.get(k, 0) + other.n_samples.get(k, 0) for k in keys},
            inputs={**self.inputs, **other.inputs},
            days=[*self.days, *other.days],
        )

    def __add__(self, other: DayStatistics) -> DayStatistics:
        """Merge (see `merge`)."""
        return self.merge(other)

    def to_datasets(self) -> dict[str, xr.Dataset]:
        """Return every `BinnedMoments` as a dataset (``temperature``, ``waveform_12``...)."""
        out = {"temperature": self.temperature.to_dataset(), "duty": self.duty.to_dataset(),
               "epoch": self.epoch.to_dataset(), "epoch_weight": self.epoch_weight.to_dataset(),
               "temperature_fine": self.temperature_fine.to_dataset(),
               "heater_off": self.heater_off.to_dataset()}
        for pct, w in zip(FitSettings().waveform_bins_percent, self.waveform, strict=False):
            out[f"waveform_{pct:.0f}"] = w.to_dataset()
        return out


def usable_bins(moments: BinnedMoments, column: int = 0) -> np.ndarray:
    """Bins that enter a fit: `MIN_BIN_SAMPLES` samples and a finite mean of ``column``."""
    mean = moments.mean()
    return (moments.count >= MIN_BIN_SAMPLES) & np.isfinite(mean[:, column])


def _empty_fine(edges: np.ndarray) -> BinnedMoments:
    return BinnedMoments.empty(edges, 1, label="temperature", units="degC",
                               value_units="degC")


def _empty_off(edges) -> BinnedMoments:
    return BinnedMoments.empty(edges, 1, label="temperature", units="degC",
                               value_units="ppt")


def _phase_edges(s: FitSettings) -> np.ndarray:
    step = 100.0 / s.phase_bins
    return (np.arange(s.phase_bins + 1) - 0.5) * step


def read_intervals(path: Path) -> np.ndarray:
    """Read solar-wind intervals (CSV ``start,stop`` in ISO UTC), shape (k, 2) datetime64.

    A header line naming ``start,stop`` is optional; ``#`` lines and blank lines are
    skipped.  `intervals_to_et` converts them where kernels are loaded.

    Raises
    ------
    InputFormatError
        Naming the file, line and field: a line without two fields, a time that is not
        ISO UTC, or a stop before its start.
    """
    path = Path(path)
    try:
        text = read_text(path, "a CSV text file of intervals 'start,stop' (ISO UTC)")
    except OSError as exc:
        raise InputFormatError(f"cannot read the intervals file: {exc}", path=str(path)) from exc
    rows: list[tuple[float, float]] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        fields = [f.strip() for f in line.split(",")]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if [f.lower() for f in fields] == ["start", "stop"]:
            continue
        if len(fields) != 2:
            raise InputFormatError(f"expected two fields 'start,stop' (ISO UTC), got "
                                   f"{len(fields)}", path=str(path), line=lineno)
        pair = []
        for name, value in zip(("start", "stop"), fields, strict=True):
            try:
                stamp = np.datetime64(value, "ms")
            except ValueError:
                raise InputFormatError(f"{value!r} is not an ISO UTC time such as "
                                       "2012-06-01T00:00:00", path=str(path), line=lineno,
                                       field=name) from None
            if np.isnat(stamp):
                raise InputFormatError(f"{value!r} is not a time", path=str(path), line=lineno,
                                       field=name)
            pair.append(stamp)
        if pair[1] < pair[0]:
            raise InputFormatError(f"stop {pair[1]} lies before start {pair[0]}",
                                   path=str(path), line=lineno, field="stop")
        rows.append((pair[0], pair[1]))
    if not rows:
        raise InputFormatError("no interval (expected lines 'start,stop' in ISO UTC)",
                               path=str(path))
    return np.array(rows, dtype="datetime64[ms]")


def intervals_to_et(intervals: np.ndarray | None) -> np.ndarray | None:
    """Return UTC ``datetime64`` interval pairs (`read_intervals`) as ET (None: None).

    A leap-second kernel must be loaded; float pairs are taken as ET already.
    """
    if intervals is None:
        return None
    iv = np.asarray(intervals)
    if iv.dtype.kind != "M":
        return iv.astype(float)
    return tt2000_to_et(datetime64_to_tt2000(iv.ravel())).reshape(iv.shape)


def inside_intervals(et: np.ndarray, intervals: np.ndarray | None) -> np.ndarray:
    """Return True for times inside any ``[start, stop)`` of ``intervals`` (all if None)."""
    et = np.asarray(et, dtype=float)
    if intervals is None:
        return np.ones(et.shape, dtype=bool)
    iv = np.asarray(intervals, dtype=float).reshape(-1, 2)
    opened = np.searchsorted(np.sort(iv[:, 0]), et, side="right")
    closed = np.searchsorted(np.sort(iv[:, 1]), et, side="right")
    return opened > closed


def relaxation_response(lag: np.ndarray, tau: float, delay: float) -> np.ndarray:
    """Normalised step response ``1 - exp(-(lag - dt) / tau)`` after ``dt``, else 0 (eq. 6f).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 6f.
    """
    lag = np.asarray(lag, dtype=float)
    return np.where(lag > delay, -np.expm1(-np.maximum(lag - delay, 0.0) / tau), 0.0)


def effective_duty(ppt: np.ndarray, threshold_ppt: float) -> np.ndarray:
    """Duty cycle (1-D) entering eq. 5: ``d`` for ``d >= threshold`` (100 ppt), else 0 (eq. 5b).

    `fluxcal.calibration.relaxation.steady_state_offset` with a unit slope.
    """
    return steady_state_offset(ppt, np.ones(1), threshold_ppt)[:, 0]


def relaxed_duty(et: np.ndarray, changes, cal: MessengerCalibration,
                 tau: float | None = None) -> np.ndarray:
    """Duty cycle (ppt) the offset has relaxed to at ``et``: eq. 6a-6f with ``D0 = 1``.

    The steady-state duty cycle of eq. 5 (``d`` from 100 ppt, else 0) relaxed with the
    calibration's tau (or ``tau``), dt and look-back
    (`fluxcal.calibration.relaxation.relaxed_offset`); ``D0 * relaxed_duty`` is the
    duty-cycle offset the pipeline applies.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 5a, 5b, 6a-6f.
    """
    rel = cal.constants["relaxation"]
    target = steady_state_offset(changes.duty_cycle_ppt, np.ones(1),
                                 float(rel["min_duty_cycle_ppt"]))
    return relaxed_offset(np.asarray(et, dtype=float), changes.time, target,
                          tau=float(rel["tau_s"] if tau is None else tau),
                          delay=float(rel["delay_s"]),
                          look_back=int(rel["look_back"]),
                          look_back_s=float(rel["look_back_s"]))[:, 0]


def reduce_day(
    science: xr.Dataset,
    heater: xr.Dataset,
    temperature: xr.Dataset,
    sclk: SclkKernel,
    cal: MessengerCalibration,
    intervals: np.ndarray | None = None,
    settings: FitSettings | None = None,
    *,
    label: str = "",
    inputs: dict[str, str] | None = None,
) -> DayStatistics:
    """Reduce raw streams to the `DayStatistics` of the four fits (module docstring).

    Parameters
    ----------
    science, heater, temperature : xarray.Dataset
        Raw streams (`fluxcal.missions.messenger.readers`); the heater stream should
        start at least 5000 s before the science (look-back of sec. 7).
    sclk : SclkKernel
        MESSENGER clock.
    cal : MessengerCalibration
        The current estimate of every term (the shipped tables on the first pass).
    intervals : ndarray, shape (k, 2), optional
        Solar-wind intervals (ET); None: all samples.
    settings : FitSettings, optional
    label : str
        Day label recorded in ``days``.
    inputs : dict, optional
        File name -> sha256 recorded for provenance.

    Returns
    -------
    DayStatistics

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7, eq. 2-7.
    """
    s = settings or FitSettings()
    out = DayStatistics.empty(s)
    out.days = [label] if label else []
    out.inputs = dict(inputs or {})
    n_total = int(science.sizes.get("time", 0))
    if n_total == 0:
        out.n_samples = {"total": 0, "used": 0}
        return out
    ds = levels.correct_time(science, cal, sclk)
    et_all = ds["et"].values
    v10 = et_all >= levels._date_et(cal, "heater_mode_v10")
    fine = ds["range"].values == 0
    inside = inside_intervals(et_all, intervals)
    keep = v10 & fine & inside
    out.n_samples = {
        "total": n_total, "before_v10": int((~v10).sum()), "coarse": int((v10 & ~fine).sum()),
        "outside_intervals": int((v10 & fine & ~inside).sum()), "used": int(keep.sum()),
        "events": 0, "events_positive": 0,
    }
    if not keep.any():
        return out
    ds = ds.isel(time=np.flatnonzero(keep))
    et = ds["et"].values
    counts = ds["counts"].values.astype(float)
    periods, changes = levels.find_heater_periods(heater, cal, sclk)
    heat = levels.correct_heater_signal(ds, periods, cal)
    w_est = heat["heater_signal"].values
    powered = heat["heater_applied"].values
    temp_c = levels.interpolate_temperature(
        et, levels.aux_times_et(temperature, sclk), temperature["temperature_c"].values)
    coeff = cal.offset_coefficients()
    c_t = two_segment_offset(temp_c, coeff)
    offset = levels.offset_model(et, temp_c, changes, cal)
    rel = cal.constants["relaxation"]
    threshold = float(rel["min_duty_cycle_ppt"])
    k = np.searchsorted(changes.time, et, side="right") - 1
    level = np.where(k >= 0, changes.duty_cycle_ppt[np.maximum(k, 0)] if len(changes) else 0.0,
                     0.0)
    level_eff = effective_duty(level, threshold)
    relaxed = relaxed_duty(et, changes, cal)
    # its derivative in tau (per second), for the in-pass tau iteration of the fit
    rel_tau = float(cal.constants["relaxation"]["tau_s"])
    slope = (relaxed_duty(et, changes, cal, tau=rel_tau * (1.0 + TAU_STEP)) - relaxed) / (
        rel_tau * TAU_STEP)
    # 1. temperature law: heater off; counts minus the heater signal, with the relaxed
    # duty cycle (the fit removes D0 times its mean, with its own D0)
    off_all = (level_eff == 0) & ~powered
    out.heater_off = BinnedMoments.accumulate(
        temp_c[off_all], relaxed[off_all], s.temperature_edges_c, label="temperature",
        units="degC", value_units="ppt")
    off = off_all & (relaxed < s.max_relaxed_off_ppt)
    values = np.column_stack([counts[off] - w_est[off], temp_c[off], relaxed[off], slope[off]])
    out.temperature = BinnedMoments.accumulate(
        temp_c[off], values, s.temperature_edges_c, label="temperature", units="degC",
        value_units="counts")
    # the same samples' temperatures in nested sub-bins (a sample accumulate drops, with
    # a NaN in any column, is dropped here too): the distribution within each bin
    t_fine = np.where(np.all(np.isfinite(values), axis=1), temp_c[off], np.nan)
    out.temperature_fine = BinnedMoments.accumulate(
        t_fine, t_fine, s.temperature_fine_edges(), label="temperature", units="degC",
        value_units="degC")
    # 2. duty-cycle law: counts minus the temperature variation and the heater signal,
    # binned by the duty cycle the offset has relaxed to (eq. 6f with unit slope), in
    # heater periods with a finite duty cycle (docs/decisions/messenger_fit.md, entry 2)
    t_ref = cal.reference_temperature_c
    c_ref = two_segment_offset(np.array([t_ref]), coeff)[0]
    p = period_index(et, periods)
    on = (level_eff > 0) & (p >= 0)
    steady = (counts - (c_t - c_ref) - w_est)[on]
    out.duty = BinnedMoments.accumulate(
        relaxed[on], np.column_stack([steady, relaxed[on], slope[on]]), s.duty_edges_ppt,
        label="duty cycle", units="ppt", value_units="counts")
    # 3. superposed epoch of the duty-cycle changes, weighted by the step (the fit divides
    # by the mean squared step: least squares for the response to a unit step)
    residual = np.column_stack([counts - offset - w_est, relaxed, slope])
    finite = np.isfinite(changes.time)
    prev = np.concatenate([[0.0], changes.duty_cycle_ppt[:-1]])
    step = (effective_duty(changes.duty_cycle_ppt, threshold)
            - effective_duty(prev, threshold))
    ev = finite & (np.abs(step) >= s.min_step_ppt) & (
        changes.time >= levels._date_et(cal, "heater_mode_v10"))
    # only changes whose epoch window holds used samples count
    t_sorted = np.sort(et)
    lag = np.asarray(s.lag_edges_s)
    ev &= (np.searchsorted(t_sorted, changes.time + lag[-1], side="left")
           > np.searchsorted(t_sorted, changes.time + lag[0], side="left"))
    out.n_samples["events"] = int(ev.sum())
    out.n_samples["events_positive"] = int((ev & (step > 0)).sum())
    if ev.any():
        out.epoch = superposed_epoch(et, residual, changes.time[ev], s.lag_edges_s,
                                     weights=step[ev], shift=0.0,
                                     value_units="counts ppt")
        out.epoch_weight = superposed_epoch(et, np.ones(et.size), changes.time[ev],
                                            s.lag_edges_s, weights=step[ev] ** 2, shift=0.0,
                                            value_units="ppt^2")
    # 4. heater waveform per duty-cycle bin: counts minus the current offsets, with the
    # weights of the bins' linear duty-cycle interpolation (sec. 6) of each sample
    if len(periods):
        pp = np.maximum(p, 0)
        duty_pct = np.where(p >= 0, periods.duty_cycle[pp] * 100.0, np.nan)
        phase = np.where(p >= 0, et - periods.start[pp], np.nan)
        half = 0.5 * 100.0 / s.phase_bins
        phase = np.where(phase >= 100.0 - half, phase - 100.0, phase)
        centres = np.asarray(s.waveform_bins_percent)
        b = duty_bin_index(duty_pct, centres)  # -1: in no bin (NaN, above 42 %, below 10 %)
        weights = interpolation_weights(duty_pct, centres)
        # the field's own variation within a heater period leaks into the phase bins (a
        # ramp of the field becomes a sawtooth): the field is estimated by the centred
        # mean over one heater period of the counts less the current model (the
        # waveform's mean over its period is zero) and removed (entry 19)
        field_est = _period_mean(et, counts - offset - w_est, 100.0)
        r4 = np.column_stack([counts - offset - field_est, phase, weights])
        period_bin = duty_bin_index(periods.duty_cycle * 100.0, centres)
        fold = np.floor(et / WAVEFORM_FOLD_BLOCK_S).astype(np.int64) % WAVEFORM_FOLDS
        covered = np.all(np.isfinite(field_est), axis=1)
        # heater-on samples whose period's duty cycle lies in no bin (above 42 %, below
        # 10 %): no column sees them, so they lie outside every stated D_RANGE (issue 34)
        beyond = powered & covered & (p >= 0) & (b < 0)
        out.n_samples["heater_on_beyond_bins"] = int(np.count_nonzero(beyond))
        for j in range(centres.size):
            sel = powered & (b == j) & covered
            starts = periods.start[periods.applied & (period_bin == j)]
            if sel.any() and starts.size:
                out.waveform[j] = phase_binned(et[sel], r4[sel], starts, 100.0, s.phase_bins,
                                               value_units="counts")
                for h in range(WAVEFORM_FOLDS):
                    part = sel & (fold == h)
                    if part.any():
                        out.waveform_folds[h][j] = phase_binned(
                            et[part], r4[part], starts, 100.0, s.phase_bins,
                            value_units="counts")
    return out


#: Blocks (s) that split the waveform samples into folds (block index modulo
#: `WAVEFORM_FOLDS`): 30 min, 18 heater periods, so that a duty-cycle bin visited for
#: an hour or two still falls into several folds (entry 29).
WAVEFORM_FOLD_BLOCK_S = 1800.0
#: Folds left out in turn to state the waveform columns' errors (entries 29, 34;
#: two halves before, whose variance estimate had one degree of freedom per phase).
WAVEFORM_FOLDS = 4


def _period_mean(t: np.ndarray, values: np.ndarray, period: float) -> np.ndarray:
    """Centred mean of ``values`` over ``[t - period / 2, t + period / 2)``, per sample.

    NaN where the window is not covered: its samples span less than ``period`` minus two
    median sample spacings, or hold fewer than 90 % of the samples that spacing gives.
    """
    n = t.size
    out = np.full(values.shape, np.nan)
    if n < 3:
        return out
    order = np.argsort(t, kind="stable")
    ts, vs = t[order], values[order]
    dt = float(np.median(np.diff(ts)))
    lo = np.searchsorted(ts, ts - period / 2.0, side="left")
    hi = np.searchsorted(ts, ts + period / 2.0, side="left")
    csum = np.vstack([np.zeros((1, vs.shape[1])), np.cumsum(vs, axis=0)])
    count = hi - lo
    span = ts[np.maximum(hi - 1, 0)] - ts[lo]
    ok = (count > 0) & (span >= period - 2.0 * dt) & (count >= 0.9 * period / max(dt, 1e-9))
    mean = (csum[hi] - csum[lo]) / np.maximum(count, 1)[:, None]
    out[order] = np.where(ok[:, None], mean, np.nan)
    return out


def interpolation_weights(duty_percent: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Weight of each duty-cycle column in the pipeline's waveform at ``duty_percent``.

    `fluxcal.calibration.heater_signal.heater_waveform` of an identity table: linear
    between bins, the edge slopes extended below 12 % and above 40 % (sec. 6).  Returns
    shape (n, n_bins); NaN duty cycles give NaN rows.
    """
    nb = np.asarray(centres).size
    identity = np.broadcast_to(np.eye(nb)[:, None, :], (nb, 101, nb))
    d = np.asarray(duty_percent, dtype=float)
    out = np.full((d.size, nb), np.nan)
    ok = np.isfinite(d)
    out[ok] = heater_waveform(np.zeros(int(ok.sum())), d[ok], identity, centres)
    return out
