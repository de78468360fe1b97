"""Text inputs read the same way everywhere: a UTF-8 BOM is dropped, binary bytes are an error.

A user who gives a binary file (a CDF, a zip, an image) where fluxcal expects a CSV, a
TOML or a ``KEY = values`` calibration file gets one line naming the file, the line and
the byte, never a ``UnicodeDecodeError``.  A file saved by a spreadsheet or an editor
with a UTF-8 byte-order mark reads like one without (the mark is not part of the first
column's name).
"""

from __future__ import annotations

import csv
from pathlib import Path

from fluxcal.errors import FluxcalError, InputFormatError

#: The UTF-8 byte-order mark some editors and spreadsheets put at the start of a file.
BOM = b"\xef\xbb\xbf"


def _where_binary(data: bytes) -> int | None:
    """Offset of the first NUL or undecodable byte of ``data``, or None for UTF-8 text."""
    nul = data.find(b"\0")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start if nul < 0 else min(nul, exc.start)
    return None if nul < 0 else nul


def binary_error(data: bytes, offset: int, path: str | Path, what: str,
                 error: type[FluxcalError] = InputFormatError,
                 first_line: int = 1) -> FluxcalError:
    """Build the error for a non-text byte at ``offset`` of ``data`` (from ``first_line``).

    Parameters
    ----------
    data : bytes
        The bytes read (a whole file, or one line of it).
    offset : int
        Offset in ``data`` of the first byte that is not text.
    path : str or Path
        The file, for the message.
    what : str
        What the file should have been, e.g. ``"a CSV text file"``.
    error : type
        `InputFormatError` (path and line as fields) or another `FluxcalError` subclass
        (e.g. `CalibrationError`), which gets them in its message.
    first_line : int
        1-based line number of ``data[0]``.

    Returns
    -------
    FluxcalError
        For the caller to raise.
    """
    line = first_line + data.count(b"\n", 0, offset)
    column = offset - (data.rfind(b"\n", 0, offset) + 1) + 1
    message = (f"not a text file (byte 0x{data[offset]:02x} at column {column} is binary); "
               f"expected {what}")
    if error is InputFormatError:
        return InputFormatError(message, path=str(path), line=line)
    return error(f"{path}, line {line}: {message}")


def decode_text(data: bytes, path: str | Path, what: str,
                error: type[FluxcalError] = InputFormatError, first_line: int = 1) -> str:
    """Decode the bytes of a text file (or of its lines from ``first_line``) as UTF-8.

    A leading UTF-8 BOM is dropped.

    Raises
    ------
    FluxcalError
        ``error`` (default `InputFormatError`) naming the file, the line and the first
        byte that is not text (a NUL, or a byte that is not UTF-8).
    """
    if data.startswith(BOM):
        data = data[len(BOM):]
    bad = _where_binary(data)
    if bad is not None:
        raise binary_error(data, bad, path, what, error, first_line)
    return data.decode("utf-8")


def read_text(path: str | Path, what: str,
              error: type[FluxcalError] = InputFormatError) -> str:
    """Read a text file as UTF-8 (a BOM dropped); binary bytes are an error (`decode_text`).

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What it should be, for the message, e.g. ``"a TOML calibration file"``.
    error : type
        The `FluxcalError` subclass raised for binary content.

    Raises
    ------
    OSError
        If the file cannot be read (the CLI reports it as one line, exit 2).
    FluxcalError
        If it holds bytes that are not text.
    """
    return decode_text(Path(path).read_bytes(), path, what, error)


def csv_header(line: str) -> list[str]:
    """Return the column names of a CSV header line (RFC 4180: names may be quoted).

    Spreadsheet exports quote every name (``"partition","met",...``); a name is taken
    without its quotes and surrounding blanks.

    Examples
    --------
    >>> csv_header('"partition", "met",rate')
    ['partition', 'met', 'rate']
    """
    row = next(csv.reader([line.strip("\r\n")], skipinitialspace=True), [])
    return [name.strip() for name in row]

