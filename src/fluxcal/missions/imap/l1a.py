"""IMAP MAG L1A: per-sensor counts and range with exact TT2000 times.

Two input routes give the same per-sensor datasets: decoded science packets
(`from_packets`, compressed or not: `fluxcal.missions.imap.vectors`) and the team's L1A
CSV layout (`read_l1a_csv`, recognised by its columns; the mode and rates come from a
name ``MAGScience-<mode>-(<pri>,<sec>)-<n>s-<date>.csv`` or from ``--csv-layout``).
Vector ``k`` of a packet is sampled at the sensor's packet time (coarse seconds +
fine/65536 s) plus ``k / vectors_per_second``; that clock reading goes through the IMAP
SCLK kernel (NAIF -43) with fluxcal's exact SCLK path (`vector_tt2000`).  The team's
expected times divide the fine time by 65535 instead, up to 15.3 us later:
docs/decisions/imap.md.

A dataset per (mode, sensor) has dimension ``time`` with the int64 TT2000 coordinate
``epoch``, ``counts`` (time, component) int64, ``range`` 0..3, the packet's
``sequence``, ``coarse``, ``fine``, the vector's ``vector_index``, the
``vectors_per_second``, ``compression`` and ``compression_width`` (the packet's ``W``;
0 for an uncompressed packet, as the team's L1A; the L1A CSV's value as written).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.imap.packets import MODES, MagPackets, vectors_per_second
from fluxcal.missions.imap.vectors import MAX_WIDTH, decode_vectors

#: NAIF id of the IMAP spacecraft clock (``imap_sclk_0036.tsc``: SCLK01_*_43).
IMAP_SCLK_ID = -43
#: Fine-time counts per second of the MAG packet times (16-bit sub-second counter).
FINE_PER_SECOND = 65536
SENSORS = ("mago", "magi")
COMPONENTS = np.array(["x", "y", "z"])
#: Vectors converted at once by `vector_tt2000` (its temporaries stay below ~20 MB).
_BLOCK = 1 << 18
_CSV_NAME = re.compile(r"MAGScience-(normal|burst)-\((\d+),(\d+)\)-(\d+)s-(\d{8})")
_LAYOUT = re.compile(r"(normal|burst)-\((\d+),(\d+)\)-(\d+)s$")
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
    shape = np.broadcast_shapes(np.shape(coarse), np.shape(fine), np.shape(index),
                                per_second.shape)
    if len(shape) == 1 and shape[0] > _BLOCK:  # bounded temporaries (peak memory)
        args = [np.broadcast_to(np.asarray(a, dtype=np.int64), shape)
                for a in (coarse, fine, index, per_second)]
        out = np.empty(shape, dtype=np.int64)
        for lo in range(0, shape[0], _BLOCK):
            out[lo:lo + _BLOCK] = vector_tt2000(clock, *(a[lo:lo + _BLOCK] for a in args))
        return out
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
    ``PRI_COARSETM``/``PRI_FNTM``), 1 MAGi.  Every step is on whole arrays (the
    vectors of every packet at once, `decode_vectors`).

    Raises
    ------
    InputFormatError
        From `decode_vectors` (a packet whose vectors cannot be decoded), naming it.
    """
    f = packets.fields
    dec = decode_vectors(packets)
    # each dataset's columns are taken for its own vectors only, never built for every
    # vector and then copied (peak memory: docs/decisions/imap.md)
    mago = (f["PRI_SENS"] == 0)[dec.packet] != dec.secondary
    out = {}
    for (code, mode), (sensor, is_mago) in itertools.product(
            MODES.items(), (("mago", True), ("magi", False))):
        take = np.flatnonzero((f["PKT_APID"] == code)[dec.packet] & (mago == is_mago))
        if take.size == 0:
            continue
        pk, sec = dec.packet[take], dec.secondary[take]
        out[(mode, sensor)] = sensor_dataset(
            clock, counts=dec.counts[take], rng=dec.range[take],
            sequence=f["SRC_SEQ_CTR"][pk],
            coarse=np.where(sec, f["SEC_COARSETM"][pk], f["PRI_COARSETM"][pk]),
            fine=np.where(sec, f["SEC_FNTM"][pk], f["PRI_FNTM"][pk]), index=dec.index[take],
            per_second=vectors_per_second(np.where(sec, f["SEC_VECSEC"][pk],
                                                   f["PRI_VECSEC"][pk])),
            compression=f["COMPRESSION"][pk], width=dec.width[pk], mode=mode, sensor=sensor)
    return out


