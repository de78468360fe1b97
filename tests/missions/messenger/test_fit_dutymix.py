"""Issue 34: the waveform part of a predicted error follows the duty-cycle mix of the day.

The heater waveforms' error a day carries is its columns' stated errors weighted by that
day's own heater-on samples per duty bin (`heater_error.waveform_part`); the fit's own
stated prediction floors each column's share at the even share over D_RANGE (a day to
be recalibrated has another mix); the heater-signal headers state each column's error
(``WAVEFORM_ERROR``) and the stated part (``WAVEFORM_PART_NT``), and calibrating a day
whose own mix puts its predicted error above the goal, or above the stated one by more
than the stated part's scatter, warns (entry 36).  Expected values: sums over the
samples written out here (brute force), a Monte Carlo of column errors, sec. 6's 4-%
bins worked by hand, the simulator's heater bits counted from the input file
(`test_fit_duty_range._period_duty_samples`), and the rule worked by hand on that
brute-force part.  docs/decisions/messenger_fit.md entries 32 and 36.
"""

from __future__ import annotations

import logging
import re
from types import SimpleNamespace

import numpy as np
import pytest

from fluxcal.calibration.heater_error import duty_bin_counts, duty_bin_index, waveform_part
from fluxcal.cli import main
from fluxcal.errors import CalibrationError
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit_merit import DaySamples, predicted_error
from fluxcal.missions.messenger.fit_variance import MOMENT_COLUMNS, MOMENT_EDGES_C
from tests.missions.messenger.test_fit_duty_range import _heater_folder, _period_duty_samples

START = "2010-03-01"
CENTRES = np.array([12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 36.0, 40.0])


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(START)


def _brute_part(err, bin_of_sample, m):
    """Mean over the samples of sum_j M_ij^2 err_j(bin)^2 (heater off: bin -1, zero)."""
    sq = np.zeros(3)
    for b in bin_of_sample:
        if b < 0:
            continue
        for i in range(3):
            for j in range(3):
                sq[i] += m[i, j] ** 2 * err[j, b] ** 2
    return np.sqrt(sq / len(bin_of_sample))


def test_duty_bins_are_the_4_percent_bins_of_sec_6():
    # bin k holds c_k - 2 <= d < c_k + 2: 10..14 % is the 12-% column's, 42 % is in none
    d = np.array([9.99, 10.0, 13.99, 14.0, 22.0, 39.0, 41.99, 42.0, 45.0, np.nan, -1.0])
    np.testing.assert_array_equal(duty_bin_index(d, CENTRES),
                                  [-1, 0, 0, 1, 3, 7, 7, -1, -1, -1, -1])
    counts, beyond = duty_bin_counts(d, CENTRES)
    np.testing.assert_array_equal(counts, [2, 1, 0, 1, 0, 0, 0, 2])
    assert beyond == 5


def test_waveform_part_is_the_mean_over_the_samples(shipped):
    rng = np.random.default_rng(3)
    err = rng.uniform(0.5, 6.0, (3, 8))
    b = rng.integers(-1, 8, 700)  # a seventh of the samples heater-off
    m = np.asarray(shipped.matrices[0])
    got = waveform_part(err, np.bincount(b[b >= 0], minlength=8), b.size, m)
    np.testing.assert_allclose(got, _brute_part(err, b, m), rtol=1e-12)
    # and what it means: columns drawn with those errors (independent, 100 phases), the
    # field error M e at each sample's phase and column, mean square over samples and
    # draws; 400 draws of 700 samples: about 2 % statistical error on the mean square
    phase = rng.integers(0, 100, b.size)
    on = b >= 0
    ms = np.zeros(3)
    draws = 400
    for _ in range(draws):
        e = rng.normal(size=(3, 100, 8)) * err[:, None, :]
        f = np.zeros((b.size, 3))
        f[on] = e[:, phase[on], b[on]].T @ m.T
        ms += (f ** 2).mean(axis=0)
    np.testing.assert_allclose(np.sqrt(ms / draws), got, rtol=0.03)


