"""RPC-MAG disturbance-removal levels H, I, J, K, L as ``Dataset -> Dataset`` functions.

* `level_h`: reaction-wheel and LAP spectral lines removed from LEVEL_C (or L).
* `level_i`: 1 s averages of LEVEL_H.
* `level_j`: two-sensor PCA of OB and IB (LEVEL_G or I, resampled onto a common
  time base): external field and each sensor's uncorrelated part (three datasets).
* `level_k`: heater square waves removed from LEVEL_B (automatic method 1);
  `level_k_assisted`: the same with disturbed intervals from another instrument
  (ROMAP, method 2).
* `level_l`: LEVEL_K rotated to ECLIPJ2000 (with the spacecraft position).
* `level_f`, `level_g`: 1 s averages of LEVEL_K and LEVEL_L (the heater-disturbance
  paths of LEVEL_F and G).

The datasets follow the Rosetta level conventions (`fluxcal.missions.rosetta.level_c`):
``b`` (time, component) in nT, ``epoch`` TT2000 ns, ``sid`` (instrument mode),
``quality``; the generic algorithms live in `fluxcal.cleaning`.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.7 (F), 4.8 (G), 4.9 (H), 4.10 (I),
   4.11 (J), 4.12 (K), 4.13 (L).
"""

from __future__ import annotations

import logging
from collections.abc import Hashable, Mapping, Sequence

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike, NDArray

from fluxcal.cleaning.heater_pooling import pool_heater_signs
from fluxcal.cleaning.pca import two_sensor_pca
from fluxcal.cleaning.resample import (
    TwoSensorResample,
    interpolate_linear,
    resample_two_sensors,
)
from fluxcal.cleaning.spectral_lines import (
    default_bandwidth,
    interpolated_lines,
    remove_spectral_lines,
)
from fluxcal.cleaning.steps import remove_heater_steps, remove_labelled_offsets
from fluxcal.errors import InputFormatError
from fluxcal.missions.rosetta import averaged
from fluxcal.missions.rosetta.level_c import level_c
from fluxcal.missions.rosetta.reaction_wheels import ReactionWheelTable

__all__ = [
    "CLEANABLE_RATES_HZ",
    "level_f",
    "level_g",
    "level_h",
    "level_i",
    "level_j",
    "level_k",
    "level_k_assisted",
    "level_l",
]

log = logging.getLogger(__name__)

#: MEDIUM (5 vectors/s) and BURST (20 vectors/s) modes: the only rates at which the
#: wheel lines emerge from the noise (seed 003 sec. 4.9); others pass through unchanged.
CLEANABLE_RATES_HZ = (5.0, 20.0)
#: LEVEL_K: stretches further apart than this (s) are not compared at their border when
#: the heater-off level is pooled (`fluxcal.cleaning.heater_pooling`): over a longer gap
#: the background may move by as much as a lander heater's field.
POOL_MAX_GAP_S = 1.0


