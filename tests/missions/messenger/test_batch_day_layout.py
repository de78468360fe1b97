"""A batch gives the samples of a single run whatever the day layout (issue 31, item 2).

Before: a 23:40-00:10 stream given as one day's batch files reported every sample done
and wrote only those before midnight (issue: "done 29,466", 18,065 written); the samples
after midnight were dropped without a word.  Now a batch day reads the science files of
the day before, the day and the day after and keeps the samples recorded in its own UTC
day (docs/decisions/products.md, "a batch day's samples").

Expected values: the single run (``edr2cdr`` on the whole stream) over the same files,
product for product and sample for sample (exact equality: the same samples calibrated
by the same code); the sample count from the simulated stream itself.  Small scale:
30 min at 1 vector/s (rate setting 6, Table 1).
"""

from __future__ import annotations

import datetime as dt
import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import copy_meta_kernel
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger.batch_day import holds_nothing_of
from fluxcal.missions.messenger.batch_task import day_file, make_day_task
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.products import day_code, split_days
from fluxcal.missions.messenger.readers import read_science
from fluxcal.missions.messenger.routes import run_edr2cdr
from fluxcal.missions.messenger.run import batch_day_rows, merge_fragment_days
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.products import read_product
from fluxcal.runs.batch import run_batch

D1, D2 = dt.date(2012, 6, 1), dt.date(2012, 6, 2)
STREAMS = (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP"))
OPTIONS = {"formats": ("tab",), "frames": ("mso",), "averages": (60,)}


@pytest.fixture(scope="module")
def stream(tmp_path_factory) -> dict:
    """23:40-00:10 UTC at 1 vector/s: the three CSV streams, kernels, and midnight split."""
    folder = tmp_path_factory.mktemp("layout")
    start = "2012-06-01T23:40:00"
    cfg = SimulationConfig(start_utc=start, duration_s=1800.0, rate_segments=[(0.0, 6)],
                           coarse_intervals=[], lead_s=1200.0)
    mk = write_messenger_like_kernels(folder / "k", start, 4000.0)
    copy_meta_kernel(mk, folder / "kernels.tm")
    with KernelPool(mk):
        sclk = SclkKernel.from_pool(-236)
        sim = simulate(cfg, load_calibration(start), sclk)
        midnight = utc_to_et(np.array(["2012-06-02T00:00:00"]))[0]
        recorded = {k: sclk.to_et(sim[k]["partition"].values, sim[k]["met"].values)
                    for k, _ in STREAMS}
    paths = write_inputs(sim, folder / "whole")
    single = folder / "single"
    run_edr2cdr([paths["science"]], [paths["heater"]], [paths["temperature"]],
                folder / "kernels.tm", single, **OPTIONS)
    return {"folder": folder, "sim": sim, "paths": paths, "single": single,
            "midnight": midnight, "recorded": recorded}


def _split_layout(stream: dict, inp: Path) -> None:
    """The documented layout: each stream split by the UTC day of its recorded time."""
    dims = {"science": "time", "heater": "heater_time", "temperature": "temperature_time"}
    for day, after in ((D1, False), (D2, True)):
        part = {k: stream["sim"][k].isel({dims[k]: (stream["recorded"][k]
                                                    >= stream["midnight"]) == after})
                for k, _ in STREAMS}
        part["truth"] = stream["sim"]["truth"].isel(
            time=(stream["recorded"]["science"] >= stream["midnight"]) == after)
        paths = write_inputs(part, inp / "tmp", stem=f"{day:%j}")
        for k, code in STREAMS:
            paths[k].replace(day_file(inp, code, day))
    shutil.rmtree(inp / "tmp")


@pytest.mark.parametrize("layout", ["whole stream as day 1", "whole stream as day 2",
                                    "split at midnight"])
def test_batch_equals_the_single_run_across_midnight(stream, tmp_path, layout, monkeypatch):
    from fluxcal.missions.messenger import batch_day

    parsed = []  # the science files each day parses
    monkeypatch.setattr(batch_day, "read_science",
                        lambda files: parsed.append([p.name for p in files])
                        or read_science(files))
    inp = tmp_path / "in"
    inp.mkdir()
    shutil.copy(stream["folder"] / "kernels.tm", inp / "kernels.tm")
    if layout == "split at midnight":
        _split_layout(stream, inp)
    else:
        day = D1 if layout.endswith("1") else D2
        for key, code in STREAMS:
            shutil.copy(stream["paths"][key], day_file(inp, code, day))
    out = tmp_path / "batch"
    task = make_day_task(inp, out, kernels=stream["folder"] / "kernels.tm", **OPTIONS)
    report = run_batch([D1, D2], task, out, scheduler="serial")
    assert [d.status for d in report.days] == ["done", "done"], report
    n_science = stream["sim"]["science"].sizes["time"]
    n_after = int((stream["recorded"]["science"] >= stream["midnight"]).sum())
    assert 0 < n_after < n_science
    # the count each day reports is the count its product holds
    assert [d.n_vectors for d in report.days] == [n_science - n_after, n_after]
    names = sorted(p.name for p in stream["single"].glob("*.TAB"))
    assert "MAGMSOSCI12154_V01.TAB" in names
    assert names == sorted(p.name for p in out.glob("*.TAB"))
    for name in names:
        a, b = read_product(stream["single"] / name), read_product(out / name)
        assert a.sizes == b.sizes, name
        for var in a.data_vars:
            np.testing.assert_array_equal(a[var].values, b[var].values, err_msg=name)
    assert sum(read_product(out / f"MAGMSOSCI{d:%y%j}_V01.TAB").sizes["time"]
               for d in (D1, D2)) == n_science
    if layout == "split at midnight":  # the neighbour's file holds none of the day's: unread
        assert parsed == [["MAGSCI_2012153.csv"], ["MAGSCI_2012154.csv"]]


def test_a_day_outside_the_batch_is_named(stream, tmp_path, caplog):
    """The samples after midnight of a batch of day 1 only: not written, and said so."""
    inp = tmp_path / "in"
    inp.mkdir()
    for key, code in STREAMS:
        shutil.copy(stream["paths"][key], day_file(inp, code, D1))
    out = tmp_path / "batch"
    task = make_day_task(inp, out, kernels=stream["folder"] / "kernels.tm", **OPTIONS)
    report = run_batch([D1], task, out, scheduler="serial")
    n_after = int((stream["recorded"]["science"] >= stream["midnight"]).sum())
    assert report.days[0].n_vectors == stream["sim"]["science"].sizes["time"] - n_after
    assert read_product(out / "MAGMSOSCI12153_V01.TAB").sizes["time"] == (
        report.days[0].n_vectors)
    assert f"{n_after} science sample(s)" in caplog.text and "2012-06-02" in caplog.text


LAG_S = 2.358  # the largest net lag of Table 1 (s)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.sampled_from([0.0, 0.5, 2.0, 2.3, 2.4, 600.0,
                                                               86399.0])),
                min_size=1, max_size=12, unique=True),
       st.lists(st.integers(1, 11), max_size=4))
