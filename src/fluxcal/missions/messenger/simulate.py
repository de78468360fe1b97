"""Forward model: raw MESSENGER MAG telemetry from a known magnetic field.

Every processing step of seed 000 is run in reverse: a known field in MSO (an offset
dipole for Mercury plus an interplanetary field and waves) is rotated into the sensor
frame, converted to counts with the inverse eq. 8 matrices of the sample's range, the
thermal offsets (two-segment temperature line plus the duty-cycle offsets relaxing as in
eq. 6a-6f) and the heater waveform (Tables 6-8) are added, the samples are time-tagged
late by the Table 1 net lag and quantised to integer counts.  The heater schedule and the
temperatures are built from a declarative schedule (duty cycle per 1000-s block), not
from the pipeline's own heater-bit analysis, so the round trip also tests that analysis.

`simulate` is a pure function of its configuration, the calibration and the loaded
kernels; `write_inputs` writes the three CSV streams and the truth side file.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-11.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.calibration.gain_matrix import nt_to_counts, range_conversion
from fluxcal.calibration.heater_signal import heater_waveform
from fluxcal.calibration.rate_latency import per_sample_lag
from fluxcal.calibration.relaxation import DutyCycleChanges
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.readers import COUNT_LIMITS

#: Mercury's offset dipole: equatorial surface field (nT), radius (km), northward
#: offset (km).  Anderson et al. (2011) values, rounded.
MERCURY_DIPOLE_NT = 195.0
MERCURY_RADIUS_KM = 2440.0
DIPOLE_OFFSET_KM = 480.0
#: Heater-off seconds at the start of the simulated heater stream (> one heater period,
#: so the quiet start is visible; see `fluxcal.calibration.relaxation.duty_cycle_changes`).
QUIET_LEAD_S = 110.0


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
        Uniform interplanetary field added (MSO, nT).
    waves : list of (amplitude_nT, period_s)
        Circularly polarised waves in the MSO Y-Z plane.
    science_windows : list of (start_s, end_s), optional
        Keep science samples only inside these intervals (seconds after ``start_utc``);
        the heater and temperature streams stay continuous (short simulated days).
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
    waves: list[tuple[float, float]] = field(default_factory=lambda: [(3.0, 2.0), (1.0, 0.31)])
    science_windows: list[tuple[float, float]] | None = None


def mercury_field_mso(pos_mso_km: np.ndarray, config: SimulationConfig) -> np.ndarray:
    """Offset-dipole Mercury field plus a uniform field (nT) at MSO positions (km)."""
    r = pos_mso_km - np.array([0.0, 0.0, DIPOLE_OFFSET_KM])
    rn = np.linalg.norm(r, axis=1)[:, None]
    rhat = r / rn
    m = np.array([0.0, 0.0, -1.0])  # southward moment: field points north at the equator
    m_dot_r = (rhat * m).sum(axis=1, keepdims=True)
    b = MERCURY_DIPOLE_NT * (MERCURY_RADIUS_KM / rn) ** 3 * (3 * m_dot_r * rhat - m)
    return b + np.asarray(config.imf_nt)


def _waves(t: np.ndarray, config: SimulationConfig) -> np.ndarray:
    out = np.zeros((t.size, 3))
    for amp, per in config.waves:
        w = 2 * np.pi * t / per
        out[:, 1] += amp * np.cos(w)
        out[:, 2] += amp * np.sin(w)
    return out


def _schedule_blocks(config: SimulationConfig, span: float) -> np.ndarray:
    n = int(np.ceil(span / config.block_s)) + 1
    d = np.asarray(config.duty_cycles_percent, dtype=int)
    return np.resize(d, n)


def _temperature(t_rel: np.ndarray, blocks: np.ndarray, config: SimulationConfig) -> np.ndarray:
    """-50 C while the heater regulates; a smooth excursion over each heater-off run."""
    temp = np.full(t_rel.shape, -50.0)
    off = blocks == 0
    k = 0
    while k < blocks.size:
        if off[k]:
            j = k
            while j < blocks.size and off[j]:
                j += 1
            a, b = k * config.block_s, j * config.block_s
            inside = (t_rel >= a) & (t_rel < b)
            phase = (t_rel[inside] - a) / (b - a)
            temp[inside] += config.excursion_c * np.sin(np.pi * phase) ** 2
            k = j
        else:
            k += 1
    return temp


def simulate(
    config: SimulationConfig, cal: MessengerCalibration, sclk
) -> dict[str, xr.Dataset]:
    """Simulate raw science, heater and temperature streams and their truth.

    Kernels (the synthetic MESSENGER-like set) must be loaded.

    Parameters
    ----------
    config : SimulationConfig
    cal : MessengerCalibration
    sclk : fluxcal.geometry.time.SclkKernel
        MESSENGER clock (-236).

    Returns
    -------
    dict
        ``"science"``, ``"heater"``, ``"temperature"`` (the raw streams, as the readers
        return them) and ``"truth"`` (``b_mso``, ``b_sensor``, ``offset``, ``heater_signal``
        per sample, coordinate ``epoch``).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-11 (run in reverse).
    """
    from fluxcal.geometry.frames import rotate
    from fluxcal.geometry.positions import position
    from fluxcal.geometry.time import et_to_tt2000, utc_to_et

    et_start = float(utc_to_et(np.array([config.start_utc]))[0])
    part_arr, met_arr = sclk.from_et(np.array([et_start]))
    partition = int(part_arr[0])
    met0 = float(np.ceil(met_arr[0]))  # first whole MET second at or after the start
    # --- heater schedule (integer MET seconds) -------------------------------------------
    # the heater stream starts with 110 s of heater off (more than one heater period):
    # the pipeline sees the heater quiet before the first edge (relaxation from zero)
    h_zero = met0 - config.lead_s
    h_met = np.arange(h_zero - QUIET_LEAD_S, met0 + config.duration_s + 200.0, 1.0)
    rel_h = h_met - h_zero
    blocks = _schedule_blocks(config, rel_h[-1] + 1)
    block_of = np.maximum(rel_h // config.block_s, 0).astype(int)
    in_period = rel_h % 100.0
    duty = blocks[block_of]
    bits = ((in_period < duty) & (rel_h >= 0)).astype(np.int8)
    # periods (by construction): each 100 s of a block with duty > 0
    p_start_rel = np.arange(0.0, rel_h[-1] + 1, 100.0)
    p_duty = blocks[(p_start_rel // config.block_s).astype(int)]
    keep = (p_duty > 0) & (p_start_rel + 100.0 <= rel_h[-1] + 1)
    p_start_rel, p_duty = p_start_rel[keep], p_duty[keep]
    p_start_et = sclk.to_et(np.full(p_start_rel.size, partition), h_zero + p_start_rel)
    # duty-cycle changes from the block schedule
    ch_t_rel, ch_d = [], []
    prev = 0
    for b, d in enumerate(blocks):
        if d != prev:
            ch_t_rel.append(b * config.block_s)
            ch_d.append(10 * d)
        prev = d
    ch_t_rel, ch_d = np.array(ch_t_rel, dtype=float), np.array(ch_d, dtype=float)
    keep = ch_t_rel <= rel_h[-1] + 1 - 100.0
    ch_t_rel, ch_d = ch_t_rel[keep], ch_d[keep]
    ch_et = sclk.to_et(np.full(ch_t_rel.size, partition), h_zero + ch_t_rel)
    # --- temperatures ------------------------------------------------------------------
    t_met = np.arange(h_met[0], h_met[-1] + 1, config.temperature_step_s)
    t_temp = np.round(_temperature(t_met - h_zero, blocks, config), 4)
    # --- science sample grid (recorded MET) ---------------------------------------------
    met_parts, rate_parts = [], []
    bounds = [f for f, _ in config.rate_segments] + [1.0]
    for (frac, rate), end in zip(config.rate_segments, bounds[1:], strict=True):
        hz = cal.sample_rate_hz[rate]
        a = met0 + frac * config.duration_s
        b = met0 + end * config.duration_s
        grid = np.arange(np.ceil(a * hz) / hz, b, 1.0 / hz)
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
    lag = per_sample_lag(rate, cal.net_lag_s)
    part = np.full(met_rec.size, partition, dtype=np.int8)
    et = sclk.to_et(part, met_rec - lag)
    # --- truth field ---------------------------------------------------------------------
    pos = position("MESSENGER", "MERCURY", "MSGR_MSO", et)
    b_mso = mercury_field_mso(pos, config) + _waves(et - et_start, config)
    deployed = levels.sensor_frame(et, cal)
    b_sensor = np.empty_like(b_mso)
    for frame, sel in (("MSGR_MAG", deployed), ("MSGR_MAG_STOWED", ~deployed)):
        if sel.any():
            b_sensor[sel] = rotate(b_mso[sel], et[sel], "MSGR_MSO", frame)
    # --- offsets and heater signal (fine counts) ---------------------------------------
    temp_true = _temperature(
        (sclk.from_et(et)[1] - h_zero), blocks, config
    )
    offset = levels.offset_model(et, temp_true, DutyCycleChanges(ch_et, ch_d), cal)
    k = np.searchsorted(p_start_et, et, side="right") - 1
    inside = (k >= 0) & (et < p_start_et[np.maximum(k, 0)] + 100.0)
    applied = inside & (p_duty[np.maximum(k, 0)] >= cal.constants["heater"]["min_on_s"])
    applied &= et >= float(utc_to_et(np.array([str(cal.date("heater_mode_v10"))]))[0])
    heater = np.zeros((et.size, 3))
    kk = k[applied]
    heater[applied] = heater_waveform(
        et[applied] - p_start_et[kk], p_duty[kk].astype(float), cal.heater_signal,
        cal.heater_duty_bins_percent,
    )
    conv = range_conversion(cal.matrices)
    total = offset + heater
    total[rng == 1] = np.einsum("ij,nj->ni", conv[1], total[rng == 1])
    counts = np.round(nt_to_counts(b_sensor, rng, cal.matrices) + total)
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
            "temperature_c": ("temperature_time", t_temp, {"units": "degC"}),
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
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w") as fh:
        fh.write(header + "\n")
        # format column-wise with numpy to keep exact fixed-point text
        cols = [np.char.mod(f, c) for f, c in zip(fmts, columns, strict=True)]
        lines = cols[0]
        for c in cols[1:]:
            lines = np.char.add(np.char.add(lines, ","), c)
        fh.write("\n".join(lines.tolist()))
        fh.write("\n")
    tmp.replace(path)


def write_inputs(sim: dict[str, xr.Dataset], out_dir: str | Path, stem: str = "MAG") -> dict:
    """Write the simulated streams as CSV (science, heater, temperature) and the truth.

    Returns
    -------
    dict
        Paths keyed ``"science"``, ``"heater"``, ``"temperature"``, ``"truth"``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
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
