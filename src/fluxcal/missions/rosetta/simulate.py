"""Forward model of RPC-MAG: raw science and HK telemetry from a known field.

The instrument is run forward from seed 003 and its tables only (the physics is in
`fluxcal.missions.rosetta.forward`; no pipeline code, see
``tests/missions/test_forward_independence.py``):

1. truth ``B_ref(t)`` at the physical event times, in ECLIPJ2000 (with kernels, rotated by
   SPICE) or directly in s/c coordinates: by default (``field="realistic"``,
   `realistic_field`) a 3-nT solar wind with a daily mean and Alfvenic rotations
   (`fluxcal.missions.solar_wind`, issue 21), or (``field="quiet"``) the slow
   deterministic waves of `truth_field`;
2. the time stamp of each vector is its event time minus the filter-mode delay of its SID
   (sec. 4.2.3.5): the truth is delayed, not the stamps corrected;
3. the Appendix B offset present at the event is added in s/c coordinates; the URF field
   solves ``R_UVW2SC B_urf = B_sc`` (sec. 4.3.1);
4. the extended-temperature-model offset of the stamp's day (with the midnight shift of
   sec. 4.2.3.3) is added, the ground calibration applied forward at the *true* temperature
   (sec. 3.2, 4.2.3.2) and the 20-bit ADC and PIU operations give the counts; the true
   temperature's thermistor voltage gives the 16-bit words (sec. 3.3.3, 4.2.2.5);
5. a few vectors are flagged bad with their counts scrambled.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 3.2-3.3, 4.1-4.3, Appendix B.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.spatial.transform import Rotation

from fluxcal.geometry.frames import rotate
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import copy_meta_kernel
from fluxcal.geometry.time import (
    SclkKernel,
    et_to_tt2000,
    leapseconds,
    tt2000_to_et,
    tt2000_to_utc,
    utc_to_tt2000,
)
from fluxcal.missions.rosetta import archive_write, calib, forward, io
from fluxcal.missions.rosetta.archive_write import write_archive_calibration
from fluxcal.missions.rosetta.calib import (
    Alignment,
    DailyOffsetModel,
    GroundCalibration,
    OffsetJumpTable,
    TimeShiftTable,
    check_sensor,
)
from fluxcal.missions.rosetta.identity import FRAME_KERNELS, SPACECRAFT_ID
from fluxcal.missions.rosetta.io import _write_atomic
from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels
from fluxcal.missions.solar_wind import AlfvenicWind, alfvenic_wind
from fluxcal.products.paths import make_folder

log = logging.getLogger(__name__)
NS = 1_000_000_000


def truth_field(seconds: np.ndarray) -> np.ndarray:
    """Return the known ambient field (nT) at ``seconds`` after the start: slow waves.

    Magnitudes up to ~60 nT, typical of the solar wind near 67P.
    """
    s = np.asarray(seconds, dtype=float)
    return np.stack(
        [
            5.0 + 20.0 * np.sin(2 * np.pi * s / 600.0),
            -3.0 + 15.0 * np.cos(2 * np.pi * s / 900.0) + 3.0 * np.sin(2 * np.pi * s / 37.0),
            2.0 + 10.0 * np.sin(2 * np.pi * s / 300.0 + 1.0),
        ],
        axis=1,
    )


#: The truth fields `simulate` knows: the realistic wind (default) and the quiet waves.
FIELDS = ("realistic", "quiet")
#: The realistic field near 67P: 3 nT, Alfvenic rotations dB/B ~ 0.55 about a sector
#: direction fixed in the truth frame (mean field over a day about 2.5 nT), f^-5/3 from
#: 12 h to 2 s, 3 % compressive, sectors of 1-3 days.
ROSETTA_WIND = AlfvenicWind(b_median_nt=3.0, mean_direction=(0.6, -0.7, 0.39))
#: Margin (s) of the realistic field's 1-s grid around the run (filter-mode delays).
FIELD_MARGIN_S = 120.0


def realistic_field(duration_s: float, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Return a 1-s grid (seconds after the start) and the realistic field (nT) on it.

    `ROSETTA_WIND` over the run plus `FIELD_MARGIN_S` either side; one draw per run, so
    that both sensors see the same field, each interpolated at its own event times.
    """
    grid = np.arange(-FIELD_MARGIN_S, duration_s + FIELD_MARGIN_S + 1.0)
    return grid, alfvenic_wind(rng, grid.size, ROSETTA_WIND)