def _moments(n: int) -> np.ndarray:
    """Offset moments of ``n`` samples at -50 C, heater relaxed to zero (R = 0)."""
    mom = np.zeros((MOMENT_EDGES_C.size - 1, len(MOMENT_COLUMNS)))
    k = int(np.searchsorted(MOMENT_EDGES_C, -49.5, side="right") - 1)
    mom[k, 0], mom[k, 1] = n, -49.5 * n
    return mom


def _result(shipped, fitted_counts, beyond, err, d_range):
    """A fitted result's stand-in: what `predicted_error` reads (no bootstrap: the
    waveform part and the counts only)."""
    stats = SimpleNamespace(waveform=[SimpleNamespace(count=np.array([c / 2, c / 2]))
                                      for c in fitted_counts],
                            n_samples={"heater_on_beyond_bins": beyond})
    return SimpleNamespace(bootstrap=None, calibration=shipped, waveform_error=err,
                           stats=stats, duty_range=d_range,
                           variance=SimpleNamespace(offset_moments=_moments(40000 * 4)))


def test_a_day_is_predicted_with_its_own_duty_counts(shipped):
    # four fitted days (160 000 samples) and one day to recalibrate (40 000 samples)
    # whose heater-on time lies mostly in the 16-% and 20-% columns; D_RANGE 14..42 %:
    # the 12-% column and the samples in no bin lie outside
    err = np.tile([9.0, 8.0, 6.0, 3.0, 2.5, 2.0, 2.0, 1.5], (3, 1)) * [[1.0], [1.2], [0.8]]
    fitted = np.array([4000, 4000, 8000, 24000, 24000, 24000, 24000, 24000], dtype=float)
    res = _result(shipped, fitted, 3000, err, (14.0, 42.0))
    day_counts = np.array([2000, 9000, 8000, 2000, 1000, 0, 0, 0], dtype=float)
    day = DaySamples(moments=_moments(40000), duty_counts=day_counts, beyond_bins=500)
    got = predicted_error(res, day=day)
    # brute force: the day's samples one by one, those outside D_RANGE left out
    n_left = 40000 - 2000 - 500
    bins = np.concatenate([np.full(int(c), k) for k, c in enumerate(day_counts) if k > 0]
                          + [np.full(n_left - int(day_counts[1:].sum()), -1)])
    m = np.asarray(shipped.matrices[0])
    np.testing.assert_allclose(got["waveform_nt"], _brute_part(err, bins, m), rtol=1e-9)
    assert got["samples_outside_duty_range"] == 2500
    assert got["heater_on_samples"] == 22500


def test_one_day_of_the_fitted_mix_is_predicted_as_the_fitted_days(shipped):
    # four fitted days (160 000 samples) and one day of the same mix at a quarter of
    # the counts: the same share per sample, hence the fitted days' own-mix part (the
    # fault fixed: the fitted days' counts over the one day's samples, 4x the shares,
    # gave twice the rms)
    err = np.tile([9.0, 8.0, 6.0, 3.0, 2.5, 2.0, 2.0, 1.5], (3, 1)) * [[1.0], [1.2], [0.8]]
    fitted = np.array([4000, 4000, 8000, 24000, 24000, 24000, 24000, 24000], dtype=float)
    res = _result(shipped, fitted, 3000, err, (14.0, 42.0))
    day = DaySamples(moments=_moments(40000), duty_counts=fitted / 4, beyond_bins=750)
    got = predicted_error(res, day=day)
    m = np.asarray(shipped.matrices[0])
    inside = np.where(CENTRES > 14.0, fitted, 0.0)
    own = np.sqrt(m ** 2 @ (err ** 2 * inside / (160000 - 7000)).sum(axis=1))
    np.testing.assert_allclose(got["waveform_nt"], own, rtol=1e-9)
    np.testing.assert_allclose(predicted_error(res)["waveform_fitted_mix_nt"], own,
                               rtol=1e-9)
    four = np.sqrt(m ** 2 @ (err ** 2 * inside / (40000 - 1750)).sum(axis=1))
    np.testing.assert_allclose(four, 2.0 * own, rtol=1e-9)  # what the fault gave


