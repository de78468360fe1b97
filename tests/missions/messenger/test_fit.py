"""``fluxcal messenger fit``: reduction and merge, the fit on known statistics, the CLI.

The fit is checked on statistics built here from closed-form laws (two lines joined at a
break, a line through cT(-50 C), an exponential step response, periodic waveforms) that
share no code with the reduction; the reduction's merge property against one pass over
the concatenated data; the CLI's error lines and ``edr2cdr --calib``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from fluxcal.calibration.binned_stats import BinnedMoments
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit import fit_calibration
from fluxcal.missions.messenger.fit_reduce import (
    DayStatistics,
    FitSettings,
    inside_intervals,
    read_intervals,
    reduce_day,
)

START = "2012-06-01T00:00:00"
#: The training streams below have a zero-mean 0.1-nT field (the demo's): the seed's
#: estimator, selected explicitly since the command's default is ``variance``.
ZERO_MEAN = ("--estimator", "zero-mean")


# ---------------------------------------------------------------------------------------
# the fit on statistics built from closed-form laws
# ---------------------------------------------------------------------------------------
def _two_segment(t, a0, b0, a1, b1):
    return np.maximum(a0 + b0 * t, a1 + b1 * t)  # convex (B1 > B0), as Table 2


def _known_statistics(truth: dict, base, rng) -> DayStatistics:
    """Bin statistics a noise-free sensor with the ``truth`` laws would give.

    Temperature bins hold samples at one temperature each (the bin mean is a point of
    the law) with a decaying duty-cycle offset ``D0 R``; duty bins hold relaxed duty
    cycles R with ``C0 + D0 R`` (C0 = law at -50 C); the epoch holds the normalised
    residual of a model with the base D0 and tau, plus the base's own step in its
    relaxed-duty column; the waveform bins hold periods at the bin centres.
    """
    s = FitSettings()
    coeff, d0 = truth["coeff"], truth["d0"]
    # 1. temperature: 11 temperatures, a small relaxed duty cycle 0..20 ppt
    temps = np.repeat(np.arange(-60.0, 41.0, 10.0), 50)
    r_off = rng.uniform(0.0, 20.0, temps.size)
    law = np.column_stack([_two_segment(temps, *coeff[j]) for j in range(3)])
    vals = law + r_off[:, None] * d0[None, :]
    # (the last column, the relaxed duty cycle's derivative in tau, is zero here: the
    # statistics are those of a model already at the true tau, tested separately below)
    temperature = BinnedMoments.accumulate(
        temps, np.column_stack([vals, temps, r_off, np.zeros_like(r_off)]),
        s.temperature_edges_c)
    # 2. duty: relaxed duty cycles inside the 40-ppt bins
    r_on = np.repeat(np.arange(110.0, 420.0, 40.0), 30) + rng.uniform(0, 20, 240)
    c_ref = np.array([_two_segment(-50.0, *coeff[j]) for j in range(3)])
    duty = BinnedMoments.accumulate(
        r_on, np.column_stack([c_ref[None, :] + r_on[:, None] * d0[None, :], r_on,
                               np.zeros_like(r_on)]),
        s.duty_edges_ppt)
    # 3. epoch: residual of the base model for a lone step, normalised
    lag = np.repeat(np.arange(-197.5, 1000.0, 5.0), 20)
    tau, dt = truth["tau"], truth["dt"]
    b_tau = float(base.constants["relaxation"]["tau_s"])
    b_dt = float(base.constants["relaxation"]["delay_s"])
    g_true = np.where(lag > dt, 1.0 - np.exp(-(lag - dt) / tau), 0.0)
    g_base = np.where(lag > b_dt, 1.0 - np.exp(-(lag - b_dt) / b_tau), 0.0)
    resid = (g_true[:, None] * d0[None, :] - g_base[:, None] * base.duty_cycle_d0[None, :]
             + rng.normal(0.0, 1e-4, (lag.size, 3)))  # spread for the standard errors
    # the base model's relaxed duty cycle of a lone unit step and its derivative in tau
    dg_base = np.where(lag > b_dt, -(lag - b_dt) / b_tau**2 * np.exp(-(lag - b_dt) / b_tau),
                       0.0)
    epoch = BinnedMoments.accumulate(lag, np.column_stack([resid, g_base, dg_base]),
                                     s.lag_edges_s)
    # 4. waveforms: periods at the bin centres (one-hot interpolation weights)
    phase = np.tile(np.arange(0.0, 100.0), 3)
    waveform = []
    for b, pct in enumerate(s.waveform_bins_percent):
        w = truth["waveform"](phase, pct)  # (n, 3)
        onehot = np.zeros((phase.size, 8))
        onehot[:, b] = 1.0
        folded = np.where(phase >= 99.5, phase - 100.0, phase)
        waveform.append(BinnedMoments.accumulate(
            folded, np.column_stack([w + 7.0, folded, onehot]),
            (np.arange(101) - 0.5)))
    # one unit step: the squared-step weights are 1
    weight = BinnedMoments.accumulate(lag, np.ones(lag.size), s.lag_edges_s)
    # the temperatures' distribution: each bin's samples at one temperature
    fine = BinnedMoments.accumulate(temps, temps, s.temperature_fine_edges())
    return DayStatistics(temperature=temperature, duty=duty, epoch=epoch, waveform=waveform,
                         epoch_weight=weight, temperature_fine=fine,
                         n_samples={"events": 40, "used": 1})


def _truth():
    def waveform(t, pct):  # zero-mean periodic shapes, amplitude growing with duty cycle
        k = pct / 40.0
        x = 2 * np.pi * t / 100.0
        return np.column_stack([k * np.sin(x), 2 * k * np.cos(x) + 0.5 * np.sin(2 * x),
                                0.3 * k * np.sin(3 * x)])

    return {"coeff": np.array([[1.0, 1.5, 15.0, 3.2], [-64.0, 2.5, -6.0, 8.3],
                               [444.0, 0.6, 467.0, 2.5]]),
            "d0": np.array([0.23, 0.43, 0.019]), "tau": 1050.0, "dt": 12.0,
            "waveform": waveform}


def test_fit_recovers_closed_form_laws():
    base = load_calibration(START)
    truth = _truth()
    stats = _known_statistics(truth, base, np.random.default_rng(3))
    res = fit_calibration(stats, base)
    cal = res.calibration
    t = np.linspace(-60.0, 40.0, 101)
    for j in range(3):
        fitted = _two_segment(t, *cal.temperature_coefficients[j])
        # noise-free points exactly on two lines: the hinge fit reproduces them, up to
        # the alternation's stopping rule (D0 settled to 1e-6 relative, times <= 20 ppt)
        assert np.max(np.abs(fitted - _two_segment(t, *truth["coeff"][j]))) < 1e-4
    # noise-free line through the held intercept
    np.testing.assert_allclose(cal.duty_cycle_d0, truth["d0"], rtol=1e-5)
    np.testing.assert_allclose(cal.duty_cycle_c0,
                               [_two_segment(-50.0, *truth["coeff"][j]) for j in range(3)],
                               atol=1e-4)
    # epoch noise 1e-4 per sample on a unit step: tau to < 0.5 %, dt to < 0.5 s
    assert res.delay_fitted
    assert abs(cal.constants["relaxation"]["tau_s"] - 1050.0) < 5.0
    assert abs(cal.constants["relaxation"]["delay_s"] - 12.0) < 0.5
    # waveforms: a smoothing spline through 100 exact points of smooth shapes, the +7
    # count level removed by the zero-mean rule
    for b, pct in enumerate(FitSettings().waveform_bins_percent):
        want = truth["waveform"](np.arange(101.0), pct)
        assert np.max(np.abs(cal.heater_signal[:, :, b] - want.T)) < 0.02


def test_unmixing_recovers_columns_from_off_centre_duty_cycles():
    # every period at 13 % or 18 %: bin averages mix columns 12/16 and 16/20 (sec. 6's
    # linear interpolation); solving the weights recovers the columns themselves
    from fluxcal.missions.messenger.fit_reduce import interpolation_weights
    from fluxcal.missions.messenger.fit_waveforms import unmix_waveforms

    s = FitSettings()
    # the weights themselves, by hand: linear between the 4-% bins, the edge slopes
    # extended outside 12..40 % (sec. 6)
    want = np.zeros((4, 8))
    want[0, :2] = [0.75, 0.25]  # 13 %
    want[1, 1:3] = [0.5, 0.5]  # 18 %
    want[2, :2] = [1.5, -0.5]  # 10 %
    want[3, 6:] = [-0.5, 1.5]  # 42 %
    np.testing.assert_allclose(interpolation_weights(
        np.array([13.0, 18.0, 10.0, 42.0]), np.asarray(s.waveform_bins_percent)), want,
        rtol=0, atol=1e-12)
    cols = {12.0: 1.0, 16.0: -2.0, 20.0: 0.5}  # per-column constant waveform (counts)
    phase = np.tile(np.arange(0.0, 100.0), 2)
    waveform = [BinnedMoments.empty(np.arange(101) - 0.5, 12) for _ in range(8)]
    for pct_list, b in (([13.0, 12.0], 0), ([15.0, 17.0], 1), ([18.0, 20.0], 2)):
        parts = []
        for pct in pct_list:
            w = interpolation_weights(np.full(phase.size, pct), np.asarray(
                s.waveform_bins_percent))
            value = sum(w[:, k] * v for k, v in enumerate(cols.values()))
            parts.append(np.column_stack([np.repeat(value[:, None], 3, 1), phase, w]))
        data = np.concatenate(parts)
        waveform[b] = BinnedMoments.accumulate(data[:, 3], data, np.arange(101) - 0.5)
    stats = DayStatistics.empty(s)
    stats.waveform = waveform
    _, columns, _ = unmix_waveforms(stats)
    for k, v in enumerate(cols.values()):
        np.testing.assert_allclose(columns[:, k, 0], v, atol=1e-9)


def test_fit_errors_name_what_is_missing():
    base = load_calibration(START)
    stats = _known_statistics(_truth(), base, np.random.default_rng(0))
    few = DayStatistics(
        temperature=BinnedMoments.accumulate(
            np.array([-50.0, -50.0, -40.0, -40.0]), np.zeros((4, 6)),
            FitSettings().temperature_edges_c),
        duty=stats.duty, epoch=stats.epoch, waveform=stats.waveform,
        epoch_weight=stats.epoch_weight, n_samples=stats.n_samples)
    with pytest.raises(FluxcalError, match=r"temperature law.*only 2 .*empty bins \(C\): "
                                           r"-100.*-30"):
        fit_calibration(few, base)
    stats.n_samples = {"events": 2}
    with pytest.raises(FluxcalError, match=r"relaxation time.*2 duty-cycle change"):
        fit_calibration(stats, base)


# ---------------------------------------------------------------------------------------
# reduction: merge == one pass; intervals
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def reduced(simulated, messenger_kernels, calibration):
    with KernelPool(messenger_kernels):
        sclk = SclkKernel.from_pool(-236)
        sci = simulated["science"]
        n = sci.sizes["time"]
        whole = reduce_day(sci, simulated["heater"], simulated["temperature"], sclk,
                           calibration)
        halves = [reduce_day(sci.isel(time=part), simulated["heater"],
                             simulated["temperature"], sclk, calibration, label=str(k))
                  for k, part in enumerate((slice(0, n // 3), slice(n // 3, None)))]
    return whole, halves


def _moments(stats: DayStatistics):
    yield stats.temperature
    yield stats.temperature_fine
    yield stats.duty
    yield stats.epoch
    yield stats.epoch_weight
    yield from stats.waveform


def test_merged_halves_equal_one_pass(reduced):
    whole, (a, b) = reduced
    merged = DayStatistics.empty().merge(a).merge(b)
    assert merged.days == ["0", "1"]
    for k in ("total", "used", "coarse", "events"):
        if k != "events":  # the epoch counts events per reduction (both halves see them)
            assert merged.n_samples[k] == whole.n_samples[k]
    for m, w in zip(_moments(merged), _moments(whole), strict=True):
        np.testing.assert_array_equal(m.count, w.count)
        filled = w.count > 1
        # float64 sums of a few 1e5 values, re-expressed about another shift
        np.testing.assert_allclose(m.mean()[filled], w.mean()[filled], rtol=0, atol=1e-8)
        np.testing.assert_allclose(m.variance()[filled], w.variance()[filled], rtol=1e-7,
                                   atol=1e-8)
    assert whole.n_samples["used"] > 0 and whole.temperature.count.sum() > 0
    assert whole.duty.count.sum() > 0 and whole.epoch.count.sum() > 0


def test_temperature_sub_bins_hold_the_temperature_law_samples(reduced):
    # the 0.25-C sub-bins nest in the 10-C bins and hold the same samples; their mean
    # temperatures lie inside them and average to the bins' mean temperatures
    whole, _ = reduced
    t, f = whole.temperature, whole.temperature_fine
    assert np.all(np.isin(t.edges, f.edges)) and np.allclose(np.diff(f.edges), 0.25)
    owner = np.digitize(f.centers, t.edges) - 1
    np.testing.assert_array_equal(np.bincount(owner, f.count, t.n_bins).astype(int), t.count)
    used = f.count > 0
    m = f.mean()[used, 0]
    assert np.all((m >= f.edges[:-1][used]) & (m < f.edges[1:][used]))
    back = np.bincount(owner[used], m * f.count[used], t.n_bins)
    filled = t.count > 0
    np.testing.assert_allclose(back[filled] / t.count[filled], t.mean()[filled, 3],
                               rtol=0, atol=1e-9)
    assert t.count.sum() > 0


def test_fit_refuses_an_unknown_temperature_law_and_a_missing_distribution():
    base = load_calibration(START)
    stats = _known_statistics(_truth(), base, np.random.default_rng(1))
    with pytest.raises(FluxcalError, match="temperature_law must be one of"):
        fit_calibration(stats, base, temperature_law="median")
    stats.temperature_fine = BinnedMoments.empty(FitSettings().temperature_fine_edges(), 1)
    with pytest.raises(FluxcalError, match="sub-bins hold 0 samples.*binned-mean"):
        fit_calibration(stats, base)
    # the seed's estimator needs no distribution: noise-free points on the law, exact
    res = fit_calibration(stats, base, temperature_law="binned-mean")
    t = np.linspace(-60.0, 40.0, 101)
    for j in range(3):
        np.testing.assert_allclose(
            _two_segment(t, *res.calibration.temperature_coefficients[j]),
            _two_segment(t, *_truth()["coeff"][j]), rtol=0, atol=1e-4)


def test_coarse_and_interval_selection(simulated, messenger_kernels, calibration):
    truth = simulated["truth"]
    et = truth["et"].values  # the forward model's true times (no pipeline code)
    fine = truth["range"].values == 0
    a, b = et[0] + 600.0, et[0] + 2400.0
    with KernelPool(messenger_kernels):
        stats = reduce_day(simulated["science"], simulated["heater"],
                           simulated["temperature"], SclkKernel.from_pool(-236), calibration,
                           np.array([[a, b]]))
    assert stats.n_samples["coarse"] == int((~fine).sum())
    # the pipeline's corrected times equal the true ones to far below a sample spacing
    assert stats.n_samples["used"] == int((fine & (et >= a) & (et < b)).sum())


def test_inside_intervals_overlapping_and_unsorted():
    t = np.arange(0.0, 100.0, 0.5)
    iv = np.array([[50.0, 60.0], [10.0, 20.0], [15.0, 30.0]])
    want = np.zeros(t.size, dtype=bool)
    for lo, hi in iv:  # a loop over three intervals
        want |= (t >= lo) & (t < hi)
    np.testing.assert_array_equal(inside_intervals(t, iv), want)
    assert inside_intervals(t, None).all()


def test_read_intervals_errors(tmp_path):
    p = tmp_path / "iv.csv"
    p.write_text("start,stop\n2012-06-01T00:00:00,2012-06-01T01:00:00\n"
                 "2012-06-01T03:00:00,2012-06-01T02:00:00\n")
    with pytest.raises(InputFormatError, match=r"iv.csv, line 3, field 'stop': stop .* lies "
                                               r"before start"):
        read_intervals(p)
    p.write_text("2012-06-01T00:00:00,yesterday\n")
    with pytest.raises(InputFormatError, match=r"line 1, field 'stop'"):
        read_intervals(p)
    p.write_text("# only a comment\n")
    with pytest.raises(InputFormatError, match="no interval"):
        read_intervals(p)
    p.write_text("2012-06-01T00:00:00,2012-06-01T01:00:00\n")
    iv = read_intervals(p)
    assert iv.shape == (1, 2) and iv[0, 1] - iv[0, 0] == np.timedelta64(3600, "s")


def test_statistics_round_trip_through_datasets(reduced):
    whole, _ = reduced
    for name, ds in whole.to_datasets().items():
        back = BinnedMoments.from_dataset(ds)
        orig = getattr(whole, name) if not name.startswith("waveform_") else whole.waveform[
            FitSettings().waveform_bins_percent.index(float(name.split("_")[1]))]
        np.testing.assert_array_equal(back.count, orig.count)


# ---------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def training(tmp_path_factory):
    """6 h at 1 Hz, zero-mean field, heater 0-40 % every 1000 s (the demo's schedule)."""
    from fluxcal.missions.messenger.fit_demo import perturbed_folder, simulate_training

    out = tmp_path_factory.mktemp("fit_training")
    return simulate_training(out, perturbed_folder(out / "truth"), START, 0.25, field="quiet",
                             sigma_nt=0.1)


def _stream_args(files, kernels=None):
    return ["--sci", str(files["science"]), "--heater", str(files["heater"]),
            "--temperature", str(files["temperature"]),
            "--kernels", str(kernels or files["kernels"])]


def test_cli_fit_then_edr2cdr_calib(tmp_path, training, simulated_files, messenger_kernels,
                                    capsys):
    from fluxcal.cli import main

    fitted = tmp_path / "fitted"
    # default passes: a fit stops on convergence or refuses (issue 34)
    rc = main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN, "--out", str(fitted)])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert "wrote 10 files" in out.out
    # the --input files are one reduction, whatever days they span (entry 62: "days: 1")
    assert "\ndays: the --input files, one reduction\n" in out.out
    names = sorted(p.name for p in fitted.iterdir())
    assert "offsets_temperature_v2.csv" in names and "processing_v2.toml" in names
    cal = load_calibration(START, fitted)
    assert {n for n, _ in cal.files} >= {"offsets_temperature_v2.csv", "heater_signal_y_v2.csv",
                                         "offsets_duty_cycle_v2.csv", "processing_v2.toml"}
    header = (fitted / "offsets_duty_cycle_v2.csv").read_text()
    assert "# source: fitted by fluxcal messenger fit" in header
    assert "estimator: distribution" in (fitted / "offsets_temperature_v2.csv").read_text()
    assert f"# input: {training['science'].name} sha256=" in header
    # the fitted tables name their inputs by file name: no folder of this machine (issue 25)
    folders = {str(training["science"].parent).encode(), str(tmp_path).encode()}
    assert not [p.name for p in fitted.iterdir() for f in folders if f in p.read_bytes()]
    products = tmp_path / "products"
    rc = main(["messenger", "edr2cdr", *_stream_args(simulated_files, messenger_kernels),
               "--out", str(products), "--formats", "tab", "--average", "",
               "--frames", "mso", "--max-offset-step", "0", "--calib", str(fitted)])
    out = capsys.readouterr()
    assert rc == 0, out.err
    labels = list(products.glob("*.LBL")) + list(products.glob("**/*.LBL"))
    assert labels
    text = labels[0].read_text()
    assert "offsets_temperature_v2.csv" in text and "heater_signal_z_v2.csv" in text


