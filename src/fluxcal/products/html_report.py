"""The run report: one ``index.html`` per output folder that a browser opens without a server.

Every run that writes into an ``--out`` folder (a single run, a batch) ends with
`write_run_report`: a page listing the run's products (relative links), showing its
quicklooks and summarising the data quality that the products record -- the samples,
time span and cadence of each time series, its gaps, its quality and flag variables
(the count of each value and the spans of non-zero flags), the counts the products
carry as global attributes (reordered, duplicate or dropped samples, validation
results) -- and the text and JSON reports of the run (a validation report, a batch
report).  Everything is read back from the products themselves, so the page is the
same for every instrument and says only what the files say.

The page is plain HTML with inline CSS, relative links only and no script; it holds no
absolute path and no time of writing, so the same products give the same bytes.  Inside
a run's staging group (`fluxcal.products.atomic.atomic_group`) the report lists the
products under their final names, reads them from their temporaries and is itself
renamed into place with them (docs/decisions/front_door.md).
"""

from __future__ import annotations

import html
import json
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

import cdflib
import numpy as np
import xarray as xr

from fluxcal.products.atomic import atomic_write_bytes, pending_renames
from fluxcal.version import software_version

#: File name of the report in the output folder.
REPORT_NAME = "index.html"
#: At most this many products are read for the data-quality summary (a long batch).
MAX_QUALITY_PRODUCTS = 200
#: A sample interval is a gap when longer than this many times both neighbouring intervals
#: and the median interval.
GAP_FACTOR = 4.0
#: Gaps and flag spans listed per product (the longest / the first ones).
MAX_LISTED = 10
#: What the page says when a run drew no figure.
NO_FIGURES = "This run wrote no figure (ask for one with --quicklook)."
#: Lines of a text report shown in the page.
MAX_TEXT_LINES = 60
#: Global attributes shown as data-quality counts (names matched case-insensitively).
QUALITY_ATTRIBUTE = re.compile(
    r"reorder|drop|duplicat|quality|flag|gap|defect|valid|reject|spike|jump|largest_step",
    re.IGNORECASE)
#: Variables summarised as flags (integer variables along time, names matched).
FLAG_VARIABLE = re.compile(r"quality|flag|defect", re.IGNORECASE)

_KINDS = {".cdf": "CDF", ".nc": "netCDF", ".zarr": "Zarr", ".tab": "PDS3 table",
          ".lbl": "PDS3 label", ".png": "quicklook", ".txt": "text report",
          ".json": "JSON report", ".csv": "CSV", ".toml": "TOML", ".html": "run report"}
#: Kinds whose data-quality is read (the first found per product stem, in this order).
_READABLE = ("CDF", "netCDF", "Zarr")


@dataclass(frozen=True)
class ProductFile:
    """One file (or Zarr store) of a run: its path relative to the report, where to read it."""

    rel: str
    source: Path
    kind: str
    size: int | None


@dataclass
class Quality:
    """What one product records about its data quality."""

    samples: int = 0
    start: str = ""
    stop: str = ""
    cadence_s: float | None = None
    gaps: list[tuple[str, str, float]] = field(default_factory=list)
    n_gaps: int = 0
    backwards: int = 0
    flags: dict[str, dict[int, int]] = field(default_factory=dict)
    flag_spans: dict[str, list[tuple[str, str, int]]] = field(default_factory=dict)
    n_flag_spans: dict[str, int] = field(default_factory=dict)
    attributes: dict[str, str] = field(default_factory=dict)
    note: str = ""


def _kind(path: Path) -> str:
    return _KINDS.get(path.suffix.lower(), path.suffix.lstrip(".").upper() or "file")


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size


def run_products(out: Path) -> list[ProductFile]:
    """Return the files of the run writing into ``out``, sorted by relative path.

    Inside a staging group: the files the group will rename into place under ``out``
    (read from their temporaries).  Outside one (a batch, whose days are committed
    already): every file under ``out`` but hidden ones, the lock and the report itself.
    """
    out = Path(out).resolve()
    found: dict[str, Path] = {}
    staged = pending_renames()
    if staged is not None:
        for tmp, final in staged:
            try:
                rel = Path(final).resolve().relative_to(out)
            except ValueError:
                continue
            found[rel.as_posix()] = Path(tmp)
    else:
        for p in out.rglob("*"):
            rel = p.relative_to(out)
            if any(part.startswith(".") for part in rel.parts):
                continue
            if any(part.endswith(".zarr") for part in rel.parts[:-1]):
                continue  # inside a Zarr store: the store is one product
            if p.is_dir() and p.suffix != ".zarr":
                continue
            found[rel.as_posix()] = p
    found.pop(REPORT_NAME, None)
    files = []
    for rel, source in sorted(found.items()):
        kind = _kind(Path(rel))
        size = None if kind in ("JSON report", "text report") else _size(source)
        files.append(ProductFile(rel, source, kind, size))
    return files


