"""Forward model of RPC-MAG at a comet for the daily-model fit (issue 34 item 4).

Written from issue 34 and seed 003 alone; no fluxcal pipeline or fit code.  The field
(URF, nT) of one day:

* magnitude ``B0 (1 + c h(t))``: ``B0`` the day's field (5-50 nT from day to day), ``h``
  a unit-variance process with an ``f^-2`` spectrum from 6 h to 2 min, ``c`` = 10 % (the
  slow compressive modulation of the issue);
* direction ``u = (k m + g) / |k m + g|``: ``m`` the day's draped direction, ``g`` three
  unit-variance ``f^-5/3`` processes from 6 h to 2 s (or the Nyquist frequency; turbulent
  rotations about the draped direction, tens of degrees with ``k`` = 1.5; the issue gives
  no range for them, ``rotation_cut_s`` = 120 stops them where the compression stops);
* 40-mHz wave packets of 1-2 nT transverse to ``u`` (Gaussian envelopes of 5 min, one
  every 20 min on average).

The sensor temperature swings by 15-30 C (peak to peak) over the day about a mean of
-120..-90 C, with a 100-min wobble of 1 C; the offset is the daily cubic of the extended
temperature model (sec. 4.2.3.3, ``P(T~)``, `_daily_mean_wind.true_coefficients`).  An
offset jump (Appendix B: a constant added from a given time on) can be added.  The
instrument is `fluxcal.missions.rosetta.forward` (the seed's model run forward).
"""

from __future__ import annotations

import numpy as np

from fluxcal.missions.rosetta import calib, forward
from fluxcal.missions.rosetta.calib import DailyOffsetModel

from ._daily_mean_wind import curve, instrument_raw, time_line, true_coefficients

NS = 1_000_000_000
COMPRESSION = 0.10
ROTATION_WEIGHT = 1.5
WAVE_HZ = 0.040
#: Shortest period (s) of the rotations' f^-5/3 spectrum.
ROTATION_CUT_S = 2.0

__all__ = ["COMPRESSION", "comet_day", "curve", "true_coefficients"]


def power_law(n: int, dt: float, slope: float, rng: np.random.Generator, dims: int,
              f_lo: float = 1.0 / 21600.0, f_hi: float = 1.0 / 120.0) -> np.ndarray:
    """Unit-variance noise with power spectrum ``f^-slope`` on ``[f_lo, f_hi]``, (n, dims)."""
    f = np.fft.rfftfreq(n, dt)
    band = (f >= f_lo) & (f <= f_hi)
    amp = np.where(band, np.maximum(f, f_lo) ** (-slope / 2.0), 0.0)
    spec = amp[:, None] * (rng.standard_normal((f.size, dims))
                           + 1j * rng.standard_normal((f.size, dims)))
    x = np.fft.irfft(spec, n, axis=0)
    return (x - x.mean(axis=0)) / x.std(axis=0)


def comet_field(secs: np.ndarray, b0: float, rng: np.random.Generator, *,
                compression: float = COMPRESSION, waves: bool = True,
                rotation_cut_s: float = ROTATION_CUT_S) -> np.ndarray:
    """The field of the module docstring at ``secs`` (evenly spaced), shape (n, 3), nT."""
    n, dt = secs.size, float(secs[1] - secs[0])
    m = rng.standard_normal(3)
    m /= np.linalg.norm(m)
    v = ROTATION_WEIGHT * m + power_law(n, dt, 5.0 / 3.0, rng, 3, f_hi=1.0 / rotation_cut_s)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    b = u * (b0 * (1.0 + compression * power_law(n, dt, 2.0, rng, 1)))
    if waves:
        # transverse 40-mHz packets: a random direction made perpendicular to u
        n_packets = max(1, int((secs[-1] - secs[0]) / 1200.0))
        centres = rng.uniform(secs[0], secs[-1], n_packets)
        amps = rng.uniform(1.0, 2.0, n_packets)
        envelope = np.zeros(n)
        for c, amp in zip(centres, amps, strict=True):  # packets, each over +-5 widths
            lo, hi = np.searchsorted(secs, [c - 750.0, c + 750.0])
            envelope[lo:hi] += amp * np.exp(-0.5 * ((secs[lo:hi] - c) / 150.0) ** 2)
        w = rng.standard_normal(3)
        w = w - (u @ w)[:, None] * u
        w /= np.linalg.norm(w, axis=1)[:, None]
        b = b + w * (envelope * np.sin(2 * np.pi * WAVE_HZ * secs))[:, None]
    return b


def temperature(secs: np.ndarray, mean_c: float, swing_c: float, phase: float) -> np.ndarray:
    """Sensor temperature (deg C): a daily swing of ``swing_c`` peak to peak and a wobble."""
    return (mean_c + 0.5 * swing_c * np.sin(2 * np.pi * secs / 86400.0 + phase)
            + 1.0 * np.sin(2 * np.pi * secs / 6000.0))


def comet_day(day: str, *, seed: int, b0: float = 18.0, rate_hz: float = 0.25,
              start_s: float = 0.0, hours: float = 24.0, mean_c: float = -105.0,
              swing_c: float = 24.0, phase: float = 0.0, compression: float = COMPRESSION,
              coefficients: np.ndarray | None = None,
              jump: np.ndarray | None = None, jump_s: float = 43200.0,
              temperature_shift_c: float = 0.0, rotation_cut_s: float = ROTATION_CUT_S):
    """Raw OB science of the comet day: ``(raw, b_true_urf, temperature_c, offset_urf)``.

    ``offset_urf`` is the true extended offset ``P(T~)`` plus the jump (nT) the forward
    model added to each vector.  ``jump`` (3, nT) is added from ``jump_s`` after midnight
    on.  ``temperature_shift_c`` moves the whole temperature history (a stretch outside
    the range of a fit).  Filter mode SID 2.
    """
    rng = np.random.default_rng(seed)
    cal = calib.load_ground_calibration("OB")
    coefficients = true_coefficients() if coefficients is None else coefficients
    secs, stamps, sid, delay = time_line(day, start_s, hours, rate_hz)
    b = comet_field(secs, b0, rng, compression=compression, rotation_cut_s=rotation_cut_s)
    temp = temperature(secs + delay, mean_c, swing_c, phase) + temperature_shift_c
    model = DailyOffsetModel(np.datetime64(day, "D"), "OB", coefficients, "truth")
    ext = forward.extended_offset(stamps, forward.reduced_temperature(temp, cal),
                                  {model.day: model})
    if jump is not None:
        ext = ext + np.where((secs + delay >= jump_s)[:, None], np.asarray(jump), 0.0)
    raw = instrument_raw(stamps, sid, b + ext, temp, cal, calib.load_nominal_conversion(),
                         f"comet day seed {seed}")
    return raw, b, temp, ext