def _vectors(ds: xr.Dataset, level: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    if "b" not in ds or "epoch" not in ds.coords and "epoch" not in ds:
        raise InputFormatError(
            f"LEVEL_{level} input needs variables 'b' (time, component) and 'epoch'",
            field="b",
        )
    b = np.asarray(ds["b"].values, dtype=float)
    epoch = np.asarray(ds["epoch"].values, dtype=np.int64)
    if b.ndim != 2 or b.shape[1] != 3 or b.shape[0] != epoch.size:
        raise InputFormatError(f"'b' has shape {b.shape}, expected ({epoch.size}, 3)", field="b")
    if epoch.size > 1 and np.any(np.diff(epoch) < 0):
        raise InputFormatError("epoch is not in time order", field="epoch")
    return b, epoch


def _with_b(ds: xr.Dataset, b: NDArray[np.float64], description: str) -> xr.Dataset:
    out = ds.copy()
    attrs = dict(ds["b"].attrs)
    attrs.setdefault("units", "nT")
    attrs["description"] = description
    out["b"] = (("time", "component"), b, attrs)
    return out


def _groups(ds: xr.Dataset) -> list[tuple[object, NDArray[np.int64]]]:
    """Sample indices per instrument mode (``sid``), or one group without ``sid``."""
    n = ds.sizes["time"]
    if "sid" not in ds:
        return [(None, np.arange(n))]
    sid = np.asarray(ds["sid"].values)
    return [(int(s), np.flatnonzero(sid == s)) for s in np.unique(sid)]


def _match_rate(dt: NDArray[np.float64], rates: Sequence[float], tol: float) -> float | None:
    good = dt[dt > 0]
    if good.size == 0:
        return None
    est = 1.0 / float(np.median(good))
    for r in rates:
        if abs(est - r) <= tol * r:
            return float(r)
    return None


def level_h(
    level: xr.Dataset,
    wheels: ReactionWheelTable | None = None,
    lap_lines_hz: Sequence[float] = (),
    *,
    bandwidth_hz: float | None = None,
    rates_hz: Sequence[float] = CLEANABLE_RATES_HZ,
    rate_tolerance: float = 0.02,
    wheel_extrapolation_s: float = 600.0,
    seed: int = 0,
) -> xr.Dataset:
    """LEVEL_C (or L) -> LEVEL_H: remove reaction-wheel and LAP lines.

    Parameters
    ----------
    level : xarray.Dataset
        LEVEL_C or LEVEL_L of the primary sensor (``b`` in nT, ``epoch``, optional
        ``sid``: each instrument mode is processed as its own series).
    wheels : ReactionWheelTable, optional
        Wheel rotation rates versus time (`read_reaction_wheels`); they are folded
        into the measured band per window.
    lap_lines_hz : sequence of float
        Fixed LAP disturbance lines (Hz, as seen in the spectrum of the mode).
    bandwidth_hz : float, optional
        Width of the replaced bands (default: 0.06 Hz at 20 Hz, scaled with the rate).
    rates_hz : sequence of float
        Sampling rates that are cleaned; a mode at any other rate is passed through
        unchanged with a note in the attributes.
    rate_tolerance : float
        Relative tolerance when matching a mode's median rate to ``rates_hz``.
    wheel_extrapolation_s : float
        How far the wheel table may be extrapolated (held) beyond its ends.
    seed : int
        Seed of the substituted noise (reproducible products).

    Returns
    -------
    xarray.Dataset
        Copy of ``level`` with cleaned ``b`` and ``level = "H"``; attributes
        ``line_removal_notes``, ``line_removal_bandwidth_hz``, ``reaction_wheel_file``,
        ``lap_lines_hz``, ``line_removal_seed``.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.9.
    """
    b, epoch = _vectors(level, "H")
    out_b = b.copy()
    notes: list[str] = []
    lap = np.asarray(list(lap_lines_hz), dtype=float)
    if epoch.size == 0 or (wheels is None and lap.size == 0):
        notes.append("no wheel table and no LAP lines: data unchanged")
    else:
        epoch0 = int(epoch[0])
        wheel_fn = None
        if wheels is not None:
            wheel_fn = interpolated_lines(
                (wheels.epoch - epoch0) / 1e9,
                wheels.frequencies,
                max_extrapolation=wheel_extrapolation_s,
            )

        def lines(tc: NDArray[np.float64]) -> NDArray[np.float64]:
            parts = [wheel_fn(tc)] if wheel_fn is not None else []
            parts.append(np.broadcast_to(lap, (np.size(tc), lap.size)))
            return np.concatenate(parts, axis=1)

        rng = np.random.default_rng(seed)
        for sid, idx in _groups(level):
            name = "all vectors" if sid is None else f"sid {sid}"
            t = (epoch[idx] - epoch0) / 1e9
            fs = _match_rate(np.diff(t), rates_hz, rate_tolerance) if idx.size > 1 else None
            if fs is None:
                rate = 1.0 / np.median(np.diff(t)[np.diff(t) > 0]) if idx.size > 2 else np.nan
                notes.append(
                    f"{name}: {idx.size} vectors at {rate:.3g} Hz, not one of "
                    f"{list(rates_hz)} Hz: passed through unchanged"
                )
                continue
            bw = default_bandwidth(fs) if bandwidth_hz is None else float(bandwidth_hz)
            check_line_arguments(name, fs, bw, lap)
            try:
                res = remove_spectral_lines(b[idx], fs, lines, times=t, bandwidth=bw, seed=rng)
            except InputFormatError as exc:
                if wheels is None or exc.field != "times":
                    raise
                raise InputFormatError(
                    f"{name}: {exc} (seconds after the first vector, TT2000 {epoch0} ns)",
                    path=wheels.source or None,
                    field="time_utc",
                ) from None
            out_b[idx] = res.values
            notes.append(
                f"{name}: {idx.size} vectors at {fs:g} Hz cleaned, delta_f = {bw:.4g} Hz, "
                f"{res.window_times.size} windows"
                + ("" if not res.notes else " (" + "; ".join(res.notes) + ")")
            )
    for note in notes:
        log.info("LEVEL_H %s", note)
    out = _with_b(level, out_b, "calibrated field; reaction wheel and LAP disturbance corrected")
    out.attrs.update(
        level="H",
        line_removal_notes="; ".join(notes),
        line_removal_bandwidth_hz=float(bandwidth_hz) if bandwidth_hz is not None else "auto",
        reaction_wheel_file=wheels.source if wheels is not None else "none",
        lap_lines_hz=[float(f) for f in lap],
        line_removal_seed=int(seed),
    )
    return out


#: Estimators of LEVEL_J (`fluxcal.cleaning.pca.two_sensor_pca` methods), default first.
PCA_ESTIMATORS = ("robust", "common-mode", "projection")


def check_line_arguments(
    name: str, fs: float, bandwidth_hz: float, lap_lines_hz: NDArray[np.float64]
) -> None:
    """Refuse a band width or LAP line that the sampling of a mode cannot hold.

    The replaced band (width ``bandwidth_hz``) must be narrower than the Nyquist
    frequency ``fs / 2`` (a band at least that wide replaces the whole spectrum: at
    20 Hz a 50-Hz band changed the data by 3.2 nT); a LAP line, given as seen in the
    mode's spectrum, must lie in ``(0, fs / 2]``.

    Raises
    ------
    InputFormatError
        One line naming the mode, its rate and the offending value.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.9.
    """
    nyquist = 0.5 * fs
    if not 0 < bandwidth_hz < nyquist:
        raise InputFormatError(
            f"{name} at {fs:g} Hz: band width {bandwidth_hz:g} Hz is not in (0, {nyquist:g}) "
            "Hz, below the Nyquist frequency; give a smaller --bandwidth",
            field="bandwidth",
        )
    bad = lap_lines_hz[~((lap_lines_hz > 0) & (lap_lines_hz <= nyquist))]
    if bad.size:
        raise InputFormatError(
            f"{name} at {fs:g} Hz: LAP line {bad[0]:g} Hz is not in (0, {nyquist:g}] Hz, "
            "the spectrum of the mode (LAP lines are given as seen in it); fix --lap-lines",
            field="lap_lines_hz",
        )


def level_i(level_h_ds: xr.Dataset, seconds: float = 1.0, *, lsk=None) -> xr.Dataset:
    """LEVEL_H -> LEVEL_I: ``seconds`` averages (1 s in the seed), time tag mid-interval.

    Needs a leap-second table (a loaded LSK or ``lsk``) for the UTC midnight origin.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.10.
    """
    out = averaged.average(level_h_ds, seconds, lsk=lsk)
    out.attrs.update(level="I")
    return out


def _average_heater_corrected(
    ds: xr.Dataset, source: str, target: str, seconds: float, lsk
) -> xr.Dataset:
    have = str(ds.attrs.get("level", source)).upper()
    if have != source:
        raise InputFormatError(
            f"LEVEL_{target} (heater disturbance) is made from LEVEL_{source}, "
            f"got a LEVEL_{have} dataset",
            field="level",
        )
    out = averaged.average(ds, seconds, lsk=lsk)
    out.attrs.update(level=target, averaged_from=f"LEVEL_{source}")
    return out


def level_f(level_k_ds: xr.Dataset, seconds: float = 1.0, *, lsk=None) -> xr.Dataset:
    """LEVEL_K -> LEVEL_F: ``seconds`` averages (1 s) of heater-corrected s/c-frame data.

    The seed's LEVEL_F is the average of LEVEL_B or, in case of heater disturbance, of
    LEVEL_K; the LEVEL_B path is the calibration pipeline's.  The averaging is the
    one of LEVEL_E/F/G (`fluxcal.missions.rosetta.averaged.average`): all vectors of
    each interval from UTC midnight summed and divided by their number, time tag at
    the interval middle; ``heater_disturbance`` is averaged alike.

    Raises
    ------
    InputFormatError
        If the dataset is not LEVEL_K.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.7.
    """
    return _average_heater_corrected(level_k_ds, "K", "F", seconds, lsk)


def level_g(level_l_ds: xr.Dataset, seconds: float = 1.0, *, lsk=None) -> xr.Dataset:
    """LEVEL_L -> LEVEL_G: ``seconds`` averages (1 s) of heater-corrected ECLIPJ2000 data.

    The seed's LEVEL_G is the average of LEVEL_C or, in case of heater disturbance, of
    LEVEL_L (position averaged alike); see `level_f` for the averaging.

    Raises
    ------
    InputFormatError
        If the dataset is not LEVEL_L.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.8.
    """
    return _average_heater_corrected(level_l_ds, "L", "G", seconds, lsk)


def _on_grid(ob: xr.Dataset, res: TwoSensorResample) -> xr.Dataset:
    """OB's per-time variables on a regular grid: floats interpolated, others nearest."""
    epoch = np.asarray(ob["epoch"].values, dtype=np.int64)
    near = np.clip(np.searchsorted(epoch, res.times), 1, max(epoch.size - 1, 1))
    near -= (res.times - epoch[near - 1]) <= (epoch[near] - res.times)  # nearest tag
    out = ob.isel(time=near)
    for name, var in ob.data_vars.items():
        if "time" in var.dims and var.dims[0] == "time" and var.dtype.kind == "f":
            vals, _, _ = interpolate_linear(epoch, var.values, res.times, reference=res.reference)
            out[name] = (var.dims, vals, var.attrs)
    return out.assign_coords(epoch=("time", res.times, ob["epoch"].attrs))


def level_j(
    ob: xr.Dataset,
    ib: xr.Dataset,
    *,
    step_s: float | None = None,
    max_gap_samples: float = 2.0,
    max_gap_s: float | None = None,
    estimator: str = "robust",
) -> dict[str, xr.Dataset]:
    """LEVEL_G/I of OB and IB -> LEVEL_J: external field and each sensor's own part.

    The two sensors are first put on a common time base
    (`fluxcal.cleaning.resample.resample_two_sensors`): the overlap of both series,
    on the OB tags there (default) or on a regular grid of ``step_s``; each sensor
    is linearly interpolated onto it, except across its own gaps longer than
    ``max_gap_samples`` sample intervals (those base times are dropped and counted).
    Identical OB/IB tags (both sensors averaged over the same intervals) need no
    interpolation and give the PCA of the samples themselves. The split is
    `fluxcal.cleaning.pca.two_sensor_pca`.

    Parameters
    ----------
    ob, ib : xarray.Dataset
        LEVEL_G or I of the outboard and inboard sensors (``b`` nT, ``epoch``).
    step_s : float, optional
        Step (s) of a regular common grid starting at the overlap start (default:
        the OB tags inside the overlap). On a grid, OB's other float variables
        (position, ...) are interpolated and integer ones (quality, sid) taken from
        the nearest OB vector.
    max_gap_samples : float
        Longest spacing bridged by interpolation, in each sensor's median sample
        intervals (default 2: one missing vector is bridged).
    max_gap_s : float, optional
        The same in seconds for both sensors (overrides ``max_gap_samples``).
    estimator : {"robust", "common-mode", "projection"}
        `fluxcal.cleaning.pca.two_sensor_pca`'s ``method``: ``"robust"`` (default,
        noise variances from the high-passed series), ``"common-mode"`` (from the
        series themselves) or ``"projection"`` (the literal principal component
        projection of sec. 4.11); recorded as ``pca_estimator``.

    Returns
    -------
    dict
        ``{"EXT": external field, "OB": uncorrelated OB part, "IB": uncorrelated IB
        part}``, each a dataset on the common times with ``b`` (nT) and attributes
        ``level = "J"``, ``pca_part``, ``pca_noise_variance_nT2`` (OB, IB per component),
        ``pca_weights``, ``pca_time_base``, ``pca_max_gap_s`` (OB, IB),
        ``pca_dropped_in_gaps`` (OB, IB), ``pca_dropped_vectors``,
        ``pca_interpolated_vectors`` (OB, IB), ``pca_outside_overlap`` (OB, IB vectors
        outside the time span both sensors cover).

    Raises
    ------
    InputFormatError
        If fewer than 3 times remain on the common time base.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.11.
    """
    b_ob, e_ob = _vectors(ob, "J")
    b_ib, e_ib = _vectors(ib, "J")
    step_ns = None if step_s is None else int(round(float(step_s) * 1e9))
    max_gap_ns = None if max_gap_s is None else int(round(float(max_gap_s) * 1e9))
    try:
        res = resample_two_sensors(
            e_ob,
            b_ob,
            e_ib,
            b_ib,
            step_ns=step_ns,
            max_gap_samples=max_gap_samples,
            max_gap_ns=max_gap_ns,
        )
    except InputFormatError as exc:
        sensor = "OB" if exc.field in ("t_a", "a") else "IB"
        field = "epoch" if str(exc.field).startswith("t_") else "b"
        text = str(exc).split(": ", 1)[-1]
        raise InputFormatError(f"{sensor}: {text}", field=field) from None
    if res.times.size < 3:
        raise InputFormatError(
            f"only {res.times.size} vectors on the common OB/IB time base "
            f"({res.base_size} in the overlap, {res.dropped} inside gaps); LEVEL_J needs "
            "both sensors over a common time span",
            field="epoch",
        )
    if estimator not in PCA_ESTIMATORS:
        raise InputFormatError(
            f"unknown PCA estimator {estimator!r}; choose one of {', '.join(PCA_ESTIMATORS)}",
            field="estimator",
        )
    pca = two_sensor_pca(res.a, res.b, method=estimator)  # type: ignore[arg-type]
    if step_ns is None:
        base = ob.isel(time=res.primary_index)
        time_base = "OB time tags inside the OB/IB overlap"
    else:
        base = _on_grid(ob, res)
        time_base = f"regular grid of {step_ns / 1e9:g} s from the OB/IB overlap start"
    span = (max(int(e_ob[0]), int(e_ib[0])), min(int(e_ob[-1]), int(e_ib[-1])))
    outside = [int(np.count_nonzero((e < span[0]) | (e > span[1]))) for e in (e_ob, e_ib)]
    stats = dict(
        level="J",
        pca_estimator=estimator,
        pca_noise_variance_nT2=[float(v) for v in pca.noise_variance.ravel()],
        pca_weights=[float(v) for v in pca.weights.ravel()],
        pca_external_variance_nT2=[float(v) for v in pca.external_variance],
        pca_inputs=[str(ob.attrs.get("source", "OB")), str(ib.attrs.get("source", "IB"))],
        pca_time_base=time_base,
        pca_max_gap_s=[g / 1e9 for g in res.max_gap_ns],
        pca_dropped_in_gaps=list(res.dropped_in_gaps),
        pca_dropped_vectors=res.dropped,
        pca_interpolated_vectors=list(res.interpolated),
        pca_outside_overlap=outside,
    )
    if res.dropped:
        log.info(
            "LEVEL_J: %d of %d common times dropped inside data gaps (OB %d, IB %d)",
            res.dropped,
            res.base_size,
            *res.dropped_in_gaps,
        )
    parts = {
        "EXT": (pca.external, "correlated OB/IB part: external field", "OB+IB"),
        "OB": (pca.uncorrelated_a, "uncorrelated OB part: s/c noise at OB", "OB"),
        "IB": (pca.uncorrelated_b, "uncorrelated IB part: s/c noise at IB", "IB"),
    }
    out: dict[str, xr.Dataset] = {}
    for key, (values, text, sensor) in parts.items():
        ds = _with_b(base, values, text)
        ds.attrs.update(stats, pca_part=key, sensor=sensor)
        out[key] = ds
    return out


def _uniform_segments(epoch: NDArray[np.int64], max_gap_s: float) -> list[tuple[int, int]]:
    """Split into runs without gaps longer than ``max_gap_s`` or overlapping modes."""
    if epoch.size < 2:
        return [(0, int(epoch.size))] if epoch.size else []
    dt = np.diff(epoch).astype(float)
    med = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    breaks = np.flatnonzero((dt > max(1.5 * med, max_gap_s * 1e9)) | (dt < 0.5 * med)) + 1
    edges = np.concatenate([[0], breaks, [epoch.size]])
    return [(int(a), int(c)) for a, c in zip(edges[:-1], edges[1:], strict=True) if c > a]


def level_k(
    level_b: xr.Dataset,
    *,
    width: int = 4,
    threshold: float | None = None,
    k_mad: float = 40.0,
    average_samples: int = 5,
    baseline_segments: int | None = 2,
    min_segment: int = 200,
    max_gap_s: float = 1.0,
    heater_direction: ArrayLike | None = None,
) -> xr.Dataset:
    """LEVEL_B -> LEVEL_K: remove heater square waves automatically (method 1).

    The vectors of each instrument mode (``sid``; all vectors when there is none) are
    taken in time order on their own, so the vectors of a new mode that overlap in time
    the end of the previous one (the filter time shifts differ: 8 s Normal, 28 s Low,
    224 s Minimum, sec. 4.2.3.5) are cleaned with their mode rather than left between
    two interleaved series.  Each stretch of a mode without gaps longer than
    ``max_gap_s`` (a few dropped vectors do not split it), of at least ``min_segment``
    vectors, is cleaned by `fluxcal.cleaning.steps.remove_heater_steps` (parameters
    passed through); shorter stretches are left unchanged.

    Which level of a square wave is "heater off" is read from the data
    (`fluxcal.cleaning.steps.heater_off_segments`); where no rule decides (a constant
    heater current seen from its first vector "on": the fallback rule ``first segment``
    takes the first level as off) the stretch is counted in ``heater_off_undecided`` and
    a warning says so.  ``heater_direction`` states the answer: the direction (s/c
    frame) in which the heater field points when the heater is on, so the level
    further along it is "on".

    Parameters
    ----------
    level_b : xarray.Dataset
        LEVEL_B (s/c frame, ``sid`` optional).
    heater_direction : array_like (3,), optional
        Direction of the heater field when on (s/c frame, any length); the disturbance
        axis and its sign are then taken as given, not estimated.
    width, threshold, k_mad, average_samples, baseline_segments
        Passed to `fluxcal.cleaning.steps.remove_heater_steps`.
    min_segment : int
        Shortest stretch (vectors) that is cleaned.
    max_gap_s : float
        Longest gap (s) inside a stretch.

    Returns
    -------
    xarray.Dataset
        Copy with cleaned ``b`` (s/c frame), ``heater_disturbance`` (time, component;
        the removed signal, nT), ``level = "K"`` and attributes ``heater_method``,
        ``heater_jumps``, ``heater_thresholds_nT2``, ``heater_off_rules`` (per cleaned
        stretch with jumps: how the heater-off level was identified, and the heater
        sign along the disturbance axis; `fluxcal.cleaning.steps.heater_off_segments`),
        ``heater_off_undecided`` (stretches where the data could not decide) and
        ``heater_direction`` (the stated direction, or ``"estimated"``).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12, 4.12.1.
    """
    b, epoch = _vectors(level_b, "K")
    out_b = b.copy()
    n_jumps = 0
    thresholds: list[float] = []
    off_rules: list[str] = []
    unchanged = 0
    undecided = 0
    direction = None
    if heater_direction is not None:
        direction = np.asarray(heater_direction, dtype=float)
        if direction.shape != (3,) or not np.linalg.norm(direction) > 0:
            raise InputFormatError(
                f"heater direction must be a non-zero 3-vector, got {heater_direction!r}",
                field="heater_direction",
            )
    stretches = []
    for _, group in _groups(level_b):
        group = group[np.argsort(epoch[group], kind="stable")]
        stretches += [group[a:c] for a, c in _uniform_segments(epoch[group], max_gap_s)]
    params = dict(width=width, threshold=threshold, k_mad=k_mad,
                  average_samples=average_samples, baseline_segments=baseline_segments)
    cleaned = []
    for idx in stretches:
        if idx.size < max(min_segment, 2 * width + 2):
            unchanged += idx.size
            continue
        res = remove_heater_steps(b[idx], direction=direction,
                                  heater_sign=None if direction is None else 1, **params)
        cleaned.append((idx, res))
    if direction is None:  # a stretch that cannot tell the off level asks the others
        results = pool_heater_signs(
            [epoch[idx] * 1e-9 for idx, _ in cleaned], [b[idx] for idx, _ in cleaned],
            [res for _, res in cleaned],
            lambda k, e, sign: remove_heater_steps(b[cleaned[k][0]], direction=e,
                                                   heater_sign=sign, **params),
            max_gap_s=POOL_MAX_GAP_S, samples=average_samples)
        cleaned = [(idx, res) for (idx, _), res in zip(cleaned, results, strict=True)]
    for idx, res in cleaned:
        out_b[idx] = res.values
        n_jumps += int(res.jump_indices.size)
        thresholds.append(float(res.threshold))
        if res.jump_indices.size:
            off_rules.append(f"{res.off_rule} (sign {res.heater_sign:+d})")
            if res.off_rule.startswith("first segment"):
                undecided += 1
                log.warning(
                    "LEVEL_K: %d vectors from TT2000 %d ns: which level is heater-off is not "
                    "decidable from the data (taken: the first); state the heater field direction "
                    "(--heater-direction X,Y,Z, s/c frame)", idx.size, int(epoch[idx[0]]),
                )
    out = _with_b(level_b, out_b, "calibrated field, s/c frame, heater disturbance eliminated")
    out["heater_disturbance"] = (
        ("time", "component"),
        b - out_b,
        {"units": "nT", "description": "removed heater disturbance (s/c frame)"},
    )
    out.attrs.update(
        level="K",
        heater_method="automatic: minimum variance + moving variance jumps (sec. 4.12.1)",
        heater_jumps=n_jumps,
        heater_thresholds_nT2=thresholds,
        heater_off_rules=off_rules,
        heater_unchanged_vectors=unchanged,
        heater_off_undecided=undecided,
        heater_direction=("estimated" if direction is None
                          else [float(v) for v in direction / np.linalg.norm(direction)]),
    )
    return out


def level_k_assisted(
    level_b: xr.Dataset,
    intervals: Sequence[tuple[int, int, Hashable]],
    offsets: Mapping[Hashable, ArrayLike] | None = None,
    *,
    reference_samples: int = 20,
) -> xr.Dataset:
    """LEVEL_B -> LEVEL_K with disturbed intervals from another instrument (method 2).

    Parameters
    ----------
    level_b : xarray.Dataset
        LEVEL_B (s/c frame).
    intervals : sequence of (start_tt2000, stop_tt2000, label)
        Disturbed intervals (e.g. identified in ROMAP data) and the active heaters.
    offsets : mapping label -> (3,) nT, optional
        Known offsets per label in the s/c frame; missing labels are estimated.
    reference_samples : int
        Undisturbed samples on each side of an interval for the estimate.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.12.2.
    """
    b, epoch = _vectors(level_b, "K")
    res = remove_labelled_offsets(epoch, b, intervals, offsets, reference_samples=reference_samples)
    out = _with_b(level_b, res.values, "calibrated field, s/c frame, heater disturbance eliminated")
    out["heater_disturbance"] = (
        ("time", "component"),
        b - res.values,
        {"units": "nT", "description": "removed heater disturbance (s/c frame)"},
    )
    out.attrs.update(
        level="K",
        heater_method="assisted: labelled intervals from another instrument (sec. 4.12.2)",
        heater_offsets_nT={str(k): [float(x) for x in v] for k, v in res.offsets.items()},
        heater_intervals=len(intervals),
    )
    return out


def level_l(
    level_k_ds: xr.Dataset,
    *,
    frame: str = "ECLIPJ2000",
    centre: str = "SUN",
    method: str = "interpolate",
    lsk=None,
) -> xr.Dataset:
    """LEVEL_K -> LEVEL_L: rotate to ECLIPJ2000 and add the spacecraft position.

    Kernels (SCLK, CK, SPK) must be loaded; the rotation is the LEVEL_C one
    (`fluxcal.missions.rosetta.level_c.level_c`, i.e. `fluxcal.geometry.frames.rotate`).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.13.
    """
    src = level_k_ds.drop_vars(["heater_disturbance"], errors="ignore")
    out = level_c(src, frame=frame, centre=centre, method=method, lsk=lsk)
    out["b"].attrs["description"] = "calibrated field, heater disturbance eliminated"
    out.attrs.update(level="L")
    return out
