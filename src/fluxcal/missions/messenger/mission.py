"""MESSENGER MAG on the mission contract (`fluxcal.runs.contract`).

Registered in fluxcal's ``pyproject.toml`` under the entry-point group
``fluxcal.missions``; the command line, ``fluxcal batch messenger``, ``fluxcal demo``
and the archived-product readers are built from `MISSION`.
"""

from __future__ import annotations

import datetime as _dt

from fluxcal.missions.messenger.identity import SPACECRAFT_ID
from fluxcal.missions.messenger.options import FORMATS
from fluxcal.runs.contract import DemoPart, Mission

_M = "fluxcal.missions.messenger"

MISSION = Mission(
    name="messenger",
    title="MESSENGER MAG: EDR -> CDR, in-flight calibration",
    spacecraft_id=SPACECRAFT_ID,
    commands=f"{_M}.cli:app",
    simulate=f"{_M}.cli:simulate",
    day_task=f"{_M}.batch_task:make_day_task",
    options=f"{_M}.options:MessengerOptions",
    formats=FORMATS,
    simulate_days=f"{_M}.batch_task:simulate_days",
    demo_days=(_dt.date(2012, 6, 1), _dt.date(2012, 6, 2)),
    demo_parts=(
        DemoPart("MESSENGER MAG EDR -> CDR (30 min simulated)", f"{_M}.demo:run_quick_demo",
                 "messenger", 20, quick=True),
        DemoPart("Geometry core", f"{_M}.geometry_demo:run_geometry_demo", "geometry", 10),
        DemoPart("MESSENGER MAG EDR -> CDR", f"{_M}.demo:run_demo", "messenger", 20),
        DemoPart("MESSENGER in-flight calibration: simulate, fit, recalibrate, compare",
                 f"{_M}.fit_demo:run_demo", "messenger_fit", 60),
    ),
    archived_products=f"{_M}.archive_products:READER",
    frame_kernels=f"{_M}.identity:FRAME_KERNELS",
    calibrate=f"{_M}.api:calibrate",
)
