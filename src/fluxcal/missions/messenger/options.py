"""The run options of MESSENGER MAG processing: one dataclass for ``edr2cdr`` and batch.

`MessengerOptions` is what ``fluxcal messenger edr2cdr`` and ``fluxcal batch
messenger`` both take (`fluxcal.runs.options.with_options` makes their command-line
options from it), so the two routes offer the same options with the same defaults.
This module imports nothing numerical: the command line reads it at start-up.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 10 (frames), sec. 12 (averages),
       sec. 13 (offset smoothness).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fluxcal.products.format_names import FORMATS as PRODUCT_FORMATS
from fluxcal.runs.options import MAX_AVERAGE_S, check_fields

#: Product frames (keys of `fluxcal.missions.messenger.levels.FRAMES`).
FRAMES = ("mso", "j2000", "mbf", "rtn", "sc", "vso")
#: Frames written unless told otherwise.
DEFAULT_FRAMES = ("mso", "j2000", "mbf", "rtn", "sc")
#: The offset report's figure (`fluxcal.missions.messenger.validation_report`).
REPORT_FIGURE = "png"
#: Every format a MESSENGER run writes: the product formats and `REPORT_FIGURE`.
FORMATS = (*PRODUCT_FORMATS, REPORT_FIGURE)
#: What a run writes unless told otherwise: PDS3 tables, CDF and the offset report's figure.
DEFAULT_FORMATS = ("tab", "cdf", REPORT_FIGURE)
#: Averaging intervals of the averaged products (s), sec. 12.
AVERAGES_S = (1, 5, 10, 60)
#: Product version ``_V<nn>`` when none is given.
DEFAULT_VERSION = 1


def _step(value: float) -> float | None:
    """``--max-offset-step`` on the command line: a threshold <= 0 disables the sec. 13 check."""
    return value if value > 0 else None


def _step_problem(value: float) -> str | None:
    """Refuse a threshold not above 0 (the Python API disables the check with None)."""
    return None if value > 0 else (f"{value:g}: give a threshold above 0 (the command "
                                   "line's <= 0, the API's None, disables the check)")


def _version_problem(value: int) -> str | None:
    return None if 1 <= value <= 99 else f"{value}: the product version is 1-99"


def _averages_problem(values: tuple[int, ...]) -> str | None:
    """Averaging intervals are 1 s to one day (`MAX_AVERAGE_S`), each once."""
    shown = ",".join(map(str, values))
    if any(not 1 <= a <= MAX_AVERAGE_S for a in values):
        return f"{shown}: give intervals of 1 to {MAX_AVERAGE_S} s (one day)"
    if len(set(values)) < len(values):
        return f"{shown}: an interval is given twice"
    return None


@dataclass(frozen=True)
class MessengerOptions:
    """Options of a MESSENGER EDR -> CDR run (single run or batch day)."""

    frames: tuple[str, ...] = field(default=DEFAULT_FRAMES, metadata={
        "help": "Frames (also: vso).", "choices": FRAMES, "empty_ok": False})
    formats: tuple[str, ...] = field(default=DEFAULT_FORMATS, metadata={
        "help": "What to write: tab (PDS3 tables), cdf, nc, zarr, png (the offset report's "
                "figure; its text is always written).", "choices": FORMATS,
        "empty_ok": False})
    averages: tuple[int, ...] = field(default=AVERAGES_S, metadata={
        "help": f"Averaging intervals (s, 1-{MAX_AVERAGE_S}); '' for none.",
        "flags": ("--average",), "check": _averages_problem})
    max_offset_step: float | None = field(default=2.0, metadata={
        "help": "Sec. 13 smoothness threshold (fine-range counts, finite); <= 0 disables.",
        "parse": _step, "check": _step_problem})
    quicklook: bool = field(default=False, metadata={
        "help": "Also write a quicklook PNG per day (field, |B|, offsets, quality flag, "
                "distance from Mercury)."})
    quicklook_frame: str | None = field(default=None, metadata={
        "help": "Frame of the quicklook's field (default: the first of --frames).",
        "choices": FRAMES})
    version: int = field(default=DEFAULT_VERSION, metadata={
        "help": "Product version: the _V<nn> of the file names.",
        "flags": ("--product-version", "--version"), "check": _version_problem})
    calib: Path | None = field(default=None, metadata={
        "help": "Calibration folder to use in place of the shipped tables (e.g. the --out "
                "of 'fluxcal messenger fit'; docs/formats/calibration.md)."})

    def __post_init__(self) -> None:
        check_fields(self)  # the command line, --config and the API refuse the same values
