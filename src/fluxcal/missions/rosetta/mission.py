"""Rosetta RPC-MAG on the mission contract (`fluxcal.runs.contract`).

Registered in fluxcal's ``pyproject.toml`` under the entry-point group
``fluxcal.missions``; the command line, ``fluxcal batch rosetta``, ``fluxcal demo`` and
the archived-product readers are built from `MISSION`.
"""

from __future__ import annotations

import datetime as _dt

import typer

from fluxcal.missions.rosetta.identity import SPACECRAFT_ID
from fluxcal.runs.contract import DemoPart, Mission

_M = "fluxcal.missions.rosetta"


def commands() -> typer.Typer:
    """Return the ``fluxcal rosetta`` commands (calibrate, fit, clean)."""
    # the command modules load when the command line is built, not with the registry
    from fluxcal.missions.rosetta import clean_cli, cli

    if not any(c.name == "clean" for c in cli.app.registered_commands):
        cli.app.command("clean")(clean_cli.clean)
    return cli.app


def before_batch(task: object) -> None:
    """Warn when the batch's alignment is fluxcal's placeholder (before the first day)."""
    from fluxcal.missions.rosetta.cli import warn_placeholder_alignment  # as in `commands`

    options = task.options  # type: ignore[attr-defined]
    if not options.alignment_from_kernels:
        warn_placeholder_alignment(options.calib)


MISSION = Mission(
    name="rosetta",
    title="Rosetta RPC-MAG: LEVEL_A..L, disturbance removal, in-flight calibration",
    spacecraft_id=SPACECRAFT_ID,
    commands=f"{_M}.mission:commands",
    simulate=f"{_M}.cli:simulate",
    day_task=f"{_M}.routes:make_day_task",
    options=f"{_M}.options:RosettaOptions",
    simulate_days=f"{_M}.batch_task:simulate_days",
    demo_days=(_dt.date(2014, 11, 1), _dt.date(2014, 11, 2)),
    demo_parts=(
        DemoPart("Rosetta RPC-MAG levels (15 min simulated)", f"{_M}.demo:run_quick_demo",
                 "rosetta", 30, quick=True),
        DemoPart("Rosetta RPC-MAG levels", f"{_M}.demo:run_demo", "rosetta", 30),
        DemoPart("Rosetta disturbance removal", f"{_M}.cleaning_demo:run_demo",
                 "rosetta_cleaning", 40),
        DemoPart("Rosetta archive round trip: EDITED raw -> calibrate -> archived products "
                 "-> compare", f"{_M}.archive_demo:run_demo", "rosetta_archive", 70),
    ),
    before_batch=f"{_M}.mission:before_batch",
    archived_products=f"{_M}.archive_products:READER",
    frame_kernels=f"{_M}.identity:FRAME_KERNELS",
    calibrate=f"{_M}.api:calibrate",
)