def test_the_fitted_days_prediction_floors_each_share_at_the_even_one(shipped):
    err = np.tile([9.0, 8.0, 6.0, 3.0, 2.5, 2.0, 2.0, 1.5], (3, 1))
    fitted = np.array([4000, 1000, 2000, 24000, 24000, 24000, 24000, 24000], dtype=float)
    res = _result(shipped, fitted, 3000, err, (14.0, 42.0))
    got = predicted_error(res)
    m = np.asarray(shipped.matrices[0])
    # inside D_RANGE: 7 bins, 123 000 heater-on samples, the even share 123000 / 7 each;
    # the 16-% and 20-% columns rise to it, the others keep their own
    n_in = 123000.0
    floored = np.array([0, n_in / 7, n_in / 7, 24000, 24000, 24000, 24000, 24000])
    n = 160000 - 4000 - 3000
    var = (err ** 2 * floored / n).sum(axis=1)
    np.testing.assert_allclose(got["waveform_nt"], np.sqrt(m ** 2 @ var), rtol=1e-9)
    var_fit = (err ** 2 * np.where(CENTRES > 14, fitted, 0) / n).sum(axis=1)
    np.testing.assert_allclose(got["waveform_fitted_mix_nt"], np.sqrt(m ** 2 @ var_fit),
                               rtol=1e-9)
    assert np.all(np.asarray(got["waveform_nt"]) > np.asarray(got["waveform_fitted_mix_nt"]))


# ---------------------------------------------------------------------------------------
# the headers: written by the fit (test_fit_duty_range's Mercury fit), read back here
# ---------------------------------------------------------------------------------------
def _error_line(values) -> str:
    return "# WAVEFORM_ERROR: " + " ".join(f"{v:g}" for v in values)


def test_waveform_error_header_round_trip(tmp_path):
    cal = load_calibration(START)  # the seed's Tables 6-8 state neither
    assert cal.waveform_error is None and cal.waveform_part_nt is None
    err = np.arange(24, dtype=float).reshape(3, 8) / 4.0
    lines = {a: _error_line(err[j]) for j, a in enumerate("xyz")}
    folder = _heater_folder(tmp_path, lines)
    np.testing.assert_array_equal(load_calibration(START, folder).waveform_error, err)
    # one file without it: no column errors (the day's part is not computed)
    folder = _heater_folder(tmp_path / "b", {**lines, "z": None})
    assert load_calibration(START, folder).waveform_error is None
    # the stated part: the least per axis over the files stating it
    folder = _heater_folder(tmp_path / "c", {"x": "# WAVEFORM_PART_NT: 0.1 0.05 0.2",
                                             "y": "# WAVEFORM_PART_NT: 0.08 0.06 0.2"})
    np.testing.assert_array_equal(load_calibration(START, folder).waveform_part_nt,
                                  [0.08, 0.05, 0.2])


@pytest.mark.parametrize("line", ["# WAVEFORM_ERROR: 1 2 3", "# WAVEFORM_ERROR: 1 2 3 4 5 6 7 x",
                                  "# WAVEFORM_ERROR: 1 2 3 4 5 6 7 -1",
                                  "# WAVEFORM_PART_NT: 0.1 nan 0.1"])
def test_malformed_waveform_errors_are_one_line_naming_the_file(tmp_path, line):
    folder = _heater_folder(tmp_path, {"y": line})
    key = line[2:].split(":")[0]
    with pytest.raises(CalibrationError, match=rf"heater_signal_y_v1\.csv: header field "
                                               rf"'{key}' must be \d finite non-negative"):
        load_calibration(START, folder)


# ---------------------------------------------------------------------------------------
# calibrating a day whose own mix weighs the columns more (the simulated 2-h day)
# ---------------------------------------------------------------------------------------
def _edr2cdr(files, kernels, out, folder) -> int:
    return main(["messenger", "edr2cdr", "--sci", str(files["science"]), "--heater",
                 str(files["heater"]), "--temperature", str(files["temperature"]),
                 "--kernels", str(kernels), "--out", str(out), "--frames", "mso",
                 "--formats", "tab", "--calib", str(folder)])