def test_every_sample_goes_to_exactly_one_batch_day(stream, samples, cuts):
    """Any day layout: the batch days' selections partition the samples (none lost or
    doubled), a lag-sized fragment joining the whole day before it as in a single run;
    a file holding none of a day's samples decides by its first and last alone."""
    with KernelPool(stream["folder"] / "kernels.tm"):
        _partition(samples, cuts)


def _partition(samples, cuts) -> None:
    base = dt.date(2012, 6, 1)
    rec = np.sort(np.array([utc_to_et(np.array([f"{base + dt.timedelta(days=d)}T00:00:00"]))[0]
                            + s for d, s in samples]))
    days = [base + dt.timedelta(days=k) for k in range(-1, 5)]
    kept = np.zeros(rec.size, dtype=int)
    for day in days:
        keep, joined = batch_day_rows(rec, day, LAG_S)
        assert joined is None or not keep.any()
        kept += keep
    assert (kept == 1).all(), (samples, kept)
    # a fragment (all of a day's samples within the lag) joins the day before when that day
    # is in the data and is no fragment itself; brute force over the (day, second) pairs
    by_day: dict[int, list[float]] = {}
    for d, s in samples:
        by_day.setdefault(d, []).append(s)
    fragment = {d: max(v) < LAG_S for d, v in by_day.items()}
    for d in by_day:
        joins = fragment[d] and d - 1 in by_day and not fragment[d - 1]
        keep, joined = batch_day_rows(rec, base + dt.timedelta(days=d), LAG_S)
        assert (joined is not None) == joins
    # and the single run's products (split_days, then merge_fragment_days) hold exactly the
    # samples each batch day keeps
    ds = xr.Dataset({"et_recorded": ("time", rec)})
    products = merge_fragment_days(ds, split_days(ds), LAG_S)
    assert sum(p.sizes["time"] for p in products) == rec.size
    for product in products:
        year, doy, _ = day_code(product)
        day = dt.date(year, 1, 1) + dt.timedelta(days=doy - 1)
        keep, _ = batch_day_rows(rec, day, LAG_S)
        np.testing.assert_array_equal(rec[keep], product["et_recorded"].values)

    # files: the sorted samples cut anywhere; a day skips each file that holds none of its
    # samples or of the next day's fragment, and sees only its first and last
    bounds = sorted({0, rec.size, *[c for c in cuts if c < rec.size]})
    files = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    for day in days:
        m = utc_to_et(np.array([f"{day + dt.timedelta(days=k)}T00:00:00" for k in (0, 1, 2)]))
        read, context = [], []
        for rows in files:
            if holds_nothing_of(rec[rows[0]], rec[rows[-1]], m, LAG_S):
                context += [rec[rows[0]], rec[rows[-1]]]
            else:
                read += list(rows)
        full, joined = batch_day_rows(rec, day, LAG_S)
        part, joined_part = batch_day_rows(rec[read], day, LAG_S, np.array(context))
        assert joined_part == joined
        np.testing.assert_array_equal(part, full[read])
        assert full.sum() == part.sum()  # no kept sample in a skipped file
