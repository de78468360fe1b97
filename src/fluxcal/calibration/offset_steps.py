"""Smoothness check of an applied offset time series (largest step per axis).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13 "Validation".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluxcal.calibration._compiled import largest_steps_kernel


@dataclass(frozen=True)
class StepReport:
    """Largest sample-to-sample step of each offset component.

    Attributes
    ----------
    largest_step : ndarray, shape (k,)
        Largest absolute step per component (offset units).
    index : ndarray of int, shape (k,)
        Index ``i`` of the sample after the step (step between ``i-1`` and ``i``).
    """

    largest_step: np.ndarray
    index: np.ndarray


def largest_steps(
    offset: np.ndarray,
    segment: np.ndarray | None = None,
    *,
    times: np.ndarray | None = None,
    max_gap: float | np.ndarray | None = None,
    time_scale: float = 0.0,
) -> StepReport:
    """Return the largest absolute step between consecutive samples, per component.

    One compiled pass (`fluxcal.calibration._compiled.largest_steps_kernel`), no step
    array; `largest_steps_reference` is the numpy version the tests compare with.

    Parameters
    ----------
    offset : ndarray, shape (n, k)
        Applied offsets (same units for every sample).
    segment : ndarray, shape (n,), optional
        Label of a sample's segment; steps between samples of different segments (e.g.
        a range change, where offsets are expressed in other counts) are ignored.
    times : ndarray, shape (n,), optional
        Sample times; with ``max_gap``, steps across data gaps
        (``times[i] - times[i-1] > max_gap``) are ignored, as across segments.
    max_gap : float or ndarray of shape (n,), optional
        Longest time step within a segment (given together with ``times``); an array
        gives the limit of the step ending at each sample (e.g. scaled to its sample
        spacing).
    time_scale : float
        With ``times``: a step over ``dt > time_scale`` counts as ``step * time_scale /
        dt`` (0: no scaling), so that the smooth change of an offset over a long sample
        spacing is not taken for a discontinuity.

    Returns
    -------
    StepReport

    Raises
    ------
    ValueError
        When only one of ``times`` and ``max_gap`` is given.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13.
    """
    if (times is None) != (max_gap is None):
        raise ValueError("times, max_gap: give both or neither")
    offset = np.asarray(offset, dtype=float)
    kw = {"times": times, "max_gap": max_gap, "time_scale": time_scale}
    if offset.ndim != 2 or offset.shape[0] < 2:
        return largest_steps_reference(offset, segment, **kw)
    use_segment = segment is not None
    seg = np.asarray(segment) if use_segment else np.zeros(1, dtype=np.int64)
    use_gaps = times is not None
    t = np.asarray(times) if use_gaps else np.zeros(1)
    gap = np.atleast_1d(np.asarray(max_gap, dtype=float)) if use_gaps else np.zeros(1)
    if ((use_segment and (seg.shape != offset.shape[:1] or seg.dtype.kind not in "biuf"))
            or (use_gaps and (t.shape != offset.shape[:1] or t.dtype.kind not in "iuf"))
            or gap.ndim != 1 or gap.size not in (1, offset.shape[0])):
        return largest_steps_reference(offset, segment, **kw)
    largest = np.empty(offset.shape[1])
    index = np.empty(offset.shape[1], dtype=np.int64)
    largest_steps_kernel(offset, seg, use_segment, t, gap, use_gaps,
                         float(time_scale) if use_gaps else 0.0, largest, index)
    return StepReport(largest, index)


def largest_steps_reference(
    offset: np.ndarray,
    segment: np.ndarray | None = None,
    *,
    times: np.ndarray | None = None,
    max_gap: float | np.ndarray | None = None,
    time_scale: float = 0.0,
) -> StepReport:
    """Numpy reference of `largest_steps` (the tests compare the two).

    Parameters and returns as `largest_steps`.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 13.
    """
    if (times is None) != (max_gap is None):
        raise ValueError("times, max_gap: give both or neither")
    offset = np.asarray(offset, dtype=float)
    if offset.shape[0] < 2:
        return StepReport(np.zeros(offset.shape[1]), np.zeros(offset.shape[1], dtype=np.int64))
    steps = np.abs(np.diff(offset, axis=0))
    if segment is not None:
        segment = np.asarray(segment)
        steps[segment[1:] != segment[:-1]] = 0.0
    if times is not None:
        dt = np.diff(np.asarray(times, dtype=float))
        gap = np.asarray(max_gap, dtype=float)
        steps[dt > (gap[1:] if gap.ndim and gap.size > 1 else gap)] = 0.0
        if time_scale > 0:
            scale = np.where(dt > time_scale, dt / time_scale, 1.0)
            steps = steps / scale[:, None]
    idx = np.argmax(steps, axis=0)
    return StepReport(steps[idx, np.arange(offset.shape[1])], idx + 1)
