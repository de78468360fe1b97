"""Compare two magnetic-field products: match in time, difference statistics, a plot.

`load_product` reads either side: an archived or fluxcal PDS3 table (``.TAB``/``.LBL``,
`fluxcal.archive.products.read_product`; a fluxcal table of another layout through
`fluxcal.products.read_product`), or a fluxcal CDF / netCDF / Zarr product.
`compare` matches every sample of A to the nearest sample of B in time (TT2000
``epoch``), keeps the pairs closer than the tolerance, one B sample per A sample at
most, and returns the statistics of ``A - B`` per field component: mean, rms, max ``|diff|``
and N, overall and per quality flag (of A, else of B), with the matched / unmatched
counts and the time differences.  `format_report` prints them; `difference_figure`
draws the differences against time.

Matching is vectorised: `numpy.searchsorted` gives each A time's neighbours in B, the
nearer one is taken, and of several A samples taking the same B sample only the nearest
keeps it (ties: the earlier A sample).  Samples where either side is NaN are matched
but left out of the statistics of that component (counted as ``nan``).

See docs/decisions/archive.md for the choices (frame check, quality source, ties).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from fluxcal.archive.pds3 import column_names, find_label, read_label
from fluxcal.archive.products import ArchivedReader, identify, normalise_frame, read_product
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.time import tt2000_to_datetime64
from fluxcal.products.attrs import variable_units
from fluxcal.products.paths import make_folder
from fluxcal.products.timeindex import default_lsk
from fluxcal.products.writer import read_product as read_fluxcal

__all__ = ["Comparison", "ComponentStats", "compare", "difference_figure", "format_report",
           "load_product", "parse_tolerance", "product_frame"]

_UNITS_NS = {"ns": 1, "us": 1_000, "ms": 1_000_000, "s": 1_000_000_000, "": 1_000_000_000}


def parse_tolerance(text: str) -> int:
    """Parse a tolerance such as ``0.01s``, ``10ms``, ``50us``, ``100ns`` or ``0.01`` (s) to ns.

    Raises
    ------
    InputFormatError
        Not a non-negative number with one of the units s, ms, us, ns.
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?\d+)?)\s*(ns|us|ms|s)?\s*", str(text))
    if m is None:
        raise InputFormatError(f"tolerance {text!r}: expected a number with unit s, ms, us "
                               "or ns (e.g. 0.01s)", field="--tolerance")
    return int(round(float(m.group(1)) * _UNITS_NS[m.group(2) or ""]))


def load_product(path: Path | str,
                 readers: Mapping[str, ArchivedReader] | None = None) -> xr.Dataset:
    """Read one product for comparison (see the module docstring).

    A PDS3 table is read as an archived product when one of ``readers`` (the missions'
    archived-product readers, passed down by the command line) accepts its columns
    (`fluxcal.archive.products.identify`), else (a fluxcal table with other columns) by
    fluxcal's own table reader.
    """
    readers = readers or {}
    path = Path(path)
    if not path.exists():
        raise InputFormatError("file not found", path=str(path))
    if path.suffix.lower() in (".tab", ".lbl"):
        label = find_label(path)
        names = column_names(read_label(label), label)
        try:
            identify(names, readers)
        except InputFormatError:
            return read_fluxcal(label)
        return read_product(label, readers)
    return read_fluxcal(path)


def field_name(ds: xr.Dataset, path: Path | str) -> str:
    """Return the field variable: ``b``, else the first (time, 3) variable in nT.

    Without one, the first (time, 4) variable in nT (x, y, z and a fourth column such as
    the magnitude or the sensor range, as some ISTP products store it), of which `compare`
    uses the first three components; without that, the one (time, 3|4) variable with
    blank units (units unknown in the report).  A vector in counts is refused by name.
    """
    if "b" in ds and ds["b"].ndim == 2 and ds["b"].shape[1] == 3:
        return "b"
    vectors = {w: [str(n) for n, v in ds.data_vars.items() if v.dims[:1] == ("time",)
                   and v.ndim == 2 and v.shape[1] == w] for w in (3, 4)}
    for width in (3, 4):
        for name in vectors[width]:
            if variable_units(ds[name]) == "nT":
                return name
    # a field whose units are left blank (e.g. an ISTP ``UNITS`` of " " on a vector that
    # also holds the sensor range): compared, and the report says "units unknown"
    blank = [n for n in vectors[3] + vectors[4] if not variable_units(ds[n])]
    if len(blank) == 1:
        return blank[0]
    counts = [n for n in vectors[3] + vectors[4]
              if variable_units(ds[n]).lower() in ("count", "counts", "dn", "adu")]
    if counts:
        raise InputFormatError(
            f"variable '{counts[0]}' is in {variable_units(ds[counts[0]])}, not nT: compare "
            "calibrated products (e.g. L1B, not L1A)", path=str(path))
    raise InputFormatError("no field vector (variable 'b', or a (time, 3) or (time, 4) "
                           "variable in nT)", path=str(path))


