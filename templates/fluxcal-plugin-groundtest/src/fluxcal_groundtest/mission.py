"""Ground-test fluxgate on fluxcal's mission contract (docs/guide/plugins.md).

Input ``GT_<yyyymmdd>.csv`` (``time_utc,cx,cy,cz,temp_c``) -> ``GROUNDTEST_<yyyymmdd>``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import typer
import xarray as xr

from fluxcal.errors import CalibrationError, FluxcalError, InputFormatError
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.products.declared import Product, Quicklook
from fluxcal.products.format_names import FORMATS
from fluxcal.runs import driver
from fluxcal.runs.contract import Mission
from fluxcal.runs.options import with_options

CALIB = Path(__file__).resolve().parent / "data" / "groundtest_calib_v1.txt"
HEADER = "time_utc,cx,cy,cz,temp_c"
SIZES = {"reference_temperature_c": 1, "offset": 3, "offset_drift": 3, "gain": 3,
         "gain_drift": 3, "misalignment": 9}


@dataclass(frozen=True)
class GroundTestOptions:
    """Run options of ``fluxcal groundtest calibrate`` and ``fluxcal batch groundtest``."""

    calib: Path | None = field(default=None, metadata={"help": "Calibration file."})
    formats: tuple[str, ...] = field(default=("cdf", "tab"), metadata={
        "help": "Product formats.", "choices": FORMATS, "empty_ok": False})
    quicklook: bool = field(default=False, metadata={"help": "Also a PNG per day."})


def read_calibration(path: Path) -> dict[str, np.ndarray]:
    """Read the ``key = numbers`` lines; a missing key or bad number names the file."""
    try:
        values = {k.strip(): np.array(v.split(), dtype=float) for k, _, v in (
            line.split("#")[0].partition("=") for line in Path(path).read_text().splitlines())
            if k.strip()}
    except ValueError as exc:
        raise CalibrationError(f"{path}: not a ground-test calibration ({exc})") from None
    bad = [k for k, n in SIZES.items() if values.get(k, np.zeros(0)).size != n]
    if bad:
        raise CalibrationError(f"{path}: {bad[0]} needs {SIZES[bad[0]]} number(s)")
    return values


def read_csv(path: Path) -> xr.Dataset:
    """Read one CSV; a bad header, time or number is one error naming the file."""
    try:
        with open(path) as f:
            if f.readline().strip() != HEADER:
                raise ValueError(f"the header is not {HEADER}")
        text = np.loadtxt(path, delimiter=",", skiprows=1, dtype=str, ndmin=2)
        epoch, numbers = utc_to_tt2000(text[:, 0]), text[:, 1:5].astype(float)
        if len(epoch) == 0 or text.shape[1] != 5 or not np.isfinite(numbers).all():
            raise ValueError("no rows, a row without 5 fields or a value not a number")
    except (ValueError, IndexError, FluxcalError) as exc:
        raise InputFormatError(f"not a ground-test CSV: {exc}", path=str(path)) from None
    return xr.Dataset({"counts": (("time", "component"), numbers[:, :3]),
                       "temperature": ("time", numbers[:, 3], {"units": "degC"})},
                      coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]})


def day_file(folder: Path, day: dt.date) -> Path:
    """Return the input file of a day."""
    return Path(folder) / f"GT_{day:%Y%m%d}.csv"


@dataclass(frozen=True)
class GroundTestRun:
    """The `fluxcal.runs.driver.Pipeline` (picklable): the driver runs its steps."""

    def check(self, options: GroundTestOptions) -> None:
        """Refuse a bad calibration file before any input is read."""
        read_calibration(options.calib or CALIB)

    def read(self, source: list[Path], options: GroundTestOptions) -> tuple[xr.Dataset, list]:
        """Read the CSV files of a run, in time order."""
        raw = xr.concat([read_csv(p) for p in source], "time")
        return raw.isel(time=np.argsort(raw["epoch"].values, kind="stable")), list(source)

    def size(self, raw: xr.Dataset) -> int:
        """Return the number of vectors read."""
        return raw.sizes["time"]

    def calibrate(self, raw: xr.Dataset, options: GroundTestOptions, progress) -> xr.Dataset:
        """Convert counts, degC to nT: offset, gain (with their drifts), misalignment."""
        c = read_calibration(options.calib or CALIB)
        dtemp = raw["temperature"].values[:, None] - c["reference_temperature_c"][0]
        sensor = c["gain"] * (1 + c["gain_drift"] * dtemp) * (
            raw["counts"].values - c["offset"] - c["offset_drift"] * dtemp)
        return raw.drop_vars("counts").assign(b=(("time", "component"), sensor @ c[
            "misalignment"].reshape(3, 3).T, {"units": "nT", "description": "field"}))

    def products(self, calibrated: xr.Dataset, options: GroundTestOptions) -> list[Product]:
        """Declare one product per UTC day (the runner splits, names and writes them)."""
        ql = [Quicklook("GROUNDTEST_QL", calibrated)] if options.quicklook else []
        return [Product("GROUNDTEST_{day:%Y%m%d}", calibrated, formats=options.formats,
                        attrs={"Logical_source": "groundtest_mag"}), *ql]

    def calibration(self, calibrated: xr.Dataset, options: GroundTestOptions) -> dict:
        """Return the calibration used (provenance; the batch manifest's key)."""
        return {"groundtest_calib": options.calib or CALIB}

    def day_files(self, input_dir: Path, day: dt.date, options) -> list[Path]:
        """Return the day's file and the day before's (a recording may cross midnight)."""
        return [p for p in (day_file(input_dir, day - dt.timedelta(days=1)),
                            day_file(input_dir, day)) if p.is_file()]


def make_day_task(input_dir: Path, out_dir: Path, **options) -> driver.DayTask:
    """Return the task of ``fluxcal batch groundtest`` (``options``: `GroundTestOptions`)."""
    if options.pop("kernels", None) is not None:
        raise FluxcalError("--kernels: the ground-test fluxgate uses no SPICE kernels")
    return driver.DayTask(GroundTestRun(), Path(input_dir), Path(out_dir),
                          GroundTestOptions(**options), name="groundtest")


app = typer.Typer(help="Ground-test fluxgate.", no_args_is_help=True)


@app.command("calibrate")
@with_options(GroundTestOptions)
def calibrate(inputs: list[Path] = typer.Option(..., "--input", exists=True, dir_okay=False,
                                                help="CSV file (repeat for more)."),
              out: Path = typer.Option(..., "--out", help="Product folder."),
              options: GroundTestOptions = None) -> None:  # type: ignore[assignment]
    """Calibrate CSV files: a product per UTC day and the run's HTML report."""
    for path in driver.run(GroundTestRun(), inputs, None, out, options)[0]:
        typer.echo(str(path))


MISSION = Mission(name="groundtest", title="Ground-test fluxgate (plugin template)",
                  commands=f"{__name__}:app", options=f"{__name__}:GroundTestOptions",
                  day_task=f"{__name__}:make_day_task",
                  simulate_days="fluxcal_groundtest.simulate:simulate_days",
                  demo_days=(dt.date(2024, 3, 12), dt.date(2024, 3, 13)))
