"""``fluxcal messenger fit`` as a function: resolve the inputs, fit, write the folder.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7.
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Callable, Sequence
from pathlib import Path

from fluxcal import preflight
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.extras import require
from fluxcal.missions.messenger.identity import FRAME_KERNELS
from fluxcal.preflight import plain_text_file
from fluxcal.products.provenance import portable_command_line, portable_text

_DAY_FILE = re.compile(r"^MAGSCI_(\d{4})(\d{3})\.csv$")


def parse_days(text: str, input_dir: Path) -> list[_dt.date]:
    """Days of ``--days`` (``FIRST:LAST`` or a comma list of ISO dates), or every day.

    Without ``text``: every day with a ``MAGSCI_YYYYDDD.csv`` in ``input_dir``.

    Raises
    ------
    InputFormatError
        A date that is not ISO, or ``LAST`` before ``FIRST``.
    """
    text = text.strip()
    if not text:
        found = [m for p in sorted(Path(input_dir).glob("MAGSCI_*.csv"))
                 if (m := _DAY_FILE.match(p.name))]
        return [_dt.date(int(m[1]), 1, 1) + _dt.timedelta(days=int(m[2]) - 1) for m in found]

    def day(value: str) -> _dt.date:
        try:
            return _dt.date.fromisoformat(value.strip())
        except ValueError:
            raise InputFormatError(f"{value!r}: expected an ISO date such as 2012-06-01",
                                   field="--days") from None

    if ":" in text:
        first, _, last = text.partition(":")
        a, b = day(first), day(last)
        if b < a:
            raise InputFormatError(f"{text!r}: the last day lies before the first",
                                   field="--days")
        return [a + _dt.timedelta(days=k) for k in range((b - a).days + 1)]
    return sorted({day(v) for v in text.split(",") if v.strip()})


def run_fit(
    *,
    sci: Sequence[Path],
    heater: Sequence[Path],
    temperature: Sequence[Path],
    kernels: Sequence[Path],
    input_dir: Path | None,
    days: str,
    intervals: Path | None,
    out: Path,
    calib: Path | None = None,
    passes: int = 6,
    fit_delay: bool = True,
    scheduler: str = "serial",
    workers: int = 2,
    progress: Callable[[str, int, int], None] | None = None,
    temperature_law: str = "distribution",
    estimator: str = "variance",
    hold_d0: str = "",
) -> str:
    """Run ``fluxcal messenger fit`` and return the summary text (`report_text`).

    Either the three streams (``sci``, ``heater``, ``temperature``, with ``kernels``) as
    one reduction, or ``input_dir`` in the batch layout with one reduction per day.

    ``hold_d0`` is the ``--hold-d0`` text: a comma list of axes whose D0 keeps the base
    value.

    Raises
    ------
    FluxcalError
        Conflicting or missing inputs, a bad ``--hold-d0``, ``--intervals`` or
        ``--days``, no day with data, and the fit's own errors
        (`fluxcal.missions.messenger.fit.fit_calibration`).
    """
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit import Chunk, day_chunks, fit_days, refuse_edr_folder
    from fluxcal.missions.messenger.fit_pictures import write_fit_pictures
    from fluxcal.missions.messenger.fit_reduce import read_intervals
    from fluxcal.missions.messenger.fit_write import report_text, write_calibration_folder
    from fluxcal.products.provenance import sha256_file

    held = tuple(a.strip().lower() for a in hold_d0.split(",") if a.strip())
    if set(held) - {"x", "y", "z"} or len(set(held)) != len(held):
        raise InputFormatError(f"--hold-d0 takes a comma list of the axes x, y, z, got "
                               f"{hold_d0!r}", field="--hold-d0")
    if held and estimator != "variance":
        raise InputFormatError("--hold-d0 needs --estimator variance", field="--hold-d0")
    if scheduler != "serial":  # before any input is read
        require("batch", f"--scheduler {scheduler}")
    streams = bool(sci or heater or temperature)
    if input_dir is not None and streams:
        raise InputFormatError("give either --input-dir or --sci/--heater/--temperature, "
                               "not both", field="--input-dir")
    if input_dir is None:
        if days.strip():
            raise InputFormatError("--days needs --input-dir", field="--days")
        for option, paths in (("--sci", sci), ("--heater", heater),
                              ("--temperature", temperature), ("--kernels", kernels)):
            if not paths:
                raise InputFormatError(f"{option} is missing (or give --input-dir)",
                                       field=option)
            if option != "--kernels":
                for path in paths:
                    plain_text_file(path, option, header_lines=1)
        chunks = [Chunk("files", tuple(map(Path, sci)), tuple(map(Path, heater)),
                        tuple(map(Path, temperature)), tuple(map(Path, kernels)))]
    else:
        if not Path(input_dir).is_dir():
            raise FluxcalError(f"{input_dir}: --input-dir is not a folder")
        if len(kernels) > 1:
            raise InputFormatError("with --input-dir give one meta-kernel", field="--kernels")
        refuse_edr_folder(Path(input_dir))
        wanted = parse_days(days, Path(input_dir))
        chunks = day_chunks(Path(input_dir), wanted, kernels[0] if kernels else None)
        if not chunks:
            raise FluxcalError(f"{input_dir}: no MAGSCI_YYYYDDD.csv science file for the "
                               "requested days")
    iv = read_intervals(intervals) if intervals is not None else None
    first = _first_time(chunks[0])
    base = load_calibration(first, calib)
    sched = None if scheduler == "local" else scheduler
    if sched not in (None, "serial"):
        preflight.reachable_scheduler(sched)
    result = fit_days(chunks, base, intervals=iv, passes=passes, scheduler=sched,
                      n_workers=workers, fit_delay=fit_delay, progress=progress,
                      temperature_law=temperature_law, estimator=estimator, hold_d0=held)
    provenance = {
        "inputs": result.stats.inputs,
        "intervals": (f"{Path(intervals).name} sha256={sha256_file(intervals)} "
                      f"({len(iv)} intervals)" if iv is not None else "all data"),
        "days": ", ".join(result.stats.days),
        "command": portable_command_line(),
    }
    provenance = {key: portable_text(value) if isinstance(value, str) else value
                  for key, value in provenance.items()}
    written = write_calibration_folder(result, Path(out), calib, provenance)
    drawn, note = write_fit_pictures(result, Path(out))
    return (report_text(result, provenance) + f"\nwrote {len(written)} files to {out}\n"
            + (note or f"pictures of the fit: {Path(out) / 'index.html'} ({len(drawn) - 1} PNG)"))


def _first_time(chunk) -> str:
    """ISO day of a chunk (its label, or the first science record's day via the kernels)."""
    try:
        return _dt.date.fromisoformat(chunk.label).isoformat()
    except ValueError:
        pass
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.missions.messenger.pipeline import day_of
    from fluxcal.missions.messenger.readers import read_science

    sci = read_science(list(chunk.science[:1]))
    with KernelPool(list(chunk.kernels), frames=FRAME_KERNELS):
        return str(day_of(sci))
