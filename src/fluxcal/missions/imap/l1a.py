"""IMAP MAG L1A: per-sensor counts and range with exact TT2000 times.

Two input routes give the same per-sensor datasets: decoded science packets
(`from_packets`) and the team's L1A CSV layout ``MAGScience-<mode>-(<pri>,<sec>)-<n>s-
<date>.csv`` (`read_l1a_csv`).  Vector ``k`` of a packet is sampled at the sensor's
packet time (coarse seconds + fine/65536 s) plus ``k / vectors_per_second``; that clock
reading goes through the IMAP SCLK kernel (NAIF -43) with fluxcal's exact SCLK path
(`vector_tt2000`).  The team's own times differ by up to 15 us: docs/decisions/imap.md.

A dataset per (mode, sensor) has dimension ``time`` with the int64 TT2000 coordinate
``epoch``, ``counts`` (time, component) int64, ``range`` 0..3, the packet's
``sequence``, ``coarse``, ``fine``, the vector's ``vector_index``, the
``vectors_per_second``, ``compression`` and ``compression_width``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap.packets import MODES, MagPackets, packet_vectors, vectors_per_second

#: NAIF id of the IMAP spacecraft clock (``imap_sclk_0036.tsc``: SCLK01_*_43).
IMAP_SCLK_ID = -43
#: Fine-time counts per second of the MAG packet times (16-bit sub-second counter).
FINE_PER_SECOND = 65536
SENSORS = ("mago", "magi")
COMPONENTS = np.array(["x", "y", "z"])
_CSV_NAME = re.compile(r"MAGScience-(normal|burst)-\((\d+),(\d+)\)-(\d+)s-(\d{8})")
_CSV_COLUMNS = ("sequence", "x_pri", "y_pri", "z_pri", "rng_pri", "x_sec", "y_sec", "z_sec",
                "rng_sec", "pri_coarse", "pri_fine", "sec_coarse", "sec_fine")


def vector_tt2000(clock: SclkKernel, coarse: np.ndarray, fine: np.ndarray,
                  index: np.ndarray, per_second: np.ndarray) -> np.ndarray:
    """Exact TT2000 ns of vectors: ``coarse + fine/65536 + index/per_second`` s of SCLK.

    The reading is held as an integer count of 1/65536 s (``per_second`` must divide
    65536: the rates are powers of two up to 128), split into whole clock ticks (the
    kernel's 1/50000 s) converted exactly by `SclkKernel.to_tt2000_ticks`, and the rest
    of a tick, added in ns (the clock rate's departure from 1, below 1e-6, changes that
    rest of at most 20 us by less than 1e-4 ns).

    Raises
    ------
    InputFormatError
        A rate that does not divide 65536, or a reading outside the kernel's partition.
    """
    per_second = np.asarray(per_second, dtype=np.int64)
    if np.any((per_second <= 0) | (FINE_PER_SECOND % np.maximum(per_second, 1) != 0)):
        bad = int(per_second[(per_second <= 0) | (FINE_PER_SECOND % np.maximum(
            per_second, 1) != 0)].ravel()[0])
        raise InputFormatError(f"{bad} vectors per second does not divide 65536",
                               field="vectors_per_second")
    reading = (np.asarray(coarse, dtype=np.int64) * FINE_PER_SECOND
               + np.asarray(fine, dtype=np.int64)
               + np.asarray(index, dtype=np.int64) * (FINE_PER_SECOND // per_second))
    tpc = int(clock.exact.ticks_per_count)
    whole_s, part = np.divmod(reading, FINE_PER_SECOND)
    sub_ticks, rest = np.divmod(part * tpc, FINE_PER_SECOND)
    ticks = whole_s * tpc + sub_ticks
    rest_ns = np.rint(rest * (1e9 / tpc) / FINE_PER_SECOND).astype(np.int64)
    return clock.to_tt2000_ticks(np.ones_like(ticks), ticks) + rest_ns


def sensor_dataset(clock: SclkKernel, counts: np.ndarray, rng: np.ndarray,
                   sequence: np.ndarray, coarse: np.ndarray, fine: np.ndarray,
                   index: np.ndarray, per_second: np.ndarray, compression: np.ndarray,
                   width: np.ndarray, *, mode: str, sensor: str) -> xr.Dataset:
    """Assemble one (mode, sensor) L1A dataset (per-vector arrays, times from `clock`)."""
    epoch = vector_tt2000(clock, coarse, fine, index, per_second)
    ds = xr.Dataset(
        {
            "counts": (("time", "component"), np.asarray(counts, dtype=np.int64),
                       {"units": "count", "description": "Fluxgate output, x y z"}),
            "range": ("time", np.asarray(rng, dtype=np.int64),
                      {"units": "1", "description": "Sensor range 0..3"}),
            "sequence": ("time", np.asarray(sequence, dtype=np.int64),
                         {"units": "1", "description": "CCSDS sequence count of the packet"}),
            "coarse": ("time", np.asarray(coarse, dtype=np.int64),
                       {"units": "s", "description": "Packet coarse time (SCLK seconds)"}),
            "fine": ("time", np.asarray(fine, dtype=np.int64),
                     {"units": "1", "description": "Packet fine time (1/65536 s)"}),
            "vector_index": ("time", np.asarray(index, dtype=np.int64),
                             {"units": "1", "description": "Vector index within the packet"}),
            "vectors_per_second": ("time", np.asarray(per_second, dtype=np.int64),
                                   {"units": "1", "description": "Vectors per second"}),
            "compression": ("time", np.asarray(compression, dtype=np.int64),
                            {"units": "1", "description": "Compression flag"}),
            "compression_width": ("time", np.asarray(width, dtype=np.int64),
                                  {"units": "1", "description": "Compression width (bits)"}),
        },
        coords={"epoch": ("time", epoch), "component": COMPONENTS},
        attrs={"mode": mode, "sensor": sensor, "level": "l1a"},
    )
    return ds


def from_packets(packets: MagPackets, clock: SclkKernel) -> dict[tuple[str, str], xr.Dataset]:
    """L1A datasets of decoded packets, keyed by (mode, sensor): ``("norm", "mago")`` ...

    ``PRI_SENS = 0`` makes MAGo the primary sensor (its vectors first, its times
    ``PRI_COARSETM``/``PRI_FNTM``), 1 MAGi.

    Raises
    ------
    InputFormatError
        From `packet_vectors` (compressed or short packets), naming the packet.
    """
    f = packets.fields
    parts: dict[tuple[str, str], list[dict[str, np.ndarray]]] = {}
    for i in range(len(packets)):
        mode = MODES[int(f["PKT_APID"][i])]
        pri, sec = packet_vectors(packets, i)
        pri_is_mago = int(f["PRI_SENS"][i]) == 0
        for (counts, rng), key in ((pri, "PRI"), (sec, "SEC")):
            sensor = "mago" if (key == "PRI") == pri_is_mago else "magi"
            n = len(rng)
            parts.setdefault((mode, sensor), []).append({
                "counts": counts, "rng": rng, "sequence": np.full(n, f["SRC_SEQ_CTR"][i]),
                "coarse": np.full(n, f[f"{key}_COARSETM"][i]),
                "fine": np.full(n, f[f"{key}_FNTM"][i]), "index": np.arange(n),
                "per_second": np.full(n, vectors_per_second(f[f"{key}_VECSEC"][i])),
                "compression": np.full(n, f["COMPRESSION"][i]), "width": np.zeros(n),
            })
    out = {}
    for (mode, sensor), chunks in parts.items():
        cat = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
        out[(mode, sensor)] = sensor_dataset(clock, **cat, mode=mode, sensor=sensor)
    return out


def read_l1a_csv(path: Path | str, clock: SclkKernel) -> dict[tuple[str, str], xr.Dataset]:
    """Read the team's L1A CSV layout into (mode, sensor) datasets like `from_packets`.

    The name ``MAGScience-<normal|burst>-(<pri>,<sec>)-<n>s-<yyyymmdd>...csv`` gives the
    mode and the vectors per second of the primary and secondary sensor; the columns are
    ``sequence``, x/y/z/rng of ``pri`` and ``sec``, ``pri_coarse``, ``pri_fine``,
    ``sec_coarse``, ``sec_fine`` and optionally ``compression``,
    ``compression_width_bits``.  Consecutive rows with the same packet (sequence and
    times) are its vectors 0, 1, ...; the primary sensor is MAGo (the layout has no
    ``PRI_SENS``; the team's validation reads it so).

    Raises
    ------
    InputFormatError
        Naming the file, line and column: a name not in that layout, a missing column,
        a value that is not an integer, more rows in a packet than it can hold.
    """
    path = Path(path)
    m = _CSV_NAME.match(path.name)
    if m is None:
        raise InputFormatError("name is not MAGScience-<normal|burst>-(<pri>,<sec>)-<n>s-"
                               "<yyyymmdd>...csv (the team's L1A CSV layout)", path=str(path))
    mode = "norm" if m.group(1) == "normal" else "burst"
    rate = {"pri": int(m.group(2)), "sec": int(m.group(3))}
    seconds = int(m.group(4))
    with path.open(newline="") as fh:
        header = fh.readline().strip().split(",")
        missing = [c for c in _CSV_COLUMNS if c not in header]
        if missing:
            raise InputFormatError(f"missing column(s) {missing}", path=str(path), line=1,
                                   field=missing[0])
        text = fh.read()
    try:
        table = np.loadtxt(text.splitlines(), delimiter=",", dtype=np.int64, ndmin=2)
    except ValueError as exc:
        raise InputFormatError(f"not a table of integers ({exc})", path=str(path)) from exc
    if table.shape[1] != len(header):
        raise InputFormatError(f"{table.shape[1]} columns, the header names {len(header)}",
                               path=str(path), line=2)
    col = {name: table[:, j] for j, name in enumerate(header)}
    n = table.shape[0]
    zeros = np.zeros(n, dtype=np.int64)
    out = {}
    for side, sensor in (("pri", "mago"), ("sec", "magi")):
        coarse, fine = col[f"{side}_coarse"], col[f"{side}_fine"]
        key = np.stack([col["sequence"], coarse, fine], axis=1)
        new = np.ones(n, dtype=bool)
        new[1:] = np.any(key[1:] != key[:-1], axis=1)
        start = np.flatnonzero(new)
        index = np.arange(n) - start[np.cumsum(new) - 1]
        limit = rate[side] * seconds
        if np.any(index >= limit):
            line = int(np.flatnonzero(index >= limit)[0]) + 2
            raise InputFormatError(f"packet holds more than {limit} {side} vectors "
                                   f"({rate[side]}/s x {seconds} s)", path=str(path),
                                   line=line, field=f"{side}_coarse")
        counts = np.stack([col[f"{a}_{side}"] for a in "xyz"], axis=1)
        out[(mode, sensor)] = sensor_dataset(
            clock, counts, col[f"rng_{side}"], col["sequence"], coarse, fine, index,
            np.full(n, rate[side]), col.get("compression", zeros),
            col.get("compression_width_bits", zeros), mode=mode, sensor=sensor)
    return out
