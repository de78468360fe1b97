"""Archive-style MESSENGER MAG EDR fixtures (PDS3 labels + tables) from a simulation.

`write_edr_archive` packs the simulated streams (`fluxcal.missions.messenger.simulate`)
into the EDR layout a mapping file declares (``data/edr_mapping_template.toml``): science
samples grouped into packets (packet MET in whole seconds, the first sample's offset in
``delta_ts`` units, the samples), one science-header row per packet (or per state change),
the heater bit in a LAC status word, the sensor temperature as raw counts.  One file per
EDR kind and UTC day, named by the mapping's patterns, written with
`fluxcal.products.tab.write_tab` (labels through `fluxcal.products.label`); optionally
older, wrong versions of every day beside the current one.

It is a forward model of the reader (`fluxcal.missions.messenger.edr`) and shares no code
with it: the packet rule is inverted here (whole-second packet MET, ``delta_ts``, ``I``)
from the recorded sample times, with Table 1 read by the forward model's own reader
(`fluxcal.missions.messenger.forward.read_tables`).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 2, sec. 5 Table 1, sec. 6.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pvl
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel, et_to_tt2000, tt2000_to_datetime64
from fluxcal.missions.messenger import forward
from fluxcal.missions.messenger.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.columns import Column
from fluxcal.products.label import Symbol, read_label, render_label
from fluxcal.products.paths import make_folder
from fluxcal.products.tab import write_tab

#: Samples per simulated science packet (fluxcal's fixture choice: odd, so packets start
#: at varied fractions of a second and ``delta_ts`` takes many values).
PACKET_SAMPLES = 7
#: DATA_SET_ID of the archived MAG EDRs (public PDS PPI listing).
DATA_SET_ID = "MESS-E/V/H/SW-MAG-2-EDR-RAWDATA-V1.0"
_US = 1_000_000
_FILE_TAGS = {"science": "SCI", "science_header": "SHD", "lac": "LAC", "status": "STAT"}


def _name(pattern: str, yyddd: str, hhmm: str, version: int) -> str:
    """Return the label file name the mapping's pattern matches (literal parts kept)."""
    text = pattern.lstrip("^").rstrip("$")
    text = re.sub(r"\(\?P<yyddd>[^)]*\)", yyddd, text)
    text = re.sub(r"\(\?P<hhmm>[^)]*\)", hhmm, text)
    text = re.sub(r"\(\?P<version>[^)]*\)", str(version), text)
    name = text.replace("\\.", ".")
    if not re.match(pattern, name):
        raise ValueError(f"cannot build a file name from the pattern {pattern!r}")
    return name


def _utc_days(partition: np.ndarray, met: np.ndarray, sclk: SclkKernel) -> np.ndarray:
    """UTC ``datetime64[m]`` of each clock reading (kernels loaded)."""
    et = sclk.to_et(partition.astype(np.int64), met)
    return tt2000_to_datetime64(et_to_tt2000(et)).astype("datetime64[m]")


def _concat(sims: Sequence[Mapping[str, xr.Dataset]], key: str, dim: str) -> xr.Dataset:
    parts = [s[key] for s in sims]
    return parts[0] if len(parts) == 1 else xr.concat(parts, dim=dim)


