"""``fluxcal batch messenger`` day task on two simulated days (serial scheduler)."""

import datetime as dt

import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.synthetic import write_messenger_like_kernels
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger.batch_task import day_file, make_day_task
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.products.batch import run_batch


def test_two_days_across_midnight(tmp_path):
    start = "2012-06-01T23:00:00"
    cfg = SimulationConfig(start_utc=start, duration_s=7200.0, rate_segments=[(0.0, 6)],
                           coarse_intervals=[], lead_s=1200.0)
    inp = tmp_path / "in"
    mk = write_messenger_like_kernels(inp / "k", start, 10000.0)
    (inp / "kernels.tm").write_text(mk.read_text())
    cal = load_calibration(start)
    with KernelPool(mk):
        sim = simulate(cfg, cal, SclkKernel.from_pool(-236))
        sclk = SclkKernel.from_pool(-236)
        midnight = utc_to_et(np.array(["2012-06-02T00:00:00"]))[0]
        rec = {k: sclk.to_et(sim[k]["partition"].values, sim[k]["met"].values)
               for k in ("science", "heater", "temperature")}
    dims = {"science": "time", "heater": "heater_time", "temperature": "temperature_time"}
    for day, sel in ((dt.date(2012, 6, 1), lambda e: e < midnight),
                     (dt.date(2012, 6, 2), lambda e: e >= midnight)):
        part = {k: sim[k].isel({dims[k]: sel(rec[k])}) for k in dims}
        part["truth"] = sim["truth"].isel(time=sel(rec["science"]))
        paths = write_inputs(part, tmp_path / "tmp", stem=f"d{day:%j}")
        for k, code in (("science", "SCI"), ("heater", "HTR"), ("temperature", "TMP")):
            paths[k].replace(day_file(inp, code, day))
    out = tmp_path / "out"
    task = make_day_task(inp, out, formats=("tab",), frames=("mso",), averages=(60,))
    report = run_batch([dt.date(2012, 6, 1), dt.date(2012, 6, 2), dt.date(2012, 6, 3)], task,
                       out, scheduler="serial")
    status = {d.day: d.status for d in report.days}
    assert status == {"2012-06-01": "done", "2012-06-02": "done", "2012-06-03": "no_data"}
    assert (out / "MAGMSOSCI12153.TAB").is_file() and (out / "MAGMSOSCI12154.TAB").is_file()
    n1 = len((out / "MAGMSOSCI12153.TAB").read_text().splitlines())
    n2 = len((out / "MAGMSOSCI12154.TAB").read_text().splitlines())
    assert n1 + n2 == sim["science"].sizes["time"]
    # a second run skips both days (manifests up to date)
    again = run_batch([dt.date(2012, 6, 1), dt.date(2012, 6, 2)], task, out, scheduler="serial")
    assert {d.status for d in again.days} == {"skipped"}
