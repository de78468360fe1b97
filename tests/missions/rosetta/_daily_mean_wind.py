"""Forward model of a calm solar wind *with a daily mean field* for the RPC-MAG fits (issue 21).

Written from the issue and seed 003 alone; no fluxcal pipeline or fit code.  The field
(URF, nT) is a 3-nT Alfvenic wind whose direction wanders about a fixed mean direction
(a sector of the Parker spiral: the day's mean field is 1.5-2 nT, the case where the
seed's zero-mean criterion puts that mean into ``P_0``):

* direction ``u = (k m + g) / |k m + g|``, ``m`` the sector direction, ``g`` a
  three-component unit-variance Ornstein-Uhlenbeck process of correlation time
  ``tau_s`` (1200 s), ``k`` = 1.2 (rotations of tens of degrees about ``m``);
* magnitude ``B0 (1 + c h)``, ``h`` a unit-variance OU process of 300 s, ``c`` = 3 %
  (the compressive part).

The instrument (raw words from the field, the extended offset of a daily polynomial,
the thermistor words) is `fluxcal.missions.rosetta.forward`, the instrument model
written from the seed that shares no code with the pipeline.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from numpy.polynomial import Polynomial
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.rosetta import calib, forward
from fluxcal.missions.rosetta.calib import DailyOffsetModel

NS = 1_000_000_000
B0 = 3.0
MEAN_DIRECTION = np.array([0.6, -0.7, 0.39])
MEAN_WEIGHT = 1.2
TAU_S = 1200.0
COMPRESSION = 0.03


def ou(n: int, dt: float, tau: float, rng: np.random.Generator, dims: int = 3) -> np.ndarray:
    """Stationary unit-variance Ornstein-Uhlenbeck process sampled at ``dt``, (n, dims)."""
    a = np.exp(-dt / tau)
    e = rng.standard_normal((n, dims))
    x = lfilter([np.sqrt(1 - a * a)], [1.0, -a], e, axis=0)
    return x + e[:1] * a ** np.arange(n)[:, None]


def daily_mean_field(n: int, dt: float, rng: np.random.Generator, *,
                     compression: float = COMPRESSION, b0: float = B0) -> np.ndarray:
    """The field of the module docstring, shape (n, 3), nT."""
    m = MEAN_DIRECTION / np.linalg.norm(MEAN_DIRECTION)
    v = MEAN_WEIGHT * m + ou(n, dt, TAU_S, rng)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    return u * (b0 * (1.0 + compression * ou(n, dt, 300.0, rng, 1)))


def true_coefficients() -> np.ndarray:
    """Power-basis ``P_0 .. P_5`` (6, 3) of a cubic about -105 C unlike any shipped model."""
    u = Polynomial([105.0, 1.0])
    coeffs = np.zeros((6, 3))
    for i, c in enumerate([(-9.0, 0.30, -3e-3, 4e-5), (14.0, -0.22, 5e-3, -6e-5),
                           (6.0, 0.45, 2e-3, 3e-5)]):
        p = Polynomial(c)(u)
        coeffs[: p.coef.size, i] = p.coef
    return coeffs


def temperature(seconds: np.ndarray, phase: float) -> np.ndarray:
    """Sensor temperature (deg C): -105 +- 18 C over the day and a 100-min wobble of 2 C."""
    return (-105.0 + 18.0 * np.sin(2 * np.pi * seconds / 86400.0 + phase)
            + 2.0 * np.sin(2 * np.pi * seconds / 6000.0))


def simulate_raw(day: str, start_s: float, hours: float, coefficients: np.ndarray, *,
                 seed: int, phase: float = 0.0, rate_hz: float = 1.0,
                 compression: float = COMPRESSION):
    """Raw OB science of ``hours`` from ``start_s`` after ``day`` midnight.

    Returns ``(raw, b_true_urf, temperature_c)`` (truth at the event times).  Filter
    mode SID 2.
    """
    rng = np.random.default_rng(seed)
    cal = calib.load_ground_calibration("OB")
    nominal = calib.load_nominal_conversion()
    secs, stamps, sid, delay = time_line(day, start_s, hours, rate_hz)
    b = daily_mean_field(secs.size, 1.0 / rate_hz, rng, compression=compression)
    temp = temperature(secs + delay, phase)
    model = DailyOffsetModel(np.datetime64(day, "D"), "OB", coefficients, "truth")
    ext = forward.extended_offset(stamps, forward.reduced_temperature(temp, cal),
                                  {model.day: model})
    raw = instrument_raw(stamps, sid, b + ext, temp, cal, nominal,
                         f"daily-mean wind seed {seed}")
    return raw, b, temp


def time_line(day: str, start_s: float, hours: float, rate_hz: float):
    """``(seconds after midnight, TT2000 stamps, SID 2, filter delay s)`` of a stretch."""
    n = int(hours * 3600 * rate_hz)
    midnight = int(utc_to_tt2000(np.array([day + "T00:00:00"]))[0])
    secs = start_s + np.arange(n) / rate_hz
    sid = np.full(n, 2, dtype=np.int16)
    delay = forward.filter_delay(sid, calib.load_time_shift_table(), secondary=False)
    return secs, midnight + np.rint(secs * NS).astype(np.int64), sid, delay


def curve(coefficients: np.ndarray, reduced_t: np.ndarray) -> np.ndarray:
    """``sum P_k T~^k`` per axis with numpy's Polynomial, (n, 3)."""
    return np.stack([Polynomial(coefficients[:, i])(reduced_t) for i in range(3)], axis=1)


