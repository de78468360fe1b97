"""The behavioural tests every mission inherits: `MissionContract` (needs pytest).

A mission (fluxcal's own or a plugin) subclasses `MissionContract` in its test suite,
as xarray's backends subclass ``DatasetIOBase``, and fills in the hooks: how to simulate
a stream from a forward model that shares no code with the pipeline (the `Truth`), the
command line of a run, and the names of a day's products.  pytest then runs, on the
mission's own products, read back with `fluxcal.read_product`:

- **round trip**: every simulated sample comes back once, at its time, with the true
  field within `MissionContract.tolerance_nt`;
- **provenance**: ``fluxcal provenance --json`` lists every input file and the
  calibration by name and SHA-256 (the SHA-256 computed here with `hashlib`);
- **day boundaries**: a stream across midnight gives the two days' products, each with
  only its own UTC day's samples, no sample lost or duplicated;
- **product names**: the run writes exactly the files `MissionContract.product_names`
  declares for its days (beside the run's report and batch files);
- **bad inputs**: a malformed input is refused naming the file, and no product is
  written;
- **declared products**: the mission's batch day task runs a
  `~fluxcal.runs.driver.Pipeline` that declares its products (``products`` and
  ``calibration``) and has no ``write`` of its own: the runner writes them
  (`fluxcal.products.declared`).

Example (docs/guide/plugins.md)::

    from fluxcal.testing import MissionContract, Truth

    class TestGroundTest(MissionContract):
        mission = "groundtest"
        tolerance_nt = 0.06
        def simulate(self, folder, start, seconds): ...
        def command(self, folder, out, truth): ...
        def product_names(self, day): ...
        def break_input(self, truth): ...
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import fluxcal.cli
from fluxcal.api import read_product
from fluxcal.cli import build_app, main
from fluxcal.runs import registry

__all__ = ["MissionContract", "Truth"]

#: Suffixes of the products whose provenance is checked (a mission's side files, e.g.
#: a text table of offsets, are named by `MissionContract.product_names` but not read).
PRODUCT_SUFFIXES = (".cdf", ".nc", ".zarr", ".lbl")


@dataclass
class Truth:
    """What a simulated stream is, from the forward model (not from the pipeline).

    Parameters
    ----------
    time : numpy.ndarray
        UTC time of each sample, ``datetime64[ns]``.
    b : numpy.ndarray
        True field of each sample, shape (n, 3), nT, in the products' frame.
    inputs : list of Path
        The files the run reads (their names and SHA-256 must be in the provenance).
    calibration : tuple of str
        Names of the calibration entries the provenance must list.
    """

    time: np.ndarray
    b: np.ndarray
    inputs: list[Path] = field(default_factory=list)
    calibration: tuple[str, ...] = ()


class MissionContract:
    """Base class of a mission's behavioural tests: subclass it as ``Test<Mission>``.

    Class attributes: `mission` (registry name), `day` (the UTC day the streams start
    on), `seconds` (length of a stream), `tolerance_nt` (largest |product - truth|, nT,
    stated with its reason in the subclass), `time_tolerance_ns` (largest time
    difference of a matched sample), `field` (the products' field variable),
    `bad_input_exit` (2 for a single run; 1 for a batch, whose failed day is reported),
    `extra_files` (a regex of the run's other files: report, manifests), `day_edge_ns`
    (how far outside its UTC day a product may hold samples: a mission whose days are
    those of the recorded time, before a time correction; state the decision).
    """

    mission: str = ""
    day: _dt.date = _dt.date(2024, 3, 12)
    seconds: float = 600.0
    tolerance_nt: float = 0.0
    time_tolerance_ns: int = 1_000
    field: str = "b"
    bad_input_exit: int = 2
    extra_files: str = r"index\.html|batch_report_.*|manifests|stitch"
    day_edge_ns: int = 0

    # --- the hooks a mission fills in -------------------------------------------------
    def simulate(self, folder: Path, start: str, seconds: float) -> Truth:
        """Write a stream from UTC ``start`` lasting ``seconds`` into ``folder``."""
        raise NotImplementedError

    def command(self, folder: Path, out: Path, truth: Truth) -> list[str]:
        """Return the ``fluxcal`` arguments that calibrate ``folder`` into ``out``."""
        raise NotImplementedError

    def product_names(self, day: _dt.date) -> list[str]:
        """Return the file names of one day's products; the first is the one read back."""
        raise NotImplementedError

    def break_input(self, truth: Truth) -> Path:
        """Make one input of ``truth`` malformed; return it."""
        raise NotImplementedError

    def register(self, monkeypatch: pytest.MonkeyPatch) -> None:
        """Register the mission if no installed entry point does (``FLUXCAL_MISSIONS``)."""

    def day_task(self, folder: Path, out: Path, truth: Truth) -> Any:
        """Return the mission's batch day task for ``folder`` (checked for declarations).

        Default: its registered ``make_day_task(folder, out)`` with no option; override
        when the task needs one (kernels, say).
        """
        return registry.get(self.mission).load("day_task")(folder, out)

    # --- fixtures and helpers -----------------------------------------------------------
    @pytest.fixture
    def cli(self, monkeypatch: pytest.MonkeyPatch):
        """Return ``run(args) -> exit code`` on a command line built after `register`."""
        self.register(monkeypatch)
        registry.rescan()
        monkeypatch.setattr(fluxcal.cli, "app", build_app())
        yield main
        registry.rescan()

    def run_stream(self, cli, tmp_path: Path, start: str) -> tuple[Truth, Path]:
        """Simulate a stream from ``start``, run the mission on it; return (truth, out)."""
        truth = self.simulate(tmp_path / "in", start, self.seconds)
        out = tmp_path / "out"
        assert cli(self.command(tmp_path / "in", out, truth)) == 0
        return truth, out

    def read_day(self, out: Path, day: _dt.date):
        """Return the times (datetime64[ns]) and field (n, 3) of the day's first product."""
        ds = read_product(out / self.product_names(day)[0])
        return ds["time"].values.astype("M8[ns]"), np.asarray(ds[self.field].values, float)

    def match(self, truth: Truth, times: np.ndarray) -> np.ndarray:
        """Return the index into the truth of each product time (within the tolerance).

        Samples of equal time (a stream that repeats an instant, e.g. across a mode
        change) are matched in order, so a product sample is never matched twice unless
        it is there twice.
        """
        order = np.argsort(truth.time, kind="stable")
        t = truth.time[order].astype(np.int64)
        x = np.asarray(times).astype("M8[ns]").astype(np.int64)
        by_time = np.argsort(x, kind="stable")
        xs = x[by_time]
        k = np.clip(np.searchsorted(t, xs), 1, len(t) - 1)
        k = np.where(np.abs(t[k - 1] - xs) <= np.abs(t[k] - xs), k - 1, k)
        starts = np.r_[0, np.flatnonzero(np.diff(k)) + 1]
        k = k + np.arange(k.size) - np.repeat(starts, np.diff(np.r_[starts, k.size]))
        assert k.max(initial=0) < len(t), "more product samples than simulated"
        worst = np.abs(t[k] - xs).max(initial=0)
        assert worst <= self.time_tolerance_ns, f"a product time is {worst} ns from its sample"
        out = np.empty_like(k)
        out[by_time] = order[k]
        return out

    # --- the contract -----------------------------------------------------------------
    def test_round_trip(self, cli, tmp_path: Path) -> None:
        """Calibrate, write, read back: every sample once, with the true field."""
        truth, out = self.run_stream(cli, tmp_path, f"{self.day}T10:00:00")
        times, b = self.read_day(out, self.day)
        index = self.match(truth, times)
        assert np.array_equal(np.sort(index), np.arange(len(truth.time))), "lost or repeated"
        error = np.abs(b - truth.b[index]).max()
        assert error <= self.tolerance_nt, f"|product - truth| up to {error} nT"

    def test_provenance(self, cli, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
        """``fluxcal provenance`` lists the inputs and the calibration by name and SHA-256."""
        truth, out = self.run_stream(cli, tmp_path, f"{self.day}T10:00:00")
        capsys.readouterr()
        products = [n for n in self.product_names(self.day)
                    if Path(n).suffix.lower() in PRODUCT_SUFFIXES]
        assert products, "no product of a format fluxcal provenance reads"
        for name in products:
            assert cli(["provenance", "--json", str(out / name)]) == 0
            prov = json.loads(capsys.readouterr().out)
            listed = {r["name"]: r.get("sha256") for r in prov["inputs"]}
            for p in truth.inputs:
                assert listed.get(p.name) == hashlib.sha256(p.read_bytes()).hexdigest(), name
            for key in truth.calibration:
                record = prov["calibration"].get(key, {})
                assert record.get("sha256") or record.get("version"), f"{name}: {key}"

    def test_day_boundary(self, cli, tmp_path: Path) -> None:
        """A stream across midnight: two days' products, no sample lost or duplicated."""
        midnight = np.datetime64(self.day + _dt.timedelta(days=1), "ns")
        start = str(midnight - np.timedelta64(int(self.seconds * 5e8), "ns"))[:19]
        truth, out = self.run_stream(cli, tmp_path, start)
        days = (self.day, self.day + _dt.timedelta(days=1))
        found = []
        for day in days:
            times, _ = self.read_day(out, day)
            assert times.size, f"no samples in the product of {day}"
            edge = np.timedelta64(self.day_edge_ns, "ns")
            first = np.datetime64(day, "D").astype("M8[ns]") - edge
            after = first + np.timedelta64(86_400, "s") + 2 * edge
            assert ((times >= first) & (times < after)).all(), f"{day}: {times[[0, -1]]}"
            found.append(self.match(truth, times))
        index = np.concatenate(found)
        assert np.array_equal(np.sort(index), np.arange(len(truth.time))), "lost or repeated"
        names = {p.name for p in out.iterdir() if not re.fullmatch(self.extra_files, p.name)}
        assert names == {n for day in days for n in self.product_names(day)}

    def test_products_are_declared(self, cli, tmp_path: Path) -> None:
        """The mission declares its products, the runner writes them (no ``write``)."""
        truth = self.simulate(tmp_path / "in", f"{self.day}T10:00:00", self.seconds)
        task = self.day_task(tmp_path / "in", tmp_path / "out", truth)
        pipeline = getattr(task, "pipeline", None)
        if pipeline is None:
            pytest.skip(f"{self.mission}: its day task is no fluxcal.runs.driver.DayTask")
        name = type(pipeline).__name__
        assert not hasattr(pipeline, "write"), (
            f"{name} writes its own products: declare them (products, calibration) and "
            "let the runner write them (docs/guide/plugins.md)")
        for method in ("products", "calibration"):
            assert callable(getattr(pipeline, method, None)), f"{name} has no {method}()"

    def test_bad_input(self, cli, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
        """A malformed input: refused naming the file, no product written."""
        truth = self.simulate(tmp_path / "in", f"{self.day}T10:00:00", self.seconds)
        bad = self.break_input(truth)
        out = tmp_path / "out"
        capsys.readouterr()
        assert cli(self.command(tmp_path / "in", out, truth)) == self.bad_input_exit
        err = capsys.readouterr().err
        if self.bad_input_exit == 2:
            (line,) = [x for x in err.splitlines() if x.strip()]
            assert line.startswith("fluxcal: error:") and bad.name in line, err
        else:  # a batch: the failed day's error in its report names the file
            report = json.loads((out / f"batch_report_{self.mission}.json").read_text())
            errors = [d.get("error") or "" for d in report["days"] if d["status"] == "failed"]
            assert errors and all(bad.name in e for e in errors), errors
        written = [p.name for p in out.glob("*") if not re.fullmatch(self.extra_files, p.name)]
        assert not written, written
