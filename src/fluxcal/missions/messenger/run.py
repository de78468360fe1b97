"""``edr2cdr`` as a function: read the streams, calibrate, validate and write per day.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from fluxcal.errors import ValidationError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.pipeline import calibrate, day_of
from fluxcal.missions.messenger.products import AVERAGES_S, day_code, split_days, write_day
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.validation_report import write_report

log = logging.getLogger(__name__)


def run_edr2cdr(
    science: Sequence[Path],
    heater: Sequence[Path],
    temperature: Sequence[Path],
    kernels: Path | Sequence[Path],
    out_dir: Path,
    *,
    frames: Sequence[str] = ("mso", "j2000", "mbf", "rtn", "sc"),
    formats: Sequence[str] = ("tab", "cdf"),
    averages: Sequence[int] = AVERAGES_S,
    max_offset_step: float | None = 2.0,
) -> list[Path]:
    """Run the MESSENGER MAG EDR -> CDR chain and write the products of every day.

    A day whose offsets fail the smoothness check (sec. 13) gets no file; the other
    days are written, then `ValidationError` is raised naming the failed days.

    Returns
    -------
    list of Path
        Every file written.
    """
    from fluxcal.products import provenance_attrs

    sci = read_science(science)
    heat = read_heater(heater)
    temp = read_temperature(temperature)
    out_dir = Path(out_dir)
    written: list[Path] = []
    failures: list[str] = []
    with KernelPool(kernels) as pool:
        cal = load_calibration(day_of(sci))
        ds = calibrate(sci, heat, temp, cal, frames=tuple(frames), max_offset_step=None)
        kernel_list = pool.kernel_list()
        prov = provenance_attrs(
            inputs=[*map(Path, science), *map(Path, heater), *map(Path, temperature)],
            calibration={name: version for name, version in cal.files},
            kernels=kernel_list,
        )
        prov["calibration_tables"] = cal.provenance()
        for day in split_days(ds):
            try:
                if max_offset_step is not None:
                    levels.validate_offsets(day, max_offset_step)
            except ValidationError as exc:
                failures.append(str(exc))
                log.error("day failed validation: %s", exc)
                continue
            files = write_day(day, out_dir, frames, formats, averages, prov)
            written += files
            yyddd = day_code(day)[2]
            written += write_report(day, out_dir / f"MAGOFFSETS{yyddd}", max_offset_step)
    if failures:
        raise ValidationError("; ".join(failures))
    return written
