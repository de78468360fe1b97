"""The IMAP MAG forward model: a known field -> counts -> science packets, with the truth.

``fluxcal simulate imap`` (`write_simulation`) writes, from a realistic solar wind
(`fluxcal.missions.solar_wind.alfvenic_wind`, turned by the spacecraft's 15-s spin):

* the science packets (`fluxcal.missions.imap.sim_packets`): normal mode (2 + 2
  vectors/s, 8-s packets) over the run and a burst (64 + 8 vectors/s, 4-s packets) in
  it; compressed with the widths given (0: uncompressed) cycling every
  `PACKETS_PER_WIDTH` packets; the range of each vector the most sensitive one that
  holds the field, and with range changes, one range less sensitive over part of
  every third packet (primary from its middle vector, secondary from its second);
* fluxcal's own simulated calibration CDF and SCLK kernel (`write_calibration`,
  `write_sclk`): invented values near the instrument's, in the layout the pipeline
  reads -- **not** the IMAP team's files -- so the simulation runs without them;
* fluxcal's own XTCE description of the packets (`sim_packets.xtce_text`);
* the truth per mode and sensor (`truth_table`): the packet's counts and range, the
  clock-tag time ``epoch`` (TT2000 ns), the time the sample measures ``epoch_b``
  (tag plus the sensor's time shift) and the field there in nT.

Counts are the nearest integers to the sensor's output ``M[range]^-1 B`` in 16-bit
units times ``2**(W - 16)`` (the width keeps ``W`` bits of it); L1B brings back
``M (c 2**(16 - W))``, within half a count of ``W`` bits of the truth.

The simulator shares no code with the pipeline it checks (no import of the decoder,
L1A or L1B modules): times are closed-form (`MET_EPOCH_TT2000_NS`), matrices inverted
here.

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing (MIT License): packet layout (see
   `fluxcal.missions.imap.sim_packets`), the L1B calibration file's variables
   (``MFOTOURFO``/``MFITOURFI`` (3, 3, 4) per range, ``OTS``/``ITS`` s,
   ``STARTVALIDITY``/``ENDVALIDITY``) and the rescale ``2**(16 - W)`` of compressed
   counts (``mag/l1b/mag_l1b.py``).
.. [2] NAIF, SCLK Required Reading (type 1 kernel); IMAP's clock: NAIF id -43, 32-bit
   seconds and 1/50000-s ticks, mission elapsed time 0 at 2010-01-01T00:00:00 UTC.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path

import cdflib
import numpy as np

from fluxcal.geometry.synthetic import sclk_text, write_meta_kernel
from fluxcal.geometry.time import datetime64_to_tt2000
from fluxcal.missions.imap import sim_packets
from fluxcal.missions.imap.sim_packets import Section
from fluxcal.missions.imap.sources import BATCH_FILES
from fluxcal.missions.solar_wind import AlfvenicWind, alfvenic_wind
from fluxcal.products.atomic import atomic_group, atomic_path, atomic_write_bytes
from fluxcal.products.timeindex import default_lsk

#: TT2000 ns of mission elapsed time 0 (2010-01-01T00:00:00 UTC = 00:01:06.184 TT).
MET_EPOCH_TT2000_NS = 315_576_066_184_000_000
FINE_PER_SECOND = 65536
#: Spin period of the spacecraft (s): IMAP spins at 4 rpm.
SPIN_PERIOD_S = 15.0
#: Consecutive packets with the same compression width.
PACKETS_PER_WIDTH = 4
#: The sensor's 16-bit output is kept below this (counts) by the choice of range.
RANGE_LIMIT = 30_000
SENSORS = ("mago", "magi")
#: fluxcal's simulated sensors: nT per 16-bit count of ranges 0..3 (the most sensitive
#: last, near the instrument's +-75000 ... +-150 nT) and a lower-triangular
#: non-orthogonality per sensor.  Invented values: not the team's calibration.
RANGE_SCALE_NT = (2.2917, 0.073291, 0.018721, 0.0045813)
SHAPE = {"mago": np.array([[1.0, 0.0, 0.0], [1.7e-3, 0.9763, 0.0], [-1.2e-3, -3.7e-3, 0.9811]]),
         "magi": np.array([[1.0, 0.0, 0.0], [-0.9e-3, 1.0121, 0.0], [2.3e-3, 1.6e-3, 0.9932]])}
#: Time shifts of the simulated sensors (s): the sample measures the field this long
#: after its clock tag.
TIME_SHIFT_S = {"mago": 0.0, "magi": 0.0015}
#: Validity of the simulated calibration (TT2000 ns): 2020-01-01 .. 2040-01-01, roughly.
VALIDITY_NS = (631_108_869_184_000_000, 1_262_260_869_184_000_000)


def matrices(sensor: str) -> np.ndarray:
    """Return the simulated calibration of ``sensor``: (range, 3, 3), nT per 16-bit count."""
    return np.array([s * SHAPE[sensor] for s in RANGE_SCALE_NT])


@dataclass(frozen=True)
class ModePlan:
    """Rates (vectors/s, powers of two), seconds per packet and sub-second phase."""

    mode: str
    primary_rate: int
    secondary_rate: int
    seconds: int
    #: Fine time of the primary's first vector, and the secondary's lag (1/65536 s).
    phase_fine: int = 13_107
    secondary_lag_fine: int = 3


NORMAL = ModePlan("norm", 2, 2, 8)
BURST = ModePlan("burst", 64, 8, 4)


@dataclass
class Truth:
    """What a simulated mode and sensor holds (one row per vector, time order)."""

    epoch: np.ndarray
    epoch_b: np.ndarray
    counts: np.ndarray
    ranges: np.ndarray
    compression: np.ndarray
    width: np.ndarray
    b_nt: np.ndarray
    sequence: np.ndarray


@dataclass
class Simulation:
    """Packets (bytes, normal then burst) and the truth per (mode, sensor)."""

    packets: bytes
    truth: dict[tuple[str, str], Truth]
    n_packets: int
    plain_in_compressed: int


def tag_tt2000(coarse: np.ndarray, fine: np.ndarray, index: np.ndarray,
               rate: np.ndarray | int) -> np.ndarray:
    """TT2000 ns (nearest) of clock readings ``coarse + fine/65536 + index/rate`` s.

    Closed form for the simulated clock (rate exactly 1 from `MET_EPOCH_TT2000_NS`).
    """
    sixteenths = (np.asarray(fine, np.int64)
                  + np.asarray(index, np.int64) * (FINE_PER_SECOND // np.asarray(rate)))
    whole, part = np.divmod(sixteenths, FINE_PER_SECOND)
    ns = (part * 1_000_000_000 + FINE_PER_SECOND // 2) // FINE_PER_SECOND
    return MET_EPOCH_TT2000_NS + (np.asarray(coarse, np.int64) + whole) * 1_000_000_000 + ns


def met_of_utc(utc: str) -> int:
    """Whole mission elapsed seconds of a UTC time (leap seconds from fluxcal's LSK)."""
    tt = int(datetime64_to_tt2000(np.array([np.datetime64(utc, "ns")]), default_lsk())[0])
    return (tt - MET_EPOCH_TT2000_NS) // 1_000_000_000


def field_at(tt2000: np.ndarray, t0_ns: int, wind: np.ndarray) -> np.ndarray:
    """Return the known field (nT) at times ``tt2000``.

    The wind on its 1-s grid from ``t0_ns``, interpolated, turned about the spin axis z
    by the spin phase (`SPIN_PERIOD_S`).
    """
    s = (np.asarray(tt2000, np.int64) - t0_ns) / 1e9
    grid = np.arange(wind.shape[0], dtype=float)
    b = np.stack([np.interp(s, grid, wind[:, j]) for j in range(3)], axis=1)
    phase = 2.0 * np.pi * s / SPIN_PERIOD_S
    c, sn = np.cos(phase), np.sin(phase)
    return np.stack([c * b[:, 0] - sn * b[:, 1], sn * b[:, 0] + c * b[:, 1], b[:, 2]], 1)


def _ranges(x16: np.ndarray) -> np.ndarray:
    """Return the most sensitive range (3 .. 0) whose output stays below `RANGE_LIMIT`.

    ``x16`` is the 16-bit output of every range, (range, vector, 3).
    """
    fits = np.abs(x16).max(axis=2) < RANGE_LIMIT
    best = np.zeros(x16.shape[1], dtype=np.int64)
    for r in range(4):
        best = np.where(fits[r], r, best)
    return best


def _sensor_block(sensor: str, tags: np.ndarray, width: int, forced: np.ndarray,
                  t0_ns: int, wind: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return counts, ranges and field of one sensor's vectors (packet, vector)."""
    shape = tags.shape
    b = field_at(tags.ravel() + int(TIME_SHIFT_S[sensor] * 1e9), t0_ns, wind)
    inverse = np.linalg.inv(matrices(sensor))
    x16 = np.einsum("rij,nj->rni", inverse, b)
    rng = np.maximum(_ranges(x16) - forced.ravel(), 0)
    x = x16[rng, np.arange(rng.size)]
    scale = 2.0 ** ((width if width else 16) - 16)
    counts = np.rint(x * scale).astype(np.int64)
    return counts.reshape(shape + (3,)), rng.reshape(shape), b.reshape(shape + (3,))


def simulate(start_met: int, seconds: int, *, plan: ModePlan = NORMAL,
             widths: tuple[int, ...] = (0, 16, 18, 13), range_changes: bool = True,
             first_sequence: int = 0, t0_ns: int | None = None,
             wind: np.ndarray | None = None, seed: int = 0, primary: str = "mago",
             ) -> Simulation:
    """Packets of one mode over ``seconds`` from ``start_met``, and their truth.

    ``wind`` is the field on a 1-s grid from ``t0_ns`` (TT2000); by default drawn
    here (`alfvenic_wind`, ``seed``) from the start.  ``primary`` names the sensor
    whose vectors come first (``PRI_SENS``).
    """
    n = max(seconds // plan.seconds, 1)
    t0_ns = MET_EPOCH_TT2000_NS + start_met * 1_000_000_000 if t0_ns is None else t0_ns
    if wind is None:
        wind = alfvenic_wind(np.random.default_rng(seed), n * plan.seconds + 64,
                             AlfvenicWind())
    k = np.arange(n)
    coarse = start_met + k * plan.seconds
    fine = np.full(n, plan.phase_fine)
    sec_fine = fine - plan.secondary_lag_fine
    rates = {"pri": plan.primary_rate, "sec": plan.secondary_rate}
    sensor_of = {"pri": primary, "sec": "magi" if primary == "mago" else "mago"}
    packet_width = np.array([widths[(i // PACKETS_PER_WIDTH) % len(widths)] for i in k])
    chunks, plain = [], 0
    truth_parts: dict[str, list] = {side: [] for side in rates}
    starts = np.flatnonzero(np.r_[True, packet_width[1:] != packet_width[:-1]])
    bounds = list(zip(starts, np.r_[starts[1:], n], strict=True))
    for lo, hi in [(a, min(a + 256, b)) for a, b in bounds for a in range(a, b, 256)]:
        sel = k[lo:hi]
        width = int(packet_width[lo])
        sections = {}
        for side, f in (("pri", fine), ("sec", sec_fine)):
            v = rates[side] * plan.seconds
            idx = np.arange(v)
            tags = tag_tt2000(coarse[sel, None], f[sel, None], idx[None, :], rates[side])
            forced = np.zeros((sel.size, v), dtype=np.int64)
            if range_changes:
                first = v // 2 if side == "pri" else 1
                last = v if side == "pri" else max(v // 2 + 1, 2)
                forced[(sel % 3 == 1), first:last] = 1
            counts, rng, b = _sensor_block(sensor_of[side], tags, width, forced, t0_ns, wind)
            sections[side] = Section(counts, rng)
            truth_parts[side].append((tags, counts, rng, b, np.full(tags.shape, width),
                                      np.broadcast_to((sel % 16384)[:, None], tags.shape)))
        header = {"VERSION": 0, "TYPE": 0, "SEC_HDR_FLG": 1,
                  "PKT_APID": sim_packets.APIDS[plan.mode], "SEQ_FLGS": 3,
                  "SRC_SEQ_CTR": (first_sequence + sel) % 16384,
                  "SHCOARSE": coarse[sel] + plan.seconds, "PUS_SPARE1": 0,
                  "PUS_VERSION": 1, "PUS_SPARE2": 0,
                  "PUS_STYPE": sim_packets.PUS_SERVICE_TYPE,
                  "PUS_SSUBTYPE": plan.seconds - 1, "MAGO_ACT": 1, "MAGI_ACT": 1,
                  "PRI_SENS": 0 if primary == "mago" else 1, "SPARE1": 0,
                  "PRI_VECSEC": int(np.log2(plan.primary_rate)),
                  "SEC_VECSEC": int(np.log2(plan.secondary_rate)), "SPARE2": 0,
                  "PRI_COARSETM": coarse[sel], "PRI_FNTM": fine[sel],
                  "SEC_COARSETM": coarse[sel], "SEC_FNTM": sec_fine[sel]}
        data, n_plain = sim_packets.packets(header, sections["pri"], sections["sec"], width)
        chunks.append(data)
        plain += n_plain
    truth = {}
    for side, parts in truth_parts.items():
        sensor = sensor_of[side]
        tags, counts, rng, b, w, seq = (np.concatenate([p[j].reshape((-1,) + p[j].shape[2:])
                                                        for p in parts]) for j in range(6))
        truth[(plan.mode, sensor)] = Truth(
            epoch=tags, epoch_b=tags + int(TIME_SHIFT_S[sensor] * 1e9), counts=counts,
            ranges=rng, compression=(w != 0).astype(np.int64), width=w, b_nt=b,
            sequence=seq)
    return Simulation(b"".join(chunks), truth, n, plain)


def quantisation_bound(truth: Truth, sensor: str) -> np.ndarray:
    """Largest error (nT) of an L1B field from the truth's counts: half a count of ``W`` bits.

    ``0.5 * 2**(16 - W) * sum_j |M[range]_ij|`` per vector and component (``W = 16``
    uncompressed): the rounding of the sensor's output to the packet's counts.
    """
    width = np.where(truth.width == 0, 16, truth.width)
    rows = np.abs(matrices(sensor)[truth.ranges]).sum(axis=2)
    return 0.5 * np.exp2(16.0 - width)[:, None] * rows


def write_sclk(path: Path) -> Path:
    """Write fluxcal's simulated IMAP SCLK kernel (-43; rate 1 from MET 0)."""
    comment = ("fluxcal simulated IMAP spacecraft clock (NAIF -43), written by 'fluxcal "
               "simulate imap' for its simulated packets: NOT the IMAP team's kernel.\n"
               "32-bit seconds and 1/50000-s ticks; mission elapsed time 0 at "
               "2010-01-01T00:00:00 UTC (TDT 315576066.184 s past J2000); rate exactly 1.")
    return atomic_write_bytes(Path(path), sclk_text(
        -43, (4294967296, 50000), [(0.0, 2.147483648e14)],
        [(0.0, MET_EPOCH_TT2000_NS / 1e9, 1.0)], comment).encode())


def write_calibration(path: Path) -> Path:
    """Write fluxcal's simulated L1B calibration CDF (the pipeline's variable layout)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        _write_calibration_cdf(tmp)
    return path


def _write_calibration_cdf(path: Path) -> None:
    cdf = cdflib.cdfwrite.CDF(str(path), cdf_spec={"Compressed": False})
    try:
        cdf.write_globalattrs({
            "Project": {0: "fluxcal"},
            "Source_name": {0: "fluxcal simulated IMAP MAG sensors"},
            "TEXT": {0: "Written by 'fluxcal simulate imap' (fluxcal.missions.imap.simulate):"
                        " invented matrices and time shifts of the simulated sensors, NOT "
                        "the IMAP MAG team's calibration."}})
        for sensor, (mat, shift) in {"mago": ("MFOTOURFO", "OTS"),
                                     "magi": ("MFITOURFI", "ITS")}.items():
            cdf.write_var({"Variable": mat, "Data_Type": cdflib.cdfwrite.CDF.CDF_DOUBLE,
                           "Num_Elements": 1, "Rec_Vary": False, "Compress": 0,
                           "Dim_Sizes": [3, 3, 4]},
                          var_data=np.ascontiguousarray(np.moveaxis(matrices(sensor), 0, 2)))
            cdf.write_var({"Variable": shift, "Data_Type": cdflib.cdfwrite.CDF.CDF_DOUBLE,
                           "Num_Elements": 1, "Rec_Vary": False, "Compress": 0, "Dim_Sizes": []},
                          var_data=np.array([TIME_SHIFT_S[sensor]]))
        for name, value in zip(("STARTVALIDITY", "ENDVALIDITY"), VALIDITY_NS, strict=True):
            cdf.write_var({"Variable": name, "Data_Type": cdflib.cdfwrite.CDF.CDF_TIME_TT2000,
                           "Num_Elements": 1, "Rec_Vary": False, "Compress": 0, "Dim_Sizes": []},
                          var_data=np.array([value], dtype=np.int64))
    finally:
        cdf.close()


def truth_table(truth: Truth) -> str:
    """CSV text of a truth (header line, one row per vector)."""
    head = ("epoch_tt2000_ns,epoch_b_tt2000_ns,sequence,x_counts,y_counts,z_counts,range,"
            "compression,compression_width,bx_nt,by_nt,bz_nt")
    cols = [truth.epoch, truth.epoch_b, truth.sequence, *truth.counts.T, truth.ranges,
            truth.compression, truth.width]
    ints = np.stack(cols, axis=1).astype(np.int64)
    rows = [",".join(map(str, r)) + "," + ",".join(f"{v:.12g}" for v in b)
            for r, b in zip(ints.tolist(), truth.b_nt.tolist(), strict=True)]
    return head + "\n" + "\n".join(rows) + "\n"


#: Names of the files `write_simulation` writes beside the packets.
SCLK_NAME = "fluxcal_sim_imap_sclk.tsc"
CALIB_NAME = "fluxcal_sim_imap_calibration.cdf"
XTCE_NAME = "fluxcal_sim_imap_mag_science.xml"


def packet_file_name(day: _dt.date) -> str:
    """``imap_mag_l0_raw_<yyyymmdd>_v001.pkts``: the name a batch day is found by."""
    return f"imap_mag_l0_raw_{day:%Y%m%d}_v001.pkts"


def write_support(out: Path) -> dict[str, Path]:
    """Write the simulated SCLK kernel, calibration and XTCE into ``out``."""
    out = Path(out)
    xtce = atomic_write_bytes(out / XTCE_NAME, sim_packets.xtce_text().encode())
    return {"kernels": write_sclk(out / SCLK_NAME), "calib": write_calibration(out / CALIB_NAME),
            "xtce": xtce}


def simulate_day(start_utc: str, hours: float, burst_minutes: float, *,
                 widths: tuple[int, ...] = (0, 16, 18, 13), range_changes: bool = True,
                 seed: int = 0) -> tuple[bytes, dict[tuple[str, str], Truth], dict[str, int]]:
    """Simulate normal mode over ``hours`` from ``start_utc``, a burst in the middle.

    Returns the packets (normal, then burst), the truth per (mode, sensor) and counts
    (packets, vectors written plain in compressed packets).
    """
    met = met_of_utc(start_utc)
    seconds = max(int(round(hours * 3600)), NORMAL.seconds)
    t0_ns = MET_EPOCH_TT2000_NS + met * 1_000_000_000
    wind = alfvenic_wind(np.random.default_rng(seed), seconds + 64, AlfvenicWind())
    norm = simulate(met, seconds, plan=NORMAL, widths=widths, range_changes=range_changes,
                    t0_ns=t0_ns, wind=wind)
    parts, truth = [norm], dict(norm.truth)
    burst_s = int(round(burst_minutes * 60))
    if burst_s > 0:
        start = met + max((seconds - burst_s) // 2, 0)
        burst = simulate(start, min(burst_s, seconds), plan=BURST, widths=widths,
                         range_changes=range_changes, t0_ns=t0_ns, wind=wind)
        parts.append(burst)
        truth.update(burst.truth)
    stats = {"packets": sum(p.n_packets for p in parts),
             "plain_in_compressed": sum(p.plain_in_compressed for p in parts)}
    return b"".join(p.packets for p in parts), truth, stats


def write_simulation(out: Path, *, start_utc: str = "2025-10-17T00:00:00",
                     hours: float = 1.0, burst_minutes: float = 5.0, days: int = 1,
                     widths: tuple[int, ...] = (0, 16, 18, 13), range_changes: bool = True,
                     seed: int = 0, truth: bool = True) -> dict[str, Path]:
    """Write ``days`` simulated days (`simulate_day`), the support files and the truth.

    Each day's packets go to ``<out>/imap_mag_l0_raw_<yyyymmdd>_v001.pkts``, its truth
    to ``<out>/truth/<yyyymmdd>_<mode>-<sensor>.csv``; returns the paths by role
    (``kernels``, ``calib``, ``xtce``, ``packets`` (the first day's), ``truth``).
    """
    out = Path(out)
    first = _dt.datetime.fromisoformat(start_utc)
    with atomic_group():  # all files or none
        paths = write_support(out)
        for d in range(days):
            day = first + _dt.timedelta(days=d)
            data, day_truth, _ = simulate_day(day.isoformat(), hours, burst_minutes,
                                              widths=widths, range_changes=range_changes,
                                              seed=seed + d)
            paths.setdefault("packets", atomic_write_bytes(
                out / packet_file_name(day.date()), data))
            if truth:
                paths.setdefault("truth", write_truth(out / "truth", day.date(), day_truth))
    return paths


def write_truth(folder: Path, day: _dt.date, truth: dict[tuple[str, str], Truth]) -> Path:
    """Write ``<folder>/<yyyymmdd>_<mode>-<sensor>.csv`` (`truth_table`); return the folder."""
    for (mode, sensor), t in truth.items():
        atomic_write_bytes(folder / f"{day:%Y%m%d}_{mode}-{sensor}.csv",
                           truth_table(t).encode())
    return folder


def simulate_days(input_dir: Path, days: list[_dt.date], *, hours: float = 0.5,
                  burst_minutes: float = 2.0, seed: int = 0) -> list[_dt.date]:
    """Write ``days`` in the input layout of ``fluxcal batch imap`` (the batch demo).

    Per day ``imap_mag_l0_raw_<yyyymmdd>_v001.pkts`` (`simulate_day` from 00:00 UTC) and
    its truth under ``truth/``; once, the batch layout's support files: ``kernels.tm``
    (a meta-kernel of the simulated SCLK), ``calibration.cdf`` and
    ``packet_definition.xml`` (fluxcal's simulated ones, `write_support`), which
    ``fluxcal batch imap`` uses when ``--kernels``/``--calib``/``--xtce`` are not given.
    """
    input_dir = Path(input_dir)
    with atomic_group():  # all files or none
        support = write_support(input_dir / "support")
        with atomic_path(input_dir / BATCH_FILES["kernels"]) as tmp:
            write_meta_kernel(tmp, [support["kernels"]])
        with atomic_path(input_dir / BATCH_FILES["calib"]) as tmp:
            _write_calibration_cdf(tmp)
        atomic_write_bytes(input_dir / BATCH_FILES["xtce"], sim_packets.xtce_text().encode())
        for k, day in enumerate(sorted(days)):
            data, truth, _ = simulate_day(f"{day.isoformat()}T00:00:00", hours,
                                          burst_minutes, seed=seed + k)
            atomic_write_bytes(input_dir / packet_file_name(day), data)
            write_truth(input_dir / "truth", day, truth)
    return sorted(days)
