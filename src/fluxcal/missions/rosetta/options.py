"""The run options of Rosetta RPC-MAG processing: one dataclass for a run and a batch day.

The options of `fluxcal.missions.rosetta.routes.RosettaRun`; ``fluxcal rosetta calibrate``
and ``fluxcal batch rosetta`` both take them (`fluxcal.runs.options.with_options`).  This
module imports nothing numerical: the command line reads it at start-up.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2-4.4 (levels, averaging, frames).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fluxcal.errors import InputFormatError
from fluxcal.products.format_names import FORMATS
from fluxcal.runs.options import MAX_AVERAGE_S, check_fields


def _average_problem(seconds: float) -> str | None:
    """Refuse an averaging interval not above 0 s or above one day (`MAX_AVERAGE_S`).

    LEVEL_E, F, G, RO-IGEP-TR0028 sec. 4.6-4.8; one day is the span of a daily product.
    """
    if 0.0 < seconds <= MAX_AVERAGE_S:
        return None
    return (f"{seconds:g} s: give an averaging interval above 0 s and at most "
            f"{MAX_AVERAGE_S} s (one day)")


def check_average(seconds: float, option: str = "--average") -> float:
    """Check an averaging interval up front (`_average_problem`; ``rosetta clean``).

    Raises
    ------
    InputFormatError
        Naming the option: an interval that is not above 0 s and at most one day.
    """
    problem = _average_problem(seconds)
    if problem is not None:
        raise InputFormatError(problem, field=option)
    return seconds


def _gap_problem(hours: float) -> str | None:
    return None if hours >= 0 else f"{hours:g} h: give a gap of 0 h or more"


#: LEVEL_C frames (``auto``: CSEQ from 2014-01-20, RO-IGEP-TR0028 sec. 4.4.1).
FRAMES = ("auto", "ECLIPJ2000", "CSEQ")


@dataclass(frozen=True)
class RosettaOptions:
    """Options of a Rosetta run: ``rosetta calibrate`` and a ``batch rosetta`` day alike."""

    formats: tuple[str, ...] = field(default=("tab", "cdf"), metadata={
        "help": "Product formats: tab, cdf, nc, zarr.", "choices": FORMATS,
        "empty_ok": False})
    calib: Path | None = field(default=None, metadata={
        "help": "Folder with calibration files overriding fluxcal's defaults (batch: default "
                "<input>/calib when it exists)."})
    quicklook: bool = field(default=False, metadata={
        "help": "Also write RPCMAG_QL_<sensor>_<yyyymmdd>.png per day (field of the highest "
                "level made among C, B, A; sensor temperature; quality; distance)."})
    levels: tuple[str, ...] | None = field(default=None, metadata={
        "help": "Comma-separated levels: A,B,C,E,F,G (default: A,B for one file; for a batch "
                "day A,B,C,E,F,G with kernels, else those that need none)."})
    primary: str = field(default="OB", metadata={
        "help": "Primary sensor (time-shift table).", "choices": ("OB", "IB")})
    average_s: float = field(default=1.0, metadata={
        "help": f"Averaging interval of E, F, G (s, above 0, at most {MAX_AVERAGE_S}).",
        "flags": ("--average",),
        "check": _average_problem})
    frame: str = field(default="auto", metadata={
        "help": "LEVEL_C frame: ECLIPJ2000, CSEQ, or auto (CSEQ from 2014-01-20, "
                "RO-IGEP-TR0028 sec. 4.4.1).", "choices": FRAMES})
    centre: str = field(default="auto", metadata={
        "help": "Body the LEVEL_C position is relative to (auto: the comet for CSEQ, "
                "else SUN)."})
    boom: str = field(default="deployed", metadata={
        "help": "Boom state: deployed or stowed.", "choices": ("deployed", "stowed")})
    stitch_gap_hours: float = field(default=3.0, metadata={
        "help": "No midnight stitching across longer gaps (RO-IGEP-TR0028 sec. 4.2.3.3).",
        "check": _gap_problem})
    alignment_from_kernels: bool = field(default=False, metadata={
        "help": "Take URF -> s/c from the frames ROS_RPC_MAG_OB/IB (needs the boom CK) "
                "instead of RPCMAG_SC_ALIGN.TXT."})
    no_jumps: bool = field(default=False, metadata={
        "help": "Skip the Appendix B offset jumps (needed with a daily model that "
                "'rosetta fit' fitted inside an Appendix B interval: it holds the jump)."})

    def __post_init__(self) -> None:
        check_fields(self)  # the command line, --config and the API refuse the same values