def test_cli_fit_error_lines(tmp_path, training, simulated_files, messenger_kernels, capsys):
    from fluxcal.cli import main

    iv = tmp_path / "iv.csv"
    iv.write_text("start,stop\n2012-06-01T01:00:00,2012-06-01T00:00:00\n")
    rc = main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
               "--intervals", str(iv), "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "iv.csv, line 2, field 'stop'" in err
    # the first 10 minutes hold heater-on data only (36 %): no temperature law
    iv.write_text("2012-06-01T00:00:00,2012-06-01T00:10:00\n")
    rc = main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
               "--intervals", str(iv), "--out", str(tmp_path / "b")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "temperature law" in err and "empty bins" in err
    assert not (tmp_path / "b").exists() or not any((tmp_path / "b").iterdir())
    # --calib without the tables
    (tmp_path / "empty").mkdir()
    rc = main(["messenger", "edr2cdr", *_stream_args(simulated_files, messenger_kernels),
               "--out", str(tmp_path / "c"), "--calib", str(tmp_path / "empty")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "--calib lacks the table(s) latency" in err
    # an unknown temperature-law estimator
    rc = main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
               "--temperature-law", "median", "--out", str(tmp_path / "e")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and ("'--temperature-law': 'median': choose one of distribution, "
                        "binned-mean") in err
    # both input styles
    rc = main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
               "--input-dir", str(tmp_path), "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "either --input-dir or --input" in err


def test_fit_report_toml_is_readable(tmp_path, training, capsys):
    import tomllib

    from fluxcal.cli import main

    fitted = tmp_path / "fitted"
    # one pass cannot show convergence: refused in one line, nothing written (issue 34)
    assert main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
                 "--out", str(fitted), "--passes", "1", "--hold-delay"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fluxcal: error: not converged after 1 passes: the last changed "
                          "tau ") and len(err.splitlines()) == 1, err
    assert not fitted.exists() or not any(fitted.iterdir())
    assert main(["messenger", "fit", *_stream_args(training), *ZERO_MEAN,
                 "--out", str(fitted), "--hold-delay"]) == 0
    capsys.readouterr()
    report = tomllib.loads((fitted / "fit_report.toml").read_text())
    assert report["relaxation"]["delay_fitted"] is False
    assert report["relaxation"]["delay_s"] == 10.0
    assert set(report["inputs"]) == {p.name for k, p in training.items()
                                     if k in ("science", "heater", "temperature")}
    assert json.dumps(report["temperature"]["x"]["A0"])  # a number
    conv = report["convergence"]
    n = conv["passes_run"]
    ratio = report["passes"][f"pass_{n}"]["changes"]["ratio"]
    assert conv["converged"] and ratio <= 1.0 and conv["stop"] == (
        f"converged after {n} passes: the last changed every parameter by at most "
        f"{ratio:.2g} of its allowance")


def test_cli_fit_refuses_an_edr_batch_folder(tmp_path, capsys):
    """An --input-dir of archived EDRs (edr_mapping.toml) is refused in one line, exit 2."""
    from fluxcal.cli import main
    from fluxcal.missions.messenger.routes import EDR_MAPPING

    (tmp_path / EDR_MAPPING).write_text("# mapping\n")
    for days in ([], ["--days", "2010-03-01"]):
        rc = main(["messenger", "fit", "--input-dir", str(tmp_path), *days,
                   "--out", str(tmp_path / "fitted")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and EDR_MAPPING in err[0], err
        assert not (tmp_path / "fitted").exists()


def test_cli_fit_default_is_the_variance_estimator(tmp_path, training, capsys):
    """Without --estimator the command minimises the variance of |B| (issue 21, item 4).

    The training streams hold a 0.1-nT zero-mean field: no interval rotates enough for
    the variance estimator; the abort names it, counts the rejections by reason and
    points to the zero-mean estimator, and nothing is written.
    """
    from fluxcal.cli import main

    rc = main(["messenger", "fit", *_stream_args(training), "--out", str(tmp_path / "v")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "variance estimator" in err and "--estimator zero-mean" in err, err
    assert "passes the selection (rejected: {" in err, err
    assert not (tmp_path / "v").exists() or not any((tmp_path / "v").iterdir())
