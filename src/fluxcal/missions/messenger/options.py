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

from fluxcal.errors import InputFormatError
from fluxcal.products.format_names import FORMATS as PRODUCT_FORMATS

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
    """``--max-offset-step``: a threshold <= 0 disables the sec. 13 check."""
    return value if value > 0 else None


def _version(value: int) -> int:
    if not 1 <= value <= 99:
        raise InputFormatError(f"{value}: the product version is 1-99", field="--version")
    return value


def _averages(values: tuple[int, ...]) -> tuple[int, ...]:
    if any(a <= 0 for a in values):
        raise InputFormatError(f"{','.join(map(str, values))!r}: intervals must be positive",
                               field="--average")
    return values


@dataclass(frozen=True)
class MessengerOptions:
    """Options of a MESSENGER EDR -> CDR run (single run or batch day)."""

    frames: tuple[str, ...] = field(default=DEFAULT_FRAMES, metadata={
        "help": "Frames (also: vso).", "choices": FRAMES})
    formats: tuple[str, ...] = field(default=DEFAULT_FORMATS, metadata={
        "help": "What to write: tab (PDS3 tables), cdf, nc, zarr, png (the offset report's "
                "figure; its text is always written).", "choices": FORMATS,
        "empty_ok": False})
    averages: tuple[int, ...] = field(default=AVERAGES_S, metadata={
        "help": "Averaging intervals (s); '' for none.", "flags": ("--average",),
        "parse": _averages})
    max_offset_step: float | None = field(default=2.0, metadata={
        "help": "Sec. 13 smoothness threshold (fine-range counts); <= 0 disables.",
        "parse": _step})
    quicklook: bool = field(default=False, metadata={
        "help": "Also write a quicklook PNG per day (field, |B|, offsets, quality flag, "
                "distance from Mercury)."})
    quicklook_frame: str | None = field(default=None, metadata={
        "help": "Frame of the quicklook's field (default: the first of --frames).",
        "choices": FRAMES})
    version: int = field(default=DEFAULT_VERSION, metadata={
        "help": "Product version: the _V<nn> of the file names.",
        "flags": ("--version", "--product-version"), "parse": _version})
    calib: Path | None = field(default=None, metadata={
        "help": "Calibration folder to use in place of the shipped tables (e.g. the --out "
                "of 'fluxcal messenger fit'; docs/formats/calibration.md)."})
