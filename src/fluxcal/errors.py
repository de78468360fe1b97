"""The one small hierarchy of fluxcal exceptions.

Every failure is raised as one of these; messages name the file, record (line) and
field involved and what was expected.  Library code never returns ``None``/``0`` to
signal failure and never prints.
"""

from __future__ import annotations


class FluxcalError(Exception):
    """Base class of every error fluxcal raises on purpose."""


class InputFormatError(FluxcalError, ValueError):
    """An input file or array does not have the expected form.

    Parameters
    ----------
    message : str
        What was wrong and what was expected.
    path : str, optional
        The offending file.
    line : int, optional
        1-based line (record) number in that file.
    field : str, optional
        The offending column or field.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = path
        self.line = line
        self.field = field
        where = []
        if path is not None:
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field '{field}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class CalibrationError(FluxcalError, ValueError):
    """A calibration file or table is missing, malformed or inconsistent."""


class CalibrationRangeError(CalibrationError):
    """A time (or temperature) lies outside every validity interval of a calibration."""


class KernelError(FluxcalError, RuntimeError):
    """A SPICE kernel is missing, or cannot answer for a frame, body or time."""


class ValidationError(FluxcalError):
    """A product failed a validation check.

    E.g. offset smoothness, "MESSENGER MAG EDR-to-CDR Processing" sec. 13.
    """


class FitRefusedError(FluxcalError):
    """A fitted calibration parameter is outside its physical range or undetermined.

    The message names the parameter, its value and error, and the data that would
    constrain it; nothing is written.
    """


class MissingExtraError(FluxcalError, ImportError):
    """An optional part of fluxcal is not installed (`fluxcal.extras`).

    The message names what needed it and the extra to install, e.g.
    ``quicklooks need matplotlib: install fluxcal[plot]``.

    Parameters
    ----------
    extra : str
        The pip extra that provides it (``plot``, ``batch``, ``zarr``).
    what : str
        What the user asked for that needs it (an option, a command).
    missing : str
        The package that is missing.
    """

    def __init__(self, extra: str, what: str, missing: str) -> None:
        self.extra = extra
        super().__init__(f"{what} needs {missing}: install fluxcal[{extra}] "
                         f"(pip install 'fluxcal[{extra}]')")