def _iso(times: np.ndarray) -> list[str]:
    return [str(t)[:23] for t in np.asarray(times, dtype="datetime64[ms]")]


def _attribute_text(value: Any) -> str:
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 1:
        value = value[0]
    if isinstance(value, np.generic):
        value = value.item()
    text = str(value)
    if text.startswith("json:"):
        text = text[5:]
    return text if len(text) <= 200 else text[:197] + "..."


def time_quality(times: np.ndarray,
                 iso: Callable[[np.ndarray], list[str]] | None = None) -> Quality:
    """Return the samples, span, cadence, gaps and backward steps of a time series.

    A gap is an interval longer than `GAP_FACTOR` times both neighbouring intervals and
    the median interval, so a change of sampling rate or jittered times are no gap; an
    interval <= 0 is a backward step (time not in order, or a repeated time).

    Parameters
    ----------
    times : numpy.ndarray
        ``datetime64`` sample times, or int64 nanoseconds on any uniform scale (a CDF's
        TT2000), in the product's order; NaT and the int64 fill value are skipped.
    iso : callable, optional
        ``iso(indices)`` -> ISO UTC strings of those samples (needed for int64 times:
        only the first, last and gap samples are converted, not every one).

    Examples
    --------
    >>> t = np.datetime64("2024-01-01T00:00:00") + np.array([0, 1, 2, 3, 60, 61, 62],
    ...                                                     dtype="timedelta64[s]")
    >>> q = time_quality(t)
    >>> q.samples, q.n_gaps, q.gaps[0][2], q.cadence_s
    (7, 1, 57.0, 1.0)
    """
    q = Quality()
    t = np.asarray(times)
    if np.issubdtype(t.dtype, np.datetime64):
        t = t.astype("datetime64[ns]")
        kept = np.flatnonzero(~np.isnat(t))
        ns = t[kept].astype(np.int64)
        if iso is None:
            def iso(idx: np.ndarray) -> list[str]:
                return _iso(t[idx])
    else:
        ns = t.astype(np.int64)
        kept = np.flatnonzero(ns != np.iinfo(np.int64).min)
        ns = ns[kept]
    if iso is None:
        raise ValueError("time_quality: int64 times need iso(indices)")
    q.samples = int(ns.size)
    if ns.size == 0:
        return q
    q.start, q.stop = iso(kept[[0, -1]])
    if ns.size < 2:
        return q
    dt = np.diff(ns) / 1e9
    q.backwards = int(np.count_nonzero(dt <= 0))
    positive = dt[dt > 0]
    if positive.size:
        q.cadence_s = float(np.median(positive))
    before = np.concatenate([dt[:1], dt[:-1]])
    after = np.concatenate([dt[1:], dt[-1:]])
    neighbours = np.maximum(before, after)
    if dt.size >= 3:
        gap = (dt > GAP_FACTOR * neighbours) & (dt > GAP_FACTOR * (q.cadence_s or 0.0))
    else:
        gap = np.zeros(dt.size, dtype=bool)
    idx = np.flatnonzero(gap)
    q.n_gaps = int(idx.size)
    longest = np.sort(idx[np.argsort(-dt[idx], kind="stable")][:MAX_LISTED])
    edges = iso(kept[np.concatenate([longest, longest + 1])]) if longest.size else []
    for k, i in enumerate(longest):
        q.gaps.append((edges[k], edges[k + longest.size], float(dt[i])))
    return q


