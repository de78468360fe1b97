"""RPC-MAG LEVEL_B: calibrated field in spacecraft coordinates.

``B_sc = R_UVW2SC B_URF`` with the sensor's fixed rotation for the deployed or stowed boom
(seed 003, sec. 4.3.1), then the post-hibernation offset jumps of Appendix B subtracted.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.4, 4.3.1, Appendix B.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import xarray as xr

from fluxcal.calibration import matrices as mat
from fluxcal.errors import CalibrationError
from fluxcal.geometry.days import utc_days
from fluxcal.geometry.frames import rotate
from fluxcal.geometry.time import tt2000_to_et, utc_to_tt2000
from fluxcal.missions.rosetta.calib import (
    Alignment,
    DailyOffsetModel,
    OffsetJumpTable,
    check_sensor,
)


def offset_jumps(
    epoch: np.ndarray, table: OffsetJumpTable, sensor: str, *, lsk=None
) -> tuple[np.ndarray, np.ndarray]:
    """Jump (nT, shape (n, 3)) to subtract from each LEVEL_B vector, and its interval index.

    Intervals are half-open ``[start, end)`` (the seed's IDL tests ``ge``/``le``; see
    docs/decisions/rosetta.md); index -1 marks a vector outside every interval (no jump).

    Raises
    ------
    CalibrationError
        If the intervals overlap, or a vector falls in an interval whose jump is unknown
        (NaN in a user table; the shipped table has every value of Appendix B).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), Appendix B.1 (OB) and B.2 (IB).
    """
    sensor = check_sensor(sensor)
    starts = utc_to_tt2000(table.start_utc, lsk)
    ends = utc_to_tt2000(table.end_utc, lsk)
    if np.any(np.diff(starts) <= 0) or np.any(ends[:-1] > starts[1:]):
        raise CalibrationError(f"{table.source}: offset-jump intervals must be sorted and disjoint")
    epoch = np.asarray(epoch, dtype=np.int64)
    jumps = table.jumps[sensor]
    ends_idx = np.searchsorted(starts, epoch[[0, -1]], side="right") - 1 if epoch.size else []
    if (
        epoch.size
        and ends_idx[0] == ends_idx[1]
        and ends_idx[0] >= 0
        and epoch.min() >= starts[ends_idx[0]]
        and epoch.max() < ends[ends_idx[0]]
    ):
        # the common case: every vector inside one interval (no per-vector search)
        idx = np.full(epoch.size, ends_idx[0])
        out = np.broadcast_to(jumps[ends_idx[0]], (epoch.size, 3)).copy()
        inside = np.ones(epoch.size, dtype=bool)
    else:
        idx = np.searchsorted(starts, epoch, side="right") - 1
        inside = (idx >= 0) & (epoch < ends[np.clip(idx, 0, None)])
        idx = np.where(inside, idx, -1)
        out = np.zeros((epoch.size, 3))
        out[inside] = jumps[idx[inside]]
    if np.isnan(out).any():
        k = int(idx[np.isnan(out).any(axis=1)][0])
        raise CalibrationError(
            f"{table.source}: the {sensor} offset jump for "
            f"{table.start_utc[k]} .. {table.end_utc[k]} "
            "is unknown ('nan' in the table); supply RPCMAG_OFFSET_JUMPS.csv with the value "
            "in --calib DIR or process without jumps"
        )
    return out, idx


def refuse_jumps_on_fitted_days(epoch: np.ndarray, jump: np.ndarray, idx: np.ndarray,
                                table: OffsetJumpTable, sensor: str,
                                daily_models: Mapping[np.datetime64, DailyOffsetModel],
                                *, lsk=None) -> None:
    """Refuse an Appendix B jump on a day whose daily model ``fluxcal rosetta fit`` wrote.

    That fit takes LEVEL_A from the ground calibration alone, with no jump removed
    (docs/decisions/rosetta_fit.md entry 3), so a constant jump over the day goes into its
    ``P_0`` (in sensor axes); subtracting the jump again in LEVEL_B would leave the field
    off by the whole jump (on a simulated 2014-08-01, 1.44 / 0.19 / 0.70 nT, while the
    file states 0.03 nT).  The daily model and the jumps are alternatives (entry 5).  A
    fitted file is one with ``T_RANGE`` (`DailyOffsetModel.temperature_range`; the
    seed's files have none); a jump of zero (before 2012) is no jump.

    Raises
    ------
    CalibrationError
        Naming the daily file, the day, the jump interval and its size, and what to do.
    """
    fitted = {d: m for d, m in daily_models.items() if m.temperature_range is not None}
    jumped = (idx >= 0) & np.any(jump != 0.0, axis=1)
    if not fitted or not jumped.any():
        return
    day_index, days, _ = utc_days(epoch, lsk)
    for k, day in enumerate(days):
        model = fitted.get(np.datetime64(day, "D"))
        hit = np.flatnonzero(jumped & (day_index == k))
        if model is None or hit.size == 0:
            continue
        row = int(idx[hit[0]])
        size = " ".join(f"{v:.4g}" for v in jump[hit[0]])
        raise CalibrationError(
            f"{Path(model.source).name}: fitted by fluxcal rosetta fit on {day}, inside the "
            f"Appendix B interval {table.start_utc[row]} .. {table.end_utc[row]} of "
            f"{Path(table.source).name} ({sensor} jump {size} nT, s/c), which the fitted "
            "P_0 already holds; subtracting the jump again would leave LEVEL_B off by it. "
            "Give --no-jumps with this daily file, or the seed's daily files with the jumps "
            "(the daily model and the jumps are alternatives, docs/decisions/rosetta_fit.md "
            "entry 5)")


def level_b(
    level_a: xr.Dataset,
    alignment: Alignment | None,
    jumps: OffsetJumpTable | None,
    *,
    boom: str = "deployed",
    spacecraft_frame: str = "ROS_SPACECRAFT",
    lsk=None,
    daily_models: Mapping[np.datetime64, DailyOffsetModel] | None = None,
) -> xr.Dataset:
    """LEVEL_A (URF) -> LEVEL_B (spacecraft coordinates).

    Parameters
    ----------
    level_a : xarray.Dataset
        Output of `fluxcal.missions.rosetta.level_a.level_a`.
    alignment : Alignment or None
        R_UVW2SC matrices (``RPCMAG_SC_ALIGN.TXT``).  ``None`` takes the rotation from the
        loaded SPICE frames instead: ``ROS_RPC_MAG_<sensor>`` -> ``spacecraft_frame`` (the
        mission frames kernel with the boom CK, issue 4), evaluated per vector.
    jumps : OffsetJumpTable or None
        Appendix B table; ``None`` skips the jump correction.
    boom : {"deployed", "stowed"}
        Which of the file's matrices (ignored with SPICE frames: the boom CK knows).
    spacecraft_frame : str
        SPICE name of the spacecraft frame (SPICE path only).
    lsk : LeapSecondTable, optional
    daily_models : mapping, optional
        The daily models LEVEL_A applied, by UTC day: a jump on a day whose model
        ``fluxcal rosetta fit`` wrote is refused (`refuse_jumps_on_fitted_days`).

    Returns
    -------
    xarray.Dataset
        Same variables, ``b`` in ``ROS_SPACECRAFT``; attributes name the alignment file
        (and whether it is fluxcal's placeholder) or the SPICE frames, and the jump table.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1 (alignment in RPCMAG_SC_ALIGN.TXT and the
       frames kernel), 4.3.1 and Appendix B.
    """
    sensor = check_sensor(level_a.attrs["sensor"])
    if alignment is None:
        mag_frame = f"ROS_RPC_MAG_{sensor}"
        et = tt2000_to_et(level_a["epoch"].values, lsk)
        b_sc = rotate(level_a["b"].values, et, mag_frame, spacecraft_frame)
        described = f"SPICE frames {mag_frame} -> {spacecraft_frame}"
    else:
        b_sc = mat.apply(alignment.matrix(sensor, boom), level_a["b"].values)
        described = f"{alignment.source} (version {alignment.version})" + (
            " PLACEHOLDER identity, not the measured alignment" if alignment.placeholder else ""
        )
    n_jumped = 0
    if jumps is not None:
        jump, idx = offset_jumps(level_a["epoch"].values, jumps, sensor, lsk=lsk)
        refuse_jumps_on_fitted_days(level_a["epoch"].values, jump, idx, jumps, sensor,
                                    daily_models or {}, lsk=lsk)
        b_sc = b_sc - jump
        n_jumped = int((idx >= 0).sum())
    out = level_a.copy()
    out["b"] = (("time", "component"), b_sc, {"units": "nT", "frame": "ROS_SPACECRAFT"})
    out.attrs.update(
        level="B",
        boom=boom if alignment is not None else "from SPICE",
        alignment=described,
        offset_jumps=(jumps.source if jumps is not None else "not applied"),
        n_offset_jump_corrected=n_jumped,
    )
    return out