def instrument_raw(stamps: np.ndarray, sid: np.ndarray, field: np.ndarray, temp: np.ndarray,
                   cal, nominal, source: str) -> xr.Dataset:
    """Return the OB sensor's raw telemetry for ``field`` (nT, with the offset) at ``temp``.

    The seed's instrument run forward (`fluxcal.missions.rosetta.forward`): counts of the
    field, thermistor words of OB at ``temp`` and IB 10 C warmer, OBT from 2003-01-01.
    """
    counts = forward.science_counts(forward.raw_field(field, temp, cal), nominal)
    words = forward.thermistor_words(temp, cal, nominal)
    ib_words = forward.thermistor_words(temp + 10.0, calib.load_ground_calibration("IB"),
                                        nominal)
    obt0 = int(utc_to_tt2000(np.array(["2003-01-01T00:00:00"]))[0])
    n = len(stamps)
    return xr.Dataset(
        {
            "obt": ("time", np.round((stamps - obt0) / NS, 6)),
            "sid": ("time", sid),
            "b_counts": (("time", "component"), counts.astype(np.int32)),
            "t_ob_counts": ("time", words.astype(np.int32)),
            "t_ib_counts": ("time", ib_words.astype(np.int32)),
            "quality": ("time", np.zeros(n, dtype=np.int16)),
        },
        coords={"epoch": ("time", stamps), "component": ["x", "y", "z"]},
        attrs={"sensor": "OB", "source": source},
    )


#: Appendix B offset jumps of the jump studies (nT, spacecraft frame), one row per interval.
TRUE_JUMPS = np.array([[4.1, -7.3, 2.6], [-3.8, 5.2, -9.4]])
#: The two 2-day intervals of the jump studies.
JUMP_INTERVALS = (("2014-08-01T00:00:00", "2014-08-03T00:00:00"),
                  ("2014-08-03T00:00:00", "2014-08-05T00:00:00"))


def jump_data(seed: int, rate_hz: float = 0.1, compression: float = COMPRESSION,
              jumps: np.ndarray = TRUE_JUMPS, field=None):
    """Four days of the daily-mean wind in CSEQ, turned into the spacecraft frame by a
    slow attitude, plus ``jumps[0]`` / ``jumps[1]`` over the two `JUMP_INTERVALS`.

    ``field(seconds, rng)``, optional, gives another CSEQ field (nT, (n, 3)).

    Returns ``(epoch tt2000, b_sc, rotation matrices, b_cseq)``.
    """
    rng = np.random.default_rng(seed)
    t0 = int(utc_to_tt2000(np.array([JUMP_INTERVALS[0][0]]))[0])
    split = int(utc_to_tt2000(np.array([JUMP_INTERVALS[1][0]]))[0])
    secs = np.arange(0.0, 4 * 86400.0, 1.0 / rate_hz)
    epoch = t0 + np.rint(secs * NS).astype(np.int64)
    second = epoch >= split
    b_cseq = (daily_mean_field(secs.size, 1.0 / rate_hz, rng, compression=compression)
              if field is None else field(secs, rng))
    rot = Rotation.from_euler("zyx", np.stack([60 * np.sin(secs / 40_000.0),
                                               20 * np.sin(secs / 25_000.0),
                                               10 * np.cos(secs / 17_000.0)], 1),
                              degrees=True).as_matrix()
    jump = np.where(second[:, None], jumps[1], jumps[0])
    return epoch, np.einsum("nji,nj->ni", rot, b_cseq) + jump, rot, b_cseq
