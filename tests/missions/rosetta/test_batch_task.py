"""``fluxcal batch rosetta``: the day task, its input layout, atomic days and resumption.

Simulated days come from the Rosetta forward model (`batch_task.simulate_days`), so the
products are checked against the field the simulator started from.
"""

import datetime as dt
import json
import pickle
import shutil

import cdflib
import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.missions.rosetta.batch_task import science_file, simulate_days
from fluxcal.missions.rosetta.routes import make_day_task
from fluxcal.missions.rosetta.simulate import read_truth_csv
from fluxcal.products import read_fluxcal_product
from fluxcal.runs.batch import DayWithoutData, run_batch

DAYS = [dt.date(2014, 11, 1), dt.date(2014, 11, 2), dt.date(2014, 11, 3)]
BAD = DAYS[1]
MINUTES = 5.0  # 6000 vectors per sensor and day: short days keep the suite fast


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """Three simulated days with kernels, calibration folder and truth files."""
    root = tmp_path_factory.mktemp("rosetta_batch_in")
    simulate_days(root, DAYS, minutes=MINUTES, truth=True, seed=3)
    return root


def _copy_with_bad_day(sim, dest):
    shutil.copytree(sim, dest)
    path = science_file(dest, BAD, "IB")  # IB runs after OB: OB's files must not survive
    lines = path.read_text().splitlines()
    fields = lines[101].split(",")
    fields[3] = "12x4"  # bx, line 102 of the file (header is line 1)
    lines[101] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    return dest


def _batch(inp, out, *extra):
    return main(["batch", "rosetta", "--start", DAYS[0].isoformat(), "--end",
                 DAYS[-1].isoformat(), "--input", str(inp), "--out", str(out), "--quiet",
                 *extra])


def _report(out):
    return json.loads((out / "batch_report_rosetta.json").read_text())


def test_layout_written_by_simulate_days(sim):
    assert (sim / "kernels.tm").is_file()
    assert (sim / "calib" / "RPCMAG_SC_ALIGN.TXT").is_file()
    for day in DAYS:
        folder = sim / f"{day:%Y%m%d}"
        assert {p.name for p in folder.iterdir()} >= {"science_OB.csv", "science_IB.csv",
                                                      "hk.csv"}
        assert (sim / "calib" / f"RPCMAG_{day:%y%m%d}_006_CALIB_OB.TXT").is_file()
        first = (folder / "science_OB.csv").read_text().splitlines()[1]
        assert first.startswith(f"{day.isoformat()}T10:00:00")


def test_serial_run_with_bad_day_then_rerun(sim, tmp_path):
    inp = _copy_with_bad_day(sim, tmp_path / "in")
    out = tmp_path / "out"
    assert _batch(inp, out, "--scheduler", "serial", "--quicklook") == 1
    rep = _report(out)
    assert rep["counts"] == {"done": 2, "skipped": 0, "no_data": 0, "failed": 1}
    bad = next(d for d in rep["days"] if d["day"] == BAD.isoformat())
    assert bad["status"] == "failed"
    # the error names the file, the line and the field
    assert "science_IB.csv" in bad["error"] and "line 102" in bad["error"]
    assert "field 'bx'" in bad["error"]
    # atomic day: the OB products of the bad day (made before IB failed) are not there
    assert not list(out.glob(f"*{BAD:%Y%m%d}*")) and not list(out.glob(f"*{BAD:%y%m%d}*"))
    assert not list(out.rglob("*fluxcal-tmp*"))
    for day in (DAYS[0], DAYS[2]):
        stamp = f"{day:%Y%m%d}"
        for sensor in ("OB", "IB"):
            for code in ("CLA", "CLB", "CLC"):  # kernels.tm: C and G too
                tabs = list(out.glob(f"RPCMAG{day:%y%m%d}T*_{code}_{sensor}_M*.TAB"))
                assert tabs and all(t.with_suffix(".LBL").is_file() for t in tabs)
            for code in ("CLE", "CLF", "CLG"):
                for suffix in ("TAB", "LBL"):
                    assert (out / f"RPCMAG{day:%y%m%d}_{code}_{sensor}_A01.{suffix}").is_file()
            for code in ("cla", "clb", "clc", "cle-", "clf-", "clg-"):
                assert list(out.glob(f"rosetta_rpcmag_{code}*{sensor.lower()}*_{stamp}_v01.cdf"))
        assert (out / f"RPCMAG_{stamp}_HKA.TAB").is_file()
        for sensor in ("OB", "IB"):
            png = out / f"RPCMAG_QL_{sensor}_{stamp}.png"
            assert png.is_file() and png.stat().st_size > 20_000
    assert rep["vectors"] == 2 * 2 * int(MINUTES * 60 * 20)  # 2 days x 2 sensors x 20 Hz

    # rerun: the good days are skipped, the bad one fails again
    assert _batch(inp, out, "--scheduler", "serial", "--quicklook") == 1
    assert _report(out)["counts"] == {"done": 0, "skipped": 2, "no_data": 0, "failed": 1}
    # repaired input: the repaired day runs, and the next day too: its incoming midnight-
    # stitching state (decision 27) changed from "chain broken" to the repaired day's end
    shutil.copy(science_file(sim, BAD, "IB"), science_file(inp, BAD, "IB"))
    assert _batch(inp, out, "--scheduler", "serial", "--quicklook") == 0
    assert _report(out)["counts"] == {"done": 2, "skipped": 1, "no_data": 0, "failed": 0}
    assert [d["status"] for d in _report(out)["days"]] == ["skipped", "done", "done"]