def temperature_profile(seconds: np.ndarray, duration_s: float, sensor: str) -> np.ndarray:
    """Sensor temperature (deg C) sweeping -140 .. +40 C over the run (cold OB, warmer IB)."""
    s = np.asarray(seconds, dtype=float)
    frac = np.clip(s / max(duration_s, 1.0), 0.0, 1.0)
    base = -140.0 + 180.0 * frac
    wobble = 1.5 * np.sin(2 * np.pi * s / 1800.0)
    return base + wobble if sensor == "OB" else np.clip(base + 10.0, -140, 40) - wobble


def mode_schedule(n: int) -> np.ndarray:
    """Filter modes SID per vector: Normal, then Burst, Medium, Low (mode changes; sec. 4.2.3.5)."""
    sid = np.full(n, 2, dtype=np.int16)
    sid[n // 4 : n // 2] = 3
    sid[n // 2 : 3 * n // 4] = 4
    sid[3 * n // 4 :] = 5
    return sid


@dataclass
class Simulation:
    """Raw datasets and truth of a forward-model run."""

    science: dict[str, xr.Dataset]
    hk: xr.Dataset
    truth: dict[str, xr.Dataset]
    attrs: dict = field(default_factory=dict)


#: Samples `raw_counts` computes at a time: its temporaries stay ~15 MB.
FORWARD_CHUNK = 1 << 16


def raw_counts(
    b_urf: np.ndarray,
    temperature: np.ndarray,
    cal: GroundCalibration,
    nominal: dict,
    *,
    extended: np.ndarray | None = None,
) -> np.ndarray:
    """Signed 20-bit counts a sensor reports for field ``b_urf`` at true ``temperature`` (deg C).

    ``extended`` (the extended-temperature-model offset, nT) is added to the field the
    sensor's ground calibration sees (sec. 4.2.3.3), then `forward.raw_field` and
    `forward.science_counts`, `FORWARD_CHUNK` samples at a time (each sample's counts
    depend on that sample only; the (n, 3, 3) matrices of a day would take ~600 MB).
    """
    temperature = np.asarray(temperature, dtype=float)
    n = temperature.shape[0] if temperature.ndim == 1 else 0
    if n <= FORWARD_CHUNK:
        b_c = np.asarray(b_urf, dtype=float) + (0.0 if extended is None else extended)
        return forward.science_counts(forward.raw_field(b_c, temperature, cal), nominal)
    out = None
    for a in range(0, n, FORWARD_CHUNK):
        part = slice(a, a + FORWARD_CHUNK)
        counts = raw_counts(b_urf[part], temperature[part], cal, nominal,
                            extended=None if extended is None else extended[part])
        if out is None:
            out = np.empty((n, *counts.shape[1:]), dtype=counts.dtype)
        out[part] = counts
    return out


def thermistor_words(temperature: np.ndarray, cal: GroundCalibration, nominal: dict) -> np.ndarray:
    """Return 16-bit thermistor words for calibrated temperatures (deg C).

    Forward of seed 003 sec. 3.3.3 and 4.2.2.5 (`forward.thermistor_words`).
    """
    return forward.thermistor_words(temperature, cal, nominal)


def simulate(
    start_utc: str,
    duration_s: float,
    *,
    calibrations: Mapping[str, GroundCalibration],
    time_shifts: TimeShiftTable,
    nominal: dict,
    alignment: Alignment,
    jumps: OffsetJumpTable | None = None,
    daily_models: Mapping[str, Mapping[np.datetime64, DailyOffsetModel]] | None = None,
    rate_hz: float = 20.0,
    primary: str = "OB",
    boom: str = "deployed",
    with_kernels: bool = False,
    bad_fraction: float = 0.005,
    hk_period_s: float = 32.0,
    seed: int = 0,
    lsk=None,
    gaps: list[tuple[float, float]] | None = None,
    field: str = "realistic",
) -> Simulation:
    """Simulate raw science files of both sensors and an HK file from a known field.

    Parameters
    ----------
    start_utc : str
        First time stamp (UTC, ISO).
    duration_s : float
    calibrations : mapping sensor -> GroundCalibration
        The instrument's "true" calibration (may differ from fluxcal's defaults).
    time_shifts, nominal, alignment, jumps, daily_models
        As passed to the pipeline.
    rate_hz : float
        Vector rate.
    primary : {"OB", "IB"}
    boom : {"deployed", "stowed"}
    with_kernels : bool
        Truth given in ECLIPJ2000 and rotated with the loaded attitude (needs a
        `KernelPool` with the Rosetta-like kernels, `fluxcal.geometry.synthetic`);
        ``obt`` from the loaded SCLK.  Without, the truth is in s/c coordinates and ``obt``
        is the elapsed SI seconds since 2003-01-01T00:00:00 UTC.
    bad_fraction : float
        Fraction of vectors flagged bad (counts scrambled).
    seed : int
        Random seed.
    gaps : list of (start_s, end_s), optional
        No vectors in these intervals (seconds after ``start_utc``): data gaps, e.g. to
        test the midnight stitching limit of sec. 4.2.3.3.
    field : {"realistic", "quiet"}
        ``realistic``: `realistic_field` (3 nT with a daily mean and Alfvenic rotations;
        its generator seeded with ``seed`` and the start second, apart from the bad-vector
        draws); ``quiet``: `truth_field` (slow waves, tens of nT).

    Returns
    -------
    Simulation
        ``science[sensor]`` raw datasets (as `io.read_science_csv` returns), ``hk``, and
        ``truth[sensor]`` with ``b_urf`` (LEVEL_A truth), ``b_sc`` (LEVEL_B truth after
        the jump correction), ``b_ref`` (ECLIPJ2000 or s/c) at the event times.
    """
    if field not in FIELDS:
        raise ValueError(f"field {field!r}: choose one of {', '.join(FIELDS)}")
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * rate_hz))
    t0 = int(utc_to_tt2000(np.array([start_utc]), lsk)[0])
    if field == "realistic":
        grid, wind = realistic_field(
            duration_s, np.random.default_rng([seed, (t0 // NS) & 0x7FFFFFFF]))

    def ambient(secs: np.ndarray) -> np.ndarray:
        if field == "quiet":
            return truth_field(secs)
        return np.column_stack([np.interp(secs, grid, wind[:, j]) for j in range(3)])

    stamps = t0 + np.rint(np.arange(n) / rate_hz * NS).astype(np.int64)
    sid = mode_schedule(n)
    if gaps:
        rel = np.arange(n) / rate_hz
        keep = np.ones(n, dtype=bool)
        for a, b in gaps:
            keep &= ~((rel >= a) & (rel < b))
        stamps, sid, n = stamps[keep], sid[keep], int(keep.sum())
    sclk = None
    if with_kernels:
        sclk = SclkKernel.from_pool(SPACECRAFT_ID)
        stamps_et = tt2000_to_et(stamps, lsk)
        obt = np.ceil(sclk.from_et(stamps_et)[1] * 1e6) / 1e6  # 6 digits, never before start
        stamps = et_to_tt2000(sclk.to_et(np.ones(n, dtype=np.int64), obt), lsk)
    else:
        obt0 = int(utc_to_tt2000(np.array(["2003-01-01T00:00:00"]), lsk)[0])
        obt = np.round((stamps - obt0) / NS, 6)

    science, truth = {}, {}
    temps = {}
    for sensor in ("OB", "IB"):
        secs = (stamps - t0) / NS
        temps[sensor] = temperature_profile(secs, duration_s, sensor)
    words = {s: thermistor_words(temps[s], calibrations[s], nominal) for s in ("OB", "IB")}

    for sensor in ("OB", "IB"):
        cal = calibrations[check_sensor(sensor)]
        secondary = check_sensor(sensor) != check_sensor(primary)
        delay = forward.filter_delay(sid, time_shifts, secondary=secondary)
        event = stamps + np.rint(delay * NS).astype(np.int64)
        secs = (event - t0) / NS
        b_ref = ambient(secs)
        if with_kernels:
            b_sc_true = rotate(b_ref, tt2000_to_et(event, lsk), "ECLIPJ2000", "ROS_SPACECRAFT")
        else:
            b_sc_true = b_ref
        jump = np.zeros((n, 3))
        if jumps is not None:
            jump = forward.jump_field(event, jumps, sensor, lsk=lsk)
        rot = alignment.matrix(sensor, boom)
        b_urf = np.linalg.solve(rot, (b_sc_true + jump).T).T
        temp = temps[sensor]
        extended = None
        models = (daily_models or {}).get(sensor)
        if models:
            extended = forward.extended_offset(
                stamps, forward.reduced_temperature(temp, cal), models, lsk)
        counts = raw_counts(b_urf, temp, cal, nominal, extended=extended)
        quality = np.zeros(n, dtype=np.int16)
        bad = rng.random(n) < bad_fraction
        quality[bad] = rng.integers(1, 8, size=int(bad.sum()))
        counts[bad] = rng.integers(-(2**19), 2**19, size=(int(bad.sum()), 3))
        if sensor == "IB":
            quality |= 8
        counts = counts.astype(np.int32)
        del jump, extended, secs, delay  # before the next sensor's temporaries
        science[sensor] = xr.Dataset(
            {
                "obt": ("time", obt, {"units": "s"}),
                "sid": ("time", sid, {"units": "1"}),
                "b_counts": (("time", "component"), counts, {"units": "count"}),
                "t_ob_counts": ("time", words["OB"].astype(np.int32), {"units": "count"}),
                "t_ib_counts": ("time", words["IB"].astype(np.int32), {"units": "count"}),
                "quality": ("time", quality, {"units": "1"}),
            },
            coords={
                "epoch": ("time", stamps, {"units": "ns", "time_base": "TT2000"}),
                "component": ["x", "y", "z"],
            },
            attrs={"sensor": sensor, "source": f"simulated {sensor}"},
        )
        truth[sensor] = xr.Dataset(
            {
                "b_urf": (("time", "component"), b_urf, {"units": "nT"}),
                "b_sc": (("time", "component"), b_sc_true, {"units": "nT"}),
                "b_ref": (
                    ("time", "component"),
                    b_ref,
                    {"units": "nT", "frame": "ECLIPJ2000" if with_kernels else "ROS_SPACECRAFT"},
                ),
                "temperature": ("time", temp + forward.KELVIN, {"units": "K"}),
                "good": ("time", ~bad, {"units": "1"}),
            },
            coords={
                "epoch": ("time", event, {"units": "ns", "time_base": "TT2000"}),
                "component": ["x", "y", "z"],
            },
            attrs={"sensor": sensor},
        )
    hk_raw = simulate_hk(
        stamps,
        obt,
        words,
        sid,
        truth["OB"]["b_urf"].values,
        nominal,
        calibrations["OB"],
        step=max(int(round(hk_period_s * rate_hz)), 1),
    )
    return Simulation(
        science,
        hk_raw,
        truth,
        {
            "start_utc": start_utc,
            "duration_s": duration_s,
            "rate_hz": rate_hz,
            "sclk": sclk is not None,
        },
    )


def simulate_hk(
    stamps: np.ndarray,
    obt: np.ndarray,
    words: Mapping[str, np.ndarray],
    sid: np.ndarray,
    b_ob: np.ndarray,
    nominal: dict,
    cal: GroundCalibration,
    *,
    step: int = 640,
) -> xr.Dataset:
    """HK records every ``step`` vectors: thermistors, nominal voltages, 16-bit OB field.

    Forward of sec. 4.2.2.1-4.2.2.4: the raw OB field (ground calibration at 0 C) and the
    2.4996 V reference through the ADC and PIU operations; the supply words are 0 (the
    nominal +5.0 V / -5.0 V, the centre of the 8-bit range).
    """
    pick = np.arange(0, len(stamps), step)
    m = pick.size
    tlm_b = forward.hk_field_words(forward.raw_field(b_ob[pick], np.zeros(m), cal), nominal)
    tlm_ref = forward.reference_voltage_word(2.4996, nominal)
    return xr.Dataset(
        {
            "obt": ("time", obt[pick], {"units": "s"}),
            "t_ob_counts": ("time", words["OB"][pick], {"units": "count"}),
            "t_ib_counts": ("time", words["IB"][pick], {"units": "count"}),
            "stage_a_id": ("time", sid[pick].astype(np.int64), {"units": "1"}),
            "stage_b_id": ("time", np.zeros(m, dtype=np.int64), {"units": "1"}),
            "filter_cfg": ("time", sid[pick].astype(np.int64), {"units": "1"}),
            "ref_voltage_counts": ("time", np.full(m, tlm_ref, dtype=np.int64), {"units": "count"}),
            "neg_voltage_counts": ("time", np.zeros(m, dtype=np.int64), {"units": "count"}),
            "pos_voltage_counts": ("time", np.zeros(m, dtype=np.int64), {"units": "count"}),
            "b_ob_counts": (("time", "component"), tlm_b, {"units": "count"}),
        },
        coords={
            "epoch": ("time", stamps[pick], {"units": "ns", "time_base": "TT2000"}),
            "component": ["x", "y", "z"],
        },
        attrs={"source": "simulated HK"},
    )


def write_truth_csv(truth: xr.Dataset, path: Path, *, lsk=None) -> Path:
    """Write the truth of one sensor (event time, b_urf, b_sc, b_ref, T) as CSV."""
    def six(v: np.ndarray) -> np.ndarray:
        return np.char.mod("%.6f", v)

    epoch = truth["epoch"].values
    cols: list = [(epoch, lambda e: tt2000_to_utc(e, digits=6, lsk=lsk)), epoch]
    header = ["time_utc", "epoch_tt2000_ns"]
    for name in ("b_urf", "b_sc", "b_ref"):
        for j, c in enumerate("xyz"):
            cols.append((truth[name].values[:, j], six))
            header.append(f"{name}_{c}")
    cols.append((truth["temperature"].values, lambda v: np.char.mod("%.4f", v)))
    cols.append(truth["good"].values.astype(int))
    header += ["temperature_k", "good"]
    return _write_atomic(Path(path), tuple(header), cols)


def synthetic_alignment() -> Alignment:
    """Return a non-trivial alignment for simulations (boom axes tilted as in ROS_V38.TF)."""
    angles = {
        ("OB", "deployed"): [-90.234, 89.944, 0.145],
        ("OB", "stowed"): [0.0, 45.0, 0.0],
        ("IB", "deployed"): [-90.285, 89.497, 0.117],
        ("IB", "stowed"): [0.0, 45.0, 0.3],
    }
    mats = {k: Rotation.from_euler("xzx", v, degrees=True).as_matrix() for k, v in angles.items()}
    return Alignment(mats, "fluxcal synthetic alignment", "sim-1")


def synthetic_daily_models(
    days: list[np.datetime64],
) -> dict[str, dict[np.datetime64, DailyOffsetModel]]:
    """Small daily extended-temperature polynomials (nT, deg C) for simulations."""
    out: dict[str, dict[np.datetime64, DailyOffsetModel]] = {"OB": {}, "IB": {}}
    for k, day in enumerate(days):
        for sensor, sign in (("OB", 1.0), ("IB", -1.0)):
            c = np.zeros((6, 3))
            c[0] = sign * np.array([1.5, -0.8, 0.6]) + 0.3 * k
            c[1] = sign * np.array([0.010, 0.004, -0.006])
            c[2] = np.array([2e-5, -1e-5, 3e-5])
            out[sensor][day] = DailyOffsetModel(day, sensor, c, f"synthetic {day}")
    return out


def write_simulation(
    out: Path,
    *,
    start_utc: str = "2014-08-01T00:00:00",
    hours: float = 1.0,
    rate_hz: float = 20.0,
    primary: str = "OB",
    seed: int = 0,
    layouts: Sequence[str] = ("files",),
    field: str = "realistic",
) -> dict[str, Path]:
    """Write a complete simulated input set into ``out`` and return the paths.

    ``out/kernels`` (Rosetta-like SCLK, FK, SPK, CK and a meta-kernel), ``out/calib``
    (synthetic ``RPCMAG_SC_ALIGN.TXT`` and daily ``RPCMAG_<yymmdd>_006_CALIB_*.TXT``),
    raw science CSVs ``RPCMAG_<yyyymmdd>_RAW_<OB|IB>.csv``, the HK CSV
    ``RPCMAG_<yyyymmdd>_RAW_HK.csv`` and the truth ``RPCMAG_<yyyymmdd>_TRUTH_<OB|IB>.csv``.
    The ground calibration is fluxcal's default.

    ``layouts`` containing ``"archive"`` also (or, without ``"files"``, instead of the
    CSVs) writes the same simulation as archive-style EDITED products under
    ``out/DATA/EDITED/`` (`archive_write`; key ``"archive"``), names the calibration
    folder ``out/CALIB`` with the archived ground-calibration names, and copies the
    meta-kernel to ``out/kernels.tm`` (the input folder of ``fluxcal batch rosetta``).
    ``field`` is `simulate`'s (``realistic`` or ``quiet``).
    """
    out = Path(out)
    archive = "archive" in layouts
    calib_dir = out / ("CALIB" if archive else "calib")
    make_folder(calib_dir)
    duration = float(hours) * 3600.0
    meta = write_rosetta_like_kernels(out / "kernels", start_utc, duration, margin_s=3600.0)
    if archive:
        copy_meta_kernel(meta, out / "kernels.tm")
        write_archive_calibration(calib_dir)
    alignment = synthetic_alignment()
    calib.write_alignment(alignment, calib_dir / calib.ALIGN_FILE)
    first = np.datetime64(start_utc[:10], "D")
    last = (np.datetime64(start_utc, "s") + np.timedelta64(int(duration) + 1200, "s")).astype(
        "M8[D]"
    )
    days = list(np.arange(first, last + np.timedelta64(1, "D"), dtype="M8[D]"))
    models = synthetic_daily_models(days)
    for sensor in ("OB", "IB"):
        for model in models[sensor].values():
            calib.write_daily_offset_model(model, calib_dir)
    stamp = start_utc[:10].replace("-", "")
    paths = {"kernels": meta, "calib": calib_dir}
    with KernelPool(meta, frames=FRAME_KERNELS):
        lsk = leapseconds()
        cals = {s: calib.load_ground_calibration(s) for s in ("OB", "IB")}
        sim = simulate(
            start_utc,
            duration,
            calibrations=cals,
            time_shifts=calib.load_time_shift_table(),
            nominal=calib.load_nominal_conversion(),
            alignment=alignment,
            jumps=calib.load_offset_jump_table(),
            daily_models=models,
            rate_hz=rate_hz,
            primary=primary,
            with_kernels=True,
            seed=seed,
            lsk=lsk,
            field=field,
        )
        for sensor in ("OB", "IB"):
            if "files" in layouts:
                paths[f"science_{sensor}"] = io.write_science_csv(
                    sim.science[sensor], out / f"RPCMAG_{stamp}_RAW_{sensor}.csv", lsk=lsk
                )
            paths[f"truth_{sensor}"] = write_truth_csv(
                sim.truth[sensor], out / f"RPCMAG_{stamp}_TRUTH_{sensor}.csv", lsk=lsk
            )
        if "files" in layouts:
            paths["hk"] = io.write_hk_csv(sim.hk, out / f"RPCMAG_{stamp}_RAW_HK.csv", lsk=lsk)
        if archive:
            for sensor in ("OB", "IB"):
                archive_write.write_science_products(sim.science[sensor], out, lsk=lsk)
            archive_write.write_hk_products(sim.hk, out, lsk=lsk)
            paths["archive"] = out.joinpath(*archive_write.EDITED)
    return paths


def read_truth_csv(path: Path) -> dict[str, np.ndarray]:
    """Read a truth file of `write_truth_csv` (columns as arrays; epoch int64)."""
    with open(path, encoding="ascii") as fh:
        header = fh.readline().strip().split(",")
    table = np.loadtxt(path, delimiter=",", skiprows=1, dtype=str)
    out = {name: table[:, j] for j, name in enumerate(header)}
    result: dict[str, np.ndarray] = {
        "epoch": out["epoch_tt2000_ns"].astype(np.int64),
        "good": out["good"].astype(int).astype(bool),
        "temperature": out["temperature_k"].astype(float),
    }
    for name in ("b_urf", "b_sc", "b_ref"):
        result[name] = np.stack([out[f"{name}_{c}"].astype(float) for c in "xyz"], axis=1)
    return result
