"""Flight-like MESSENGER MAG forward model: weeks of cruise solar wind in the raw streams.

The verification model of issue 13 (in-flight calibration).  It writes what the
instrument would have sent while the spacecraft cruised in the solar wind, in the batch
input layout (``MAGSCI/MAGHTR/MAGTMP_YYYYDDD.csv``, ``kernels.tm``; see
docs/formats/messenger.md), from *true* calibration tables that differ from the seed's
(written into a calibration folder in fluxcal's own format by `write_true_calibration`).

It shares no code with the fit or the pipeline: the instrument is run forward with
`fluxcal.missions.messenger.forward` (tables read by its own reader; eq. 8 solved for
counts, Table 2 as the maximum of two lines, the duty-cycle offset relaxed by an IIR
filter, Tables 6-8 interpolated), SPICE (`fluxcal.geometry`) only for time and the
synthetic kernels.  Checked by ``tests/missions/test_forward_independence.py``.

Model (docs/decisions/messenger_fit_verification.md):

- **solar wind** in sensor axes (``FlightConfig.solar_wind``, `WINDS`):
  ``"realistic"`` (the default, `RealisticWindModel`, `fluxcal.missions.solar_wind`): 18 nT
  log-normal ``|B|``, Alfvenic rotations ``dB/B`` ~ 0.55 with an f^-5/3 spectrum from 12 h
  to 2 s, a 3 % compressive part, a Parker-spiral direction fixed in sensor axes and
  sectors of 1-3 days (issue 21); ``"quiet"`` (`SolarWindModel`, the model of issue 13):
  ``B = |B| u``, the direction ``u`` the normalised sum of a sector mean ``s(t) m p`` (``p``
  a fixed Parker-spiral direction, ``s = +-1`` flipping after dwell times drawn from
  ``sector_days``) and a 3-D Gaussian process of unit variance per component (two
  cascaded first-order relaxations, correlation time about ``2 alfven_correlation_s``),
  ``|B|`` log-normal around 7 nT with a slow (``b_correlation_s``) and a compressive
  (``compressive_correlation_s``, relative rms ``compressive_fraction``) part;
- **heater and temperature**: the V10 controller sets a duty cycle per 1000-s evaluation
  (ten 100-s periods, sec. 7); runs of regulated blocks (sensor at -50 C, duty cycle a
  random walk in 10..45 %) alternate with heater-off runs (duty 0) in which the
  temperature makes an excursion to a peak in ``peak_c`` and cools ``dip_c`` below -50 C
  before the heater resumes; the heater bit (1 s) is on for the first ``d`` seconds of
  every period; the offset and waveform follow the bit after the 10-s delay (forward);
- **instrument**: zero level = Table 2 at the true temperature + the relaxed duty-cycle
  offset + the Tables 6-8 waveform (sec. 6, 7), counts from eq. 8, rounded.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-8, Tables 1-4, 6-8.
.. [2] Belcher, J. W., and L. Davis (1971), Large-amplitude Alfven waves in the
   interplanetary medium, 2, J. Geophys. Res., 76, 3534 (constant-``|B|`` rotations).
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
from scipy.signal import lfilter

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import write_meta_kernel
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.missions.solar_wind import AlfvenicWind, alfvenic_wind
from fluxcal.products.atomic import atomic_path, atomic_write_bytes
from fluxcal.products.paths import make_folder

DAY_S = 86_400.0
#: Heater period (s) and the controller's evaluation interval (s), sec. 6 and 7.
PERIOD_S = 100.0
BLOCK_S = 1000.0
#: Sensor temperature while the heater regulates (sec. 7).
REGULATED_C = -50.0
#: Excursion peaks are drawn one per stratum in groups of this many.
PEAK_STRATA = 6
#: Heater-off seconds before the first heater period (> one period: a quiet start).
QUIET_LEAD_S = 110.0


@dataclass
class SolarWindModel:
    """Statistics of the *quiet* solar wind (sensor axes, nT, s): ``solar_wind="quiet"``.

    The wind of issue 13: 7 nT, rotations of a two-stage relaxation (f^-4 spectrum above
    its corner), sectors of 2-6 days (docs/decisions/messenger_fit_verification.md,
    section 2).

    Attributes
    ----------
    b_median_nt, b_log_sigma, b_correlation_s : float
        ``|B|`` is ``b_median_nt exp(b_log_sigma g)`` with ``g`` a unit Gaussian process of
        correlation time ``b_correlation_s`` (5-10 nT for the defaults).
    compressive_fraction, compressive_correlation_s : float
        Relative rms and correlation time of the compressive factor ``1 + f h``.
    alfven_correlation_s : float
        Time constant of each of the two relaxations that make the rotating part.
    parker_strength : float
        Weight ``m`` of the sector mean direction against the unit-variance rotations.
    parker_direction : tuple of float
        Mean-field direction ``p`` in sensor axes (normalised).
    sector_days : tuple of float
        Range of the sector dwell times (days), uniform.
    noise_nt : float
        White noise per sample (nT), e.g. the sensor's own noise.
    """

    b_median_nt: float = 7.0
    b_log_sigma: float = 0.18
    b_correlation_s: float = 12 * 3600.0
    compressive_fraction: float = 0.03
    compressive_correlation_s: float = 300.0
    alfven_correlation_s: float = 900.0
    parker_strength: float = 1.0
    parker_direction: tuple[float, float, float] = (0.55, -0.6, 0.58)
    sector_days: tuple[float, float] = (2.0, 6.0)
    noise_nt: float = 0.01


@dataclass
class RealisticWindModel(AlfvenicWind):
    """Statistics of the *realistic* solar wind (the default, ``solar_wind="realistic"``).

    `fluxcal.missions.solar_wind.AlfvenicWind` (18 nT, ``dB/B`` 0.55, f^-5/3 from 12 h to
    2 s, 3 % compressive, sectors of 1-3 days along the Parker direction in sensor axes)
    plus the white noise of the sensor.

    Attributes
    ----------
    noise_nt : float
        White noise per sample (nT).
    """

    noise_nt: float = 0.01


#: The solar winds `simulate_flight` knows by name (``FlightConfig.solar_wind``).
WINDS = {"realistic": RealisticWindModel, "quiet": SolarWindModel}


def wind_model(wind: str | SolarWindModel | RealisticWindModel
               ) -> SolarWindModel | RealisticWindModel:
    """Return the wind model of a name in `WINDS` (a model is returned as it is).

    Raises
    ------
    ValueError
        An unknown name.
    """
    if isinstance(wind, str):
        if wind not in WINDS:
            raise ValueError(f"solar wind {wind!r}: choose one of {', '.join(WINDS)}")
        return WINDS[wind]()
    return wind


@dataclass
class HeaterModel:
    """The heater controller's schedule (in 1000-s evaluation blocks) and temperatures.

    Attributes
    ----------
    regulated_blocks, off_blocks : tuple of int
        Ranges (inclusive) of the lengths of regulated and heater-off runs.
    duty_percent : tuple of int
        Range of the regulated duty cycle (percent).
    duty_step_percent : int
        Largest duty-cycle change at one evaluation.
    change_probability : float
        Probability that an evaluation changes the duty cycle.
    peak_c, dip_c : tuple of float
        Ranges of an excursion's peak temperature (stratified: each group of
        `PEAK_STRATA` excursions has one peak in every sixth of the range) and of its
        dip below -50 C at the end (uniform).
    """

    regulated_blocks: tuple[int, int] = (3, 24)
    off_blocks: tuple[int, int] = (3, 14)
    duty_percent: tuple[int, int] = (10, 45)
    duty_step_percent: int = 8
    change_probability: float = 0.75
    peak_c: tuple[float, float] = (-45.0, 55.0)
    dip_c: tuple[float, float] = (0.0, 12.0)


@dataclass
class FlightConfig:
    """What to simulate.

    Attributes
    ----------
    start : str
        First day (ISO date, a midnight UTC); after V10 (2007-03-09) so the heater model
        of sec. 6-7 applies.
    days : int
        Number of consecutive whole days of science.
    rate_setting : int
        Table 1 rate setting (6 = 1 vector/s, 10 = 20 vectors/s).
    seed : int
        Seed of the random generator (the whole simulation is a function of it).
    solar_wind : str, RealisticWindModel or SolarWindModel
        ``"realistic"`` (default) or ``"quiet"`` (`WINDS`), or a model.
    heater : HeaterModel
    lead_s : float
        Heater-off lead (at -50 C) before the first day, in the previous day's files.
    temperature_step_s : float
        Spacing of the temperature stream (s).
    rate_changes : list of (seconds, rate_setting)
        Rate setting from these seconds after ``start`` on (after ``rate_setting``).
    coarse_intervals, science_gaps : list of (seconds, seconds)
        Intervals (seconds after ``start``) in coarse range / without science samples.
    heater_gaps, temperature_gaps : list of (seconds, seconds)
        Intervals without heater bits (shorter than a period) / temperatures (< 600 s).
    """

    start: str = "2010-03-01"
    days: int = 7
    rate_setting: int = 6
    seed: int = 13
    solar_wind: str | RealisticWindModel | SolarWindModel = "realistic"
    heater: HeaterModel = field(default_factory=HeaterModel)
    lead_s: float = 2000.0
    temperature_step_s: float = 10.0
    rate_changes: list[tuple[float, int]] = field(default_factory=list)
    coarse_intervals: list[tuple[float, float]] = field(default_factory=list)
    science_gaps: list[tuple[float, float]] = field(default_factory=list)
    heater_gaps: list[tuple[float, float]] = field(default_factory=list)
    temperature_gaps: list[tuple[float, float]] = field(default_factory=list)


@dataclass(frozen=True)
class CalibrationChanges:
    """How the true tables differ from the seed's (factors per axis x, y, z).

    Table 2 keeps its form: ``A0``, ``B0``, ``B1`` scaled, the break temperature
    ``T_m`` moved by ``tm_shift_c`` and ``A1`` following from eq. 4; Table 3's ``C0`` is
    the new Table 2 at -50 C (the seed's constraint) and ``D0`` scaled; tau scaled;
    Tables 6-8 scaled per axis.
    """

    a0: tuple[float, float, float] = (1.3, 0.75, 1.2)
    b0: tuple[float, float, float] = (0.75, 1.25, 0.7)
    b1: tuple[float, float, float] = (1.3, 0.8, 1.35)
    tm_shift_c: tuple[float, float, float] = (-6.0, 5.0, 4.0)
    d0: tuple[float, float, float] = (1.35, 0.7, 1.6)
    tau: float = 0.75
    waveform: tuple[float, float, float] = (1.4, 0.7, 1.3)
    version: int = 2


# --- true calibration tables ---------------------------------------------------------------


def _packaged(name: str) -> Path:
    folder = Path(str(resources.files("fluxcal.missions.messenger") / "data"))
    return folder / f"{name}_v1.{'toml' if name == 'processing' else 'csv'}"


def _rewrite_csv(src: Path, dest: Path, columns: dict[str, list[str]], note: str,
                 version: int) -> None:
    """Copy a packaged CSV table with new column values, version and a provenance note."""
    lines = src.read_text().splitlines()
    header = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    names = body[0].split(",")
    rows = [ln.split(",") for ln in body[1:]]
    for name, values in columns.items():
        j = names.index(name)
        for row, value in zip(rows, values, strict=True):
            row[j] = value
    header = [re.sub(r"^# version: \d+", f"# version: {version}", ln) for ln in header]
    header.insert(2, f"# fluxcal flight simulation TRUTH: {note}")
    atomic_write_bytes(dest, "\n".join(header + [",".join(names)]
                                        + [",".join(r) for r in rows]) + "\n", now=True)


def write_true_calibration(folder: str | Path, changes: CalibrationChanges | None = None
                           ) -> list[Path]:
    """Write the true (altered) calibration tables as a fluxcal calibration folder.

    Every packaged table is copied; Tables 2, 3, 6-8 and the processing constants are
    rewritten with ``changes`` under version ``changes.version``, so that both
    `fluxcal.missions.messenger.forward.read_tables` (the simulator) and
    ``load_calibration(day, folder)`` (the pipeline) read them.

    Returns
    -------
    list of Path
        The table files of the folder (one per table).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3-5, Tables 2-3, 6-8.
    """
    ch = changes or CalibrationChanges()
    out = Path(folder)
    make_folder(out)
    seed = forward.read_tables(None)
    v = ch.version
    paths: list[Path] = []
    # Table 2: the same form, moved break temperature, A1 from eq. 4
    a0 = seed.a0 * np.asarray(ch.a0)
    b0 = seed.b0 * np.asarray(ch.b0)
    b1 = seed.b1 * np.asarray(ch.b1)
    tm = (seed.a0 - seed.a1) / (seed.b1 - seed.b0) + np.asarray(ch.tm_shift_c)
    a1 = a0 - tm * (b1 - b0)
    if not np.all(b1 > b0):
        raise ValueError("altered Table 2 is not convex (B1 <= B0)")
    p = out / f"offsets_temperature_v{v}.csv"
    _rewrite_csv(_packaged("offsets_temperature"), p, {
        "A0": [f"{x:.6f}" for x in a0], "B0": [f"{x:.6f}" for x in b0],
        "A1": [f"{x:.6f}" for x in a1], "B1": [f"{x:.6f}" for x in b1],
        "Tm_c": [f"{x:.6f}" for x in tm]}, f"Table 2 altered by {ch}", v)
    paths.append(p)
    # Table 3: C0 = Table 2 at -50 C, D0 scaled
    c0 = np.maximum(a0 + b0 * REGULATED_C, a1 + b1 * REGULATED_C)
    p = out / f"offsets_duty_cycle_v{v}.csv"
    _rewrite_csv(_packaged("offsets_duty_cycle"), p, {
        "C0": [f"{x:.6f}" for x in c0],
        "D0": [f"{x:.7f}" for x in seed.d0 * np.asarray(ch.d0)]}, "Table 3 altered", v)
    paths.append(p)
    for k, axis in enumerate("xyz"):
        name = f"heater_signal_{axis}"
        cols = {str(int(b)) if float(b).is_integer() else str(b):
                [f"{x:.5f}" for x in seed.heater[k][:, j] * ch.waveform[k]]
                for j, b in enumerate(seed.heater_bins)}
        p = out / f"{name}_v{v}.csv"
        _rewrite_csv(_packaged(name), p, cols, f"values x {ch.waveform[k]}", v)
        paths.append(p)
    text = _packaged("processing").read_text()
    tau = seed.constants["relaxation"]["tau_s"] * ch.tau
    text = re.sub(r"(?m)^version = \d+", f"version = {v}", text)
    text = re.sub(r"(?m)^tau_s = .*$", f"tau_s = {tau:.3f}", text)
    p = out / f"processing_v{v}.toml"
    atomic_write_bytes(p, f"# fluxcal flight simulation TRUTH: tau x {ch.tau}\n" + text, now=True)
    paths.append(p)
    for name in ("latency", "gain_matrix"):
        p = out / _packaged(name).name
        atomic_write_bytes(p, _packaged(name).read_bytes(), now=True)
        paths.append(p)
    return paths


# --- random processes ----------------------------------------------------------------------


def _relaxation(rng: np.random.Generator, n: int, tau_s: float, dims: int = 1,
                order: int = 1) -> np.ndarray:
    """Stationary unit-variance Gaussian process on a 1-s grid, shape (n, dims).

    ``order`` cascaded first-order relaxations (AR(1), ``a = exp(-1/tau)``) of white
    noise, started 6 tau early so the start is stationary; normalised by the closed-form
    variance (1 for one stage, ``(1 + a^2) / (1 - a^2)`` for two).
    """
    a = float(np.exp(-1.0 / tau_s))
    burn = int(6 * tau_s * order) + 1
    x = rng.standard_normal((n + burn, dims))
    for _ in range(order):
        x = lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], x, axis=0)
    if order == 2:
        x /= np.sqrt((1.0 + a * a) / (1.0 - a * a))
    elif order != 1:
        raise ValueError("order must be 1 or 2")
    return x[burn:]


def _sectors(rng: np.random.Generator, n: int, days: tuple[float, float]) -> np.ndarray:
    """Sector polarity +-1 on a 1-s grid: flips after uniform dwell times."""
    lo, hi = days[0] * DAY_S, days[1] * DAY_S
    dwell = rng.uniform(lo, hi, size=int(n / lo) + 3)
    flips = np.cumsum(dwell) - rng.uniform(0.0, dwell[0])
    sign = rng.choice([-1.0, 1.0])
    count = np.searchsorted(flips, np.arange(n), side="right")
    return sign * np.where(count % 2 == 0, 1.0, -1.0)


def solar_wind(rng: np.random.Generator, n: int,
               model: str | SolarWindModel | RealisticWindModel = "realistic") -> np.ndarray:
    """Solar-wind field (nT, sensor axes) on a 1-s grid, shape (n, 3).

    Realistic (`RealisticWindModel`): `fluxcal.missions.solar_wind.alfvenic_wind`.  Quiet
    (`SolarWindModel`): direction ``normalise(s m p + v)``, magnitude a log-normal slow
    part times the compressive factor (see the module docstring).
    """
    model = wind_model(model)
    if isinstance(model, AlfvenicWind):
        return alfvenic_wind(rng, n, model)
    p = np.asarray(model.parker_direction, dtype=float)
    p /= np.linalg.norm(p)
    v = _relaxation(rng, n, model.alfven_correlation_s, dims=3, order=2)
    s = _sectors(rng, n, model.sector_days)
    u = s[:, None] * model.parker_strength * p + v
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    g = _relaxation(rng, n, model.b_correlation_s)[:, 0]
    h = _relaxation(rng, n, model.compressive_correlation_s)[:, 0]
    mag = model.b_median_nt * np.exp(model.b_log_sigma * g) * (
        1.0 + model.compressive_fraction * h)
    return u * mag[:, None]


@dataclass(frozen=True)
class Schedule:
    """Duty cycle (percent) per 1000-s block and the temperature on a 1-s grid."""

    duty_percent: np.ndarray
    temperature_c: np.ndarray


def heater_schedule(rng: np.random.Generator, n_blocks: int, lead_blocks: int,
                    model: HeaterModel) -> Schedule:
    """Draw the controller's duty cycles and the sensor temperature.

    Blocks ``< lead_blocks`` are heater off at -50 C; then regulated and heater-off runs
    alternate (a loop over runs, about one per 6 h, not over samples).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (10-s persistence), sec. 7
       (1000-s evaluation, temperature varies only with the heater off, eq. 2).
    """
    duty = np.zeros(n_blocks, dtype=np.int64)
    n = int(n_blocks * BLOCK_S)
    temp = np.full(n, REGULATED_C)
    k, regulated = lead_blocks, True
    lo, hi = model.duty_percent
    d = int(rng.integers(lo, hi + 1))
    peaks: list[float] = []
    while k < n_blocks:
        if regulated:
            length = int(rng.integers(model.regulated_blocks[0], model.regulated_blocks[1] + 1))
            steps = rng.integers(-model.duty_step_percent, model.duty_step_percent + 1, length)
            steps[rng.random(length) > model.change_probability] = 0
            steps[0] = 0
            seq = np.empty(length, dtype=np.int64)
            for j in range(length):  # a random walk reflected at the range ends
                d = d + int(steps[j])
                d = 2 * hi - d if d > hi else (2 * lo - d if d < lo else d)
                seq[j] = d
            duty[k:k + length] = seq[: max(0, min(length, n_blocks - k))]
        else:
            length = int(rng.integers(model.off_blocks[0], model.off_blocks[1] + 1))
            a, b = int(k * BLOCK_S), int(min(n_blocks, k + length) * BLOCK_S)
            x = (np.arange(a, b) - a) / float(length * BLOCK_S)
            if not peaks:  # stratified: every group of excursions spans the range
                strata = rng.permutation(PEAK_STRATA) + rng.random(PEAK_STRATA)
                peaks = list(model.peak_c[0] + np.diff(model.peak_c)[0] * strata / PEAK_STRATA)
            peak = peaks.pop() - REGULATED_C
            dip = rng.uniform(*model.dip_c)
            rise = REGULATED_C + peak * np.sin(np.pi * np.minimum(x / 0.8, 1.0)) ** 2
            fall = REGULATED_C - dip * np.sin(np.pi * np.clip((x - 0.8) / 0.2, 0, 1)) ** 2
            temp[a:b] = np.where(x < 0.8, rise, fall)
            d = int(rng.integers(lo, hi + 1))  # the level the heater resumes at
        k += length
        regulated = not regulated
    return Schedule(duty, temp)


# --- the instrument ---------------------------------------------------------------------------


@dataclass
class FlightRun:
    """What `simulate_flight` wrote.

    Attributes
    ----------
    input_dir : Path
        The batch input folder (``MAG*_YYYYDDD.csv``, ``kernels.tm``, ``truth/``).
    calibration_dir : Path
        The true calibration tables (fluxcal format).
    days : list of datetime.date
        Days with science.
    n_samples : int
        Science samples written.
    duty_percent : ndarray
        Commanded duty cycle per 1000-s block from the schedule origin.
    origin_met : float
        MET (partition 1 or 2 as of the start) of the schedule origin (block 0).
    """

    input_dir: Path
    calibration_dir: Path
    days: list[_dt.date]
    n_samples: int
    duty_percent: np.ndarray
    origin_met: float


def _intervals_mask(x: np.ndarray, intervals: list[tuple[float, float]]) -> np.ndarray:
    inside = np.zeros(x.shape, dtype=bool)
    for a, b in intervals:
        inside |= (x >= a) & (x < b)
    return inside


def _write(path: Path, header: str, columns: list[np.ndarray]) -> None:
    """Write CSV columns fast (Arrow's C writer).

    Integers as such, floats as the shortest text that reads back to the same float64
    (MET and temperatures stay exact).
    """
    table = pa.table(dict(zip(header.split(","), columns, strict=True)))
    with atomic_path(path, now=True) as tmp, tmp.open("wb") as fh:
        fh.write((header + "\n").encode())
        pacsv.write_csv(table, fh, write_options=pacsv.WriteOptions(include_header=False))


def _day_samples(met_a: float, met_b: float, t0_met: float, config: FlightConfig,
                 hz_of: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return recorded MET and rate setting of the samples recorded in [met_a, met_b)."""
    bounds = [(0.0, config.rate_setting)] + sorted(config.rate_changes)
    mets, rates = [], []
    for j, (s0, rate) in enumerate(bounds):
        s1 = bounds[j + 1][0] if j + 1 < len(bounds) else np.inf
        a, b = max(met_a, t0_met + s0), min(met_b, t0_met + s1)
        if b <= a:
            continue
        hz = float(hz_of[rate])
        k = np.arange(np.ceil(a * hz - 1e-9), np.ceil(b * hz - 1e-9))
        mets.append(np.round(k / hz, 6))
        rates.append(np.full(k.size, rate, dtype=np.int64))
    if not mets:
        return np.empty(0), np.empty(0, dtype=np.int64)
    return np.concatenate(mets), np.concatenate(rates)


def simulate_flight(out_dir: str | Path, config: FlightConfig | None = None,
                    changes: CalibrationChanges | None = None, *, truth: bool = True,
                    wind: Callable[[np.random.Generator, int], np.ndarray] | None = None,
                    schedule: Callable[[np.random.Generator, int, int], Schedule] | None = None,
                    ) -> FlightRun:
    """Simulate ``config.days`` days of cruise solar wind into a batch input folder.

    Writes ``out_dir/calibration`` (the true tables, `write_true_calibration`),
    ``out_dir/input`` with ``kernels/`` (synthetic MESSENGER-like set), ``kernels.tm``,
    ``MAGSCI/MAGHTR/MAGTMP_YYYYDDD.csv`` per UTC day of the recorded MET (heater and
    temperature lead in the previous day's files) and, with ``truth``,
    ``truth/MAGTRUTH_YYYYDDD.npz`` (`read_flight_truth`): recorded ``met``, ``range``,
    ``b_sensor`` (nT, sensor axes), ``zero_level`` (fine counts: Table 2 + relaxed
    duty-cycle offset + heater waveform), ``temperature_c`` and ``duty_percent``.

    Parameters
    ----------
    out_dir : path
        Folder to write (created).
    config : FlightConfig, optional
    changes : CalibrationChanges, optional
        The true tables' differences from the seed (default `CalibrationChanges()`).
    truth : bool
        Write the truth files.
    wind : callable, optional
        ``wind(rng, n)`` -> field (nT, sensor axes) on the 1-s grid, shape (n, 3), used
        instead of `solar_wind` with ``config.solar_wind`` (e.g. an independent
        solar-wind model written elsewhere); the noise of ``config.solar_wind`` still adds.
    schedule : callable, optional
        ``schedule(rng, n_blocks, lead_blocks)`` -> `Schedule` (duty cycle per 1000-s block
        from the schedule origin, temperature on its 1-s grid; heater off at -50 C before
        ``lead_blocks``), used instead of `heater_schedule` with ``config.heater`` (e.g.
        an orbit's heater schedule written elsewhere, issue 34).

    Returns
    -------
    FlightRun

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 (net lag), sec. 6 (waveform
       from the bit's rising edge), sec. 7 (eq. 2-5, relaxation), sec. 8 (eq. 8).
    """
    config = config or FlightConfig()
    wind_stats = wind_model(config.solar_wind)
    out = Path(out_dir)
    cal_dir = out / "calibration"
    tables = forward.read_tables(write_true_calibration(cal_dir, changes))
    inp = out / "input"
    make_folder(inp)
    first = _dt.date.fromisoformat(config.start)
    start_utc = f"{first}T00:00:00"
    span = config.days * DAY_S
    mk = write_messenger_like_kernels(inp / "kernels", start_utc, span + config.lead_s,
                                      attitude_step=60.0, margin_s=config.lead_s + 3600.0)
    write_meta_kernel(inp / "kernels.tm", sorted(p for p in mk.parent.iterdir()
                                                 if p.suffix != ".tm"))
    rng = np.random.default_rng(config.seed)
    heater_c = tables.constants["heater"]
    min_on = float(heater_c["min_on_s"])
    days = [first + _dt.timedelta(days=k) for k in range(-1, config.days + 1)]
    with KernelPool(mk, frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        edges_et = utc_to_et(np.array([f"{d}T00:00:00" for d in days]))
        parts, edges_met = sclk.from_et(edges_et)
        if np.any(parts != parts[0]):
            raise ValueError("the simulated span crosses the SCLK partition change")
        partition = int(parts[0])
        t0_met = float(edges_met[1])  # recorded MET of the first midnight
        origin = float(np.floor(t0_met)) - config.lead_s  # schedule origin (block 0)
        n = int(edges_met[-1] - origin + 4 * BLOCK_S)
        n_blocks = n // int(BLOCK_S) + 1
        lead_blocks = int(np.ceil(config.lead_s / BLOCK_S))
        sched = (heater_schedule(rng, n_blocks, lead_blocks, config.heater) if schedule is None
                 else schedule(rng, n_blocks, lead_blocks))
        field_grid = (solar_wind(rng, sched.temperature_c.size, wind_stats)
                      if wind is None else np.asarray(wind(rng, sched.temperature_c.size),
                                                      dtype=float))
        grid = np.arange(sched.temperature_c.size, dtype=float)  # seconds since origin
        duty_grid = sched.duty_percent[(grid // BLOCK_S).astype(np.int64)]
        delta = forward.relaxed_duty_offset(grid, 10.0 * duty_grid, tables)
        # --- heater bits and temperatures: one stream over the whole span -----------------
        h_u = np.arange(-QUIET_LEAD_S, edges_met[-1] - origin, 1.0)
        bits = ((np.mod(h_u, PERIOD_S) < duty_grid[np.maximum(h_u, 0).astype(np.int64)])
                & (h_u >= 0)).astype(np.int64)
        keep_h = ~_intervals_mask(h_u - (t0_met - origin), config.heater_gaps)
        t_u = np.arange(0.0, edges_met[-1] - origin, config.temperature_step_s)
        t_val = np.round(np.interp(t_u, grid, sched.temperature_c), 4)
        keep_t = ~_intervals_mask(t_u - (t0_met - origin), config.temperature_gaps)
        h_met, t_met = origin + h_u[keep_h], origin + t_u[keep_t]
        bits, t_val = bits[keep_h], t_val[keep_t]
        written: list[_dt.date] = []
        total = 0
        for k, day in enumerate(days[:-1]):
            met_a, met_b = float(edges_met[k]), float(edges_met[k + 1])
            stem = f"{day:%Y%j}"
            for code, met, col, head in (
                ("HTR", h_met.astype(np.int64), bits, "partition,met,heater"),
                ("TMP", t_met, t_val, "partition,met,temperature_c"),
            ):
                sel = (met >= met_a) & (met < met_b)
                if sel.any():
                    _write(inp / f"MAG{code}_{stem}.csv", head,
                           [np.full(sel.sum(), partition), met[sel], col[sel]])
            if k == 0:
                continue
            met_rec, rate = _day_samples(met_a, met_b, t0_met, config, tables.sample_rate_hz)
            rel = met_rec - t0_met
            keep = ~_intervals_mask(rel, config.science_gaps)
            met_rec, rate, rel = met_rec[keep], rate[keep], rel[keep]
            if met_rec.size == 0:
                continue
            rng_flag = _intervals_mask(rel, config.coarse_intervals).astype(np.int64)
            u = met_rec - tables.net_lag_s[rate] - origin  # true time since the origin
            b = np.column_stack([np.interp(u, grid, field_grid[:, j]) for j in range(3)])
            if wind_stats.noise_nt > 0:
                b += wind_stats.noise_nt * rng.standard_normal(b.shape)
            temp = np.interp(u, grid, sched.temperature_c)
            zero = forward.temperature_offset(temp, tables)
            for j in range(3):
                zero[:, j] += np.interp(u, grid, delta[:, j])
            d_sample = sched.duty_percent[(u // BLOCK_S).astype(np.int64)]
            powered = (d_sample >= min_on) & (d_sample < 100) & (u >= 0)
            if powered.any():
                zero[powered] += forward.heater_waveform(np.mod(u[powered], PERIOD_S),
                                                         d_sample[powered], tables)
            counts = np.rint(forward.counts_from_field(b, zero, rng_flag, tables))
            if counts.min() < -32768 or counts.max() > 32767:
                raise ValueError(f"{day}: simulated counts exceed the 16-bit limits")
            counts = counts.astype(np.int64)
            _write(inp / f"MAGSCI_{stem}.csv", "partition,met,rate,range,cx,cy,cz",
                   [np.full(met_rec.size, partition), met_rec, rate, rng_flag,
                    counts[:, 0], counts[:, 1], counts[:, 2]])
            if truth:
                make_folder(inp / "truth")
                with atomic_path(inp / "truth" / f"MAGTRUTH_{stem}.npz", now=True) as tmp:
                    np.savez(tmp, met=met_rec, range=rng_flag, b_sensor=b, zero_level=zero,
                             temperature_c=temp, duty_percent=d_sample)
            written.append(day)
            total += met_rec.size
    return FlightRun(inp, cal_dir, written, total, sched.duty_percent, origin)


def read_flight_truth(input_dir: str | Path, day: _dt.date) -> dict[str, np.ndarray]:
    """Read the truth of ``day`` written by `simulate_flight` (arrays by name)."""
    with np.load(Path(input_dir) / "truth" / f"MAGTRUTH_{day:%Y%j}.npz") as data:
        return {k: data[k] for k in data.files}
