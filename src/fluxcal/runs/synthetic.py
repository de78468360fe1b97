"""The synthetic "mission" on the contract: the batch machinery without a mission pipeline.

Its day task (`fluxcal.runs.synthetic_task`) calibrates synthetic counts with one gain
and offset; ``fluxcal batch synthetic`` and the batch demo use it.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field

from fluxcal.products.format_names import FORMATS
from fluxcal.runs.contract import Mission
from fluxcal.runs.options import check_fields


@dataclass(frozen=True)
class SyntheticOptions:
    """Options of a synthetic batch day."""

    formats: tuple[str, ...] = field(default=("tab", "cdf"), metadata={
        "help": "Product formats: tab, cdf, nc, zarr.", "choices": FORMATS,
        "empty_ok": False})
    quicklook: bool = field(default=False, metadata={"help": "Also write a PNG per day."})
    delay: float = field(default=0.0, metadata={
        "help": "Seconds each day waits before it writes (tests: a day in flight).",
        "check": lambda s: None if s >= 0 else f"{s:g} s: give 0 s or more"})
    hog_mb_on: str = field(default="", metadata={
        "help": "YYYY-MM-DD:MB: that day holds MB of memory for 5 s (tests: a worker out of "
                "memory)."})


    def __post_init__(self) -> None:
        check_fields(self)


#: The synthetic "mission": the batch machinery with no mission pipeline behind it.
MISSION = Mission(
    name="synthetic",
    title="Synthetic counts (exercises the batch machinery)",
    day_task="fluxcal.runs.synthetic_task:make_day_task",
    options="fluxcal.runs.synthetic:SyntheticOptions",
    formats=FORMATS,
    simulate_days="fluxcal.runs.synthetic_task:simulate_days",
    demo_days=(_dt.date(2024, 1, 1), _dt.date(2024, 1, 2)),
)