def flag_quality(q: Quality, name: str, times: np.ndarray, values: np.ndarray,
                 iso: Callable[[np.ndarray], list[str]] | None = None) -> None:
    """Add a flag variable to ``q``: the count of each value and the non-zero spans.

    ``times`` and ``iso`` as in `time_quality` (the spans' first and last samples).
    """
    v = np.asarray(values)
    if v.ndim != 1 or v.size == 0:
        return
    if v.min() >= 0 and v.max() < 65536:  # small codes: a count, no sort
        counts = np.bincount(v.astype(np.int64))
        distinct = np.flatnonzero(counts)
        counts = counts[distinct]
    else:
        distinct, counts = np.unique(v, return_counts=True)
    q.flags[name] = {int(d): int(c) for d, c in zip(distinct, counts, strict=True)}
    if np.shape(times) != v.shape:
        return
    if iso is None:
        t = np.asarray(times, dtype="datetime64[ns]")

        def iso(idx: np.ndarray) -> list[str]:
            return _iso(t[idx])
    change = np.flatnonzero(v[1:] != v[:-1]) + 1
    starts = np.concatenate([[0], change])
    stops = np.concatenate([change, [v.size]]) - 1
    nonzero = v[starts] != 0
    starts, stops = starts[nonzero], stops[nonzero]
    q.n_flag_spans[name] = int(starts.size)
    first, last = starts[:MAX_LISTED], stops[:MAX_LISTED]
    if first.size:
        edges = iso(np.concatenate([first, last]))
        q.flag_spans[name] = [(edges[k], edges[k + first.size], int(v[i]))
                              for k, i in enumerate(first)]
    else:
        q.flag_spans[name] = []


def _quality_attributes(attrs: dict[str, Any]) -> dict[str, str]:
    return {k: _attribute_text(v) for k, v in sorted(attrs.items())
            if QUALITY_ATTRIBUTE.search(k)}


def _cdf_quality(path: Path) -> Quality:
    f = cdflib.CDF(str(path))
    names = f.cdf_info().zVariables
    time_var = next((n for n in names if f.varinq(n).Data_Type_Description
                     in ("CDF_TIME_TT2000", "CDF_EPOCH", "CDF_EPOCH16")), None)
    if time_var is None:
        q = Quality(note="no time variable")
    else:
        raw = f.varget(time_var)
        raw = np.atleast_1d(np.asarray(raw if raw is not None else [], dtype=np.int64)
                            if f.varinq(time_var).Data_Type_Description == "CDF_TIME_TT2000"
                            else np.asarray(cdflib.cdfepoch.to_datetime(raw)
                                            if raw is not None else [], "datetime64[ns]"))

        def iso(idx: np.ndarray) -> list[str]:  # only the samples shown are converted
            return _iso(np.asarray(cdflib.cdfepoch.to_datetime(raw[idx]), "datetime64[ns]")
                        if raw.dtype == np.int64 else raw[idx])

        q = time_quality(raw, iso)
        for n in names:
            if n != time_var and FLAG_VARIABLE.search(n):
                values = f.varget(n)
                if values is not None and np.issubdtype(np.asarray(values).dtype, np.integer):
                    flag_quality(q, n, raw, np.asarray(values), iso)
    q.attributes = _quality_attributes(f.globalattsget())
    return q


def _xarray_quality(path: Path, kind: str) -> Quality:
    ds = xr.open_zarr(path) if kind == "Zarr" else xr.open_dataset(path)
    with ds:
        time_name = next((n for n in [*ds.coords, *ds.data_vars]
                          if np.issubdtype(ds[n].dtype, np.datetime64)), None)
        if time_name is None:
            q = Quality(note="no time variable")
        else:
            times = ds[time_name].values
            q = time_quality(times)
            for n in ds.data_vars:
                var = ds[n]
                if (FLAG_VARIABLE.search(str(n)) and var.dims == ds[time_name].dims
                        and np.issubdtype(var.dtype, np.integer)):
                    flag_quality(q, str(n), times, var.values)
        q.attributes = _quality_attributes(dict(ds.attrs))
    return q


def product_quality(product: ProductFile) -> Quality | None:
    """Return what a CDF, netCDF or Zarr product records about its quality (else None)."""
    try:
        if product.kind == "CDF":
            return _cdf_quality(product.source)
        if product.kind in ("netCDF", "Zarr"):
            return _xarray_quality(product.source, product.kind)
    except Exception as exc:  # noqa: BLE001 - the report says so and goes on
        return Quality(note=f"not readable for the summary: {type(exc).__name__}: {exc}"[:200])
    return None