def product_frame(ds: xr.Dataset, var: str,
                  readers: Mapping[str, ArchivedReader] | None = None) -> str | None:
    """Frame code of a product's field (attrs ``frame``/``coordinate_system``), or None.

    Frame names are coded by ``readers``' frame codes (`normalise_frame`).
    """
    attrs = ds[var].attrs
    for key in ("coordinate_system", "COORDINATE_SYSTEM", "frame"):
        code = normalise_frame(attrs.get(key), readers)
        if code:
            return code
    for key in ("COORDINATE_SYSTEM_NAME", "output_frame"):
        code = normalise_frame(ds.attrs.get(key), readers)
        if code:
            return code
    return None


@dataclass(frozen=True)
class ComponentStats:
    """Statistics of ``A - B`` of one component over the matched, finite pairs."""

    mean: float
    rms: float
    max_abs: float
    n: int
    nan: int


@dataclass
class Comparison:
    """The result of `compare` (times in ns, differences in the field's units)."""

    path_a: str
    path_b: str
    n_a: int
    n_b: int
    tolerance_ns: int
    components: list[str]
    units: str
    frame_a: str | None
    frame_b: str | None
    epoch: np.ndarray  # epochs of A at the matched pairs
    dt_ns: np.ndarray  # epoch A - epoch B of each pair
    diff: np.ndarray  # (pairs, 3) A - B
    quality: np.ndarray | None  # flag of each pair (as stored: integer or text)
    quality_source: str | None
    ambiguous: int = 0  # matched A samples with more than one B sample within tolerance
    overall: list[ComponentStats] = field(default_factory=list)
    by_quality: dict[str, list[ComponentStats]] = field(default_factory=dict)

    @property
    def matched(self) -> int:
        """Number of matched pairs."""
        return int(self.epoch.size)


def _stats(diff: np.ndarray, groups: np.ndarray | None = None,
           n_groups: int = 1) -> list[list[ComponentStats]]:
    """Per group and component statistics, by bincount (no loop over samples)."""
    if groups is None:
        groups = np.zeros(diff.shape[0], dtype=np.intp)
    out: list[list[ComponentStats]] = [[] for _ in range(n_groups)]
    for k in range(diff.shape[1]):
        d = diff[:, k]
        ok = np.isfinite(d)
        g, v = groups[ok], d[ok]
        n = np.bincount(g, minlength=n_groups)
        nan = np.bincount(groups[~ok], minlength=n_groups)
        s1 = np.bincount(g, weights=v, minlength=n_groups)
        s2 = np.bincount(g, weights=v * v, minlength=n_groups)
        mx = np.zeros(n_groups)
        if v.size:
            np.maximum.at(mx, g, np.abs(v))
        with np.errstate(invalid="ignore", divide="ignore"):
            mean, rms = s1 / n, np.sqrt(s2 / n)
        for j in range(n_groups):  # per group (a handful), not per sample
            out[j].append(ComponentStats(float(mean[j]) if n[j] else float("nan"),
                                         float(rms[j]) if n[j] else float("nan"),
                                         float(mx[j]) if n[j] else float("nan"),
                                         int(n[j]), int(nan[j])))
    return out


