"""Forward model: raw MESSENGER MAG telemetry from a known magnetic field.

The instrument is run forward, from the seed and its tables only (no pipeline code; see
`fluxcal.missions.messenger.forward` and ``tests/missions/test_forward_independence.py``):

1. a declarative schedule: duty cycle per 1000-s block (the V10 controller's evaluation
   interval, sec. 7) gives the 1-s heater bits (on for the first ``d`` s of every 100-s
   period); the sensor temperature is -50 C while the heater regulates and rises over
   heater-off runs (before V10: 22.4 C in sunlight, -50 C in shadow, a fixed value stowed);
2. a known field in MSO (offset dipole, interplanetary field, waves) at the true sample
   times, rotated into the sensor frame with SPICE; the interplanetary field is by
   default the realistic solar wind of `fluxcal.missions.solar_wind` (18 nT, Alfvenic
   rotations with an f^-5/3 spectrum, 3 % compressive, about the direction of
   ``imf_nt``), or ``solar_wind="quiet"`` the uniform ``imf_nt`` (issue 21);
3. the zero level: Table 2 at the true temperature, plus (from V10) the duty-cycle offset
   relaxing by explicit time stepping and the heater waveform of Tables 6-8 in powered
   periods (sec. 6, 7);
4. counts by solving eq. 8 of the sample's range, rounded to integers;
5. recorded MET = true MET + the Table 1 net lag of the rate setting (sec. 5, forward).

`simulate` is a pure function of its configuration, the tables and the loaded kernels;
`write_inputs` writes the three CSV streams and the truth side file.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-11.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from fluxcal.geometry.frames import rotate
from fluxcal.geometry.positions import position
from fluxcal.geometry.time import et_to_tt2000, utc_to_et
from fluxcal.missions.messenger import forward
from fluxcal.missions.solar_wind import AlfvenicWind, alfvenic_wind
from fluxcal.products.atomic import atomic_path
from fluxcal.products.paths import make_folder

if TYPE_CHECKING:
    from fluxcal.geometry.time import SclkKernel
    from fluxcal.missions.messenger.calibration_data import MessengerCalibration

#: Mercury's offset dipole: equatorial surface field (nT), radius (km), northward
#: offset (km).  Anderson et al. (2011) values, rounded.
MERCURY_DIPOLE_NT = 195.0
MERCURY_RADIUS_KM = 2440.0
DIPOLE_OFFSET_KM = 480.0
#: Heater-off seconds at the start of the simulated heater stream (> one heater period,
#: so the quiet start is visible in the bits).
QUIET_LEAD_S = 110.0
#: Signed 16-bit count limits of the EDR counts.
COUNT_LIMITS = (-32768, 32767)


@dataclass
class SimulationConfig:
    """What to simulate.

    Attributes
    ----------
    start_utc : str
        Start (ISO UTC) of the science interval.
    duration_s : float
        Length of the science interval (s).
    rate_segments : list of (fraction, rate_setting)
        Rate setting in force from ``fraction`` of the interval on.
    coarse_intervals : list of (fraction, fraction)
        Intervals in coarse range (range flag 1).
    duty_cycles_percent : list of int
        Heater duty cycle (percent) of each consecutive 1000-s block, repeated as needed.
    block_s : float
        Length of a duty-cycle block (1000 s: the V10 controller's interval).
    lead_s : float
        Heater and temperature data start this long before the science (look-back).
    temperature_step_s : float
        Spacing of the temperature samples (s).
    excursion_c : float
        Peak temperature rise above -50 C in a block run with the heater off.
    imf_nt : tuple of float
        Interplanetary field (MSO, nT): added as it is with ``solar_wind="quiet"``; its
        direction is the mean direction of the realistic wind (zero: no interplanetary
        field in either).
    solar_wind : {"realistic", "quiet"}
        ``realistic`` (default): the interplanetary field is
        `fluxcal.missions.solar_wind.alfvenic_wind` (18 nT log-normal, Alfvenic rotations
        dB/B ~ 0.55 with an f^-5/3 spectrum from 12 h to 2 s, 3 % compressive, sectors of
        1-3 days) about the direction of ``imf_nt``; ``quiet``: the uniform ``imf_nt``.
    seed : int
        Seed of the realistic wind (with the start time: each day its own wind).
    waves : list of (amplitude_nT, period_s)
        Circularly polarised waves in the MSO Y-Z plane.
    science_windows : list of (start_s, end_s), optional
        Keep science samples only inside these intervals (seconds after ``start_utc``);
        the heater and temperature streams stay continuous (short simulated days).
    sunlit_temperature_c, shadow_temperature_c, stowed_temperature_c : float
        Sensor temperature before V10 (2007-03-09): deployed in sunlight (sec. 7: mean
        22.4 C), deployed in shadow (V9 regulation at -50 C), stowed (not in the seed).
    jitter_every : int
        If > 0, every ``jitter_every``-th heater period has its on-time in the bits
        lengthened and shortened by 1 s in turn (the 1-s command iteration, sec. 6); the
        commanded duty cycle, hence the physics, is the block's.
    heater_gaps : list of (start_s, end_s)
        Heater records dropped in these intervals (seconds after the heater schedule start,
        i.e. ``lead_s`` before ``start_utc``): LAC gaps.
    """

    start_utc: str = "2012-06-01T00:00:00"
    duration_s: float = 7200.0
    rate_segments: list[tuple[float, int]] = field(
        default_factory=lambda: [(0.0, 10), (0.45, 8), (0.55, 6), (0.62, 9), (0.7, 10)]
    )
    coarse_intervals: list[tuple[float, float]] = field(default_factory=lambda: [(0.3, 0.38)])
    duty_cycles_percent: list[int] = field(
        default_factory=lambda: [40, 36, 0, 0, 0, 25, 8, 44, 30, 17, 40, 21]
    )
    block_s: float = 1000.0
    lead_s: float = 1200.0
    temperature_step_s: float = 10.0
    excursion_c: float = 55.0
    imf_nt: tuple[float, float, float] = (12.0, -8.0, 5.0)
    solar_wind: str = "realistic"
    seed: int = 0
    waves: list[tuple[float, float]] = field(default_factory=lambda: [(3.0, 2.0), (1.0, 0.31)])
    science_windows: list[tuple[float, float]] | None = None
    sunlit_temperature_c: float = 22.4
    shadow_temperature_c: float = -50.0
    stowed_temperature_c: float = 0.0
    jitter_every: int = 0
    heater_gaps: list[tuple[float, float]] = field(default_factory=list)


def mercury_field_mso(pos_mso_km: np.ndarray, config: SimulationConfig,
                      imf: np.ndarray | None = None) -> np.ndarray:
    """Offset-dipole Mercury field plus the interplanetary field (nT) at MSO positions (km).

    ``imf``: the interplanetary field per position, (n, 3); None: the uniform
    ``config.imf_nt``.
    """
    r = pos_mso_km - np.array([0.0, 0.0, DIPOLE_OFFSET_KM])
    rn = np.linalg.norm(r, axis=1)[:, None]
    rhat = r / rn
    m = np.array([0.0, 0.0, -1.0])  # southward moment: field points north at the equator
    m_dot_r = (rhat * m).sum(axis=1, keepdims=True)
    b = MERCURY_DIPOLE_NT * (MERCURY_RADIUS_KM / rn) ** 3 * (3 * m_dot_r * rhat - m)
    return b + (np.asarray(config.imf_nt) if imf is None else imf)


#: The interplanetary fields `SimulationConfig.solar_wind` names.
SOLAR_WINDS = ("realistic", "quiet")


def interplanetary_field(t: np.ndarray, et_start: float, config: SimulationConfig
                         ) -> np.ndarray:
    """Interplanetary field (MSO, nT) at ``t`` seconds after the start, shape (n, 3).

    ``quiet``: the uniform ``imf_nt``.  ``realistic``: `alfvenic_wind` on a 1-s grid over
    the samples' span (mean direction along ``imf_nt``, generator seeded with ``seed`` and
    the start's whole ET second), linearly interpolated to ``t``.

    Raises
    ------
    ValueError
        ``solar_wind`` not in `SOLAR_WINDS`.
    """
    if config.solar_wind not in SOLAR_WINDS:
        raise ValueError(f"solar_wind {config.solar_wind!r}: choose one of "
                         f"{', '.join(SOLAR_WINDS)}")
    t = np.asarray(t, dtype=float)
    imf = np.asarray(config.imf_nt, dtype=float)
    if config.solar_wind == "quiet" or t.size == 0 or not np.any(imf):
        return np.broadcast_to(imf, (t.size, 3)).copy()
    t0 = np.floor(t.min()) - 1.0
    grid = t0 + np.arange(int(np.ceil(t.max() - t0)) + 2, dtype=float)
    rng = np.random.default_rng([config.seed, int(np.floor(et_start)) & 0x7FFFFFFF])
    wind = alfvenic_wind(rng, grid.size, AlfvenicWind(mean_direction=tuple(imf)))
    return np.column_stack([np.interp(t, grid, wind[:, j]) for j in range(3)])


def _waves(t: np.ndarray, config: SimulationConfig) -> np.ndarray:
    out = np.zeros((t.size, 3))
    for amp, per in config.waves:
        w = 2 * np.pi * t / per
        out[:, 1] += amp * np.cos(w)
        out[:, 2] += amp * np.sin(w)
    return out


def _block_duty(u: np.ndarray, config: SimulationConfig) -> np.ndarray:
    """Duty cycle (percent) commanded at ``u`` seconds after the heater schedule starts."""
    d = np.asarray(config.duty_cycles_percent, dtype=int)
    block = np.floor(np.asarray(u, dtype=float) / config.block_s).astype(np.int64)
    return np.where(block >= 0, d[np.mod(np.maximum(block, 0), d.size)], 0)


def _on_time(u: np.ndarray, config: SimulationConfig, tables: forward.SeedTables) -> np.ndarray:
    """Return the heater-on seconds of the 100-s period containing each ``u`` (the bits).

    The block's duty cycle, with the ``jitter_every`` +-1 s alternation of the bits.
    """
    period = float(tables.constants["heater"]["period_s"])
    duty = _block_duty(u, config)
    on_s = duty.astype(float)
    if config.jitter_every > 0:
        p = np.floor(np.asarray(u, dtype=float) / period).astype(np.int64)
        jitter = (np.mod(p, config.jitter_every) == config.jitter_every - 1) & (
            duty > tables.constants["heater"]["min_on_s"]) & (duty < 100)
        on_s += np.where(jitter, np.where(np.mod(p // config.jitter_every, 2) == 0, 1, -1), 0)
    return on_s


def _regulated_temperature(u: np.ndarray, config: SimulationConfig) -> np.ndarray:
    """-50 C while the heater regulates; a sin^2 excursion over each heater-off run."""
    u = np.asarray(u, dtype=float)
    n_blocks = int(np.ceil(max(u.max(initial=0.0), 0.0) / config.block_s)) + 2
    off = _block_duty(np.arange(n_blocks) * config.block_s, config) == 0
    edges = np.diff(np.concatenate([[0], off.astype(int), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    temp = np.full(u.shape, -50.0)
    for a, b in zip(starts * config.block_s, ends * config.block_s, strict=True):
        inside = (u >= a) & (u < b)
        temp[inside] += config.excursion_c * np.sin(np.pi * (u[inside] - a) / (b - a)) ** 2
    return temp


def _sunlit(et: np.ndarray) -> np.ndarray:
    """Sensor side sunlit: the Sun has a positive +Y component in MSGR_SPACECRAFT."""
    sun = rotate(position("SUN", "MESSENGER", "J2000", et), et, "J2000", "MSGR_SPACECRAFT")
    return sun[:, 1] > 0


def _temperature(
    u: np.ndarray, et: np.ndarray, config: SimulationConfig, tables: forward.SeedTables,
    et_of: dict[str, float],
) -> np.ndarray:
    """Return the true sensor temperature (degC) at schedule seconds ``u`` (ET ``et``)."""
    temp = _regulated_temperature(u, config)
    early = et < et_of["heater_mode_v10"]
    if early.any():
        sun = _sunlit(et[early])
        t_early = np.where(sun, config.sunlit_temperature_c, config.shadow_temperature_c)
        stowed = et[early] < et_of["boom_deployment"]
        temp[early] = np.where(stowed, config.stowed_temperature_c, t_early)
    return temp


def _sample_grid(
    config: SimulationConfig, met0: float, tables: forward.SeedTables
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return recorded MET, rate setting and range flag of every science sample."""
    met_parts, rate_parts = [], []
    bounds = [f for f, _ in config.rate_segments] + [1.0]
    for (frac, rate), end in zip(config.rate_segments, bounds[1:], strict=True):
        hz = tables.sample_rate_hz[rate]
        a = met0 + frac * config.duration_s
        b = met0 + end * config.duration_s
        # whole multiples of the sample period, each divided once: exactly on the grid
        # (np.arange's accumulated step left 1-us jitter after rounding at MET ~ 2.5e8 s)
        grid = np.arange(np.ceil(a * hz), np.ceil(b * hz)) / hz
        met_parts.append(grid)
        rate_parts.append(np.full(grid.size, rate, dtype=np.int8))
    met_rec = np.round(np.concatenate(met_parts), 6)
    rate = np.concatenate(rate_parts)
    if config.science_windows is not None:
        rel = met_rec - met0
        keep = np.zeros(met_rec.size, dtype=bool)
        for a, b in config.science_windows:
            keep |= (rel >= a) & (rel < b)
        met_rec, rate = met_rec[keep], rate[keep]
    rng = np.zeros(met_rec.size, dtype=np.int8)
    for a, b in config.coarse_intervals:
        lo, hi = met0 + a * config.duration_s, met0 + b * config.duration_s
        rng[(met_rec >= lo) & (met_rec < hi)] = 1
    return met_rec, rate, rng


def simulate(
    config: SimulationConfig, cal: MessengerCalibration | None, sclk: SclkKernel
) -> dict[str, xr.Dataset]:
    """Simulate raw science, heater and temperature streams and their truth.

    Kernels (the synthetic MESSENGER-like set) must be loaded.

    Parameters
    ----------
    config : SimulationConfig
    cal : MessengerCalibration or None
        Only its ``paths`` are used: the forward model reads those table files itself
        (`fluxcal.missions.messenger.forward.read_tables`); None reads the packaged v1.
    sclk : fluxcal.geometry.time.SclkKernel
        MESSENGER clock (-236).

    Returns
    -------
    dict
        ``"science"``, ``"heater"``, ``"temperature"`` (the raw streams, as the readers
        return them) and ``"truth"`` (``b_mso``, ``b_sensor``, ``offset`` (Table 2 +
        duty-cycle offset, fine counts), ``heater_signal`` (fine counts), ``temperature``
        per sample, coordinate ``epoch``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-8 (forward).
    """
    tables = forward.read_tables(None if cal is None or not cal.paths else cal.paths)
    et_of = {k: float(utc_to_et(np.array([str(tables.date(k))]))[0])
             for k in ("boom_deployment", "heater_mode_v10")}
    et_start = float(utc_to_et(np.array([config.start_utc]))[0])
    part_arr, met_arr = sclk.from_et(np.array([et_start]))
    partition = int(part_arr[0])
    met0 = float(np.ceil(met_arr[0]))  # first whole MET second at or after the start
    # --- heater schedule: 1-s bits, on for the first d seconds of each 100-s period -----
    period = float(tables.constants["heater"]["period_s"])
    h_zero = met0 - config.lead_s
    h_met = np.arange(h_zero - QUIET_LEAD_S, met0 + config.duration_s + 200.0, 1.0)
    u_h = h_met - h_zero
    bits = ((np.mod(u_h, period) < _on_time(u_h, config, tables)) & (u_h >= 0)).astype(np.int8)
    kept = np.ones(h_met.size, dtype=bool)
    for a, b in config.heater_gaps:
        kept &= ~((u_h >= a) & (u_h < b))
    h_met, bits = h_met[kept], bits[kept]
    # --- science samples at their true times (recorded MET minus the net lag, sec. 5) ---
    met_rec, rate, rng = _sample_grid(config, met0, tables)
    met_true = met_rec - tables.net_lag_s[rate]
    part = np.full(met_rec.size, partition, dtype=np.int8)
    et = sclk.to_et(part, met_true)
    u = met_true - h_zero
    # --- temperatures ------------------------------------------------------------------
    t_met = np.arange(h_met[0], h_met[-1] + 1, config.temperature_step_s)
    t_et = sclk.to_et(np.full(t_met.size, partition), t_met)
    t_stream = np.round(_temperature(t_met - h_zero, t_et, config, tables, et_of), 4)
    temp_true = _temperature(u, et, config, tables, et_of)
    # --- truth field ---------------------------------------------------------------------
    pos = position("MESSENGER", "MERCURY", "MSGR_MSO", et)
    imf = (None if config.solar_wind == "quiet"
           else interplanetary_field(et - et_start, et_start, config))
    b_mso = mercury_field_mso(pos, config, imf) + _waves(et - et_start, config)
    deployed = et >= et_of["boom_deployment"]
    b_sensor = np.empty_like(b_mso)
    for frame, sel in (("MSGR_MAG", deployed), ("MSGR_MAG_STOWED", ~deployed)):
        if sel.any():
            b_sensor[sel] = rotate(b_mso[sel], et[sel], "MSGR_MSO", frame)
    # --- zero level (fine counts): Table 2 + duty-cycle relaxation + heater waveform ----
    v10 = et >= et_of["heater_mode_v10"]
    offset = forward.temperature_offset(temp_true, tables)
    grid = np.arange(u_h[0], u_h[-1] + 1.0, 1.0)
    duty_ppt = 10.0 * _block_duty(grid, config) * (grid >= 0)
    delta = forward.relaxed_duty_offset(grid, duty_ppt, tables)
    for axis in range(3):
        offset[:, axis] += np.where(v10, np.interp(u, grid, delta[:, axis]), 0.0)
    since_edge = np.mod(u, period)
    d_sample = _on_time(u, config, tables)  # the period's actual duty cycle (sec. 6)
    # the waveform belongs to the 100-s on/off cycle: none below the 10-s persistence (the
    # spacecraft ignores the request, sec. 6) and none at 100 % (no cycle, no rising edge)
    powered = (v10 & (u >= 0) & (d_sample >= tables.constants["heater"]["min_on_s"])
               & (d_sample < 100))
    heater = np.zeros((et.size, 3))
    if powered.any():
        heater[powered] = forward.heater_waveform(since_edge[powered], d_sample[powered], tables)
    counts = np.rint(forward.counts_from_field(b_sensor, offset + heater, rng, tables))
    if counts.min() < COUNT_LIMITS[0] or counts.max() > COUNT_LIMITS[1]:
        raise ValueError("simulated counts exceed the 16-bit limits; reduce the field")
    comp = {"component": ["x", "y", "z"]}
    science = xr.Dataset(
        {
            "partition": ("time", part, {"units": "1"}),
            "met": ("time", met_rec, {"units": "s"}),
            "rate": ("time", rate, {"units": "1"}),
            "range": ("time", rng, {"units": "1"}),
            "counts": (("time", "component"), counts.astype(np.int32), {"units": "counts"}),
        },
        coords=comp,
    )
    heater_ds = xr.Dataset(
        {
            "partition": ("heater_time", np.full(h_met.size, partition, dtype=np.int8)),
            "met": ("heater_time", h_met, {"units": "s"}),
            "heater": ("heater_time", bits, {"units": "1"}),
        }
    )
    temp_ds = xr.Dataset(
        {
            "partition": ("temperature_time", np.full(t_met.size, partition, dtype=np.int8)),
            "met": ("temperature_time", t_met, {"units": "s"}),
            "temperature_c": ("temperature_time", t_stream, {"units": "degC"}),
        }
    )
    vec = ("time", "component")
    truth = xr.Dataset(
        {
            "et": ("time", et, {"units": "s"}),
            "range": ("time", rng, {"units": "1"}),
            "b_mso": (vec, b_mso, {"units": "nT"}),
            "b_sensor": (vec, b_sensor, {"units": "nT"}),
            "offset": (vec, offset, {"units": "counts"}),
            "heater_signal": (vec, heater, {"units": "counts"}),
            "temperature": ("time", temp_true, {"units": "degC"}),
        },
        coords={"epoch": ("time", et_to_tt2000(et), {"units": "ns"}), **comp},
        attrs={"description": "fluxcal MESSENGER forward-model truth",
               "start_utc": config.start_utc},
    )
    return {"science": science, "heater": heater_ds, "temperature": temp_ds, "truth": truth}


def _write_csv(path: Path, header: str, columns: list[np.ndarray], fmts: list[str]) -> None:
    with atomic_path(path, now=True) as tmp, tmp.open("w") as fh:
        fh.write(header + "\n")
        # format column-wise with numpy to keep exact fixed-point text
        cols = [np.char.mod(f, c) for f, c in zip(fmts, columns, strict=True)]
        lines = cols[0]
        for c in cols[1:]:
            lines = np.char.add(np.char.add(lines, ","), c)
        fh.write("\n".join(lines.tolist()))
        fh.write("\n")


def write_inputs(sim: dict[str, xr.Dataset], out_dir: str | Path, stem: str = "MAG") -> dict:
    """Write the simulated streams as CSV (science, heater, temperature) and the truth.

    Returns
    -------
    dict
        Paths keyed ``"science"``, ``"heater"``, ``"temperature"``, ``"truth"``.
    """
    out = Path(out_dir)
    make_folder(out)
    s, h, t, tr = sim["science"], sim["heater"], sim["temperature"], sim["truth"]
    paths = {k: out / f"{stem}_{k}.csv" for k in ("science", "heater", "temperature", "truth")}
    c = s["counts"].values
    _write_csv(paths["science"], "partition,met,rate,range,cx,cy,cz",
               [s["partition"].values, s["met"].values, s["rate"].values, s["range"].values,
                c[:, 0], c[:, 1], c[:, 2]], ["%d", "%.6f", "%d", "%d", "%d", "%d", "%d"])
    _write_csv(paths["heater"], "partition,met,heater",
               [h["partition"].values, h["met"].values, h["heater"].values], ["%d", "%.0f", "%d"])
    _write_csv(paths["temperature"], "partition,met,temperature_c",
               [t["partition"].values, t["met"].values, t["temperature_c"].values],
               ["%d", "%.3f", "%.4f"])
    b = tr["b_mso"].values
    _write_csv(paths["truth"], "epoch_tt2000,et,range,bx_mso,by_mso,bz_mso",
               [tr["epoch"].values, tr["et"].values, tr["range"].values, b[:, 0], b[:, 1], b[:, 2]],
               ["%d", "%.6f", "%d", "%.6f", "%.6f", "%.6f"])
    return paths


def read_truth(path: str | Path) -> xr.Dataset:
    """Read the truth side file written by `write_inputs`."""
    data = np.loadtxt(path, delimiter=",", skiprows=1, dtype=float, ndmin=2)
    epoch = np.loadtxt(path, delimiter=",", skiprows=1, usecols=0, dtype=np.int64, ndmin=1)
    return xr.Dataset(
        {
            "et": ("time", data[:, 1], {"units": "s"}),
            "range": ("time", data[:, 2].astype(np.int8), {"units": "1"}),
            "b_mso": (("time", "component"), data[:, 3:6], {"units": "nT"}),
        },
        coords={"epoch": ("time", epoch, {"units": "ns"}), "component": ["x", "y", "z"]},
    )
