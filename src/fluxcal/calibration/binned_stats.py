"""Binned and superposed-epoch sufficient statistics that merge exactly across days.

Each day (or any chunk of data) reduces to a `BinnedMoments`: per bin the number of
samples and, per component, the sums of ``v - shift`` and ``(v - shift)**2``.  Two
reductions over the same bin edges add; the sum of the per-day reductions equals the
reduction of the concatenated data (to float64 rounding of the sums), so a month or a
mission runs as a map-reduce whose partial results can be saved to netCDF
(`BinnedMoments.to_dataset`) and merged later.

Numerics
--------
Sums of squares of values with a large common offset cancel catastrophically when the
variance is formed (``S2/n - (S1/n)**2``).  Every `BinnedMoments` therefore stores a
per-component reference ``shift`` and accumulates ``v - shift``.  By default the shift
is the median of the first (up to) 1024 samples kept by that reduction; merging two
reductions with different shifts re-expresses the smaller about the larger's shift
exactly in algebra
(``sum (v-a) = sum (v-b) + n (b-a)``, ``sum (v-a)**2 = sum (v-b)**2 + 2 (b-a) sum (v-b)
+ n (b-a)**2``), which loses nothing measurable because both shifts lie within the data.
A caller that wants bit-for-bit reproducible merges passes one fixed ``shift`` to every
reduction (e.g. a nominal offset).  See docs/decisions/fits.md, entry 1.

Bins are half-open ``[edges[i], edges[i+1])`` including the last one; samples outside
the edges, or with a NaN in any component or in ``x``, are ignored.  An empty bin has
``count == 0``; its mean is NaN; a bin with fewer than two samples has a NaN variance.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 (superposed epoch of the heater
   cycle, 4 % duty-cycle bins), sec. 7 (10 C temperature bins, 4 % duty-cycle bins,
   the 1200-s superposed epoch of duty-cycle changes).
.. [2] T. F. Chan, G. H. Golub, R. J. LeVeque, "Algorithms for computing the sample
   variance: analysis and recommendations", Am. Stat. 37 (1983) 242-247 (shifted data).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError

__all__ = ["BinnedMoments", "phase_binned", "superposed_epoch"]

#: Number of (sample, event) pairs handled at once by `superposed_epoch`.
_EPOCH_CHUNK = 4_000_000


def _as_edges(edges: np.ndarray) -> np.ndarray:
    edges = np.asarray(edges, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2:
        raise InputFormatError(
            f"bin edges must be a 1-D array of at least 2 values, got shape {edges.shape}",
            field="edges",
        )
    if not np.all(np.isfinite(edges)) or np.any(np.diff(edges) <= 0):
        raise InputFormatError("bin edges must be finite and strictly increasing", field="edges")
    return edges


def _as_values(values: np.ndarray, n: int, name: str = "values") -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2 or values.shape[0] != n:
        raise InputFormatError(
            f"{name} must have shape (n,) or (n, n_comp) with n = {n}, got {values.shape}",
            field=name,
        )
    return values


@dataclass(eq=False)
class BinnedMoments:
    """Per-bin counts and shifted sums (sufficient statistics for mean and variance).

    Attributes
    ----------
    edges : ndarray, shape (n_bins + 1,)
        Strictly increasing bin edges; bins are ``[edges[i], edges[i+1])``.
    count : ndarray of int64, shape (n_bins,)
        Number of samples in each bin.
    total : ndarray, shape (n_bins, n_comp)
        Sum of ``value - shift`` in each bin, per component.
    total_sq : ndarray, shape (n_bins, n_comp)
        Sum of ``(value - shift)**2`` in each bin, per component.
    shift : ndarray, shape (n_comp,)
        Reference subtracted from every value before summing (see module Notes).
    label : str
        What the bin coordinate is (e.g. ``"temperature"``, ``"lag"``).
    units : str
        Units of the bin coordinate.
    value_units : str
        Units of the values.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 and 7.
    """

    edges: np.ndarray
    count: np.ndarray
    total: np.ndarray
    total_sq: np.ndarray
    shift: np.ndarray = field(default_factory=lambda: np.zeros(1))
    label: str = ""
    units: str = ""
    value_units: str = ""

    def __post_init__(self) -> None:
        self.edges = _as_edges(self.edges)
        n_bins = self.edges.size - 1
        self.count = np.asarray(self.count, dtype=np.int64)
        self.total = np.asarray(self.total, dtype=np.float64)
        self.total_sq = np.asarray(self.total_sq, dtype=np.float64)
        if self.total.ndim == 1:
            self.total = self.total[:, None]
        if self.total_sq.ndim == 1:
            self.total_sq = self.total_sq[:, None]
        n_comp = self.total.shape[1]
        self.shift = np.broadcast_to(np.asarray(self.shift, dtype=np.float64), (n_comp,)).copy()
        if (
            self.count.shape != (n_bins,)
            or self.total.shape != (n_bins, n_comp)
            or self.total_sq.shape != (n_bins, n_comp)
        ):
            raise InputFormatError(
                f"inconsistent shapes: edges {self.edges.shape}, count {self.count.shape}, "
                f"total {self.total.shape}, total_sq {self.total_sq.shape}",
                field="count",
            )

    # -- construction -------------------------------------------------------------------
    @property
    def n_bins(self) -> int:
        """Number of bins."""
        return int(self.count.size)

    @property
    def n_comp(self) -> int:
        """Number of value components."""
        return int(self.total.shape[1])

    @property
    def centers(self) -> np.ndarray:
        """Bin centres, shape (n_bins,)."""
        return 0.5 * (self.edges[:-1] + self.edges[1:])

    @classmethod
    def empty(
        cls,
        edges: np.ndarray,
        n_comp: int = 1,
        *,
        shift: np.ndarray | float = 0.0,
        label: str = "",
        units: str = "",
        value_units: str = "",
    ) -> BinnedMoments:
        """Return a reduction with no samples (the identity of `merge`)."""
        edges = _as_edges(edges)
        n_bins = edges.size - 1
        return cls(
            edges=edges,
            count=np.zeros(n_bins, dtype=np.int64),
            total=np.zeros((n_bins, n_comp)),
            total_sq=np.zeros((n_bins, n_comp)),
            shift=np.broadcast_to(np.asarray(shift, dtype=np.float64), (n_comp,)).copy(),
            label=label,
            units=units,
            value_units=value_units,
        )

    @classmethod
    def accumulate(
        cls,
        x: np.ndarray,
        values: np.ndarray,
        edges: np.ndarray,
        *,
        shift: np.ndarray | float | None = None,
        label: str = "",
        units: str = "",
        value_units: str = "",
    ) -> BinnedMoments:
        """Reduce samples ``(x, values)`` to per-bin counts and shifted sums.

        Parameters
        ----------
        x : ndarray, shape (n,)
            Bin coordinate of each sample (temperature, duty cycle, lag, phase, ...).
        values : ndarray, shape (n,) or (n, n_comp)
            Values to average.  A sample with a NaN in ``x`` or in any component is
            ignored, as is a sample outside ``[edges[0], edges[-1])``.
        edges : ndarray, shape (n_bins + 1,)
            Strictly increasing bin edges.
        shift : float or ndarray (n_comp,), optional
            Reference subtracted before summing.  Default: the median of the first
            (up to) 1024 samples kept, per component (0 where none): within a few
            standard deviations of the bin means, which is all the shifted sums need.
        label, units, value_units : str
            Metadata carried to `to_dataset`.

        Returns
        -------
        BinnedMoments

        Examples
        --------
        Two days reduced separately merge to the reduction of both:

        >>> import numpy as np
        >>> edges = np.array([-60.0, -50.0, -40.0])
        >>> day1 = BinnedMoments.accumulate([-55.0, -45.0], [400.0, 410.0], edges)
        >>> day2 = BinnedMoments.accumulate([-52.0, np.nan], [402.0, 1.0], edges)
        >>> both = day1 + day2
        >>> both.count.tolist(), both.mean()[:, 0].tolist()
        ([2, 1], [401.0, 410.0])
        """
        edges = _as_edges(edges)
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 1:
            raise InputFormatError(f"x must be 1-D, got shape {x.shape}", field="x")
        values = _as_values(values, x.size)
        n_bins = edges.size - 1
        n_comp = values.shape[1]
        # invalid samples (outside, NaN x or any NaN component) go to a dump bin n_bins,
        # dropped after the bincounts: no copy of the kept values is made
        idx = _bin_index(edges, x)
        for k in range(n_comp):  # components (a handful), never samples
            idx[~np.isfinite(values[:, k])] = n_bins
        if shift is None:
            shift_arr = _default_shift(values, idx < n_bins)
        else:
            shift_arr = np.broadcast_to(np.asarray(shift, dtype=np.float64), (n_comp,)).copy()
        count = np.bincount(idx, minlength=n_bins + 1)[:n_bins].astype(np.int64)
        total = np.empty((n_bins, n_comp))
        total_sq = np.empty((n_bins, n_comp))
        for k in range(n_comp):
            d = values[:, k] - shift_arr[k]
            total[:, k] = np.bincount(idx, weights=d, minlength=n_bins + 1)[:n_bins]
            total_sq[:, k] = np.bincount(idx, weights=d * d, minlength=n_bins + 1)[:n_bins]
        return cls(
            edges=edges,
            count=count,
            total=total,
            total_sq=total_sq,
            shift=shift_arr,
            label=label,
            units=units,
            value_units=value_units,
        )

    # -- merging ------------------------------------------------------------------------
    def reshifted(self, shift: np.ndarray | float) -> BinnedMoments:
        """Return the same statistics expressed about another reference ``shift``."""
        new = np.broadcast_to(np.asarray(shift, dtype=np.float64), (self.n_comp,)).copy()
        total, total_sq = self._sums_about(new)
        return self._assembled(self.count.copy(), total, total_sq, new, self)

    def _sums_about(self, new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``total`` and ``total_sq`` about the reference ``new`` (shape (n_comp,))."""
        delta = self.shift - new  # v - new = (v - old) + delta (exact when delta == 0)
        n = self.count[:, None].astype(np.float64)
        total = self.total + n * delta
        total_sq = self.total_sq + 2.0 * delta * self.total + n * delta * delta
        return total, total_sq

    def _assembled(self, count: np.ndarray, total: np.ndarray, total_sq: np.ndarray,
                   shift: np.ndarray, other: BinnedMoments) -> BinnedMoments:
        """Build a reduction on these edges from sums already checked against them.

        `merge` and `reshifted` build their results from arrays whose shapes and types
        their operands' own checks have fixed, so they skip `__post_init__`'s checks,
        which cost more than the sums themselves on the few hundred bins of a merge.  The
        metadata are this one's, or where empty ``other``'s.
        """
        out = object.__new__(BinnedMoments)
        out.edges, out.count, out.total, out.total_sq, out.shift = (
            self.edges, count, total, total_sq, shift)
        out.label = self.label or other.label
        out.units = self.units or other.units
        out.value_units = self.value_units or other.value_units
        return out

    def merge(self, other: BinnedMoments) -> BinnedMoments:
        """Return the reduction of both data sets (bin edges must be identical).

        The result keeps the shift of the operand with more samples (this one on a tie)
        and re-expresses the other about it, so merging into an empty accumulator never
        forces a far-away reference on the data.

        Raises
        ------
        InputFormatError
            If the edges or the number of components differ.
        """
        if not isinstance(other, BinnedMoments):
            raise TypeError(f"cannot merge BinnedMoments with {type(other).__name__}")
        if self.edges is not other.edges and (
                self.edges.shape != other.edges.shape
                or not np.array_equal(self.edges, other.edges)):
            raise InputFormatError(
                f"cannot merge binned statistics with different bin edges "
                f"({self.edges.size - 1} bins on [{self.edges[0]}, {self.edges[-1]}] vs "
                f"{other.edges.size - 1} bins on [{other.edges[0]}, {other.edges[-1]}])",
                field="edges",
            )
        if self.n_comp != other.n_comp:
            raise InputFormatError(
                f"cannot merge binned statistics of {self.n_comp} and {other.n_comp} components",
                field="total",
            )
        # keep the reference of the operand holding more samples (ties: this one), so an
        # empty accumulator never imposes its (arbitrary) shift on the data
        base, extra = (other, self) if other.count.sum() > self.count.sum() else (self, other)
        total, total_sq = extra._sums_about(base.shift)
        return self._assembled(base.count + extra.count, base.total + total,
                               base.total_sq + total_sq, base.shift.copy(), other)

    def __add__(self, other: BinnedMoments) -> BinnedMoments:
        """Merge (see `merge`)."""
        return self.merge(other)

    # -- statistics ---------------------------------------------------------------------
    def mean(self) -> np.ndarray:
        """Per-bin mean, shape (n_bins, n_comp); NaN in empty bins."""
        n = self.count[:, None].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, self.total / n, np.nan) + self.shift

    def variance(self) -> np.ndarray:
        """Per-bin unbiased sample variance, shape (n_bins, n_comp); NaN where count < 2."""
        n = self.count[:, None].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            m2 = self.total_sq - self.total * self.total / n
            var = np.where(n > 1, np.maximum(m2, 0.0) / (n - 1.0), np.nan)
        return var

    def standard_error(self) -> np.ndarray:
        """Per-bin standard error of the mean ``sqrt(variance / count)``; NaN where count < 2."""
        n = self.count[:, None].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(self.variance() / n)

    # -- persistence --------------------------------------------------------------------
    def to_dataset(self) -> xr.Dataset:
        """Return the statistics as an xarray Dataset (netCDF-ready, `from_dataset` reads it).

        Variables: ``count (bin)``, ``total (bin, component)``, ``total_sq (bin,
        component)``, ``shift (component)``, ``bin_edges (edge)``; coordinate
        ``bin_center (bin)``; convenience ``mean``/``standard_error`` are *not* stored
        (they follow from the sums).
        """
        return xr.Dataset(
            data_vars={
                "count": (("bin",), self.count),
                "total": (("bin", "component"), self.total),
                "total_sq": (("bin", "component"), self.total_sq),
                "shift": (("component",), self.shift),
                "bin_edges": (("edge",), self.edges, {"units": self.units}),
            },
            coords={"bin_center": (("bin",), self.centers, {"units": self.units})},
            attrs={
                "title": "fluxcal binned sufficient statistics",
                "label": self.label,
                "units": self.units,
                "value_units": self.value_units,
                "comment": (
                    "total = sum(value - shift), total_sq = sum((value - shift)^2) per bin "
                    "[edges[i], edges[i+1]); merge by adding after re-expressing about one shift"
                ),
            },
        )

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> BinnedMoments:
        """Rebuild from `to_dataset`'s form.

        Raises
        ------
        InputFormatError
            If a variable is missing.
        """
        for name in ("count", "total", "total_sq", "shift", "bin_edges"):
            if name not in ds:
                src = ds.encoding.get("source")
                raise InputFormatError(
                    "not a fluxcal binned-statistics dataset", path=src, field=name
                )
        return cls(
            edges=np.asarray(ds["bin_edges"].values, dtype=np.float64),
            count=np.asarray(ds["count"].values, dtype=np.int64),
            total=np.asarray(ds["total"].transpose("bin", "component").values),
            total_sq=np.asarray(ds["total_sq"].transpose("bin", "component").values),
            shift=np.asarray(ds["shift"].values, dtype=np.float64),
            label=str(ds.attrs.get("label", "")),
            units=str(ds.attrs.get("units", "")),
            value_units=str(ds.attrs.get("value_units", "")),
        )


