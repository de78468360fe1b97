"""A toy fluxgate mission, registered from the test folder (``FLUXCAL_MISSIONS``).

Everything a mission hands the runner in ~100 lines: a run-options dataclass, a reader,
a level function, a single-run command, a picklable day task, a simulator and a demo
part.  No generic file of fluxcal names it.

Input per day: ``TOY_<yyyymmdd>.csv`` with header ``epoch_ns,cx,cy,cz`` (counts);
B = gain * counts with the gain of ``--gain`` (nT/count).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import typer
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products.writer import write_product
from fluxcal.runs.batch import DayInputs, DayResult, DayWithoutData
from fluxcal.runs.contract import DemoPart, Mission
from fluxcal.runs.options import with_options

DAY_NS = 86_400 * 10**9
EPOCH_2024 = 757_339_269_184_000_000  # TT2000 of 2024-01-01T00:00:00 UTC (cdflib)


@dataclass(frozen=True)
class ToyOptions:
    """Options of a toy run (single run and batch alike)."""

    gain: float = field(default=0.5, metadata={"help": "Gain (nT/count)."})
    formats: tuple[str, ...] = field(default=("cdf",), metadata={
        "help": "Product formats.", "choices": ("cdf", "nc"), "empty_ok": False})


def read_counts(path: Path) -> xr.Dataset:
    """Read a toy CSV; a bad line is one error naming file and line."""
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    except ValueError as exc:
        raise InputFormatError(f"not a toy CSV ({exc})", path=str(path)) from exc
    return xr.Dataset({"counts": (("time", "component"), data[:, 1:].astype(float))},
                      coords={"epoch": ("time", data[:, 0]), "component": ["x", "y", "z"]})


def calibrate(raw: xr.Dataset, gain: float) -> xr.Dataset:
    """Level function: counts -> nT."""
    return xr.Dataset({"B": (("time", "component"), raw["counts"].values * gain,
                             {"units": "nT"})}, coords=raw.coords,
                      attrs={"Logical_source": "toy_b", "Data_type": "l1>toy"})


def day_file(folder: Path, day: dt.date) -> Path:
    """Input file of a day."""
    return Path(folder) / f"TOY_{day:%Y%m%d}.csv"


def simulate_days(input_dir: Path, days: list[dt.date]) -> None:
    """Write 10 samples per day of a known field (counts 2, 4, 6 -> 1, 2, 3 nT at gain 0.5)."""
    Path(input_dir).mkdir(parents=True, exist_ok=True)
    for day in days:
        t0 = EPOCH_2024 + (day - dt.date(2024, 1, 1)).days * DAY_NS
        rows = [f"{t0 + i * 10**9},2,4,6" for i in range(10)]
        day_file(input_dir, day).write_text("epoch_ns,cx,cy,cz\n" + "\n".join(rows) + "\n")


@dataclass(frozen=True)
class ToyDayTask:
    """One toy day (picklable)."""

    input_dir: Path
    out_dir: Path
    gain: float = 0.5
    formats: tuple[str, ...] = ("cdf",)
    name: str = "toy"

    def inputs(self, day: dt.date) -> DayInputs:
        """Return the day's file."""
        return DayInputs((day_file(self.input_dir, day),))

    def __call__(self, day: dt.date) -> DayResult:
        """Calibrate and write one day."""
        path = day_file(self.input_dir, day)
        if not path.exists():
            raise DayWithoutData(f"no input {path}")
        ds = calibrate(read_counts(path), self.gain)
        stem = Path(self.out_dir) / f"TOY_{day:%Y%m%d}"
        return DayResult(day, write_product(ds, stem, formats=self.formats), ds.sizes["time"])


def make_day_task(input_dir: Path, out_dir: Path, **options) -> ToyDayTask:
    """Build the batch task (options: the fields of `ToyOptions`)."""
    keep = {k: v for k, v in options.items() if k in ("gain", "formats")}
    return ToyDayTask(Path(input_dir), Path(out_dir), **keep)


app = typer.Typer(help="Toy mission commands.", no_args_is_help=True)


@app.command("calibrate")
@with_options(ToyOptions)
def calibrate_command(
    input_file: Path = typer.Option(..., "--input", help="Toy CSV."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    options: ToyOptions = None,  # type: ignore[assignment]
) -> None:
    """Calibrate one toy file."""
    out.mkdir(parents=True, exist_ok=True)
    ds = calibrate(read_counts(input_file), options.gain)
    for p in write_product(ds, out / input_file.stem, formats=options.formats):
        typer.echo(str(p))


def run_demo(out: Path) -> str:
    """Demo part: simulate a day and calibrate it."""
    simulate_days(out, [dt.date(2024, 1, 1)])
    task = make_day_task(out, out / "products")
    result = task(dt.date(2024, 1, 1))
    return f"toy: {len(result.products)} product(s) in {out / 'products'}"


MISSION = Mission(
    name="toy",
    title="Toy fluxgate (test mission)",
    commands="tests.runs.toy_mission:app",
    day_task="tests.runs.toy_mission:make_day_task",
    options="tests.runs.toy_mission:ToyOptions",
    simulate_days="tests.runs.toy_mission:simulate_days",
    demo_days=(dt.date(2024, 1, 1), dt.date(2024, 1, 2)),
    demo_parts=(DemoPart("Toy mission", "tests.runs.toy_mission:run_demo", "toy", 5),),
)


def run_quick_demo(out: Path) -> str:
    """Quick demo part: one calibrated day and the run's HTML report."""
    from fluxcal.products.html_report import write_run_report

    simulate_days(out / "input", [dt.date(2024, 1, 1)])
    result = make_day_task(out / "input", out / "products")(dt.date(2024, 1, 1))
    report = write_run_report(out / "products")
    return f"toy: {len(result.products)} product(s); report {report}"


MISSION = dataclasses.replace(MISSION, demo_parts=(
    *MISSION.demo_parts,
    DemoPart("Toy first run", "tests.runs.toy_mission:run_quick_demo", "toy", 5, quick=True)))