def match(epoch_a: np.ndarray, epoch_b: np.ndarray, tolerance_ns: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """Return the indices ``(ia, ib)`` of the matched pairs (both sorted by A time).

    ``epoch_b`` must be sorted.  Each A sample takes the nearer of its two neighbours
    in B; pairs farther apart than ``tolerance_ns`` are dropped; a B sample taken by
    several A samples stays with the nearest (the earlier on a tie).
    """
    a = np.asarray(epoch_a, dtype=np.int64)
    b = np.asarray(epoch_b, dtype=np.int64)
    if a.size == 0 or b.size == 0:
        return np.empty(0, np.intp), np.empty(0, np.intp)
    right = np.clip(np.searchsorted(b, a), 0, b.size - 1)
    left = np.clip(right - 1, 0, b.size - 1)
    d_right, d_left = np.abs(b[right] - a), np.abs(a - b[left])
    ib = np.where(d_left <= d_right, left, right)
    dist = np.minimum(d_left, d_right)
    ia = np.flatnonzero(dist <= tolerance_ns)
    ib, dist = ib[ia], dist[ia]
    # A and B sorted: the nearest B index never decreases with A, so the A samples that
    # share a B sample are adjacent; only those few are sorted to find the nearest
    shared = np.zeros(ib.size, dtype=bool)
    same = ib[1:] == ib[:-1]
    shared[1:] |= same
    shared[:-1] |= same
    if not shared.any():
        return ia, ib
    sub = np.flatnonzero(shared)
    order = sub[np.lexsort((ia[sub], dist[sub], ib[sub]))]  # by B, distance, A index
    first = np.ones(order.size, dtype=bool)
    first[1:] = ib[order][1:] != ib[order][:-1]
    keep = np.sort(np.concatenate([np.flatnonzero(~shared), order[first]]))
    return ia[keep], ib[keep]


def _sorted(ds: xr.Dataset) -> xr.Dataset:
    epoch = ds["epoch"].values
    if epoch.size > 1 and not (np.diff(epoch) >= 0).all():
        return ds.isel(time=np.argsort(epoch, kind="stable"))
    return ds


def compare(a: xr.Dataset, b: xr.Dataset, tolerance_ns: int, *, path_a: str = "A",
            path_b: str = "B", force: bool = False,
            readers: Mapping[str, ArchivedReader] | None = None) -> Comparison:
    """Match ``a`` and ``b`` in time and compute the statistics of ``a - b``.

    Parameters
    ----------
    a, b : xarray.Dataset
        Products with an int64 TT2000 ``epoch`` along ``time`` and a field vector.
    tolerance_ns : int
        Largest ``|epoch A - epoch B|`` of a pair, ns.
    path_a, path_b : str
        Names for messages and the report.
    force : bool
        Compare even when the two frames are known and differ.
    readers : mapping of name -> ArchivedReader, optional
        Whose frame codes name the frames (a mission's MSO frame -> ``MSO``).

    Raises
    ------
    FluxcalError
        Different frames without ``force``; different field units; no ``epoch``.
    """
    for ds, p in ((a, path_a), (b, path_b)):
        if "epoch" not in ds.coords and "epoch" not in ds:
            raise InputFormatError(
                "product has no epoch (TT2000) along time: no variable 'Epoch' and no "
                "CDF_TIME_TT2000 variable named by a DEPEND_0", path=p)
    a, b = _sorted(a), _sorted(b)
    va, vb = field_name(a, path_a), field_name(b, path_b)
    fa, fb = product_frame(a, va, readers), product_frame(b, vb, readers)
    if fa and fb and fa != fb and not force:
        raise FluxcalError(f"the products are in different frames: {path_a} is {fa}, "
                           f"{path_b} is {fb} (compare the same frame, or --force)")
    ua, ub = variable_units(a[va]), variable_units(b[vb])
    if ua and ub and ua != ub:
        raise FluxcalError(f"the field units differ: {path_a} has {ua}, {path_b} has {ub}")
    ea, eb = a["epoch"].values.astype(np.int64), b["epoch"].values.astype(np.int64)
    ia, ib = match(ea, eb, tolerance_ns)
    diff = (a[va].values[ia, :3].astype(np.float64)
            - b[vb].values[ib, :3].astype(np.float64))
    dim = a[va].dims[1]
    comps = [str(c) for c in a[dim].values[:3]] if dim in a.coords else ["1", "2", "3"]
    quality, source = None, None
    for ds, idx, p in ((a, ia, path_a), (b, ib, path_b)):
        if "quality" in ds and ds["quality"].dims == ("time",):
            quality, source = np.asarray(ds["quality"].values[idx]), p
            break
    result = Comparison(path_a, path_b, int(ea.size), int(eb.size), int(tolerance_ns), comps,
                        ua or ub, fa, fb, ea[ia], ea[ia] - eb[ib], diff, quality, source)
    ta = ea[ia]
    within = (np.searchsorted(eb, ta + tolerance_ns, side="right")
              - np.searchsorted(eb, ta - tolerance_ns, side="left"))
    result.ambiguous = int(np.count_nonzero(within > 1))
    result.overall = _stats(diff)[0]
    if quality is not None and quality.size:
        flags, groups = np.unique(quality, return_inverse=True)
        per = _stats(diff, groups.astype(np.intp), flags.size)
        result.by_quality = {str(f.item() if hasattr(f, "item") else f): s
                             for f, s in zip(flags, per, strict=True)}
    return result


def _row(name: str, s: ComponentStats) -> str:
    return (f"  {name:<10} {s.mean:14.6f} {s.rms:14.6f} {s.max_abs:14.6f} {s.n:10d}"
            + (f"  ({s.nan} NaN)" if s.nan else ""))


def format_report(c: Comparison) -> str:
    """Return the printed report: counts, time differences, per-component statistics."""
    lines = [f"A: {c.path_a} ({c.n_a} samples, frame {c.frame_a or 'unknown'})",
             f"B: {c.path_b} ({c.n_b} samples, frame {c.frame_b or 'unknown'})",
             f"tolerance {c.tolerance_ns / 1e9:g} s: {c.matched} matched, "
             f"{c.n_a - c.matched} only in A, {c.n_b - c.matched} only in B"]
    if c.ambiguous:
        lines.append(f"{c.ambiguous} of the matched A samples had more than one B sample "
                     "within the tolerance (the nearest was taken)")
    if not c.matched:
        lines.append("no pair matched: the products do not overlap in time within the "
                     "tolerance")
    else:
        dt_ms = c.dt_ns / 1e6
        lines.append(f"time A - B (ms): mean {dt_ms.mean():.6f}, max |dt| "
                     f"{np.abs(dt_ms).max():.6f}")
    head = f"  {'A - B':<10} {'mean':>14} {'rms':>14} {'max |diff|':>14} {'N':>10}"
    lines += [f"difference A - B ({c.units or 'units unknown'}), all samples", head]
    lines += [_row(n, s) for n, s in zip(c.components, c.overall, strict=True)]
    for flag, stats in c.by_quality.items():
        lines.append(f"quality {flag} (flag of {'A' if c.quality_source == c.path_a else 'B'})")
        lines += [_row(n, s) for n, s in zip(c.components, stats, strict=True)]
    return "\n".join(lines)


def difference_figure(c: Comparison) -> Any:
    """Draw a figure with one panel of ``A - B`` per component against UTC time."""
    from fluxcal.products.quicklook import Figure, envelope  # the plot extra's module
    fig = Figure(figsize=(10, 7), layout="constrained")
    axes = fig.subplots(len(c.components) + 1, 1, sharex=True)
    t = tt2000_to_datetime64(c.epoch, default_lsk()) if c.matched else np.array([], "M8[ns]")
    # min/max envelope per equal-count bin when long (quicklook's): a day of 20 Hz
    # pairs drawn point by point would take minutes and show the same picture
    for ax, name, k in zip(axes, c.components, range(len(c.components)), strict=False):
        ax.plot(*envelope(t, c.diff[:, k]), ".", ms=1.5,
                color=("tab:blue", "tab:green", "tab:red")[k])
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_ylabel(f"{name} A-B ({c.units})" if c.units else f"{name} A-B")
    axes[-1].plot(*envelope(t, c.dt_ns / 1e6), ".", ms=1.5, color="0.3")
    axes[-1].set_ylabel("t A-B (ms)")
    axes[-1].set_xlabel("UTC")
    fig.suptitle(f"{Path(c.path_a).name} - {Path(c.path_b).name}: {c.matched} pairs, "
                 f"{c.n_a - c.matched} only in A, {c.n_b - c.matched} only in B",
                 fontsize=10)
    return fig


def write_difference_plot(c: Comparison, out_dir: Path) -> Path:
    """Write ``compare_<A>_vs_<B>.png`` in ``out_dir`` (atomically); return its path."""
    from fluxcal.products.quicklook import save_png

    out_dir = Path(out_dir)
    make_folder(out_dir)
    name = f"compare_{Path(c.path_a).stem}_vs_{Path(c.path_b).stem}.png"
    return save_png(difference_figure(c), out_dir / name)