def _brute_day_part(files, err) -> tuple[np.ndarray, np.ndarray]:
    """The day's waveform part by brute force from the input files: each fine-range
    sample's period duty cycle (bits counted), the 10-s persistence (sec. 6), sec. 6's
    bins; the samples in no bin left out of the denominator (they lie outside every
    D_RANGE)."""
    duty, _ = _period_duty_samples(files)
    rng_flag = np.loadtxt(files["science"], delimiter=",", skiprows=1, usecols=(3,))
    fine = rng_flag == 0
    on = fine & (duty >= 10)
    b = np.where(on, np.floor((duty - 10.0) / 4.0), -1).astype(int)
    beyond = on & ((b < 0) | (b > 7))
    b = np.where(beyond, -1, b)[fine & ~beyond]
    return _brute_part(err, b, np.asarray(load_calibration(START).matrices[0])), b


def _fit_folder(tmp_path, err, stated, total=None, goal=None):
    """Packaged tables whose heater files state ``err`` and the part ``stated`` (nT), and
    whose processing file states the predicted error ``total`` and the goal (``[fit]``,
    as `fit_write` writes them; None: no such table, an older fit's form)."""
    part = " ".join(repr(float(v)) for v in stated)
    folder = _heater_folder(tmp_path, {a: _error_line(err[j]) + f"\n# WAVEFORM_PART_NT: {part}"
                                       for j, a in enumerate("xyz")})
    if total is not None:
        p = folder / "processing_v1.toml"
        p.write_text(p.read_text() + "\n[fit]\npredicted_error_nt = ["
                     + ", ".join(repr(float(v)) for v in total) + f"]\nerror_goal_nt = {goal!r}\n")
    return folder


def _numbers(pattern: str, msg: str) -> np.ndarray:
    return np.array([float(v) for v in re.search(pattern, msg).groups()])


#: The day's blocks: 40, 36, 25, 30 % (44 % in no bin, 8 % not applied).  Columns: 1
#: count everywhere but the 24-% column (25 % lies in it), 20 counts.
_ERR = np.where(np.arange(8) == 3, 20.0, 1.0)[None, :].repeat(3, axis=0)
_NUM3 = r"([\d.]+) / ([\d.]+) / ([\d.]+)"


def test_calibrate_warns_when_the_days_mix_gives_more_than_stated(
        tmp_path, simulated_files, messenger_kernels, caplog):
    # a table stating its waveform part (0.05 nT) but no predicted error or goal (no
    # [fit]): the part stands for the total and no goal is stated, so the day warns when
    # its part exceeds 0.05 by more than the part's scatter 0.05 / sqrt(6) = 0.0204
    expected, b = _brute_day_part(simulated_files, _ERR)
    assert np.all(expected > 0.05 + 0.05 / np.sqrt(6.0))  # the rule worked by hand
    folder = _fit_folder(tmp_path, _ERR, [0.05] * 3)
    with caplog.at_level(logging.WARNING):
        assert _edr2cdr(simulated_files, messenger_kernels, tmp_path / "out", folder) == 0
    msgs = [r.getMessage() for r in caplog.records if "WAVEFORM_PART_NT" in r.getMessage()]
    assert len(msgs) == 1, msgs
    got = _numbers(r"is " + _NUM3 + " nT", msgs[0])
    # period boundaries by lag-corrected time against MET (under 1 %), printed to 0.001
    np.testing.assert_allclose(got, expected, rtol=0.02, atol=0.001)
    assert ("against the 0.050 / 0.050 / 0.050 nT +- 0.020 / 0.020 / 0.020 "
            "heater_signal_x_v1.csv states") in msgs[0], msgs[0]
    # with no other part stated the day's total is its part
    np.testing.assert_allclose(_numbers(r"predicted error is " + _NUM3, msgs[0]), got)
    assert "no goal stated, beyond the table's by more than the part's scatter" in msgs[0]
    fullest = CENTRES[np.argmax(np.bincount(b[b >= 0], minlength=8))]
    assert f"most at the {fullest:g}-% column" in msgs[0], msgs[0]
    # a table stating more than the day gives: nothing said
    folder = _fit_folder(tmp_path / "b", _ERR, [2.0] * 3)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert _edr2cdr(simulated_files, messenger_kernels, tmp_path / "out2", folder) == 0
    assert not [r for r in caplog.records if "WAVEFORM_PART_NT" in r.getMessage()]


@pytest.mark.parametrize(("case", "ratio"), [("within", 1.15), ("goal", 1.10),
                                             ("scatter", 1.6)])
