"""Spoiling a contract test's text input (`MissionContract.break_input`) in one place.

The contract's bad-input check needs one field of one record made unreadable; the
missions' CSV inputs are spoiled the same way, by text, without any reader of fluxcal.
"""

from __future__ import annotations

from pathlib import Path


def replace_csv_field(path: Path, line: int, field: int, text: str) -> Path:
    """``path`` with field ``field`` (an index; negative from the end) of its line ``line``
    (0-based, header lines counted) replaced by ``text``; returns ``path``."""
    lines = path.read_text().splitlines()
    fields = lines[line].split(",")
    fields[field] = text
    lines[line] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    return path
