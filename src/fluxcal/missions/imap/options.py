"""The run options of IMAP MAG processing: one dataclass for ``imap calibrate`` and batch.

This module imports nothing numerical: the command line reads it at start-up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fluxcal.products.format_names import FORMATS


@dataclass(frozen=True)
class ImapOptions:
    """Options of an IMAP MAG run (single run or batch day)."""

    level: str = field(default="l1b", metadata={
        "help": "l1a (counts) or l1b (nT).", "choices": ("l1a", "l1b")})
    formats: tuple[str, ...] = field(default=("cdf",), metadata={
        "help": "Product formats: cdf, nc, tab, zarr.", "choices": FORMATS,
        "empty_ok": False})
    calib: Path | None = field(default=None, metadata={
        "help": "L1B calibration CDF of the IMAP MAG team (e.g. "
                "imap_calibration_mag_20240229_v01.cdf); needed for l1b."})
    xtce: Path | None = field(default=None, metadata={
        "help": "The team's XTCE packet definition MAG_SCI_COMBINED.xml (default: the "
                "one of the installed imap-processing package, fluxcal[imap])."})
    csv_layout: str | None = field(default=None, metadata={
        "help": "Mode and rates of an L1A CSV whose name does not give them, as the "
                "team's names do: <normal|burst>-(<pri>,<sec>)-<n>s, e.g. normal-(2,2)-8s."})
    layout: str = field(default="fluxcal", metadata={
        "help": "fluxcal (b in nT, Epoch) or team (the IMAP MAG team's CDF variables: "
                "epoch, vectors, compression_flags ...; CDF only).",
        "choices": ("fluxcal", "team")})
    quicklook: bool = field(default=False, metadata={
        "help": "Also write a PNG quicklook per mode, sensor and UTC day (L1B)."})
