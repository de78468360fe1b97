"""Removal of narrow spectral lines (reaction wheels, LAP) from a vector time series.

The procedure of the LEVEL_H product of seed 003, in a form usable for any
magnetometer: the series is cut into windows of 1024 samples overlapping by 25 %, each
window is Fourier transformed without a taper, and in a band of width ``delta_f``
around every (aliased) line frequency the spectrum is replaced by complex Gaussian
noise whose mean power is the power just outside the band (random phase, seeded and
reproducible).  The windows are transformed back and recombined with complementary
raised-cosine crossfade weights (they sum to one at every sample), so the cleaned
series stays continuous across window boundaries.

Only the *change* ``cleaned - original`` is synthesised per window and crossfaded, so a
series is left bit-for-bit unchanged where no line band was touched, and outside the
bands the change is limited to the crossfade's spectral leakage (see the tests).

References
----------
.. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028, issue 3 rev. 1),
   sec. 4.9 (LEVEL_H: reaction wheel and LAP disturbance removal).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fluxcal.errors import InputFormatError

__all__ = [
    "BURST_BANDWIDTH_HZ",
    "LineRemovalResult",
    "crossfade_weights",
    "default_bandwidth",
    "dynamic_spectrum",
    "fold_frequency",
    "interpolated_lines",
    "remove_spectral_lines",
    "window_starts",
]

log = logging.getLogger(__name__)

#: Band width used by the instrument team in BURST mode (20 vectors/s), seed 003 sec. 4.9.
BURST_BANDWIDTH_HZ = 0.06
#: Sampling rate of the BURST mode of seed 003, at which `BURST_BANDWIDTH_HZ` applies.
BURST_RATE_HZ = 20.0

#: Bins skipped on each side of a band before the neighbourhood starts (Hann main lobe).
_GUARD_BINS = 2

LineFrequencies = Callable[[NDArray[np.float64]], NDArray[np.float64]] | ArrayLike


def fold_frequency(frequency: ArrayLike, fs: float) -> NDArray[np.float64]:
    """Alias a frequency into the measured band ``[0, fs/2]`` (sampling theorem).

    Parameters
    ----------
    frequency : array_like
        True frequencies in Hz (sign ignored; NaN propagates).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    ndarray
        Apparent frequencies in ``[0, fs/2]``.

    References
    ----------
    .. [1] RO-IGEP-TR0028, sec. 4.9 ("folded down ... according to the Nyquist
       sampling theorem").

    Examples
    --------
    >>> fold_frequency([3.0, 12.0, 27.5, 40.0], 20.0)
    array([3. , 8. , 7.5, 0. ])
    """
    if fs <= 0:
        raise InputFormatError(f"sampling rate must be > 0, got {fs}", field="fs")
    f = np.mod(np.abs(np.asarray(frequency, dtype=float)), fs)
    return np.where(f > fs / 2, fs - f, f)


def default_bandwidth(fs: float) -> float:
    """Width ``delta_f`` of the replaced band for sampling rate ``fs``.

    0.06 Hz at 20 vectors/s (seed value) and proportional to ``fs`` otherwise, so the
    band always spans the same number (about 3) of 1024-point FFT bins.

    References
    ----------
    .. [1] RO-IGEP-TR0028, sec. 4.9 ("For Burst mode we use delta_f = 0.06 Hz";
       proportional scaling is a fluxcal decision, docs/decisions/cleaning.md).
    """
    return BURST_BANDWIDTH_HZ * fs / BURST_RATE_HZ


def window_starts(n: int, length: int, overlap: float) -> NDArray[np.int64]:
    """First-sample indices of windows of ``length`` covering ``n`` samples.

    Windows advance by ``length - round(overlap * length)`` samples; the last window is
    moved back to end exactly at the last sample, so every sample is covered.
    """
    if n < length:
        raise InputFormatError(f"series of {n} samples shorter than window {length}", field="n")
    hop = length - int(round(overlap * length))
    starts = np.arange(0, n - length + 1, hop, dtype=np.int64)
    if starts[-1] != n - length:
        starts = np.append(starts, np.int64(n - length))
    return starts


def crossfade_weights(starts: ArrayLike, length: int, n: int) -> NDArray[np.float64]:
    """Weights (n_windows, length) for recombining overlapping windows; they sum to one.

    Each window gets a raised-cosine ramp over its overlap with the previous and the
    next window (``sin^2`` up, ``cos^2`` down, complementary), flat 1 elsewhere; the
    tapers are then divided by their sum at each sample, which makes the weights sum
    to exactly one even where three windows overlap (short last window).
    """
    s = np.asarray(starts, dtype=np.int64)
    nw = s.size
    k = np.arange(length)
    ends = s + length
    left = np.zeros(nw, dtype=np.int64)
    right = np.zeros(nw, dtype=np.int64)
    left[1:] = np.maximum(ends[:-1] - s[1:], 0)
    right[:-1] = np.maximum(ends[:-1] - s[1:], 0)
    # most windows share the same pair of overlaps: build each distinct taper once
    pairs, inverse = np.unique(np.stack([left, right], axis=1), axis=0, return_inverse=True)
    shapes = np.ones((pairs.shape[0], length))
    for row, (lo, ro) in enumerate(pairs):
        if lo > 0:
            shapes[row, :lo] = np.sin(0.5 * np.pi * (np.arange(lo) + 0.5) / lo) ** 2
        if ro > 0:
            shapes[row, length - ro :] *= np.cos(0.5 * np.pi * (np.arange(ro) + 0.5) / ro) ** 2
    taper = shapes[inverse.ravel()]
    idx = (s[:, None] + k[None, :]).ravel()
    total = np.bincount(idx, weights=taper.ravel(), minlength=n)
    return taper / total[idx].reshape(nw, length)


def interpolated_lines(
    times: ArrayLike, frequencies: ArrayLike, *, max_extrapolation: float = 600.0
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Line frequencies varying with time, e.g. reaction wheel rates from a table.

    Parameters
    ----------
    times : array_like, shape (m,)
        Increasing times (seconds, same time base as the series) of the table rows.
    frequencies : array_like, shape (m, k)
        True (unfolded) frequencies in Hz of ``k`` lines; NaN means "line absent".
    max_extrapolation : float
        How far (seconds) outside the table the first/last rows are held constant.

    Returns
    -------
    callable
        ``f(t) -> (len(t), k)`` linear interpolation in time.  Raises
        `InputFormatError` for times further than ``max_extrapolation`` outside.
    """
    tt = np.asarray(times, dtype=float)
    ff = np.asarray(frequencies, dtype=float)
    if ff.ndim == 1:
        ff = ff[:, None]
    if tt.ndim != 1 or ff.shape[0] != tt.size or tt.size < 1:
        raise InputFormatError(
            f"times {tt.shape} and frequencies {ff.shape} do not match", field="frequencies"
        )
    if tt.size > 1 and np.any(np.diff(tt) <= 0):
        raise InputFormatError("times must be strictly increasing", field="times")

    def at(t: NDArray[np.float64]) -> NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        outside = (t < tt[0] - max_extrapolation) | (t > tt[-1] + max_extrapolation)
        if np.any(outside):
            bad = t[outside][0]
            raise InputFormatError(
                f"line frequencies needed at t={bad:.3f} s but the table covers "
                f"[{tt[0]:.3f}, {tt[-1]:.3f}] s (+/- {max_extrapolation} s)",
                field="times",
            )
        return np.stack([np.interp(t, tt, ff[:, j]) for j in range(ff.shape[1])], axis=-1)

    return at


@dataclass(frozen=True)
class LineRemovalResult:
    """Output of `remove_spectral_lines`.

    Attributes
    ----------
    values : ndarray, shape like the input
        Cleaned series.
    bandwidth : float
        Width ``delta_f`` (Hz) of the replaced bands.
    window_times : ndarray
        Time (same scale as ``times``) of the first sample of each FFT window.
    line_frequencies : ndarray, shape (n_windows, n_lines)
        Folded line frequencies (Hz) used in each window (NaN: line absent).
    segments : list of (int, int)
        Sample ranges processed separately (split at gaps longer than
        ``max_fill_samples``, repeated or interleaved times); ranges shorter than 8
        samples are left unchanged.
    notes : list of str
        Human-readable notes (short segments passed through, ...).
    """

    values: NDArray[np.float64]
    bandwidth: float
    window_times: NDArray[np.float64]
    line_frequencies: NDArray[np.float64]
    segments: list[tuple[int, int]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _line_callable(lines: LineFrequencies) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    if callable(lines):
        return lines
    fixed = np.atleast_1d(np.asarray(lines, dtype=float))
    if fixed.ndim != 1:
        raise InputFormatError(
            "fixed line frequencies must be a 1-D list of Hz", field="line_frequencies"
        )
    return lambda t: np.broadcast_to(fixed, (np.size(t), fixed.size))


def _segments(times: NDArray[np.float64], fs: float, max_fill: int) -> list[tuple[int, int]]:
    """Maximal runs of samples whose spacing lies within [0.5, max_fill + 1.5] / fs."""
    dt = np.diff(times)
    breaks = np.flatnonzero((dt > (max_fill + 1.5) / fs) | (dt < 0.5 / fs)) + 1
    edges = np.concatenate([[0], breaks, [times.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _band_edges(
    f_low: NDArray[np.float64],
    f_high: NDArray[np.float64],
    f_centre: NDArray[np.float64],
    df: float,
    nb: int,
    bandwidth: float,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """Inclusive bin ranges [lo, hi] of the bands; the DC bin is never touched.

    The band spans ``[f_low - delta_f/2, f_high + delta_f/2]`` where ``f_low``/``f_high``
    are the extreme folded frequencies of the line within the window (equal for a
    steady line); the bin nearest ``f_centre`` is always included.
    """
    valid = np.isfinite(f_low) & np.isfinite(f_high) & np.isfinite(f_centre)
    half = 0.5 * bandwidth / df
    near = np.rint(np.where(valid, f_centre, 0.0) / df)
    lo = np.minimum(np.ceil(np.where(valid, f_low, 0.0) / df - half - 1e-9), near)
    hi = np.maximum(np.floor(np.where(valid, f_high, 0.0) / df + half + 1e-9), near)
    lo = np.clip(lo, 1, nb - 1).astype(np.int64)
    hi = np.clip(hi, 0, nb - 1).astype(np.int64)
    valid &= hi >= lo
    return lo, hi, valid


def _neighbour_power(
    power: NDArray[np.float64],
    usable: NDArray[np.bool_],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    neighbour_bins: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean background power per bin just below and just above each band.

    ``power`` (c, nw, nb), ``usable`` (nw, nb), ``lo``/``hi`` (nw, k); returns two
    (c, nw, k) arrays.  Bins within `_GUARD_BINS` of the band are skipped; a side with
    no usable bin takes the other side's value, and if both are empty the window's
    mean usable power is used.
    """
    c, nw, nb = power.shape
    cs_p = np.concatenate([np.zeros((c, nw, 1)), np.cumsum(power * usable, axis=-1)], axis=-1)
    cs_n = np.concatenate([np.zeros((nw, 1)), np.cumsum(usable, axis=-1)], axis=-1)

    def side(a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.float64]:
        a = np.clip(a, 0, nb)
        b = np.clip(b, 0, nb)
        s = np.take_along_axis(cs_p, np.broadcast_to(b, (c, *b.shape)), axis=-1) - (
            np.take_along_axis(cs_p, np.broadcast_to(a, (c, *a.shape)), axis=-1)
        )
        m = np.take_along_axis(cs_n, b, axis=-1) - np.take_along_axis(cs_n, a, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(m > 0, s / m, np.nan)

    g = _GUARD_BINS
    p_left = side(lo - g - neighbour_bins, lo - g)  # bins [lo-g-S, lo-g)
    p_right = side(hi + 1 + g, hi + 1 + g + neighbour_bins)  # bins (hi+g, hi+g+S]
    with np.errstate(invalid="ignore", divide="ignore"):
        fallback = (cs_p[..., -1] / cs_n[:, -1])[..., None]
    p_left, p_right = (
        np.where(np.isfinite(p_left), p_left, p_right),
        np.where(np.isfinite(p_right), p_right, p_left),
    )
    p_left = np.nan_to_num(np.where(np.isfinite(p_left), p_left, fallback))
    p_right = np.nan_to_num(np.where(np.isfinite(p_right), p_right, fallback))
    return p_left, p_right


def _slow_part(
    x: NDArray[np.float64], fs: float, f_pass: float, f_stop: float
) -> NDArray[np.float64]:
    """Low-pass (n, c) of a whole segment: 1 below ``f_pass``, cos^2 to 0 at ``f_stop``.

    The segment is extended at both ends by odd reflection about its end values
    (``2 x[0] - x[k]``), which continues the value and the slope, so the transform's
    periodic wrap, placed four stop-band periods away from the data, does not leak
    into the segment; the extension is removed after filtering.
    """
    n = x.shape[0]
    p = int(min(n - 1, np.ceil(4.0 * fs / f_stop)))
    head = 2.0 * x[:1] - x[p:0:-1]
    tail = 2.0 * x[-1:] - x[-2 : -p - 2 : -1]
    ext = np.concatenate([head, x, tail])
    m = scipy.fft.next_fast_len(ext.shape[0], real=True)
    ext = np.pad(ext, ((0, m - ext.shape[0]), (0, 0)), mode="edge")
    f = scipy.fft.rfftfreq(m, 1.0 / fs)
    ramp = np.clip((f - f_pass) / (f_stop - f_pass), 0.0, 1.0)
    gain = np.cos(0.5 * np.pi * ramp) ** 2
    low = scipy.fft.irfft(scipy.fft.rfft(ext, axis=0) * gain[:, None], n=m, axis=0)
    return low[p : p + n]


def _poly_basis(length: int, degree: int) -> NDArray[np.float64]:
    """Orthonormal basis (length, degree + 1) of the polynomials on ``length`` points.

    QR of a Vandermonde matrix in ``[-1, 1]``; the least-squares polynomial of ``a``
    (last axis) is ``(a Q) Q^T``.  ``degree < 0``: an empty basis (no detrending).
    """
    if degree < 0:
        return np.zeros((length, 0))
    s = np.linspace(-1.0, 1.0, length)
    q, _ = np.linalg.qr(np.vander(s, min(degree, length - 1) + 1, increasing=True))
    return q


def _clean_segment(
    x: NDArray[np.float64],
    t: NDArray[np.float64],
    fs: float,
    lines: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    bandwidth: float,
    window_length: int,
    overlap: float,
    neighbour_bins: int,
    detection_snr: float,
    rng: np.random.Generator,
    detrend_degree: int = 3,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """Clean one gap-free segment ``x`` (n, c); returns (cleaned, starts, folded lines)."""
    n, c = x.shape
    length = min(window_length, n)
    starts = window_starts(n, length, overlap)
    nw = starts.size
    idx = starts[:, None] + np.arange(length)[None, :]
    nb = length // 2 + 1
    df = fs / length
    t_first, t_last = t[starts], t[starts + length - 1]
    t_mid = 0.5 * (t_first + t_last)
    raw = np.asarray(lines(np.concatenate([t_first, t_mid, t_last])), dtype=float)
    f_first, f_mid, f_last = fold_frequency(raw.reshape(3, nw, -1), fs)  # each (nw, k)
    f_low = np.minimum(np.minimum(f_first, f_mid), f_last)
    f_high = np.maximum(np.maximum(f_first, f_mid), f_last)
    lo, hi, valid = _band_edges(f_low, f_high, f_mid, df, nb, bandwidth)  # (nw, k)
    width = np.where(valid, hi - lo + 1, 0)  # (nw, k)
    nbw = int(width.max()) if width.size else 0
    if nbw == 0:
        return x.copy(), starts, f_mid
    # The slow part (field, trends, waves below the bands) is removed before the
    # transforms and never enters them: only the change made in the band bins is
    # transformed back and added to the series.  Without this, the untapered windows'
    # leakage of a strong slow field sits in the band bins and replacing it adds a
    # line (issue 11).  Two stages: a low-pass of the whole segment (`_slow_part`)
    # stopping a power of two of bins >= 4 below each window's lowest band (guard
    # bins off), then each window's least-squares polynomial of `detrend_degree`.
    lowest = np.where(valid, lo, nb).min(axis=1) - _GUARD_BINS  # (nw,)
    level = np.where(lowest >= 4, 2 ** np.floor(np.log2(np.maximum(lowest, 1))), 0)
    frames = x.T[:, idx]  # (c, nw, L)
    for stop_bins in np.unique(level[level > 0]):
        sel = level == stop_bins
        f_stop = float(stop_bins) * df
        resid = x - _slow_part(x, fs, 0.5 * f_stop, f_stop)
        frames[:, sel] = resid.T[:, idx[sel]]
    q = _poly_basis(length, detrend_degree)
    frames = frames - (frames @ q) @ q.T
    spec = scipy.fft.rfft(frames, axis=-1)  # (c, nw, nb)
    k_lines = lo.shape[1]
    bidx = lo[..., None] + np.arange(nbw)  # (nw, k, B): bins of each band, gathered
    bvalid = np.arange(nbw) < width[..., None]
    bidx = np.where(bvalid, bidx, 0)
    w_of = np.broadcast_to(np.arange(nw)[:, None, None], bidx.shape)
    mask = np.zeros((nw, nb), dtype=bool)
    mask[w_of[bvalid], bidx[bvalid]] = True
    flat_b = bidx.reshape(nw, -1)

    def gather(a: NDArray) -> NDArray:
        """(..., nw, nb) -> (..., nw, k, B) values at the band bins."""
        ind = np.broadcast_to(flat_b, (*a.shape[:-2], *flat_b.shape))
        return np.take_along_axis(a, ind, axis=-1).reshape(*a.shape[:-1], k_lines, nbw)

    # Background level from a Hann-tapered spectrum of the same window: the untapered
    # spectrum's slowly decaying sidelobes would carry the line into its neighbours.
    taper = np.hanning(length + 2)[1:-1]
    tapered = scipy.fft.rfft(frames * taper, axis=-1)
    power = (tapered.real**2 + tapered.imag**2) / np.mean(taper**2)  # (c, nw, nb)
    usable = ~mask
    usable[:, 0] = False  # DC carries the field, not background noise
    p_left, p_right = _neighbour_power(power, usable, lo, hi, neighbour_bins)  # (c, nw, k)

    # 1) Fit and subtract each line (a sinusoid whose folded frequency moves linearly
    #    from the window's first to last sample) by least squares on its band bins; its
    #    whole rectangular-window leakage pattern goes with it (subtracted in the time
    #    domain).  Only significant fits (band power > detection_snr x background) count.
    sb = gather(spec)  # (c, nw, k, B): current spectrum at the band bins
    model_t = np.zeros((c, nw, length), dtype=np.float32)
    nn = np.arange(length)
    qf = q.astype(np.float32)
    q_b = gather(np.broadcast_to(scipy.fft.rfft(q.T, axis=-1)[:, None, :], (q.shape[1], nw, nb)))
    for j in range(k_lines):  # loop over the few lines only
        wj = bvalid[:, j, :]  # (nw, B)
        if not wj.any():
            continue
        fa = np.nan_to_num(f_first[:, j])[:, None]
        fb = np.nan_to_num(f_last[:, j])[:, None]
        phase = (2 * np.pi / fs) * (fa * nn + (fb - fa) * nn**2 / (2 * (length - 1)))
        # reduced to [0, 2 pi) in float64, then single precision: the fit needs ~1e-4
        # relative accuracy (-80 dB) and float32 cos/sin/FFT are several times faster
        phase = np.mod(phase, 2 * np.pi).astype(np.float32)
        u_t, v_t = np.cos(phase), np.sin(phase)  # (nw, L) float32
        # fitted against the detrended window, so the basis is detrended too (in the
        # spectrum: minus its polynomial's transform); the full sinusoid (u_t, v_t) is
        # what is subtracted from the series
        ub = gather(scipy.fft.rfft(u_t, axis=-1)) - np.einsum("wd,dwkb->wkb", u_t @ qf, q_b)
        vb = gather(scipy.fft.rfft(v_t, axis=-1)) - np.einsum("wd,dwkb->wkb", v_t @ qf, q_b)
        uj, vj = ub[:, j, :], vb[:, j, :]
        uu = np.sum(wj * np.abs(uj) ** 2, axis=-1)
        vv = np.sum(wj * np.abs(vj) ** 2, axis=-1)
        uv = np.sum(wj * (uj.conj() * vj).real, axis=-1)
        su = np.sum(wj * (uj.conj() * sb[:, :, j, :]).real, axis=-1)  # (c, nw)
        sv = np.sum(wj * (vj.conj() * sb[:, :, j, :]).real, axis=-1)
        det = uu * vv - uv**2
        ok = det > 1e-12 * np.maximum(uu * vv, 1e-300)
        with np.errstate(invalid="ignore", divide="ignore"):
            alpha = np.where(ok, (vv * su - uv * sv) / det, 0.0)
            beta = np.where(ok, (uu * sv - uv * su) / det, 0.0)
        fit_power = alpha**2 * uu + beta**2 * vv + 2 * alpha * beta * uv
        bg_power = 0.5 * (p_left[..., j] + p_right[..., j]) * width[:, j]
        keep = (fit_power > detection_snr * bg_power) & valid[:, j]
        alpha = np.where(keep, alpha, 0.0)
        beta = np.where(keep, beta, 0.0)
        sb -= alpha[..., None, None] * ub + beta[..., None, None] * vb
        model_t += alpha.astype(np.float32)[..., None] * u_t
        model_t += beta.astype(np.float32)[..., None] * v_t

    # The background around the bands, again from the Hann-tapered spectrum but now of
    # the window without the fitted lines: a strong line's Hann sidelobes 4 bins away
    # (-50 dB) would otherwise set the substituted noise above the background.
    if np.any(model_t):
        tapered = scipy.fft.rfft((frames - model_t) * taper, axis=-1)
        power = (tapered.real**2 + tapered.imag**2) / np.mean(taper**2)
        p_left, p_right = _neighbour_power(power, usable, lo, hi, neighbour_bins)

    # 2) Replace the band bins by complex Gaussian noise (random phase) whose mean power
    #    runs linearly from the level below the band to the level above it.
    frac = np.clip((np.arange(nbw) + 1) / (width[..., None] + 1), 0.0, 1.0)  # (nw, k, B)
    target = p_left[..., None] + (p_right - p_left)[..., None] * frac  # (c, nw, k, B)
    target = np.maximum(target, 0.0)  # round-off of the cumulative sums
    noise = rng.standard_normal((2, *target.shape))
    real_bin = (bidx == nb - 1) & (length % 2 == 0)  # Nyquist bin of an even-length FFT
    z = np.where(real_bin, noise[0] + 0j, (noise[0] + 1j * noise[1]) / np.sqrt(2.0))
    new = np.sqrt(target) * z
    delta = np.zeros_like(spec)
    delta[:, w_of[bvalid], bidx[bvalid]] = (new - sb)[:, bvalid]

    # 3) Transform only the change back and crossfade it into the series.
    change = scipy.fft.irfft(delta, n=length, axis=-1) - model_t  # (c, nw, L)
    weights = crossfade_weights(starts, length, n)
    flat_idx = idx.ravel()
    out = x.copy()
    for comp in range(c):
        out[:, comp] += np.bincount(flat_idx, weights=(weights * change[comp]).ravel(), minlength=n)
    return out, starts, f_mid


def remove_spectral_lines(
    values: ArrayLike,
    fs: float,
    line_frequencies: LineFrequencies,
    *,
    times: ArrayLike | None = None,
    bandwidth: float | None = None,
    window_length: int = 1024,
    overlap: float = 0.25,
    neighbour_bins: int = 4,
    detection_snr: float = 10.0,
    max_fill_samples: int = 10,
    detrend_degree: int = 3,
    seed: int | np.random.Generator = 0,
) -> LineRemovalResult:
    """Remove narrow (possibly drifting, aliased) spectral lines from a series.

    Parameters
    ----------
    values : array_like, shape (n,) or (n, c)
        Uniformly sampled series (e.g. the three field components in nT).
    fs : float
        Sampling rate in Hz.
    line_frequencies : callable or array_like
        True (unfolded) line frequencies in Hz: either a fixed list (e.g. LAP lines) or
        a callable ``f(t) -> (len(t), k)`` evaluated at each window's centre time (see
        `interpolated_lines` for reaction-wheel tables).  NaN means "no line".
    times : array_like, shape (n,), optional
        Sample times in seconds (default ``arange(n) / fs``).  Gaps of up to
        ``max_fill_samples`` missing samples are filled by linear interpolation for the
        transforms only (the filled samples are not returned); longer gaps, repeated or
        interleaved times split the series into segments processed separately;
        segments shorter than 8 samples are left unchanged (noted in the result).
    bandwidth : float, optional
        Width ``delta_f`` (Hz) of the replaced band around each folded line (default
        `default_bandwidth`: 0.06 Hz at 20 Hz).  The bin nearest the line is always
        replaced; the DC bin never is.
    window_length : int
        FFT window length in samples (1024 in the seed).
    overlap : float
        Fractional overlap of consecutive windows (0.25 in the seed), in [0, 0.5].
    neighbour_bins : int
        Number of bins on each side of a band whose mean power sets the noise level.
    detection_snr : float
        A line is fitted and subtracted (with its leakage) in a window only where the
        fitted band power exceeds this multiple of the background power in the band;
        otherwise only the band replacement is done.
    max_fill_samples : int
        Longest gap (in missing samples) bridged by interpolation inside a segment.
    detrend_degree : int
        Degree of the least-squares polynomial removed from each window (after the
        segment's low-pass) before the transforms; -1 disables it.
    seed : int or numpy.random.Generator
        Seed of the substituted noise (reproducible).

    Returns
    -------
    LineRemovalResult
        Cleaned values plus the windows and folded frequencies used.

    Raises
    ------
    InputFormatError
        On malformed arguments.

    Notes
    -----
    The slow part is removed before the transforms and left in the series: an
    untapered window's leakage of a strong slow field reaches the band bins, and
    replacing that leakage by background noise would add a line (issue 11).  It is
    removed in two stages: a low-pass of the whole segment (odd reflection at the
    ends, cos^2 transition from half to all of a power of two of bins >= 4 that stays
    `_GUARD_BINS` below the window's lowest band), then the window's least-squares
    polynomial of ``detrend_degree``.  Each window is then transformed with a real FFT
    (the non-negative half of the complex
    FFT of a real series; replacing a bin and its mirror together keeps the series
    real), without a taper as in the seed.  Because an untapered window leaks a line
    into neighbouring bins with only 1/d amplitude decay, a 0.06 Hz band alone removes
    only about 19 dB of a line's power; fluxcal therefore first fits, in each window,
    a sinusoid at the known (linearly drifting) folded frequency to the band bins and
    subtracts it with its whole leakage pattern, then replaces the band bins as the
    seed describes: complex Gaussian noise of mean power linearly interpolated between
    the mean powers of ``neighbour_bins`` bins just below and above the band (random,
    uniformly distributed phase).  The background levels are read from a Hann-tapered
    spectrum of the same window after the fitted lines are subtracted, two bins away
    from the band, so the line's own leakage does not inflate them.

    References
    ----------
    .. [1] Rosetta RPC-MAG Calibration Procedure (RO-IGEP-TR0028), sec. 4.9.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 20.0
    >>> t = np.arange(20000) / fs
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(0, 0.1, t.size) + np.sin(2 * np.pi * 27.3 * t)  # aliased to 7.3 Hz
    >>> res = remove_spectral_lines(x, fs, [27.3])
    >>> bool(np.std(res.values) < 0.2)
    True
    """
    x = np.asarray(values, dtype=float)
    one_d = x.ndim == 1
    if one_d:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 1:
        raise InputFormatError(f"expected (n,) or (n, c) values, got {x.shape}", field="values")
    if not np.all(np.isfinite(x)):
        raise InputFormatError("values contain non-finite samples", field="values")
    if fs <= 0:
        raise InputFormatError(f"sampling rate must be > 0, got {fs}", field="fs")
    if window_length < 8:
        raise InputFormatError(
            f"window_length must be >= 8, got {window_length}", field="window_length"
        )
    if not 0 <= overlap <= 0.5:
        raise InputFormatError(f"overlap must be in [0, 0.5], got {overlap}", field="overlap")
    if detection_snr < 0:
        raise InputFormatError(
            f"detection_snr must be >= 0, got {detection_snr}", field="detection_snr"
        )
    if max_fill_samples < 0:
        raise InputFormatError(
            f"max_fill_samples must be >= 0, got {max_fill_samples}", field="max_fill_samples"
        )
    if neighbour_bins < 1:
        raise InputFormatError(
            f"neighbour_bins must be >= 1, got {neighbour_bins}", field="neighbour_bins"
        )
    n = x.shape[0]
    t = np.arange(n) / fs if times is None else np.asarray(times, dtype=float)
    if t.shape != (n,):
        raise InputFormatError(f"times has shape {t.shape}, expected ({n},)", field="times")
    if not np.all(np.isfinite(t)):
        raise InputFormatError("times contain non-finite values", field="times")
    bw = default_bandwidth(fs) if bandwidth is None else float(bandwidth)
    if bw <= 0:
        raise InputFormatError(f"bandwidth must be > 0 Hz, got {bw}", field="bandwidth")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    lines = _line_callable(line_frequencies)

    out = x.copy()
    all_starts: list[NDArray[np.float64]] = []
    all_folded: list[NDArray[np.float64]] = []
    notes: list[str] = []
    segs = _segments(t, fs, max_fill_samples) if n > 1 else [(0, n)]
    n_short = n_filled = 0
    for a, b in segs:
        if b - a < 8:
            n_short += b - a
            continue
        # put the segment on its uniform grid, filling short gaps linearly
        pos = np.floor((t[a:b] - t[a]) * fs + 0.5).astype(np.int64)
        grid = np.arange(pos[-1] + 1)
        if grid.size == b - a:
            xs = x[a:b]
        else:
            xs = np.stack([np.interp(grid, pos, x[a:b, j]) for j in range(x.shape[1])], 1)
            n_filled += grid.size - (b - a)
        cleaned, starts, folded = _clean_segment(
            xs,
            t[a] + grid / fs,
            fs,
            lines,
            bw,
            window_length,
            overlap,
            neighbour_bins,
            detection_snr,
            rng,
            detrend_degree,
        )
        out[a:b] = cleaned[pos]
        all_starts.append(t[a] + starts / fs)
        all_folded.append(folded)
    if n_short:
        notes.append(f"{n_short} samples in segments shorter than 8 samples left unchanged")
    if n_filled:
        notes.append(f"{n_filled} missing samples filled by interpolation for the FFT only")
    for note in notes:
        log.info(note)
    k = all_folded[0].shape[1] if all_folded else 0
    return LineRemovalResult(
        values=out[:, 0] if one_d else out,
        bandwidth=bw,
        window_times=np.concatenate(all_starts) if all_starts else np.zeros(0),
        line_frequencies=np.concatenate(all_folded) if all_folded else np.zeros((0, k)),
        segments=segs,
        notes=notes,
    )


def dynamic_spectrum(
    values: ArrayLike, fs: float, *, window_length: int = 1024, overlap: float = 0.25
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Power spectral density per window, for plots of the line removal.

    Parameters
    ----------
    values : array_like, shape (n,)
        One component of a uniformly sampled series.
    fs : float
        Sampling rate in Hz.
    window_length, overlap
        As in `remove_spectral_lines`.

    Returns
    -------
    starts : ndarray (n_windows,)
        First sample of each window.
    frequencies : ndarray (n_bins,)
        Bin frequencies in Hz.
    psd : ndarray (n_windows, n_bins)
        One-sided PSD (units^2/Hz) with a Hann taper (display only; the cleaning itself
        uses no taper).
    """
    x = np.asarray(values, dtype=float)
    length = min(window_length, x.size)
    starts = window_starts(x.size, length, overlap)
    frames = x[starts[:, None] + np.arange(length)[None, :]]
    frames = frames - frames.mean(axis=1, keepdims=True)
    taper = np.hanning(length)
    spec = scipy.fft.rfft(frames * taper, axis=-1)
    psd = (np.abs(spec) ** 2) / (fs * np.sum(taper**2))
    psd[:, 1:-1] *= 2.0
    return starts, scipy.fft.rfftfreq(length, 1.0 / fs), psd