def time_axis_key(product: ProductFile) -> tuple | None:
    """Return (records, first time, last time, flag variables) of a CDF, else None.

    Products with the same key share their time axis (one day in several frames or
    levels): the summary reads one of them (`write_run_report`).  Only the first and
    last records are read.
    """
    if product.kind != "CDF":
        return None
    try:
        f = cdflib.CDF(str(product.source))
        names = f.cdf_info().zVariables
        for n in names:
            info = f.varinq(n)
            if info.Data_Type_Description in ("CDF_TIME_TT2000", "CDF_EPOCH", "CDF_EPOCH16"):
                last = int(info.Last_Rec)
                if last < 0:
                    return None
                ends = [np.asarray(f.varget(n, startrec=r, endrec=r)).tobytes()
                        for r in (0, last)]
                flags = tuple(sorted(v for v in names if v != n and FLAG_VARIABLE.search(v)))
                return (n, last, *ends, flags)
    except Exception:  # noqa: BLE001 - read in full (and reported) by product_quality
        return None
    return None


def _stem(rel: str) -> str:
    return rel.rsplit(".", 1)[0].lower()


def quality_products(products: Sequence[ProductFile]) -> list[ProductFile]:
    """Return the products whose quality is summarised: one readable file per stem.

    A product written as CDF and netCDF (the same data) is read once, from the first
    of `_READABLE`; at most `MAX_QUALITY_PRODUCTS`.
    """
    chosen: dict[str, ProductFile] = {}
    for kind in _READABLE:
        for p in products:
            if p.kind == kind:
                chosen.setdefault(_stem(p.rel), p)
    return sorted(chosen.values(), key=lambda p: p.rel)[:MAX_QUALITY_PRODUCTS]