def test_calibrate_judges_the_days_total_against_the_goal_and_the_scatter(
        tmp_path, simulated_files, messenger_kernels, caplog, case, ratio):
    # a fitted table's [fit] numbers around the day's brute-force part W_d: the stated
    # part W_s = W_d / ratio, the rest of the stated total a tenth of it (T = W_s
    # sqrt(1.01)).  "within": 1.15x (the 16-day runs reached 1.18x), goal 1 nT: the day's
    # total is at most 0.16 W_s above T, inside the scatter 0.41 W_s: silent.
    # "goal": 1.10x, the goal 0.95 of the day's largest total (above every T): warns,
    # above the goal.  "scatter": 1.6x, goal 1 nT: 0.6 W_s above T: warns.
    expected, _ = _brute_day_part(simulated_files, _ERR)
    stated = expected / ratio
    total = stated * np.sqrt(1.01)
    day_total = np.sqrt(total ** 2 - stated ** 2 + expected ** 2)   # the rule by hand
    goal = 0.95 * float(day_total.max()) if case == "goal" else 1.0
    assert np.all(total < goal)
    over_goal = day_total > goal
    beyond = day_total - total > stated / np.sqrt(6.0)
    assert (over_goal | beyond).any() == (case != "within")
    folder = _fit_folder(tmp_path, _ERR, stated, total, goal)
    with caplog.at_level(logging.WARNING):
        assert _edr2cdr(simulated_files, messenger_kernels, tmp_path / "out", folder) == 0
    msgs = [r.getMessage() for r in caplog.records if "WAVEFORM_PART_NT" in r.getMessage()]
    if case == "within":
        assert not msgs, msgs
        return
    assert len(msgs) == 1, msgs
    msg = msgs[0]
    # the one line: the day's part, the stated part and its scatter, the day's total,
    # the stated total and the goal (nT)
    np.testing.assert_allclose(_numbers(r"is " + _NUM3 + " nT", msg), expected, rtol=0.02,
                               atol=0.001)
    np.testing.assert_allclose(_numbers(r"against the " + _NUM3 + " nT", msg), stated,
                               atol=5e-4)
    np.testing.assert_allclose(_numbers(r"nT \+- " + _NUM3, msg), stated / np.sqrt(6.0),
                               atol=5e-4)
    np.testing.assert_allclose(_numbers(r"predicted error is " + _NUM3, msg), day_total,
                               rtol=0.02, atol=0.001)
    np.testing.assert_allclose(_numbers(r"against the table's " + _NUM3, msg), total,
                               atol=5e-4)
    assert f"its goal {goal:g} nT" in msg, msg
    if case == "goal":
        assert over_goal.any() and not beyond.any()
        assert msg.endswith("above the goal (sec. 6)"), msg
    else:
        assert beyond.all() and not over_goal.any()
        assert msg.endswith("beyond the table's by more than the part's scatter (sec. 6)"), msg


@pytest.mark.parametrize("field, text", [
    ("predicted_error_nt", 'predicted_error_nt = [0.05, "x", 0.05]\nerror_goal_nt = 0.1'),
    ("predicted_error_nt", "predicted_error_nt = [0.05, 0.05]\nerror_goal_nt = 0.1"),
    ("error_goal_nt", "predicted_error_nt = [0.05, 0.05, 0.05]\nerror_goal_nt = -1.0"),
])
def test_a_malformed_fit_section_is_refused_naming_file_and_field(
        tmp_path, simulated_files, messenger_kernels, capsys, field, text):
    # the warning's numbers come from the processing file's [fit]; a hand-edited, broken
    # value must not quietly turn the warning into the no-[fit] rule: exit 2, one line
    # naming the file and the field, nothing written
    folder = _fit_folder(tmp_path, _ERR, [0.05] * 3)
    p = folder / "processing_v1.toml"
    p.write_text(p.read_text() + "\n[fit]\n" + text + "\n")
    out = tmp_path / "out"
    assert _edr2cdr(simulated_files, messenger_kernels, out, folder) == 2
    err = capsys.readouterr().err
    assert "processing_v1.toml" in err and f"[fit] {field}" in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert not out.exists() or not any(out.iterdir())