def _bin_index(edges: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Bin of each ``x`` in half-open ``[edges[i], edges[i+1])``; ``n_bins`` if outside/NaN.

    Uniform edges take ``floor`` plus a one-step correction against the edges
    themselves (same result as ``searchsorted``, ~5x faster); others ``searchsorted``.
    """
    n_bins = edges.size - 1
    step = np.diff(edges)
    if np.allclose(step, step[0], rtol=1e-9, atol=0.0):
        with np.errstate(invalid="ignore"):
            f = np.floor((x - edges[0]) / step[0])
        i = np.clip(np.where(np.isfinite(f), f, 0.0), 0, n_bins - 1).astype(np.intp)
        i -= x < edges[i]
        np.clip(i, 0, n_bins - 1, out=i)
        i += x >= edges[i + 1]
        np.clip(i, 0, n_bins - 1, out=i)
        inside = (x >= edges[0]) & (x < edges[-1])
        return np.where(inside, i, n_bins)
    i = np.searchsorted(edges, x, side="right") - 1  # NaN sorts last: i = n_bins
    return np.where((i >= 0) & (i < n_bins), i, n_bins)


def _default_shift(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Median of the first (up to) 1024 valid samples, per component; 0 if none."""
    head = np.flatnonzero(valid[: 1 << 16])
    if head.size == 0:
        head = np.flatnonzero(valid)
    if head.size == 0:
        return np.zeros(values.shape[1])
    return np.median(values[head[:1024]], axis=0)


def _sorted_time(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise InputFormatError(f"t must be 1-D, got shape {t.shape}", field="t")
    values = _as_values(values, t.size)
    if t.size > 1 and np.any(np.diff(t) < 0):
        order = np.argsort(t, kind="stable")
        t, values = t[order], values[order]
    return t, values


def superposed_epoch(
    t: np.ndarray,
    values: np.ndarray,
    event_t: np.ndarray,
    lag_edges: np.ndarray,
    weights: np.ndarray | None = None,
    *,
    max_gap: float | None = None,
    shift: np.ndarray | float | None = None,
    label: str = "lag",
    units: str = "s",
    value_units: str = "",
) -> BinnedMoments:
    """Superposed-epoch statistics of ``values * weight_e`` against lag ``t - event_t[e]``.

    Every sample within ``[event + lag_edges[0], event + lag_edges[-1])`` of an event
    contributes once per such event (windows may overlap).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s); need not be sorted.
    values : ndarray, shape (n,) or (n, n_comp)
        Sample values; NaN samples are ignored.
    event_t : ndarray, shape (m,)
        Event times (s), e.g. the duty-cycle changes.
    lag_edges : ndarray, shape (n_bins + 1,)
        Lag bin edges (s), e.g. ``np.arange(-200, 1001, 10)``.
    weights : ndarray, shape (m,), optional
        Per-event factor applied to the values (finite; an event time or weight that
        is not raises), e.g. ``1 / delta_d`` so that positive and
        negative duty-cycle steps combine normalised (sec. 7).  Default 1.  For
        steps ``delta_d`` of various sizes, ``delta_d / mean(delta_d**2)`` gives the
        least-squares (minimum-variance) normalisation: the bin mean is then the
        regression of the offset change on ``delta_d``; ``1 / delta_d`` amplifies the
        noise of small steps (see docs/decisions/fits.md).
    max_gap : float, optional
        If given, only events whose whole window is covered by samples no more than
        ``max_gap`` apart (and within ``max_gap`` of both window ends) are used, so that
        every bin sees the same set of events.  An event with a partial window puts its
        own (weighted) baseline into some bins and not others: a spurious step in the
        epoch.  Default: every event, partial windows included.
    shift, label, units, value_units
        As for `BinnedMoments.accumulate`.

    Returns
    -------
    BinnedMoments
        Over lag.

    Examples
    --------
    A unit step up and a step of -2 down, normalised by ``1/delta``, combine:

    >>> import numpy as np
    >>> t = np.arange(0.0, 40.0)
    >>> v = np.where(t < 10, 0.0, 1.0) + np.where(t < 30, 0.0, -2.0)
    >>> e = superposed_epoch(t, v, [10.0, 30.0], [-4.0, 0.0, 4.0], weights=[1.0, -0.5])
    >>> e.mean()[:, 0].tolist()
    [-0.25, 0.75]

    Notes
    -----
    Window bounds come from ``searchsorted`` on the sorted times for every event; the
    (sample, event) index pairs are concatenated with ``np.repeat`` and reduced by
    ``np.bincount`` in chunks of at most a few million pairs.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (1200-s epoch starting 200 s
       before each duty-cycle change, steps normalised and of both signs combined).
    """
    lag_edges = _as_edges(lag_edges)
    t, values = _sorted_time(t, values)
    event_t = np.asarray(event_t, dtype=np.float64).ravel()
    if weights is None:
        w = np.ones(event_t.size)
    else:
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.shape != event_t.shape:
            raise InputFormatError(
                f"weights must have one value per event ({event_t.size}), got {w.shape}",
                field="weights",
            )
    for name, arr in (("event_t", event_t), ("weights", w)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise InputFormatError(
                f"{bad.size} non-finite value(s), first at event {bad[0]} ({arr[bad[0]]}); "
                "a zero duty-cycle step normalised by 1/delta_d is not an event",
                field=name,
            )
    n_comp = values.shape[1]
    lo = np.searchsorted(t, event_t + lag_edges[0], side="left")
    hi = np.searchsorted(t, event_t + lag_edges[-1], side="left")
    if max_gap is not None:
        full = _window_covered(t, event_t + lag_edges[0], event_t + lag_edges[-1], lo, hi,
                               float(max_gap))
        event_t, w, lo, hi = event_t[full], w[full], lo[full], hi[full]
    length = hi - lo
    if shift is None:
        # One reference for every chunk: the weighted mean over the events' windows
        # would need a pass of its own; the weighted overall mean is as good a centre.
        finite = np.all(np.isfinite(values), axis=1)
        base = values[finite].mean(axis=0) if finite.any() else np.zeros(n_comp)
        mean_w = float(np.mean(w)) if w.size else 1.0
        shift = base * mean_w
    result = BinnedMoments.empty(
        lag_edges, n_comp, shift=shift, label=label, units=units, value_units=value_units
    )
    # chunk boundaries over events so that each chunk holds at most _EPOCH_CHUNK pairs
    cum = np.concatenate(([0], np.cumsum(length)))
    bounds = np.searchsorted(cum, np.arange(0, cum[-1], _EPOCH_CHUNK), side="right") - 1
    bounds = np.unique(np.concatenate((bounds, [event_t.size])))
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if b <= a:
            continue
        n_pairs = length[a:b]
        tot = int(n_pairs.sum())
        if tot == 0:
            continue
        ev = np.repeat(np.arange(a, b), n_pairs)
        start = np.repeat(cum[a:b] - cum[a], n_pairs)
        sample = lo[ev] + (np.arange(tot) - start)
        lag = t[sample] - event_t[ev]
        part = BinnedMoments.accumulate(
            lag, values[sample] * w[ev][:, None], lag_edges, shift=result.shift
        )
        result = result.merge(part)
    return result


def _window_covered(
    t: np.ndarray, start: np.ndarray, stop: np.ndarray, lo: np.ndarray, hi: np.ndarray,
    max_gap: float,
) -> np.ndarray:
    """Return True where samples ``t[lo:hi]`` cover ``[start, stop)`` with no gap > max_gap."""
    if not max_gap > 0:
        raise InputFormatError(f"max_gap must be positive, got {max_gap}", field="max_gap")
    gap = np.concatenate(([0], np.cumsum(np.diff(t) > max_gap)))  # gaps before sample i
    nonempty = hi > lo
    first = np.where(nonempty, lo, 0)
    last = np.where(nonempty, hi - 1, 0)
    out = nonempty.copy()
    if t.size:
        out &= gap[last] == gap[first]
        out &= t[first] - start <= max_gap
        out &= stop - t[last] <= max_gap
    return out


def phase_binned(
    t: np.ndarray,
    values: np.ndarray,
    cycle_start_t: np.ndarray,
    period: float,
    n_bins: int,
    *,
    centered: bool = True,
    shift: np.ndarray | float | None = None,
    label: str = "phase",
    units: str = "s",
    value_units: str = "",
) -> BinnedMoments:
    """Statistics of a periodic waveform against time since the most recent cycle start.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s).
    values : ndarray, shape (n,) or (n, n_comp)
        Sample values.
    cycle_start_t : ndarray, shape (m,)
        Cycle start times (s), e.g. the rising edges of the heater bit (sec. 6).
    period : float
        Nominal cycle length (s), 100 s for the heater of seed 000.  Samples more than one
        period after their cycle start, and samples before the first start, are excluded.
    n_bins : int
        Number of phase bins over one period.
    centered : bool
        If True (default) bin ``k`` is centred on phase ``k * period / n_bins`` (so 100
        bins are centred on t = 0, 1, ..., 99 s, the grid of Tables 6-8) and phases in
        the last half bin ``[period - step/2, period)`` fold into bin 0 (the waveform is
        periodic: Tables 6-8 give the same value at 0 and 100 s).  If False the bins are
        ``[k step, (k+1) step)``.
    shift, label, units, value_units
        As for `BinnedMoments.accumulate`.

    Returns
    -------
    BinnedMoments
        Over phase; with ``centered`` the edges run from ``-step/2`` to
        ``period - step/2``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 and Appendix Tables 6-8.
    """
    if not (np.isfinite(period) and period > 0):
        raise InputFormatError(f"period must be positive, got {period}", field="period")
    if int(n_bins) != n_bins or n_bins < 1:
        raise InputFormatError(f"n_bins must be a positive integer, got {n_bins}", field="n_bins")
    n_bins = int(n_bins)
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise InputFormatError(f"t must be 1-D, got shape {t.shape}", field="t")
    values = _as_values(values, t.size)
    starts = np.sort(np.asarray(cycle_start_t, dtype=np.float64).ravel())
    if not np.all(np.isfinite(starts)):
        raise InputFormatError("cycle start times must be finite", field="cycle_start_t")
    k = np.searchsorted(starts, t, side="right") - 1
    phase = np.full(t.shape, np.nan)
    has = k >= 0
    phase[has] = t[has] - starts[k[has]]
    phase[phase >= period] = np.nan
    step = period / n_bins
    if centered:
        edges = (np.arange(n_bins + 1) - 0.5) * step
        phase = np.where(phase >= period - 0.5 * step, phase - period, phase)
    else:
        edges = np.arange(n_bins + 1) * step
    return BinnedMoments.accumulate(
        phase, values, edges, shift=shift, label=label, units=units, value_units=value_units
    )