def _packets(sci: xr.Dataset, days: np.ndarray, unit_us: int,
             packet_samples: int) -> dict[str, np.ndarray]:
    """Group samples into packets: same partition, rate and UTC day, evenly spaced.

    Returns per sample the packet number, whole-second packet MET, ``delta_ts`` and the
    1-based index ``I`` in its packet.
    """
    hz = forward.read_tables().sample_rate_hz
    rate = sci["rate"].values.astype(np.int64)
    part = sci["partition"].values.astype(np.int64)
    t_us = np.rint(sci["met"].values * _US).astype(np.int64)
    period = np.rint(_US / hz[rate]).astype(np.int64)
    n = t_us.size
    brk = np.ones(n, dtype=bool)
    brk[1:] = ((part[1:] != part[:-1]) | (rate[1:] != rate[:-1]) | (days[1:] != days[:-1])
               | (t_us[1:] - t_us[:-1] != period[1:]))
    run_start = np.flatnonzero(brk)
    pos = np.arange(n) - run_start[np.cumsum(brk) - 1]
    new = brk | (pos % packet_samples == 0)
    packet = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    met0_us = (t_us[first] // _US) * _US
    offset = t_us[first] - met0_us
    if np.any(offset % unit_us):
        raise ValueError("a packet's first sample is not on the delta_ts grid "
                         f"({unit_us} us) after a whole MET second")
    index = np.arange(n) - first[packet] + 1
    return {"packet": packet, "met": (met0_us // _US)[packet],
            "delta_ts": (offset // unit_us)[packet], "index": index, "first": first}


def _write(ds: xr.Dataset, columns: list[Column], stem: Path, vectors: dict[str, str],
           extra: dict[str, Any]) -> list[Path]:
    """Write table + label; merge each vector's three columns into one ``ITEMS = 3`` column.

    ``vectors`` maps a variable to its label name when it is written as one column with
    ITEMS (the other vectors stay three scalar columns).  fluxcal's own ``FLUXCAL:*``
    column keywords are removed: an archive label has none.
    """
    tab, lbl = write_tab(ds, stem, columns, extra)
    label = read_label(lbl)
    table = label["TABLE"]
    new_table = pvl.PVLObject()
    cols: list[pvl.PVLObject] = []
    for key, value in table.items():
        if key != "COLUMN":
            new_table.append(key, value)
            continue
        col = pvl.PVLObject((k, v) for k, v in value.items() if not k.startswith("FLUXCAL:"))
        var = str(value.get("FLUXCAL:VARIABLE", ""))
        if var in vectors and cols and cols[-1]["NAME"] == vectors[var]:
            head = cols[-1]
            head["ITEMS"] = head.get("ITEMS", 1) + 1
            head["BYTES"] = col["START_BYTE"] + col["BYTES"] - head["START_BYTE"]
            continue
        if var in vectors:
            col["NAME"] = vectors[var]
            col["ITEM_BYTES"] = col["BYTES"]
            col["ITEM_OFFSET"] = col["BYTES"] + 1
            col["ITEMS"] = 1
        cols.append(col)
    order = ("NAME", "DATA_TYPE", "START_BYTE", "BYTES", "ITEMS", "ITEM_BYTES", "ITEM_OFFSET")
    for i, col in enumerate(cols):
        ordered = pvl.PVLObject([("COLUMN_NUMBER", i + 1)])
        for k in order:
            if k in col:
                ordered[k] = col[k]
        for k, v in col.items():
            if k not in ordered:
                ordered[k] = v
        new_table.append("COLUMN", ordered)
    new_table["COLUMNS"] = len(cols)
    label["TABLE"] = new_table
    for block in (label, new_table, *new_table.getall("COLUMN")):
        for key in ("PDS_VERSION_ID", "RECORD_TYPE", "INTERCHANGE_FORMAT", "DATA_TYPE"):
            if key in block:  # symbols again (reading the label back made them text)
                block[key] = Symbol(str(block[key]))
    atomic_write_bytes(lbl, render_label(label).encode("ascii"), now=True)
    return [tab, lbl]


def _split_days(minutes: np.ndarray) -> list[tuple[np.ndarray, str, str]]:
    """Row indices per UTC day, with the day's ``yyddd`` and its first row's ``hhmm``."""
    days = minutes.astype("datetime64[D]")
    out = []
    for day in np.unique(days):
        rows = np.flatnonzero(days == day)
        first = minutes[rows[0]].astype(object)
        out.append((rows, f"{first:%y%j}", f"{first:%H%M}"))
    return out


def write_edr_archive(
    sims: Mapping[str, xr.Dataset] | Sequence[Mapping[str, xr.Dataset]],
    out_dir: str | Path,
    mapping: str | Path,
    sclk: SclkKernel,
    *,
    version: int = 2,
    superseded: Sequence[int] = (1,),
    header: str = "packet",
    packet_samples: int = PACKET_SAMPLES,
    seed: int = 0,
) -> list[Path]:
    """Write simulated streams as archive-style MAG EDRs in the mapping's layout.

    Parameters
    ----------
    sims : dict of Dataset, or a sequence of them
        ``simulate`` output(s) (``science``, ``heater``, ``temperature``); several are
        concatenated in the given (time) order, e.g. two runs either side of a clock
        reset.
    out_dir : path
        Written as ``<out_dir>/<SCI|SHD|LAC|STAT>/<yyyy>/<label and table>``.
    mapping : path
        Mapping file: column names, partition style, delta_ts unit, heater bit,
        temperature conversion (a polynomial of degree 1: temperatures are written as
        ``rint((T - c0) / c1)`` counts) and file patterns.
    sclk : fluxcal.geometry.time.SclkKernel
        MESSENGER clock (kernels loaded): the UTC day of each record names its file.
    version : int
        Version ``_V<n>`` of the correct files.
    superseded : sequence of int
        Older versions written beside every day's files, with wrong content (science
        counts + 100, the heater bit flipped, temperatures + 100 counts, the rate of
        every header row changed), which the reader must skip.
    header : {"packet", "changes"}
        One science-header row per packet, or only where the rate changes (and at the
        first packet of each day).
    packet_samples : int
        Largest number of samples per packet.
    seed : int
        Seed of the random filler bits of the LAC status word.

    Returns
    -------
    list of Path
        Every file written.

    Raises
    ------
    ValueError
        A sample time off the ``delta_ts`` grid, a temperature conversion that is not
        a degree-1 polynomial, a bad ``header`` value.
    """
    if header not in ("packet", "changes"):
        raise ValueError(f"header must be 'packet' or 'changes', got {header!r}")
    m = tomllib.loads(Path(mapping).read_text(encoding="utf-8"))
    runs = [sims] if isinstance(sims, Mapping) else list(sims)
    sci = _concat(runs, "science", "time")
    heat = _concat(runs, "heater", "heater_time")
    temp = _concat(runs, "temperature", "temperature_time")
    out = Path(out_dir)
    rng = np.random.default_rng(seed)
    written: list[Path] = []

    def col(kind: str, field: str) -> str:
        return str(m[kind][field].get("column", ""))

    def emit(kind: str, data: dict[str, tuple[np.ndarray, str]], part: np.ndarray,
             met: np.ndarray, minutes: np.ndarray, vectors: dict[str, str] | None = None,
             spoil: dict[str, Any] | None = None) -> None:
        """One file per UTC day (and older spoiled versions); ``data``: name -> (values, fmt)."""
        if col(kind, "partition"):
            data = {col(kind, "partition"): (part, "I2"), **data}
        for rows, yyddd, hhmm in _split_days(minutes):
            for v in (*superseded, version):
                values = {k: a[rows] for k, (a, _) in data.items()}
                if v != version and spoil:
                    values = {k: spoil[k](a) if k in spoil else a for k, a in values.items()}
                ds = xr.Dataset({k: (("time",) if a.ndim == 1 else ("time", "component")
                                     if a.shape[1] == 3 and k == counts_name
                                     else ("time", f"{k}_item"), a)
                                 for k, a in values.items()},
                                coords={"component": ["x", "y", "z"]})
                columns = [Column(k, fmt, unit=doc.get(k, ("", ""))[0],
                                  description=doc.get(k, ("", ""))[1],
                                  label=k if k not in (vectors or {}) else k + "{c}")
                           for k, (_, fmt) in data.items()]
                pattern = m[kind]["file"]["pattern"]
                name = _name(pattern, yyddd, hhmm, v)
                folder = out / _FILE_TAGS[kind] / f"20{yyddd[:2]}"
                make_folder(folder)
                p0, p1 = int(part[rows[0]]), int(part[rows[-1]])
                extra = {"DATA_SET_ID": DATA_SET_ID, "INSTRUMENT_ID": "MAG",
                         "PRODUCT_VERSION_ID": str(v),
                         "SPACECRAFT_CLOCK_START_COUNT": f"{p0}/{met[rows[0]]:.6f}",
                         "SPACECRAFT_CLOCK_STOP_COUNT": f"{p1}/{met[rows[-1]]:.6f}"}
                written.extend(_write(ds, columns, folder / Path(name).stem, vectors or {},
                                      extra))

    unit_s = float(m["science"]["delta_ts"]["unit_s"])
    doc = {
        col("science", "met"): ("s", "Packet MET (whole seconds of the spacecraft clock)"),
        col("science", "delta_ts"): (f"{unit_s:g} s", "Offset of the packet's first "
                                     f"sample from the packet MET, in units of {unit_s:g} s"),
        col("science", "sample_index"): ("N/A", "Sample number I in the packet (1 = first)"),
        col("science", "range"): ("N/A", "Range flag: 0 fine (+-1530 nT), 1 coarse"),
        col("science_header", "rate"): ("N/A", "Rate setting 0-10 (Table 1)"),
        col("lac", "heater"): ("N/A", "Status word; the heater request bit is bit "
                               f"{m['lac']['heater'].get('bit', 0)}"),
        col("status", "temperature"): ("N/A", "Sensor temperature, raw counts"),
        col("status", "met"): ("s", "MET of the status record"),
        col("lac", "met"): ("s", "MET of the 1-s LAC record"),
        "MODE": ("N/A", "Instrument mode (simulation: always 0)"),
    }
    counts_name = m["science"]["counts"].get("column") or ""
    doc[counts_name] = ("N/A", "Sensor x, y, z, signed 16-bit counts")
    for name in m["science"]["counts"].get("columns") or ():
        doc[name] = ("N/A", f"Sensor {name}, signed 16-bit counts")
    # --- science and science header ------------------------------------------------------
    spart, smet = sci["partition"].values, sci["met"].values
    sminutes = _utc_days(spart, smet, sclk)
    unit_us = int(round(float(m["science"]["delta_ts"]["unit_s"]) * _US))
    pk = _packets(sci, sminutes.astype("datetime64[D]"), unit_us, packet_samples)
    counts = m["science"]["counts"]
    data: dict[str, tuple[np.ndarray, str]] = {
        col("science", "met"): (pk["met"], "I10"),
        col("science", "delta_ts"): (pk["delta_ts"], "I3"),
    }
    if col("science", "sample_index"):
        data[col("science", "sample_index")] = (pk["index"], "I4")
    data[col("science", "range")] = (sci["range"].values.astype(np.int64), "I1")
    c = sci["counts"].values.astype(np.int64)
    if counts.get("column"):
        data[counts["column"]] = (c, "I6")
        vectors = {counts["column"]: counts["column"]}
    else:
        for j, name in enumerate(counts["columns"]):
            data[name] = (c[:, j], "I6")
        vectors = {}
    spoil = {counts.get("column") or counts["columns"][0]:
             lambda a: np.clip(a + 100, -32768, 32767)}
    first = pk["first"]
    if m["science"]["sample_index"].get("from", "rows") == "items":
        # one row per packet, the samples as ITEMS (padded with 0 after the last sample)
        rows, n_items = first.size, packet_samples
        slot = (pk["packet"], pk["index"] - 1)
        packed = {}
        for name, (values, fmt) in data.items():
            if name in (col("science", "met"), col("science", "delta_ts")):
                packed[name] = (values[first], fmt)
                continue
            grid = np.zeros((rows, n_items, *values.shape[1:]), dtype=values.dtype)
            grid[slot] = values
            if grid.ndim == 3:  # one counts column of 3N items: x1 y1 z1 x2 ...
                grid = grid.reshape(rows, -1)
            packed[name] = (grid, fmt)
        count_col = m["science"].get("sample_count", {}).get("column", "")
        if count_col:
            packed[count_col] = (np.bincount(pk["packet"], minlength=rows), "I3")
            doc[count_col] = ("N/A", "Number of valid samples (items) in the packet")
        data = packed
        vectors = {name: name for name, (v, _) in data.items() if v.ndim == 2}
        emit("science", data, spart[first], pk["met"][first].astype(float), sminutes[first],
             vectors, spoil)
    else:
        emit("science", data, spart, pk["met"].astype(float), sminutes, vectors, spoil)
    rate = sci["rate"].values.astype(np.int64)[first]
    hday = sminutes[first].astype("datetime64[D]")
    keep = np.ones(first.size, dtype=bool)
    if header == "changes":
        keep[1:] = (rate[1:] != rate[:-1]) | (hday[1:] != hday[:-1]) | (
            spart[first][1:] != spart[first][:-1])
    hrows = first[keep]
    emit("science_header",
         {col("science_header", "met"): (pk["met"][hrows], "I10"),
          col("science_header", "rate"): (rate[keep], "I2"),
          "MODE": (np.zeros(hrows.size, dtype=np.int64), "I1")},
         spart[hrows], pk["met"][hrows].astype(float), sminutes[hrows],
         spoil={col("science_header", "rate"): lambda a: (a + 1) % 11})
    # --- LAC: the heater bit inside a status word -----------------------------------------
    hpart, hmet = heat["partition"].values, heat["met"].values
    if np.any(hmet != np.round(hmet)):
        raise ValueError("heater records must be at whole MET seconds")
    bits = heat["heater"].values.astype(np.int64)
    hspec = m["lac"]["heater"]
    if "bit" in hspec:
        b = int(hspec["bit"])
        filler = rng.integers(0, 256, bits.size) & ~(1 << b)
        word = filler | (bits << b)
        flip = 1 << b
    else:
        word, flip = bits, 1
    emit("lac", {col("lac", "met"): (hmet.astype(np.int64), "I10"),
                 col("lac", "heater"): (word, "I4")},
         hpart, hmet, _utc_days(hpart, hmet, sclk),
         spoil={col("lac", "heater"): lambda a: a ^ flip})
    # --- status: temperature as raw counts -------------------------------------------------
    conv = m["status"]["temperature"]["conversion"]
    coef = conv.get("coefficients") or []
    if conv.get("kind") != "polynomial" or len(coef) != 2 or coef[1] == 0:
        raise ValueError("the fixture writer needs a degree-1 polynomial temperature "
                         "conversion [c0, c1] in the mapping")
    tcounts = np.rint((temp["temperature_c"].values - coef[0]) / coef[1]).astype(np.int64)
    tpart, tmet = temp["partition"].values, temp["met"].values
    emit("status", {col("status", "met"): (tmet, "F17.6"),
                    col("status", "temperature"): (tcounts, "I8")},
         tpart, tmet, _utc_days(tpart, tmet, sclk),
         spoil={col("status", "temperature"): lambda a: a + 100})
    return written


def filled_mapping(template: str | Path, out: str | Path,
                   coefficients: Sequence[float] = (-150.0, 0.0625)) -> Path:
    """Copy the mapping template with a simulation's temperature conversion declared.

    The template has no conversion (the procedure document gives none); the simulator declares its
    own (default ``degC = -150 + n / 16``) so its EDRs can be read back.
    """
    text = Path(template).read_text(encoding="utf-8")
    coef = ", ".join(repr(float(c)) for c in coefficients)
    new, n = re.subn(r"(?m)^coefficients = \[\]",
                     f"coefficients = [{coef}]  # fluxcal simulation: not the instrument's",
                     text)
    if n != 1:
        raise ValueError(f"{template}: no empty 'coefficients = []' line to fill")
    atomic_write_bytes(Path(out), new, now=True)
    return Path(out)


def simulate_edr_layout(out: str | Path, start_utc: str = "2012-06-01T00:00:00",
                        duration_s: float = 7200.0, solar_wind: str = "realistic"
                        ) -> dict[str, Path]:
    """Simulate MAG telemetry and write it as archive-style EDRs, with a filled mapping.

    Writes ``kernels/``, ``edr/`` (`write_edr_archive`: versions 1 (wrong) and 2 of
    every day, and ``edr/edr_mapping.toml``: the template with the simulation's
    temperature conversion; the name `fluxcal batch messenger` recognises), and
    ``inputs/`` (the same streams as CSV, and the truth).  Sensor
    temperatures are quantised to the conversion's 1/16 degC counts before both are
    written, so the EDR and CSV routes see the same numbers.  ``solar_wind``: the
    interplanetary field, ``realistic`` or ``quiet`` (`SimulationConfig`).

    Returns
    -------
    dict
        Paths keyed ``kernels``, ``edr``, ``mapping``, ``science``, ``heater``,
        ``temperature``, ``truth``.
    """
    out = Path(out)
    make_folder(out)
    config = SimulationConfig(start_utc=start_utc, duration_s=duration_s,
                              solar_wind=solar_wind)
    mk = write_messenger_like_kernels(
        out / "kernels", start_utc, duration_s + 2 * config.lead_s,
        plus_y_sunward=[(0.25 * duration_s, 0.45 * duration_s)],
    )
    make_folder(out / "edr")
    mapping = filled_mapping(template_path(), out / "edr" / "edr_mapping.toml")
    c0, c1 = -150.0, 0.0625
    with KernelPool(mk, frames=FRAME_KERNELS):
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        sim = simulate(config, None, sclk)
        t = sim["temperature"]["temperature_c"]
        sim["temperature"]["temperature_c"] = c0 + c1 * np.rint((t - c0) / c1)
        write_edr_archive(sim, out / "edr", mapping, sclk)
    paths = write_inputs(sim, out / "inputs")
    return {"kernels": mk, "edr": out / "edr", "mapping": mapping, **paths}


def template_path() -> Path:
    """Return the path of the packaged mapping template."""
    return Path(str(resources.files("fluxcal.missions.messenger") / "data"
                    / "edr_mapping_template.toml"))


__all__ = ["DATA_SET_ID", "PACKET_SAMPLES", "filled_mapping", "template_path",
           "write_edr_archive"]
