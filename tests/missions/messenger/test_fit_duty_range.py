"""Issue 34: the duty-cycle range over which the heater waveforms are determined (D_RANGE).

The fit states ``D_RANGE`` (`fit_waveforms.supported_duty_range`: the contiguous fitted 4-% bins
around the fullest, from the lower edge of the first to the upper edge of the last) in
the heater-signal tables' headers; `load_calibration` reads it back; calibrating
heater-on samples outside it warns with how many and how far (the pipeline extrapolates
the columns there, sec. 6); the predicted error's waveform part holds for the samples
inside it.  Expected values: the rule worked by hand on constructed bin counts, the
simulator's duty-cycle schedule (``conftest.sim_config``: blocks of 40, 36, 0, 0, 0, 25,
8, 44 % ...) with the heater bits counted by brute force from the input file, and the
Mercury-orbit forward model's truth (`tests/missions/messenger/_hard_worlds.py`, duty
cycles 10-45 %).  docs/decisions/messenger_fit.md entry 25.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from fluxcal.cli import main
from fluxcal.errors import CalibrationError
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
from fluxcal.missions.messenger.fit_waveforms import MIN_PHASE_BINS, supported_duty_range
from fluxcal.missions.messenger.fit_write import write_calibration_folder
from fluxcal.missions.messenger.flight_sim import FlightConfig, read_flight_truth, simulate_flight
from tests.missions.messenger._fit_tables import tables_with_header_lines
from tests.missions.messenger._hard_worlds import MercuryOrbit
from tests.missions.messenger._unseen_day import recalibrate_errors

START = "2010-03-01"
CENTRES = np.array([12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 36.0, 40.0])


# ---------------------------------------------------------------------------------------
# the rule (fast)
# ---------------------------------------------------------------------------------------
def _counts(per_bin: list[int], filled: list[int] | None = None) -> np.ndarray:
    """Per bin: ``per_bin[j]`` samples spread over ``filled[j]`` of 100 phase bins."""
    filled = filled or [100] * len(per_bin)
    out = np.zeros((len(per_bin), 100), dtype=int)
    for j, (n, f) in enumerate(zip(per_bin, filled, strict=True)):
        if f:
            out[j, :f] = n // f
    return out


def test_duty_range_is_the_supported_run_around_the_fullest_bin():
    fitted = np.ones((3, 8), dtype=bool)
    # every bin supported: 10..42 % (the lower edge of 12 %'s bin, the upper of 40 %'s)
    assert supported_duty_range(_counts([500] * 8), fitted, CENTRES) == (10.0, 42.0)
    # 12 and 16 % empty, 20..36 % supported, 40 % holding too few phase bins (49 < 50):
    # the run 20..36 % -> 18..38 %
    counts = _counts([0, 0, 400, 800, 900, 700, 300, 200],
                     [0, 0, 100, 100, 100, 100, 100, MIN_PHASE_BINS - 1])
    assert supported_duty_range(counts, fitted, CENTRES) == (18.0, 38.0)
    # a gap at 28 % (column kept on one axis): two runs; the fullest bin (32 %, 2000
    # samples) decides: 32..40 % -> 30..42 %, though the run 12..24 % holds more in all
    counts = _counts([600, 600, 600, 600, 900, 2000, 200, 200])
    gap = fitted.copy()
    gap[1, 4] = False
    assert supported_duty_range(counts, gap, CENTRES) == (30.0, 42.0)
    # a bin with enough phase bins but samples below MIN_BIN_SAMPLES (1 each) is no support
    counts = _counts([200] * 7 + [100])
    assert supported_duty_range(counts, fitted, CENTRES) == (10.0, 38.0)
    # nothing fitted: no range
    assert supported_duty_range(_counts([500] * 8), ~fitted, CENTRES) is None


def _heater_folder(tmp_path, lines: dict[str, str | None]):
    """The packaged tables with a header line added to heater_signal_{axis}."""
    return tables_with_header_lines(
        tmp_path, {f"heater_signal_{axis}_v1.csv": line for axis, line in lines.items()})


def test_d_range_header_round_trip(tmp_path):
    assert load_calibration(START).duty_range is None  # the seed's Tables 6-8 state none
    folder = _heater_folder(tmp_path, {a: "# D_RANGE: 18 38" for a in "xyz"})
    assert load_calibration(START, folder).duty_range == (18.0, 38.0)
    # files of different ranges: the narrowest (their intersection)
    folder = _heater_folder(tmp_path / "b", {"x": "# D_RANGE: 10 42", "y": "# D_RANGE: 14 38",
                                             "z": None})
    assert load_calibration(START, folder).duty_range == (14.0, 38.0)


@pytest.mark.parametrize("text", ["42 10", "40", "a b", "10 inf"])
def test_malformed_d_range_is_one_line_naming_the_file(tmp_path, text):
    folder = _heater_folder(tmp_path, {"y": f"# D_RANGE: {text}"})
    with pytest.raises(CalibrationError, match=r"heater_signal_y_v1\.csv: header field "
                                               r"'D_RANGE' must be two numbers"):
        load_calibration(START, folder)


def test_disjoint_d_ranges_are_refused(tmp_path):
    folder = _heater_folder(tmp_path, {"x": "# D_RANGE: 10 20", "z": "# D_RANGE: 30 42"})
    with pytest.raises(CalibrationError, match=r"heater_signal_z_v1\.csv: header field "
                                               r"'D_RANGE' does not overlap"):
        load_calibration(START, folder)


# ---------------------------------------------------------------------------------------
# the warning, from the command line (the 2-h simulated day of conftest)
# ---------------------------------------------------------------------------------------
def _period_duty_samples(files) -> tuple[np.ndarray, np.ndarray]:
    """Brute force from the input files: per science sample, the duty cycle (percent) of
    the 100-s heater period holding it (on bits counted from each rising edge of the bit
    file; 0 outside any period), by MET."""
    h = np.loadtxt(files["heater"], delimiter=",", skiprows=1)
    met, bits = h[:, 1], h[:, 2].astype(int)
    rise = np.flatnonzero(np.diff(bits) == 1) + 1
    starts = met[rise]
    duty = np.array([bits[(met >= s) & (met < s + 100.0)].sum() for s in starts], dtype=float)
    sci = np.loadtxt(files["science"], delimiter=",", skiprows=1, usecols=(1,))
    k = np.searchsorted(starts, sci, side="right") - 1
    inside = (k >= 0) & (sci < starts[np.maximum(k, 0)] + 100.0)
    return np.where(inside, duty[np.maximum(k, 0)], 0.0), sci


def test_edr2cdr_warns_for_heater_on_samples_outside_d_range(
        tmp_path, simulated_files, messenger_kernels, caplog):
    # D_RANGE 28..42 %: of the schedule's heater-on blocks (40, 36, 25, 44, 30 %) the
    # 25 % block lies 3 % below, the 44 % block 2 % above (its upper edge excluded)
    folder = _heater_folder(tmp_path, {a: "# D_RANGE: 28 42" for a in "xyz"})
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        code = main(["messenger", "edr2cdr", "--sci", str(simulated_files["science"]),
                     "--heater", str(simulated_files["heater"]), "--temperature",
                     str(simulated_files["temperature"]), "--kernels", str(messenger_kernels),
                     "--out", str(out), "--frames", "mso", "--formats", "tab",
                     "--calib", str(folder)])
    assert code == 0
    msgs = [r.getMessage() for r in caplog.records if "D_RANGE" in r.getMessage()]
    assert len(msgs) == 1, msgs  # once per run
    msg = msgs[0]
    duty, _ = _period_duty_samples(simulated_files)
    on = duty >= 10  # the 10-s persistence (sec. 6): the 8 % block carries no signal
    n_out = int(np.count_nonzero(on & ((duty < 28) | (duty >= 42))))
    n_on = int(np.count_nonzero(on))
    assert n_out > 0
    n_warned, n_of = (int(x) for x in msg.split(" heater-on")[0].split(" of "))
    # the pipeline places the samples by their lag-corrected time, the brute force by
    # MET: a period boundary moves by under one second of its 100 (1 %)
    assert n_warned == pytest.approx(n_out, rel=0.01), (msg, n_out)
    assert n_of == pytest.approx(n_on, rel=0.01), (msg, n_on)
    assert ("lie at heater duty cycles outside the range heater_signal_x_v1.csv states "
            "(D_RANGE 28.0..42.0 %, upper edge excluded)") in msg, msg
    assert "down to 25.0 % (3.0 % below) and up to 44.0 % (2.0 % above)" in msg, msg
    assert "extrapolated" in msg
    # the seed's tables state no D_RANGE: nothing said
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert main(["messenger", "edr2cdr", "--sci", str(simulated_files["science"]),
                     "--heater", str(simulated_files["heater"]), "--temperature",
                     str(simulated_files["temperature"]), "--kernels", str(messenger_kernels),
                     "--out", str(tmp_path / "out2"), "--frames", "mso",
                     "--formats", "tab"]) == 0
    assert not [r for r in caplog.records if "D_RANGE" in r.getMessage()]


# ---------------------------------------------------------------------------------------
# the fit in the Mercury orbit (forward model, 2 fitted days, ~30 s): duty cycles to 45 %
# ---------------------------------------------------------------------------------------
def test_fit_states_d_range_and_the_samples_above_it_are_warned_and_left_out(tmp_path,
                                                                           caplog):
    w = MercuryOrbit(3400)
    run = simulate_flight(tmp_path / "sim", FlightConfig(start=START, days=3, seed=3400),
                          wind=w.field, schedule=w.schedule, truth=True)
    res = fit_days(day_chunks(run.input_dir, run.days[:2]), load_calibration(START),
                   estimator="variance", guard=False)
    # the world's duty walk fills every 4-% bin: every column fitted, D_RANGE 10..42 %;
    # its duty cycles reach 45 %, in no bin
    assert res.duty_range == (10.0, 42.0)
    m = res.merit
    assert m["duty_range_pct"] == [10.0, 42.0]
    truth = [read_flight_truth(run.input_dir, d) for d in run.days[:2]]
    d = np.concatenate([t["duty_percent"] for t in truth])
    on = (d >= 10) & (d < 100)
    # the fit counts the heater-on samples of the solar-wind selection it reduces (all
    # here); the truth's, less the first heater period of each block the fit cannot
    # place and the field-estimate edges: within 5 %
    share_true = np.count_nonzero(on & (d >= 42)) / np.count_nonzero(on)
    share_fit = m["samples_outside_duty_range"] / m["heater_on_samples"]
    assert share_true > 0.005  # 1000 samples (one 1000-s block at 42-45 %)
    assert share_fit == pytest.approx(share_true, rel=0.05), (share_fit, share_true)
    # the waveform part holds for the samples inside: each column's stated error
    # weighted by its bin's share of the samples inside T_RANGE and D_RANGE (at the
    # fitted mix); the stated part floors each share at the even one (entry 32)
    count = np.array([wf.count.sum() for wf in res.stats.waveform], dtype=float)
    n_in = m["samples"] - m["samples_outside_duty_range"]
    var = (res.waveform_error ** 2 * count).sum(axis=1) / n_in
    mat = np.asarray(res.calibration.matrices[0])
    np.testing.assert_allclose(m["waveform_fitted_mix_nt"], np.sqrt(mat ** 2 @ var),
                               rtol=1e-9)
    even = np.maximum(count, count.sum() / count.size)  # every bin inside 10..42 %
    var = (res.waveform_error ** 2 * even).sum(axis=1) / n_in
    np.testing.assert_allclose(m["waveform_nt"], np.sqrt(mat ** 2 @ var), rtol=1e-9)
    # the written tables state it, the loader reads it, calibrating warns for them
    out = tmp_path / "fitted"
    write_calibration_folder(res, out, None, {"inputs": {}, "intervals": "all data",
                                              "days": "2", "command": "test"}, study=True)
    for axis in "xyz":
        text = next(out.glob(f"heater_signal_{axis}_v*.csv")).read_text()
        assert "# D_RANGE: 10 42\n" in text
        assert "the predicted error's waveform part holds for the heater-on samples inside "\
               "D_RANGE 10..42 %" in text
    cal = load_calibration(START, out)
    assert cal.duty_range == (10.0, 42.0)
    # each column's stated error and the stated part, read back (4 significant digits)
    np.testing.assert_allclose(cal.waveform_error, res.waveform_error, rtol=1e-3)
    np.testing.assert_allclose(cal.waveform_part_nt, m["waveform_nt"], rtol=1e-3)
    with caplog.at_level(logging.WARNING):
        err, truth3 = recalibrate_errors(run.input_dir, run.days[2], out)
    msg = next(r.getMessage() for r in caplog.records if "D_RANGE" in r.getMessage())
    d3 = truth3["duty_percent"]
    n_out = int(np.count_nonzero((d3 >= 42) & (d3 < 100)))
    assert int(msg.split(" of ")[0]) == pytest.approx(n_out, rel=0.01), (msg, n_out)
    assert f"up to {d3[d3 < 100].max():.1f} %" in msg, msg
    print(f"D_RANGE {res.duty_range}; fitted outside {share_fit:.1%} (truth "
          f"{share_true:.1%}); waveform part {np.round(m['waveform_nt'], 3)} nT; {msg}")

