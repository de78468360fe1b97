"""Issue 34's two hard MESSENGER worlds, independent forward models (numpy only).

Written from the issue's text, with none of fluxcal's code (the only import from fluxcal
is `flight_sim.Schedule`, the forward model's container for a heater schedule):

**Hard cruise wind** (`cruise_hard_wind`), ``B = |B| u`` in sensor axes on a 1-s grid:

* ``u = normalise(p(t) + a v)``: ``v`` three Gaussian components with an f^-3/2 spectrum
  from 12 h to 2 s, ``a = 0.5 / sqrt(3)`` (``dB/B`` ~ 0.5); ``p(t)`` the mean direction,
  scattered about a sector (Parker) direction and changing at discontinuities, a Poisson
  process of one per hour: rotational (``|B|`` kept) or tangential (``|B|`` jumps to a
  fresh log-normal factor of sigma 0.15 about the daily level), each turning over 5-60 s;
* ``|B|``: a daily level drawn log-uniform in 5-30 nT (joined by 3-h cosine ramps at the
  day boundaries) times a broadband compressive factor ``1 + c h`` (``h`` unit-variance
  f^-3/2 from 1 h to 2 s, ``c`` 0.10-0.15) times magnetic holes, a Poisson process of one
  per hour, each ``1 - depth sin^2`` with depth 40-90 % over 10-120 s (direction kept).

**Mercury orbit** (`MercuryOrbit`): 12-h orbits with periapsis at ``phase + 12 h k``:

* magnetosphere passes of 1.0-1.8 h centred on periapsis (drawn per orbit), ``|B|`` from
  60 nT at the magnetopause rising as ``cos^2`` to a peak of 150-500 nT at periapsis, the
  direction turning through 150 deg in a fixed plane (a dipole seen along the orbit),
  with flux-transfer events (4-20 per pass, 2-10 s bipolar signatures of 20-60 % of the
  local field along a normal, plus a core enhancement of half that);
* 15-40 min of magnetosheath either side: 2.5-4x the wind's ``|B|``, compressive
  (``1 + 0.35 h``, ``h`` f^-1 from 10 min to 2 s, mirror-mode-like), direction
  ``normalise(p_sh + 0.6 v)``;
* 15-40 nT wind between (drawn per orbit), Alfvenic rotations ``dB/B`` ~ 0.5 (f^-5/3),
  3 % compressive;
* heater: off from periapsis -1.5 h to +3.5 h (rounded to the controller's 1000-s
  blocks); a warm excursion ``-50 + A exp(-((t - t_pk)/w)^2)`` with peak 50 + A in
  -35..+45 C (stratified per 4 orbits), ``t_pk`` periapsis -10..+30 min (or a later
  range, `MercuryOrbit.peak_lag_min`), ``w`` 20-40 min,
  ramped in over 10 min; every other orbit (alternating, the first one's parity drawn) a
  dip to -60 C after the peak (``sin^2`` over the last 60 % of the off window); otherwise
  at most 2 C below -50. Regulated in between at -50 C, duty cycle a reflected random walk
  in 10-45 % (steps of at most 8 %, 3 in 4 blocks change).

**A true temperature law per realisation** (`drawn_law`, ``--draw-law`` of
``benchmarks/messenger_fit_pulls.py``): the flight model's true Table 2 drawn from the
seed, so that pulls of the break temperatures (held or free) test a spread of truths
and not one fixed table: per axis ``A0`` x U(0.75, 1.3), ``B0`` x U(0.7, 1.3), ``B1`` x
U(0.75, 1.4) and the break ``T_m`` moved by U(-8, +8) C (``A1`` from eq. 4); the other
tables as `CalibrationChanges`' defaults.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6-7 (heater period 100 s, 1000-s
   evaluation, temperature varies only with the heater off; Table 2 and eq. 3-4).
.. [2] Issue 34, "MESSENGER, hard cruise wind" and "MESSENGER, Mercury orbit".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluxcal.missions.messenger.flight_sim import CalibrationChanges, Schedule
from tests.missions.messenger._realistic_wind import powerlaw

DAY_S = 86400.0
HOUR_S = 3600.0
ORBIT_S = 12 * HOUR_S
BLOCK_S = 1000.0
REGULATED_C = -50.0
PARKER = (0.55, -0.6, 0.58)


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _events(rng: np.random.Generator, n: int, per_hour: float) -> np.ndarray:
    """Poisson event times (s) in [0, n)."""
    k = rng.poisson(per_hour * n / HOUR_S)
    return np.sort(rng.uniform(0.0, n, k))


#: Ranges of `drawn_law` (factors on the seed's Table 2, and the break's move in C).  The
#: seed's breaks lie at -10.2 / -12.7 / -14.8 C ("the offsets vary slowly with temperature
#: below -10 C", sec. 7); moved by up to 8 C they stay in -23..-2 C, the heater-off warm
#: runs' span.  The factors bracket `CalibrationChanges`' defaults (0.75-1.35); every
#: draw keeps ``B1 > B0`` (the seed's ratios are 2.1 / 3.2 / 4.5, the draws' least
#: 2.1 x 0.75 / 1.3 = 1.2).
LAW_FACTORS = {"a0": (0.75, 1.3), "b0": (0.7, 1.3), "b1": (0.75, 1.4)}
LAW_TM_SHIFT_C = (-8.0, 8.0)


def drawn_law(seed: int) -> CalibrationChanges:
    """The flight model's true tables with Table 2 drawn per realisation (module docstring).

    A function of ``seed`` only (its own stream, apart from the world's draws).
    """
    rng = np.random.default_rng([seed, 36])
    draw = {k: tuple(float(x) for x in rng.uniform(lo, hi, 3))
            for k, (lo, hi) in LAW_FACTORS.items()}
    shift = tuple(float(x) for x in rng.uniform(*LAW_TM_SHIFT_C, 3))
    return CalibrationChanges(**draw, tm_shift_c=shift)


@dataclass(frozen=True)
class CruiseEvents:
    """What `cruise_hard_wind` put in (for the statistics tests)."""

    day_level_nt: np.ndarray
    hole_start_s: np.ndarray
    hole_width_s: np.ndarray
    hole_depth: np.ndarray
    discontinuity_s: np.ndarray
    tangential: np.ndarray
    compressive: float


def _daily_level(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Daily |B| levels (log-uniform 5-30 nT) on the grid, 3-h sin^2 ramps at midnights."""
    days = int(np.ceil(n / DAY_S)) + 1
    level = rng.uniform(np.log(5.0), np.log(30.0), days)
    t = np.arange(n, dtype=float)
    logb = np.full(n, level[0])
    for k in range(days - 1):  # one ramp per day
        x = np.clip((t - (k + 1) * DAY_S) / (3 * HOUR_S) + 0.5, 0.0, 1.0)
        logb += (level[k + 1] - level[k]) * np.sin(0.5 * np.pi * x) ** 2
    return np.exp(logb), np.exp(level)


def cruise_hard_events(rng: np.random.Generator, n: int, compressive: float | None = None
                       ) -> tuple[np.ndarray, CruiseEvents]:
    """The hard cruise wind (module docstring) and what it contains: ``(field, events)``."""
    c = rng.uniform(0.10, 0.15) if compressive is None else float(compressive)
    p0 = _unit(np.asarray(PARKER, dtype=float))
    sector = rng.choice([-1.0, 1.0])
    # discontinuities: new mean direction and (tangential) a |B| step, turning over 5-60 s
    tdisc = _events(rng, n, 1.0)
    m = tdisc.size
    dirs = _unit(sector * p0[None, :] + 0.6 * rng.standard_normal((m + 1, 3)))
    tang = rng.random(m) < 0.5
    # |B| factor per segment: a fresh log-normal draw after a tangential discontinuity,
    # the previous one kept after a rotational (stationary, no random walk)
    draws = 0.15 * rng.standard_normal(m + 1)
    last_td = np.maximum.accumulate(np.where(np.r_[True, tang], np.arange(m + 1), 0))
    steps = draws[last_td]
    turn = rng.uniform(5.0, 60.0, m)
    t = np.arange(n, dtype=float)
    seg = np.searchsorted(tdisc, t, side="right")  # segment index 0..m
    prev_t = np.r_[-np.inf, tdisc][seg]
    prev_w = np.r_[1.0, turn][seg]
    blend = np.sin(0.5 * np.pi * np.clip((t - prev_t) / prev_w, 0.0, 1.0)) ** 2
    before = np.maximum(seg - 1, 0)
    mean_dir = _unit((1 - blend)[:, None] * dirs[before] + blend[:, None] * dirs[seg])
    log_step = (1 - blend) * steps[before] + blend * steps[seg]
    v = powerlaw(rng, n, 3, -1.5, 1.0 / (12 * HOUR_S), 0.5)
    u = _unit(mean_dir + (0.5 / np.sqrt(3.0)) * v)
    level, day_level = _daily_level(rng, n)
    h = powerlaw(rng, n, 1, -1.5, 1.0 / HOUR_S, 0.5)[:, 0]
    mag = level * np.exp(log_step) * np.maximum(1.0 + c * h, 0.2)
    # magnetic holes: 1 - depth sin^2 over the width
    thole = _events(rng, n, 1.0)
    width = rng.uniform(10.0, 120.0, thole.size)
    depth = rng.uniform(0.4, 0.9, thole.size)
    for a, w, d in zip(thole, width, depth, strict=True):  # one loop per hole (~1 per hour)
        i0, i1 = int(a), min(n, int(np.ceil(a + w)) + 1)
        x = np.clip((t[i0:i1] - a) / w, 0.0, 1.0)
        mag[i0:i1] *= 1.0 - d * np.sin(np.pi * x) ** 2
    ev = CruiseEvents(day_level, thole, width, depth, tdisc, tang, c)
    return u * mag[:, None], ev


def cruise_hard_wind(rng: np.random.Generator, n: int, compressive: float | None = None
                     ) -> np.ndarray:
    """Field (nT, sensor axes) of the hard cruise wind on a 1-s grid, shape (n, 3)."""
    return cruise_hard_events(rng, n, compressive)[0]


@dataclass
class MercuryOrbit:
    """The Mercury-orbit world (module docstring): field and heater schedule.

    Both share the orbit phase, drawn from ``seed`` (the grids of `simulate_flight` start
    at its schedule origin, the same 1-s grid for the field and the temperature).
    """

    seed: int
    #: Range (min) of the warm peak's time after periapsis: the issue does not say; the
    #: default puts it inside the magnetosphere pass (warmed by the planet at closest
    #: approach), ``(40, 80)`` (``--world mercury-orbit-late``) after the pass, in the
    #: magnetosheath and the wind (a sensor that lags the planet's heating).
    peak_lag_min: tuple[float, float] = (-10.0, 30.0)

    def __post_init__(self) -> None:
        rng = np.random.default_rng([self.seed, 34])
        self.phase_s = float(rng.uniform(2 * HOUR_S, 2 * HOUR_S + ORBIT_S))
        self._rng = rng

    def periapses(self, n: int) -> np.ndarray:
        """Periapsis times (s since the origin) that touch ``[0, n)``."""
        k = np.arange(-1, int(np.ceil(n / ORBIT_S)) + 2)
        return self.phase_s + ORBIT_S * k

    def orbits(self, n: int) -> dict[str, np.ndarray]:
        """Per-orbit draws (a function of the seed and the orbit count only)."""
        tp = self.periapses(n)
        rng = np.random.default_rng([self.seed, 34, tp.size])
        k = tp.size
        strata = np.concatenate([rng.permutation(4) for _ in range(k // 4 + 1)])[:k]
        return {
            "periapsis_s": tp,
            "ms_half_s": 0.5 * HOUR_S * rng.uniform(1.0, 1.8, k),
            "peak_nt": rng.uniform(150.0, 500.0, k),
            "sheath_in_s": 60.0 * rng.uniform(15.0, 40.0, k),
            "sheath_out_s": 60.0 * rng.uniform(15.0, 40.0, k),
            "wind_nt": rng.uniform(15.0, 40.0, k),
            "temp_peak_c": -35.0 + 80.0 * (strata + rng.random(k)) / 4.0,
            "temp_peak_at_s": 60.0 * rng.uniform(*self.peak_lag_min, k),
            "temp_width_s": 60.0 * rng.uniform(20.0, 40.0, k),
            "cold_dip": (np.arange(k) + rng.integers(0, 2)) % 2 == 0,
            "small_dip_c": rng.uniform(0.0, 2.0, k),
            "fte_count": rng.integers(4, 21, k),
        }

    # --- field -----------------------------------------------------------------------------

    def field(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Field (nT, sensor axes) on the 1-s grid from the origin, shape (n, 3)."""
        return self.field_regions(rng, n)[0]

    def field_regions(self, rng: np.random.Generator, n: int
                      ) -> tuple[np.ndarray, np.ndarray]:
        """``(field, region)``: region 0 wind, 1 magnetosheath, 2 magnetosphere."""
        o = self.orbits(n)
        t = np.arange(n, dtype=float)
        # solar wind: Alfvenic rotations about a sector direction, |B| per orbit
        p0 = _unit(np.asarray(PARKER, dtype=float))
        v = powerlaw(rng, n, 3, -5.0 / 3.0, 1.0 / (12 * HOUR_S), 0.5)
        u_sw = _unit(rng.choice([-1.0, 1.0]) * p0 + (0.5 / np.sqrt(3.0)) * v)
        tp = o["periapsis_s"]
        near = np.clip(np.searchsorted(tp, t - 0.5 * ORBIT_S), 0, tp.size - 1)  # nearest
        b_sw = np.interp(t, tp + 0.5 * ORBIT_S, np.r_[o["wind_nt"][1:], o["wind_nt"][-1]])
        h = powerlaw(rng, n, 1, -2.0, 1.0 / HOUR_S, 1.0 / 300.0)[:, 0]
        out = u_sw * (b_sw * (1.0 + 0.03 * h))[:, None]
        region = np.zeros(n, dtype=np.int8)
        # magnetosheath: compressive, 2.5-4x the wind
        hs = powerlaw(rng, n, 1, -1.0, 1.0 / 600.0, 0.5)[:, 0]
        vs = powerlaw(rng, n, 3, -5.0 / 3.0, 1.0 / 1800.0, 0.5)
        p_sh = _unit(np.array([0.2, 0.9, -0.4]))
        b_sh = b_sw * rng.uniform(2.5, 4.0) * np.maximum(1.0 + 0.35 * hs, 0.1)
        sheath = _unit(p_sh + 0.6 * vs) * b_sh[:, None]
        dt = t - tp[near]
        half = o["ms_half_s"][near]
        in_ms = np.abs(dt) < half
        in_sh = ~in_ms & (((dt < 0) & (dt > -half - o["sheath_in_s"][near]))
                          | ((dt > 0) & (dt < half + o["sheath_out_s"][near])))
        # 30-s smooth boundaries (bow shock, magnetopause)
        edge_in = -half - o["sheath_in_s"][near]
        edge_out = half + o["sheath_out_s"][near]
        w_sh = np.clip(np.minimum(dt - edge_in, edge_out - dt) / 30.0, 0.0, 1.0)
        w_sh = np.where(in_sh | in_ms, w_sh, 0.0)
        out = (1 - w_sh)[:, None] * out + w_sh[:, None] * sheath
        region[in_sh] = 1
        # magnetosphere: cos^2 rise to the peak, direction turning in a plane
        x = np.clip(dt / half, -1.0, 1.0)
        mag = 60.0 + (o["peak_nt"][near] - 60.0) * np.cos(0.5 * np.pi * x) ** 2
        ang = np.deg2rad(75.0) * x
        e1, e2 = _unit(np.array([0.0, 0.3, 1.0])), _unit(np.array([-1.0, 0.2, 0.0]))
        e2 = _unit(e2 - e1 * (e1 @ e2))
        u_ms = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
        b_ms = u_ms * mag[:, None]
        normal = _unit(np.cross(e1, e2))
        for j, tpj in enumerate(tp):  # flux-transfer events: one loop per event
            for tc in tpj + rng.uniform(-1.0, 1.0, int(o["fte_count"][j])) * o["ms_half_s"][j]:
                w = rng.uniform(2.0, 10.0)
                i0, i1 = max(0, int(tc - 3 * w)), min(n, int(tc + 3 * w) + 1)
                if i1 <= i0:
                    continue
                s = (t[i0:i1] - tc) / w
                amp = rng.uniform(0.2, 0.6) * mag[i0:i1]
                b_ms[i0:i1] += ((amp * 2.33 * s * np.exp(-s * s))[:, None] * normal
                                + (0.5 * amp * np.exp(-s * s))[:, None] * u_ms[i0:i1])
        w_ms = np.where(in_ms, np.clip((half - np.abs(dt)) / 30.0, 0.0, 1.0), 0.0)
        out = (1 - w_ms)[:, None] * out + w_ms[:, None] * b_ms
        region[in_ms] = 2
        return out, region

    # --- heater and temperature ------------------------------------------------------------

    def schedule(self, rng: np.random.Generator, n_blocks: int, lead_blocks: int) -> Schedule:
        """Duty cycle per 1000-s block and temperature on the 1-s grid (module docstring).

        Blocks before ``lead_blocks`` are heater off at -50 C (the forward model's quiet
        lead).
        """
        n = int(n_blocks * BLOCK_S)
        o = self.orbits(n)
        off = np.zeros(n_blocks, dtype=bool)
        off[:lead_blocks] = True
        temp = np.full(n, REGULATED_C)
        t = np.arange(n, dtype=float)
        for j, tp in enumerate(o["periapsis_s"]):  # one loop per orbit
            b0 = int(np.floor((tp - 1.5 * HOUR_S) / BLOCK_S))
            b1 = int(np.ceil((tp + 3.5 * HOUR_S) / BLOCK_S))
            lo, hi = max(b0, lead_blocks), min(b1, n_blocks)
            if hi <= lo:
                continue
            off[lo:hi] = True
            a, b = lo * BLOCK_S, hi * BLOCK_S
            seg = t[int(a):int(b)]
            amp = o["temp_peak_c"][j] - REGULATED_C
            tpk = tp + o["temp_peak_at_s"][j]
            warm = amp * np.exp(-(((seg - tpk) / o["temp_width_s"][j]) ** 2))
            warm *= np.clip((seg - a) / 600.0, 0.0, 1.0)
            dip_c = 10.0 if o["cold_dip"][j] else o["small_dip_c"][j]
            x = np.clip((seg - (a + 0.4 * (b - a))) / (0.6 * (b - a)), 0.0, 1.0)
            temp[int(a):int(b)] = REGULATED_C + warm - dip_c * np.sin(np.pi * x) ** 2
        duty = np.zeros(n_blocks, dtype=np.int64)
        steps = rng.integers(-8, 9, n_blocks)
        steps[rng.random(n_blocks) > 0.75] = 0
        d = int(rng.integers(10, 46))
        for k in range(n_blocks):  # a reflected walk, one step per 1000-s block
            if off[k]:
                continue
            d += int(steps[k])
            d = 90 - d if d > 45 else (20 - d if d < 10 else d)
            duty[k] = d
        return Schedule(duty, temp)