def test_local_cluster_two_workers(sim, tmp_path):
    inp = _copy_with_bad_day(sim, tmp_path / "in")
    out = tmp_path / "out"
    task = make_day_task(inp, out, formats=("cdf",))
    report = run_batch(DAYS, task, out, n_workers=2, name="rosetta")
    assert report.n_workers == 2
    assert [d.status for d in report.days] == ["done", "failed", "done"]
    assert "science_IB.csv" in report.days[1].error and "line 102" in report.days[1].error
    assert not list(out.glob(f"*{BAD:%Y%m%d}*")) and not list(out.glob(f"*{BAD:%y%m%d}*"))
    again = run_batch(DAYS, task, out, scheduler="serial", name="rosetta")
    assert [d.status for d in again.days] == ["skipped", "failed", "skipped"]


@pytest.fixture(scope="module")
def serial_products(sim, tmp_path_factory):
    out = tmp_path_factory.mktemp("rosetta_batch_out")
    # ECLIPJ2000: the simulator's truth frame (the default in the comet phase is CSEQ)
    task = make_day_task(sim, out, formats=("cdf",), frame="ECLIPJ2000")
    report = run_batch(DAYS[:1], task, out, scheduler="serial")
    assert report.ok, report.days
    return out


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_batch_products_recover_truth(sim, serial_products, sensor):
    # LEVEL_C in ECLIPJ2000 against the simulator's field at the good samples; 0.03 nT as
    # in test_cli: quantization of the 20-bit words and the 1 us CSV time rounding
    truth = read_truth_csv(sim / f"{DAYS[0]:%Y%m%d}" / f"truth_{sensor}.csv")
    good = truth["good"]
    ref = truth["b_ref"][good][np.argsort(truth["epoch"][good], kind="stable")]
    name = f"rosetta_rpcmag_clc-{sensor.lower()}_{DAYS[0]:%Y%m%d}_v01.cdf"
    c = read_fluxcal_product(serial_products / name)
    assert c.sizes["time"] == ref.shape[0]
    rms = np.sqrt(((c["b"].values - ref) ** 2).mean(axis=0))
    assert np.all(rms < 0.03), rms


def test_cdf_carries_rosetta_istp_attributes(serial_products):
    cdf = cdflib.CDF(str(serial_products / f"rosetta_rpcmag_clb-ob_{DAYS[0]:%Y%m%d}_v01.cdf"))
    g = cdf.globalattsget()
    assert g["Project"] == ["ROSETTA>International Rosetta Mission"]
    assert g["Source_name"][0].startswith("ROSETTA>")
    assert g["Descriptor"][0].startswith("RPCMAG>")
    assert g["Discipline"] == ["Space Physics>Interplanetary Studies"]
    assert g["LEVEL"] == ["LEVEL_B"] and g["SENSOR"] == ["OB"]
    assert cdf.varattsget("b")["UNITS"] == "nT"
    assert cdf.varattsget("temperature")["UNITS"] == "K"


def test_manifest_inputs_only_the_days_calibration(sim, serial_products):
    man = json.loads((serial_products / "manifests" / "rosetta_2014-11-01.json").read_text())
    keys = set(man["inputs"])
    assert any(k.endswith("RPCMAG_141101_006_CALIB_OB.TXT") for k in keys)
    assert not any("141102_006" in k for k in keys)  # another day's model: no redo
    assert any(k.endswith("kernels.tm") for k in keys)
    assert "input:science_IB.csv" in keys  # by file name: the manifest names no folder
    assert not any(str(sim) in k for k in keys), keys


def test_day_without_data_and_picklable(sim, tmp_path):
    task = make_day_task(sim, tmp_path, quicklook=True, levels="A,B", unknown=1)
    assert pickle.loads(pickle.dumps(task)) == task
    with pytest.raises(DayWithoutData, match="20141104"):
        task(dt.date(2014, 11, 4))
    report = run_batch([dt.date(2014, 11, 4)], task, tmp_path, scheduler="serial")
    assert report.days[0].status == "no_data"


