"""Day task for ``fluxcal batch messenger`` (one EDR day -> its CDR products).

Input folder layout (one file per stream and day, day = UTC day of the recorded time)::

    MAGSCI_YYYYDDD.csv   science samples
    MAGHTR_YYYYDDD.csv   heater bits (the previous day's file is read too, for the
                         5-change look-back of sec. 7, when present)
    MAGTMP_YYYYDDD.csv   sensor temperatures (previous and next day read when present)
    kernels.tm           meta-kernel (or ``--kernels``)

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5-13.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path

from fluxcal.missions.messenger.products import AVERAGES_S


def day_file(folder: Path, stream: str, day: _dt.date) -> Path:
    """Return ``folder/MAG<stream>_YYYYDDD.csv``."""
    return Path(folder) / f"MAG{stream}_{day:%Y%j}.csv"


@dataclass(frozen=True)
class MessengerDayTask:
    """Calibrate one MESSENGER MAG day and write its products (picklable)."""

    input_dir: Path
    out_dir: Path
    kernels: Path | None = None
    formats: tuple[str, ...] = ("tab", "cdf")
    frames: tuple[str, ...] = ("mso", "j2000", "mbf", "rtn", "sc")
    averages: tuple[int, ...] = AVERAGES_S
    max_offset_step: float | None = 2.0
    calib: Path | None = None
    quicklook: bool = False
    quicklook_frame: str | None = None

    def _kernels(self) -> Path:
        return Path(self.kernels) if self.kernels else Path(self.input_dir) / "kernels.tm"

    def _files(self, day: _dt.date) -> dict[str, list[Path]]:
        one = _dt.timedelta(days=1)
        sci = [day_file(self.input_dir, "SCI", day)]
        heat = [p for p in (day_file(self.input_dir, "HTR", day - one),
                            day_file(self.input_dir, "HTR", day)) if p.exists()]
        temp = [p for p in (day_file(self.input_dir, "TMP", day - one),
                            day_file(self.input_dir, "TMP", day),
                            day_file(self.input_dir, "TMP", day + one)) if p.exists()]
        return {"science": sci, "heater": heat, "temperature": temp}

    def inputs(self, day: _dt.date):
        """Return the day's input files, kernels and calibration folder."""
        from fluxcal.missions.messenger.calibration_data import data_dir
        from fluxcal.missions.messenger.products import istp_files
        from fluxcal.products.batch import DayInputs

        files = [p for group in self._files(day).values() for p in group if p.exists()]
        folder = Path(self.calib) if self.calib else data_dir()
        cal = {p.name: p for p in sorted(folder.glob("*_v*.*"))}
        # product metadata: a changed ISTP attribute file redoes the day too
        cal.update({p.name: p for p in (*istp_files(), data_dir() / "istp_products.yaml")})
        return DayInputs(tuple(files + [self._kernels()]), cal)

    def __call__(self, day: _dt.date):
        """Process ``day``; raise `DayWithoutData` when its science file is missing."""
        from fluxcal.missions.messenger.readers import (
            read_heater,
            read_science,
            read_temperature,
        )
        from fluxcal.missions.messenger.run import calibrate_and_write
        from fluxcal.products.batch import DayResult, DayWithoutData, worker_kernel_pool

        files = self._files(day)
        if not files["science"][0].exists():
            raise DayWithoutData(f"no science file {files['science'][0]}")
        sci = read_science(files["science"])
        heat = read_heater(files["heater"])
        temp = read_temperature(files["temperature"])
        pool = worker_kernel_pool(self._kernels())
        paths = calibrate_and_write(
            sci, heat, temp, Path(self.out_dir),
            inputs=[p for group in files.values() for p in group],
            kernel_list=pool.kernel_list(), frames=self.frames, formats=self.formats,
            averages=self.averages, max_offset_step=self.max_offset_step,
            calibration_folder=self.calib, only_day=f"{day:%y%j}",
            quicklook=self.quicklook, quicklook_frame=self.quicklook_frame,
        )
        return DayResult(day, paths, n_vectors=int(sci.sizes["time"]))


def make_day_task(input_dir: Path, out_dir: Path, **options) -> MessengerDayTask:
    """Build the task for ``fluxcal batch messenger``.

    Options: kernels, formats, calib, frames, averages, max_offset_step, quicklook,
    quicklook_frame; unknown options are ignored.
    """
    allowed = {"kernels", "formats", "calib", "frames", "averages", "max_offset_step",
               "quicklook", "quicklook_frame"}
    opts = {k: v for k, v in options.items() if k in allowed and v is not None}
    for key in ("formats", "frames", "averages"):
        if key in opts:
            opts[key] = tuple(opts[key])
    return MessengerDayTask(Path(input_dir), Path(out_dir), **opts)
