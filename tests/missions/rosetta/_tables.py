"""The Rosetta calibration tables a forward-model test runs with, and the run itself.

`rosetta_tables` loads the five tables (ground calibrations of both sensors, time shifts,
nominal conversion, alignment, offset jumps) from fluxcal's shipped ones or a user folder;
`simulate_with` runs the forward model (`fluxcal.missions.rosetta.simulate`, which shares
no code with the pipeline: tests/missions/test_forward_independence.py) with them.  The
expected values stay in each test.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

from fluxcal.missions.rosetta import calib, simulate


class RosettaTables(NamedTuple):
    """The tables a simulation and LEVEL_A/B read (unpacks as ``cals, ts, nom, al, jumps``)."""

    cals: dict[str, Any]
    time_shifts: Any
    nominal: Any
    alignment: Any
    jumps: Any


def rosetta_tables(calib_dir: Path | None = None, *, alignment: Any = None) -> RosettaTables:
    """The tables of ``calib_dir`` (None: fluxcal's shipped ones); ``alignment`` replaces
    the loaded alignment where given."""
    return RosettaTables(
        {s: calib.load_ground_calibration(s, calib_dir) for s in ("OB", "IB")},
        calib.load_time_shift_table(calib_dir),
        calib.load_nominal_conversion(calib_dir),
        calib.load_alignment(calib_dir) if alignment is None else alignment,
        calib.load_offset_jump_table(calib_dir),
    )


def simulate_with(tables: RosettaTables, start: str, seconds: float, **kwargs: Any) -> Any:
    """The forward model from ``start`` for ``seconds`` with ``tables``; ``kwargs`` go to
    `simulate.simulate` (and may replace a table, e.g. ``jumps=None``)."""
    return simulate.simulate(start, seconds, **{
        "calibrations": tables.cals, "time_shifts": tables.time_shifts,
        "nominal": tables.nominal, "alignment": tables.alignment, "jumps": tables.jumps,
        **kwargs})
