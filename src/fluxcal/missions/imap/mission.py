"""IMAP MAG on the mission contract (`fluxcal.runs.contract`).

Registered in fluxcal's ``pyproject.toml`` under the entry-point group
``fluxcal.missions``: ``fluxcal imap calibrate`` and the demo part come from `MISSION`.
"""

from __future__ import annotations

import datetime

from fluxcal.products.format_names import FORMATS
from fluxcal.runs.contract import DemoPart, Mission

#: NAIF id of IMAP (its SCLK kernel's id).
SPACECRAFT_ID = -43

MISSION = Mission(
    name="imap",
    title="IMAP MAG: CCSDS packets -> L1A counts -> L1B nT (real ground-test data)",
    spacecraft_id=SPACECRAFT_ID,
    commands="fluxcal.missions.imap.cli:app",
    simulate="fluxcal.missions.imap.cli:simulate",
    day_task="fluxcal.missions.imap.routes:make_day_task",
    options="fluxcal.missions.imap.options:ImapOptions",
    # the batch tour runs on simulated days with fluxcal's own simulated kernel,
    # calibration and packet description (docs/decisions/imap.md)
    simulate_days="fluxcal.missions.imap.simulate:simulate_days",
    demo_days=(datetime.date(2025, 10, 17), datetime.date(2025, 10, 18)),
    formats=FORMATS,
    demo_parts=(DemoPart("IMAP MAG from real packets: L0 -> L1A -> L1B",
                         "fluxcal.missions.imap.demo:run_demo", "imap", 80),
                DemoPart("IMAP MAG from real packets: L1B", "fluxcal.missions.imap.demo:"
                         "run_quick_demo", "imap", 80, quick=True)),
    calibrate="fluxcal.missions.imap.api:calibrate",
)
