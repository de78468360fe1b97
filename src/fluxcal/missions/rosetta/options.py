"""The run options of a Rosetta RPC-MAG batch day (``fluxcal batch rosetta``).

The fields are those of `fluxcal.missions.rosetta.batch_task.RosettaDayTask` beside its
folders; their command-line names are those of ``fluxcal rosetta calibrate``.  This
module imports nothing numerical: the command line reads it at start-up.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2-4.4 (levels, averaging, frames).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fluxcal.products.format_names import FORMATS

#: LEVEL_C frames (``auto``: CSEQ from 2014-01-20, RO-IGEP-TR0028 sec. 4.4.1).
FRAMES = ("auto", "ECLIPJ2000", "CSEQ")


@dataclass(frozen=True)
class RosettaOptions:
    """Options of a Rosetta batch day."""

    formats: tuple[str, ...] = field(default=("tab", "cdf"), metadata={
        "help": "Product formats: tab, cdf, nc, zarr.", "choices": FORMATS,
        "empty_ok": False})
    calib: Path | None = field(default=None, metadata={
        "help": "Calibration folder (default: <input>/calib when it exists, else "
                "fluxcal's)."})
    quicklook: bool = field(default=False, metadata={"help": "Also write a PNG per day."})
    levels: tuple[str, ...] | None = field(default=None, metadata={
        "help": "Comma-separated levels (default: A,B,C,E,F,G with kernels, else those "
                "that need none)."})
    primary: str = field(default="OB", metadata={
        "help": "Primary sensor (time-shift table).", "choices": ("OB", "IB")})
    average_s: float = field(default=1.0, metadata={
        "help": "Averaging interval of E, F, G (s).", "flags": ("--average",)})
    frame: str = field(default="auto", metadata={
        "help": "LEVEL_C frame: ECLIPJ2000, CSEQ, or auto (CSEQ from 2014-01-20, "
                "RO-IGEP-TR0028 sec. 4.4.1).", "choices": FRAMES})
    centre: str = field(default="auto", metadata={
        "help": "Body the LEVEL_C position is relative to (auto: the comet for CSEQ, "
                "else SUN)."})
    boom: str = field(default="deployed", metadata={
        "help": "Boom state: deployed or stowed.", "choices": ("deployed", "stowed")})