def test_without_kernels_levels_a_b_e_f(tmp_path):
    # no kernels: times from time_utc, LEVEL_C/G not made; LEVEL_B recovers the s/c truth
    inp = tmp_path / "in"
    day = dt.date(2014, 11, 5)
    simulate_days(inp, [day], minutes=2.0, kernels=False, truth=True)
    assert not (inp / "kernels.tm").exists()
    out = tmp_path / "out"
    task = make_day_task(inp, out, formats=("cdf",))
    assert task.options.levels == ("A", "B", "E", "F")
    result = task(day)
    codes = sorted({p.name.split("_")[2] for p in result.products})
    assert codes == ["cla-hk", "cla-ib", "cla-ob", "clb-ib", "clb-ob", "cle-ib-a01",
                     "cle-ob-a01", "clf-ib-a01", "clf-ob-a01"]
    truth = read_truth_csv(inp / f"{day:%Y%m%d}" / "truth_OB.csv")
    good = truth["good"]
    ref = truth["b_sc"][good][np.argsort(truth["epoch"][good], kind="stable")]
    b = read_fluxcal_product(out / f"rosetta_rpcmag_clb-ob_{day:%Y%m%d}_v01.cdf")
    rms = np.sqrt(((b["b"].values - ref) ** 2).mean(axis=0))
    assert np.all(rms < 0.03), rms  # same budget as LEVEL_C above


def test_calibrate_quicklook_option(sim, tmp_path):
    folder = sim / f"{DAYS[0]:%Y%m%d}"
    args = ["rosetta", "calibrate", "--science", str(folder / "science_OB.csv"), "--sensor",
            "OB", "--levels", "A,B", "--calib", str(sim / "calib"), "--out", str(tmp_path),
            "--formats", "cdf", "--quicklook"]
    assert main(args) == 0
    png = tmp_path / f"RPCMAG_QL_OB_{DAYS[0]:%Y%m%d}.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20_000
    name = f"rosetta_rpcmag_cla-ob_{DAYS[0]:%Y%m%d}_v01.cdf"
    g = cdflib.CDF(str(tmp_path / name)).globalattsget()
    assert g["Project"] == ["ROSETTA>International Rosetta Mission"]


def test_quicklook_figure_panels(sim, serial_products):
    # the quicklook dataset draws field, temperature and distance (rendering checked by
    # axes labels, not pixels)
    import matplotlib.pyplot as plt

    from fluxcal.products.quicklook import quicklook_figure

    c = read_fluxcal_product(serial_products / f"rosetta_rpcmag_clc-ob_{DAYS[0]:%Y%m%d}_v01.cdf")
    fig = quicklook_figure(c, field="b")
    labels = " ".join(ax.get_ylabel() for ax in fig.axes)
    plt.close(fig)
    assert "nT" in labels and "K" in labels and "km" in labels


def test_demo_writes_rosetta_inputs(tmp_path):
    # `make demo` simulates the two Rosetta demo days through batch_task.simulate_days
    from fluxcal.runs import registry

    rosetta = registry.get("rosetta")
    days = list(rosetta.demo_days)
    rosetta.load("simulate_days")(tmp_path, days)
    task = make_day_task(tmp_path, tmp_path / "out")
    assert task.options.levels == ("A", "B", "C", "E", "F", "G")
    for day in days:
        # OB, IB, HK, kernels.tm, and the previous day's OB and IB (the vectors their
        # filter shift moves past midnight belong to this day, decision 30)
        previous = day - dt.timedelta(days=1) in days
        assert len(task.inputs(day).files) == 4 + 2 * previous


def test_quicklook_temperatures_of_both_sensors_recover_truth(sim):
    # each science file carries both thermistor words; the quicklook draws both sensors'
    # temperatures.  Forward model: the simulator's temperature profiles (truth files, raw
    # record order).  Tolerance: one thermistor word step (16-bit quantization).
    from fluxcal.geometry.kernels import KernelPool
    from fluxcal.geometry.time import leapseconds
    from fluxcal.missions.rosetta import calib, io, level_a
    from fluxcal.missions.rosetta.products import thermistor_temperatures

    folder = sim / f"{DAYS[0]:%Y%m%d}"
    nominal = calib.load_nominal_conversion()
    cals = {s: calib.load_ground_calibration(s) for s in ("OB", "IB")}
    with KernelPool():
        raw = io.read_science_csv(folder / "science_OB.csv", "OB", lsk=leapseconds())
    temps = thermistor_temperatures(raw, cals, nominal)
    good = read_truth_csv(folder / "truth_OB.csv")["good"]
    for sensor in ("OB", "IB"):
        truth = read_truth_csv(folder / f"truth_{sensor}.csv")["temperature"][good]
        epoch, kelvin = temps[sensor]
        assert epoch.shape == kelvin.shape == truth.shape
        words = raw[f"t_{sensor.lower()}_counts"].values
        grid = level_a.sensor_temperature(np.arange(words.min() - 1, words.max() + 2),
                                          cals[sensor], nominal)
        step = np.abs(np.diff(grid)).max()
        assert step < 0.1  # K: the quantization is fine enough for this to mean something
        assert np.abs(kelvin - truth).max() <= step, (sensor, step)
