"""``fluxcal messenger fit`` as a function: resolve the inputs, fit, write the folder.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7.
"""

from __future__ import annotations

import datetime as _dt
import math
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
_HOLD = re.compile(r"^(?P<axis>[xyz])(?:=(?P<value>[^+]+?))?(?:\+-(?P<width>.+))?$")


def parse_hold_d0(text: str) -> dict[str, tuple[float | None, float | None]]:
    """Return ``{axis: (value, width)}`` of the ``--hold-d0`` text.

    A comma list of ``AXIS[=VALUE][+-WIDTH]``: ``VALUE`` (counts/ppt) defaults to the
    base table's D0 (None here), ``WIDTH`` (counts/ppt) to `fit_guards.HOLD_D0_DEFAULT_WIDTH`
    of the value (None here; `fit_holds.held_d0_values`; docs/decisions/messenger_fit.md
    entry 18).

    Raises
    ------
    InputFormatError
        An item that is not of that form, a repeated axis, a value or width that is not
        finite, a negative width.
    """
    out: dict[str, tuple[float | None, float | None]] = {}
    for item in (x.strip().lower().replace(" ", "") for x in text.split(",")):
        if not item:
            continue
        m = _HOLD.match(item)
        try:
            value = float(m["value"]) if m and m["value"] is not None else None
            width = float(m["width"]) if m and m["width"] is not None else None
        except ValueError:
            m = None
        # nan and inf parse as floats but switch no check on (README, "numbers finite")
        finite = all(v is None or math.isfinite(v) for v in (value, width)) if m else False
        if (m is None or not finite or m["axis"] in out
                or (width is not None and width < 0)):
            raise InputFormatError(
                f"--hold-d0 takes a comma list of the axes x, y, z, each as AXIS, "
                f"AXIS=VALUE, AXIS+-WIDTH or AXIS=VALUE+-WIDTH (counts/ppt), each axis "
                f"once, numbers finite, width not negative; got {text!r}", field="--hold-d0")
        out[m["axis"]] = (value, width)
    return out


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
    passes: int = 12,
    fit_delay: bool = True,
    scheduler: str = "serial",
    workers: int = 2,
    progress: Callable[[str, int, int], None] | None = None,
    temperature_law: str = "distribution",
    estimator: str = "variance",
    hold_d0: str = "",
    error_goal: float | None = None,
    max_compressive_share: float | None = None,
) -> str:
    """Run ``fluxcal messenger fit`` and return the summary text (`report_text`).

    Either the three streams (``sci``, ``heater``, ``temperature``, with ``kernels``) as
    one reduction, or ``input_dir`` in the batch layout with one reduction per day.

    ``hold_d0`` is the ``--hold-d0`` text (`parse_hold_d0`); ``error_goal`` the largest
    predicted error (nT) of a recalibrated day (None: `fit_merit.ERROR_GOAL_NT`);
    ``max_compressive_share`` the compressive share allowed (None:
    `fit_merit.MAX_COMPRESSIVE_SHARE`).

    Raises
    ------
    FluxcalError
        An ``out`` that already holds calibration tables, conflicting or missing
        inputs, a bad ``--hold-d0``, ``--intervals`` or ``--days``, no day with data,
        and the fit's own errors (`fluxcal.missions.messenger.fit.fit_calibration`).
    """
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit import ESTIMATORS, TEMPERATURE_LAWS
    from fluxcal.missions.messenger.fit_passes import Chunk, day_chunks, fit_days, refuse_edr_folder
    from fluxcal.missions.messenger.fit_pictures import write_fit_pictures
    from fluxcal.missions.messenger.fit_reduce import read_intervals
    from fluxcal.missions.messenger.fit_write import (
        refuse_out_with_tables,
        report_text,
        write_calibration_folder,
    )
    from fluxcal.products.provenance import sha256_file

    refuse_out_with_tables(Path(out))  # before any work (README, decision 66)
    for option, value, allowed in (("--estimator", estimator, ESTIMATORS),
                                   ("--temperature-law", temperature_law, TEMPERATURE_LAWS)):
        if value not in allowed:
            raise InputFormatError(f"{value!r}: choose one of {', '.join(allowed)}",
                                   field=option)
    held = parse_hold_d0(hold_d0)
    if held and estimator != "variance":
        raise InputFormatError("--hold-d0 needs --estimator variance", field="--hold-d0")
    from fluxcal.missions.messenger.fit_merit import ERROR_GOAL_NT, MAX_COMPRESSIVE_SHARE

    goal = ERROR_GOAL_NT if error_goal is None else float(error_goal)
    if not goal > 0:
        raise InputFormatError(f"--error-goal must be a positive number of nT, got {goal}",
                               field="--error-goal")
    share = MAX_COMPRESSIVE_SHARE if max_compressive_share is None else float(
        max_compressive_share)
    if not 0 < share <= 1:
        raise InputFormatError(f"--max-compressive-share must lie in (0, 1], got {share}",
                               field="--max-compressive-share")
    if scheduler != "serial":  # before any input is read
        require("batch", f"--scheduler {scheduler}")
    streams = bool(sci or heater or temperature)
    if input_dir is not None and streams:
        raise InputFormatError("give either --input-dir or --input/--heater/--temperature, "
                               "not both", field="--input-dir")
    if input_dir is None:
        if days.strip():
            raise InputFormatError("--days needs --input-dir", field="--days")
        for option, paths in (("--input", sci), ("--heater", heater),
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
                      temperature_law=temperature_law, estimator=estimator, hold_d0=held,
                      error_goal=goal, max_compressive_share=share)
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
    from fluxcal.missions.messenger.chain import day_of
    from fluxcal.missions.messenger.readers import read_science

    sci = read_science(list(chunk.science[:1]))
    with KernelPool(list(chunk.kernels), frames=FRAME_KERNELS):
        return str(day_of(sci))