def csv_header(path: Path | str) -> list[str] | None:
    """Return the column names of a file in the team's L1A CSV layout, else None.

    The file is the team's layout when its first line (read up to 4 KiB) is text naming
    every column of `_CSV_COLUMNS`; the file name plays no part.
    """
    with open(path, "rb") as fh:
        first = fh.readline(4096)
    try:
        names = first.decode("ascii").strip().split(",")
    except UnicodeDecodeError:
        return None
    return names if set(_CSV_COLUMNS) <= set(names) else None


def csv_layout(path: Path, layout: str | None) -> tuple[str, dict[str, int], int]:
    """Mode, vectors per second (``pri``, ``sec``) and seconds per packet of an L1A CSV.

    From ``layout`` (``--csv-layout``, e.g. ``normal-(2,2)-8s``) when given, else from
    a name ``MAGScience-<normal|burst>-(<pri>,<sec>)-<n>s-<yyyymmdd>...`` (the team's
    convention: the file's columns do not hold them).

    Raises
    ------
    InputFormatError
        Neither says (names the file and ``--csv-layout``), or a layout not in that form.
    """
    if layout is not None:
        m = _LAYOUT.match(layout)
        if m is None:
            raise InputFormatError(f"{layout!r} is not <normal|burst>-(<pri>,<sec>)-<n>s, "
                                   "e.g. normal-(2,2)-8s", field="--csv-layout")
    else:
        m = _CSV_NAME.match(path.name)
        if m is None:
            raise InputFormatError(
                "the team's L1A CSV layout, but its name does not give the mode and "
                "vectors per second (MAGScience-<normal|burst>-(<pri>,<sec>)-<n>s-<date>"
                ".csv): give them with --csv-layout, e.g. normal-(2,2)-8s", path=str(path))
    mode = "norm" if m.group(1) == "normal" else "burst"
    rate = {"pri": int(m.group(2)), "sec": int(m.group(3))}
    if min(rate.values()) < 1 or int(m.group(4)) < 1:
        raise InputFormatError(f"layout {m.group(0)!r}: rates and seconds must be >= 1",
                               path=str(path), field="--csv-layout")
    return mode, rate, int(m.group(4))


def read_l1a_csv(path: Path | str, clock: SclkKernel, *, layout: str | None = None
                 ) -> dict[tuple[str, str], xr.Dataset]:
    """Read the team's L1A CSV layout into (mode, sensor) datasets like `from_packets`.

    The columns are ``sequence``, x/y/z/rng of ``pri`` and ``sec``, ``pri_coarse``,
    ``pri_fine``, ``sec_coarse``, ``sec_fine`` and optionally ``compression``,
    ``compression_width_bits``; the mode and rates come from `csv_layout`.
    Consecutive rows with the same packet (sequence and times) are its vectors 0, 1,
    ...; the primary sensor is MAGo (the layout has no ``PRI_SENS``; the team's
    validation reads it so).

    Raises
    ------
    InputFormatError
        Naming the file, line and column: not the layout, a missing column, a value
        that is not an integer, more rows in a packet than it can hold, a compression
        flag not 0/1 or a compressed row's width outside 1..20.
    """
    path = Path(path)
    header = csv_header(path)
    if header is None:
        raise InputFormatError(f"not the team's L1A CSV layout (a first line naming "
                               f"{', '.join(_CSV_COLUMNS)})", path=str(path), line=1)
    mode, rate, seconds = csv_layout(path, layout)
    with path.open(newline="") as fh:
        fh.readline()
        text = fh.read()
    try:
        table = np.loadtxt(text.splitlines(), delimiter=",", dtype=np.int64, ndmin=2)
    except ValueError as exc:
        raise InputFormatError(f"not a table of integers ({exc})", path=str(path)) from exc
    if table.size == 0:
        raise InputFormatError("no vector rows after the header", path=str(path), line=2)
    if table.shape[1] != len(header):
        raise InputFormatError(f"{table.shape[1]} columns, the header names {len(header)}",
                               path=str(path), line=2)
    col = {name: table[:, j] for j, name in enumerate(header)}
    n = table.shape[0]
    zeros = np.zeros(n, dtype=np.int64)
    compression = col.get("compression", zeros)
    width = col.get("compression_width_bits", zeros)
    bad = ((compression != 0) & (compression != 1)) | (
        (compression == 1) & ((width < 1) | (width > MAX_WIDTH)))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputFormatError(f"compression {int(compression[k])} with width "
                               f"{int(width[k])}: expected 0, or 1 with a width 1..{MAX_WIDTH}",
                               path=str(path), line=k + 2, field="compression")
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
            np.full(n, rate[side]), compression, width, mode=mode, sensor=sensor)
    return out
