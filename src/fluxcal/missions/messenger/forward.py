"""MESSENGER MAG instrument model in the forward direction: counts from field.

Written from seed 000 and its tables alone, sharing no code with the pipeline
(`fluxcal.calibration`, `fluxcal.missions.messenger.levels`): the tables are parsed here
from the packaged data files (a small reader of its own), and every step runs the way
the instrument does, not as the inverse of a pipeline function:

- eq. 8 (Table 4) is written as its matrix and *solved* for the counts of a field;
- the temperature offset is the convex two-segment line of Table 2 (``max`` of the two
  lines, since ``B1 > B0`` on every axis), not eq. 3a/3b's branch on ``T_m``;
- the duty-cycle offset relaxes toward ``D0 d`` (eq. 5a/5b, Table 3) by explicit time
  stepping of ``dD/dt = (D* - D) / tau`` on a 1-s grid (an IIR filter), held for ``dt``
  after each duty-cycle change and with infinite memory, instead of eq. 6a-6f's
  five-change closed form;
- the heater waveform (Tables 6-8) is interpolated with a regular-grid interpolator that
  extrapolates linearly in duty cycle (sec. 6).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-8, Tables 1-4, Appendix Tables 6-8.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.signal import lfilter

#: Table stems of the packaged data files this model reads.
TABLES = ("latency", "offsets_temperature", "offsets_duty_cycle", "gain_matrix",
          "heater_signal_x", "heater_signal_y", "heater_signal_z", "processing")


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a ``#``-commented CSV file (numbers as float, else text)."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip() and ln[0] != "#"]
    names = lines[0].split(",")
    rows = np.array([ln.split(",") for ln in lines[1:]], dtype=str)
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        try:
            out[name] = rows[:, j].astype(float)
        except ValueError:
            out[name] = rows[:, j]
    return out


@dataclass(frozen=True)
class SeedTables:
    """The seed's tables as printed (fine-range counts, seconds, degC).

    Attributes
    ----------
    sample_rate_hz, net_lag_s : ndarray, shape (11,)
        Table 1 by rate setting.
    a0, b0, a1, b1 : ndarray, shape (3,)
        Table 2 per axis.
    d0 : ndarray, shape (3,)
        Table 3 slopes (counts per part per 1000).
    gains : dict
        Table 4 per range flag (0 fine, 1 coarse): ``kx ky kz alpha beta gamma``.
    heater_t, heater_bins, heater : ndarray
        Tables 6-8: seconds 0..100, duty-cycle bin centres (percent), values (3, 101, 8).
    constants : dict
        The processing TOML (tau, dt, thresholds, dates).
    """

    sample_rate_hz: np.ndarray
    net_lag_s: np.ndarray
    a0: np.ndarray
    b0: np.ndarray
    a1: np.ndarray
    b1: np.ndarray
    d0: np.ndarray
    gains: dict
    heater_t: np.ndarray
    heater_bins: np.ndarray
    heater: np.ndarray
    constants: dict

    def date(self, key: str) -> np.datetime64:
        """Return a date of the processing table (``boom_deployment``, ``heater_mode_v10``)."""
        return np.datetime64(self.constants["quality"][key], "s")


def read_tables(paths: Iterable[Path] | None = None) -> SeedTables:
    """Read the seed tables from ``paths`` (e.g. ``MessengerCalibration.paths``).

    Without paths, version 1 of every packaged table is read.
    """
    if paths is None:
        folder = Path(str(resources.files("fluxcal.missions.messenger") / "data"))
        paths = [folder / f"{t}_v1.{'toml' if t == 'processing' else 'csv'}" for t in TABLES]
    found = {Path(p).name.rsplit("_v", 1)[0]: Path(p) for p in paths}
    lat = _read_csv(found["latency"])
    order = np.argsort(lat["rate_setting"])
    temp = _read_csv(found["offsets_temperature"])
    duty = _read_csv(found["offsets_duty_cycle"])
    gain = _read_csv(found["gain_matrix"])
    gains = {int(flag): {k: float(gain[k][i]) for k in ("kx", "ky", "kz", "alpha", "beta",
                                                         "gamma")}
             for i, flag in enumerate(gain["range_flag"])}
    heater = []
    for axis in "xyz":
        cols = _read_csv(found[f"heater_signal_{axis}"])
        bins = [c for c in cols if c != "t_s"]
        heater.append(np.column_stack([cols[c] for c in bins]))
        t_s = cols["t_s"]
    return SeedTables(
        sample_rate_hz=lat["sample_rate_hz"][order], net_lag_s=lat["net_lag_s"][order],
        a0=temp["A0"], b0=temp["B0"], a1=temp["A1"], b1=temp["B1"], d0=duty["D0"],
        gains=gains, heater_t=t_s, heater_bins=np.array([float(b) for b in bins]),
        heater=np.stack(heater), constants=tomllib.loads(found["processing"].read_text()),
    )


def eq8_matrix(tables: SeedTables, range_flag: int) -> np.ndarray:
    """Return the counts -> nT matrix of eq. 8 for one range, written from Table 4."""
    g = tables.gains[range_flag]
    kx, ky, kz = g["kx"], g["ky"], g["kz"]
    return np.array([[kx, 0.0, 0.0],
                     [g["alpha"] * kx, ky, 0.0],
                     [g["beta"] * kx, g["gamma"] * ky, kz]])


def counts_from_field(
    b_sensor: np.ndarray, zero_level_fine: np.ndarray, range_flag: np.ndarray,
    tables: SeedTables,
) -> np.ndarray:
    """Unrounded counts the sensor reports for field ``b_sensor`` (nT, sensor axes).

    The zero level (offsets and heater signal, fine-range counts) is a field-equivalent
    quantity of the sensor: it is added as ``M_fine z`` nT before the range's eq. 8 is
    solved, so it appears as ``z`` counts in fine range and as the same nT in coarse range.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 1, sec. 8 eq. 8, Table 4.
    """
    fine = eq8_matrix(tables, 0)
    total_nt = np.asarray(b_sensor, dtype=float) + np.asarray(zero_level_fine) @ fine.T
    out = np.empty_like(total_nt)
    for flag in (0, 1):
        sel = np.asarray(range_flag) == flag
        if sel.any():
            out[sel] = np.linalg.solve(eq8_matrix(tables, flag), total_nt[sel].T).T
    return out


def temperature_offset(temperature_c: np.ndarray, tables: SeedTables) -> np.ndarray:
    """Table 2 offset (fine counts), shape (n, 3): the larger of the two lines.

    Both lines meet at ``T_m`` and ``B1 > B0`` on every axis, so the two-segment line of
    eq. 3a/3b/4 is their maximum (checked here).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 3a, 3b, 4, Table 2.
    """
    if not np.all(tables.b1 > tables.b0):
        raise ValueError("Table 2 is not convex: B1 <= B0 on some axis")
    t = np.asarray(temperature_c, dtype=float)[:, None]
    return np.maximum(tables.a0 + tables.b0 * t, tables.a1 + tables.b1 * t)


def relaxed_duty_offset(
    grid_s: np.ndarray, duty_ppt: np.ndarray, tables: SeedTables
) -> np.ndarray:
    """Duty-cycle offset shift (fine counts) on a regular 1-s grid, shape (n, 3).

    ``duty_ppt[i]`` is the duty cycle commanded over ``[grid_s[i], grid_s[i] + 1)`` (zero
    before the grid).  As sec. 7 describes the transitions: after each duty-cycle change the
    offset holds for ``dt`` (the delay to heater power), then relaxes toward the new steady
    state ``D0 d`` (``d >= 100`` ppt, else 0; eq. 5a/5b) with time constant ``tau``.  Run
    here by explicit time stepping, the exact one-step solution of ``dD/dt = (D* - D)/tau``
    for a target constant over each 1-s step, as an IIR filter over the whole history (no
    five-change look-back, which is the pipeline's approximation, error <= 0.6 DN by
    sec. 7).  ``D = 0`` at ``grid_s[0]``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 eq. 5a, 5b, Table 3, the
       relaxation paragraph (tau = 872 s, dt = 10 s).
    """
    rel = tables.constants["relaxation"]
    step = float(grid_s[1] - grid_s[0])
    delay = int(round(rel["delay_s"] / step))
    d = np.asarray(duty_ppt, dtype=float)
    change = np.diff(np.concatenate([[0.0], d])) != 0
    count = np.concatenate([np.zeros(delay, dtype=np.int64), np.cumsum(change)])
    held = count[delay:] - count[: d.size] > 0  # a change within the last dt
    target = np.where(d[:, None] >= rel["min_duty_cycle_ppt"], d[:, None] * tables.d0, 0.0)
    a = np.exp(-step / rel["tau_s"])
    relaxing = lfilter([1.0 - a], [1.0, -a], target[~held], axis=0)
    steps_done = np.cumsum(~held)  # relaxing steps completed by grid_s[i] + step
    after = np.vstack([np.zeros((1, 3)), relaxing])[steps_done]  # state at grid_s[i] + step
    return np.vstack([np.zeros((1, 3)), after[:-1]])


def heater_waveform(
    seconds_since_edge: np.ndarray, duty_percent: np.ndarray, tables: SeedTables
) -> np.ndarray:
    """Heater signal (fine counts), shape (n, 3), from Tables 6-8.

    Linear in time and in duty cycle; below 12 % and above 40 % the edge bins' slope is
    extended (sec. 6).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    points = np.column_stack([seconds_since_edge, duty_percent])
    out = np.empty((points.shape[0], 3))
    for axis in range(3):
        f = RegularGridInterpolator((tables.heater_t, tables.heater_bins), tables.heater[axis],
                                    method="linear", bounds_error=False, fill_value=None)
        out[:, axis] = f(points)
    return out