# --------------------------------------------------------------------------- rendering

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:1.5em auto;
max-width:72em;padding:0 1em;color:#1b1f24;line-height:1.4}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.2em;border-bottom:1px solid #d0d7de;
padding-bottom:.2em;margin-top:1.6em}.sub{color:#57606a;margin-top:0}
table{border-collapse:collapse;font-size:.9em;margin:.5em 0}
th,td{border:1px solid #d0d7de;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f6f8fa}td.num{text-align:right;font-variant-numeric:tabular-nums}
.ok{color:#1a7f37}.warn{color:#9a6700}.bad{color:#cf222e;font-weight:bold}
figure{display:inline-block;margin:.5em;vertical-align:top}
figure img{max-width:100%;width:34em;border:1px solid #d0d7de}
figcaption{font-size:.85em;color:#57606a}
pre{background:#f6f8fa;padding:.6em;overflow-x:auto;font-size:.85em}
details{margin:.3em 0}summary{cursor:pointer}
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _href(rel: str, kind: str) -> str:
    return quote(rel + ("/" if kind == "Zarr" else ""))


def _link(p: ProductFile) -> str:
    return f'<a href="{_href(p.rel, p.kind)}">{_e(p.rel)}</a>'


def _human(size: int | None) -> str:
    if size is None:
        return ""
    for unit in ("B", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1000.0
    return ""


def _products_section(products: Sequence[ProductFile]) -> list[str]:
    rows = [f"<tr><td>{_link(p)}</td><td>{_e(p.kind)}</td>"
            f'<td class="num">{_human(p.size)}</td></tr>' for p in products]
    return ["<h2 id=\"products\">Products</h2>",
            f"<p>{len(products)} files.</p>" if products else "<p>No products.</p>",
            "<table><tr><th>file</th><th>kind</th><th>size</th></tr>", *rows, "</table>"]


def _quicklook_section(products: Sequence[ProductFile],
                       captions: Mapping[str, str] | None = None,
                       no_figures: str = NO_FIGURES) -> list[str]:
    pngs = [p for p in products if p.kind == "quicklook"]
    lines = ["<h2 id=\"quicklooks\">Quicklooks</h2>"]
    if not pngs:
        return [*lines, f"<p>{_e(no_figures)}</p>"]
    for p in pngs:
        text = (captions or {}).get(p.rel, "")
        caption = _e(p.rel) + (f": {_e(text)}" if text else "")
        lines.append(f'<figure><a href="{_href(p.rel, p.kind)}"><img src="'
                     f'{_href(p.rel, p.kind)}" alt="{_e(p.rel)}"></a>'
                     f"<figcaption>{caption}</figcaption></figure>")
    return lines


def _flags_text(q: Quality) -> str:
    parts = []
    for name, counts in q.flags.items():
        values = ", ".join(f"{v}: {c:,}" for v, c in counts.items())
        spans = q.n_flag_spans.get(name)
        parts.append(f"{_e(name)} ({values})" + (f"; {spans:,} non-zero span(s)"
                                                 if spans is not None else ""))
    return "<br>".join(parts)


def _attribute_html(name: str, value: str) -> str:
    """One recorded attribute; a validity flag that says ``no`` (and why) stands out."""
    text = f"{_e(name)}: {_e(value)}"
    if "valid" in name.lower() and value.strip().lower().startswith(("no", "false")):
        return f'<span class="warn">{text}</span>'
    return text


def _quality_section(qualities: Sequence[tuple[Sequence[ProductFile], Quality]],
                     n_readable: int) -> list[str]:
    lines = ["<h2 id=\"quality\">Data quality</h2>"]
    if not qualities:
        return [*lines, "<p>No CDF, netCDF or Zarr product to read the data quality from "
                "(the reports below, if any, hold it).</p>"]
    shown = sum(len(members) for members, _q in qualities)
    if n_readable > shown:
        lines.append(f"<p>The first {shown} of {n_readable} products.</p>")
    lines.append("<p>A gap is a sample interval longer than "
                 f"{GAP_FACTOR:g} times both its neighbours and the median interval (the "
                 "cadence); a backward step is an interval "
                 "&le; 0 (time not in order, or repeated). Products on the same times "
                 "(a day in several frames or levels) share a row, read from the first; "
                 "what it records is the first's.</p>")
    lines.append("<table><tr><th>product</th><th>samples</th><th>first</th><th>last</th>"
                 "<th>cadence (s)</th><th>gaps</th><th>backward steps</th><th>flags</th>"
                 "<th>recorded by the product</th></tr>")
    for members, q in qualities:
        gaps = (f'<span class="{"warn" if q.n_gaps else "ok"}">{q.n_gaps:,}</span>'
                + (f" (longest {max(g[2] for g in q.gaps):,.1f} s)" if q.gaps else ""))
        back = f'<span class="{"bad" if q.backwards else "ok"}">{q.backwards:,}</span>'
        attrs = "<br>".join(_attribute_html(k, v) for k, v in q.attributes.items())
        if q.note:
            attrs = (attrs + "<br>" if attrs else "") + f'<span class="warn">{_e(q.note)}</span>'
        cadence = "" if q.cadence_s is None else f"{q.cadence_s:.6g}"
        names = "<br>".join(_link(p) for p in members)
        lines.append(f"<tr><td>{names}</td><td class=\"num\">{q.samples:,}</td>"
                     f"<td>{_e(q.start)}</td><td>{_e(q.stop)}</td><td class=\"num\">{cadence}"
                     f"</td><td>{gaps}</td><td>{back}</td><td>{_flags_text(q)}</td>"
                     f"<td>{attrs}</td></tr>")
    lines.append("</table>")
    for members, q in qualities:
        spans = [(n, s) for n, s in q.flag_spans.items() if s]
        if not q.gaps and not spans:
            continue
        lines.append(f"<details><summary>{_e(members[0].rel)}"
                     + (f" and {len(members) - 1} more on the same times" if len(members) > 1
                        else "") + ": gaps and flag spans</summary>")
        if q.gaps:
            lines.append(f"<p>{len(q.gaps)} longest of {q.n_gaps} gap(s):</p><table><tr>"
                         "<th>last sample before</th><th>first sample after</th>"
                         "<th>seconds</th></tr>")
            lines += [f"<tr><td>{_e(a)}</td><td>{_e(b)}</td><td class=\"num\">{s:,.3f}</td>"
                      "</tr>" for a, b, s in q.gaps]
            lines.append("</table>")
        for name, rows in spans:
            lines.append(f"<p>{_e(name)}: first {len(rows)} of {q.n_flag_spans[name]} "
                         "non-zero span(s):</p><table><tr><th>from</th><th>to</th>"
                         "<th>value</th></tr>")
            lines += [f"<tr><td>{_e(a)}</td><td>{_e(b)}</td><td class=\"num\">{v}</td></tr>"
                      for a, b, v in rows]
            lines.append("</table>")
        lines.append("</details>")
    return lines


def _batch_table(report: dict[str, Any]) -> list[str]:
    counts = ", ".join(f"{v} {k}" for k, v in report.get("counts", {}).items())
    lines = [f"<p>{_e(counts)}</p>", "<table><tr><th>day</th><th>status</th><th>why</th>"
             "<th>vectors</th><th>error</th></tr>"]
    for d in report.get("days", []):
        status = str(d.get("status", ""))
        css = {"done": "ok", "skipped": "ok", "failed": "bad"}.get(status, "warn")
        lines.append(f"<tr><td>{_e(d.get('day', ''))}</td><td class=\"{css}\">{_e(status)}"
                     f"</td><td>{_e(d.get('reason') or '')}</td>"
                     f"<td class=\"num\">{int(d.get('n_vectors', 0) or 0):,}</td>"
                     f"<td>{_e(d.get('error') or '')}</td></tr>")
    lines.append("</table>")
    return lines


def _reports_section(products: Sequence[ProductFile]) -> list[str]:
    reports = [p for p in products if p.kind in ("text report", "JSON report")]
    lines = ["<h2 id=\"reports\">Reports</h2>"]
    if not reports:
        return [*lines, "<p>This run wrote no text or JSON report.</p>"]
    for p in reports:
        try:
            text = p.source.read_text(errors="replace")
        except OSError as exc:
            lines.append(f"<p>{_link(p)}: not readable ({_e(exc.strerror)})</p>")
            continue
        lines.append(f"<h3>{_link(p)}</h3>")
        if p.kind == "JSON report":
            try:
                data = json.loads(text)
            except ValueError:
                data = None
            if isinstance(data, dict) and isinstance(data.get("days"), list):
                lines += _batch_table(data)
                continue
        shown = text.splitlines()
        more = len(shown) - MAX_TEXT_LINES
        lines.append("<pre>" + _e("\n".join(shown[:MAX_TEXT_LINES])) + "</pre>")
        if more > 0:
            lines.append(f"<p>({more} more lines in the file)</p>")
    return lines


def render(title: str, products: Sequence[ProductFile],
           qualities: Sequence[tuple[Sequence[ProductFile], Quality]], n_readable: int,
           version: str = "", captions: Mapping[str, str] | None = None,
           no_figures: str = NO_FIGURES) -> str:
    """Return the report page (HTML5, inline CSS, relative links, no script).

    ``captions`` maps a figure's relative path to the sentence under it; ``no_figures``
    is the text of a run that drew none.
    """
    sections = (("runs", "Run reports"), ("quicklooks", "Quicklooks"), ("products", "Products"))
    if not any(p.kind == "run report" for p in products):
        sections = (("quicklooks", "Quicklooks"), ("quality", "Data quality"),
                    ("reports", "Reports"), ("products", "Products"))
    nav = " | ".join(f'<a href="#{a}">{t}</a>' for a, t in sections)
    runs = [p for p in products if p.kind == "run report"]
    body = [f"<h1>{_e(title)}</h1>",
            f'<p class="sub">Written by fluxcal {_e(version)}; open this file from its '
            "folder: every link is relative to it.</p>", f"<p>{nav}</p>"]
    if runs:  # an overview of several runs (the demo): their reports first
        body += ["<h2 id=\"runs\">Run reports</h2>", "<p>Each run's products, quicklooks "
                 "and data quality:</p>", "<ul>", *[f"<li>{_link(p)}</li>" for p in runs],
                 "</ul>", *_quicklook_section(products, captions, no_figures)]
    else:
        body += [*_quicklook_section(products, captions, no_figures),
                 *_quality_section(qualities, n_readable),
                 *_reports_section(products)]
    body += _products_section(products)
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


def write_run_report(out: Path, title: str | None = None,
                     products: Iterable[ProductFile] | None = None, *,
                     captions: Mapping[str, str] | None = None,
                     no_figures: str = NO_FIGURES) -> Path | None:
    """Write ``out/index.html``, the report of the run writing into ``out``.

    Parameters
    ----------
    out : Path
        The run's output folder.
    title : str, optional
        Page title (default: ``fluxcal run: <folder name>``).
    products : iterable of ProductFile, optional
        The files to list (default: `run_products`).
    captions : mapping, optional
        Figure path (relative to ``out``) -> what the figure shows (`render`).
    no_figures : str
        What the page says when the run drew no figure.

    Returns
    -------
    Path or None
        The report (inside a staging group: renamed into place with the products), or
        None when the run wrote nothing into ``out``.
    """
    out = Path(out)
    files = list(run_products(out) if products is None else products)
    if not files:
        return None
    groups: dict[tuple, list[ProductFile]] = {}
    for p in quality_products(files):  # one read per time axis (frames, levels of a day)
        groups.setdefault(time_axis_key(p) or (p.rel,), []).append(p)
    qualities = [(members, q) for members in groups.values()
                 if (q := product_quality(members[0])) is not None]
    page = render(title or f"fluxcal run: {out.resolve().name}", files, qualities,
                  len({_stem(p.rel) for p in files if p.kind in _READABLE}),
                  software_version(), captions, no_figures)
    return atomic_write_bytes(out / REPORT_NAME, page.encode("utf-8"))
