import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import welch

from fluxcal.cleaning.spectral_lines import (
    crossfade_weights,
    default_bandwidth,
    fold_frequency,
    interpolated_lines,
    remove_spectral_lines,
    window_starts,
)
from fluxcal.errors import InputFormatError
from tests.cleaning._synthetic import red_noise, red_psd, rotating_field

FS = 20.0
N = 2**17  # 6554 s at 20 Hz: ~170 FFT windows
PSD_1HZ = 1e-2  # nT^2/Hz at 1 Hz, f^-2: solar-wind-like red noise
FLOOR = 1e-5  # nT^2/Hz: sensor noise floor (~3 pT/sqrt(Hz))


@pytest.mark.parametrize(
    ("f", "fs", "expected"),
    [
        (3.0, 20.0, 3.0),  # already in band
        (10.0, 20.0, 10.0),  # Nyquist
        (12.0, 20.0, 8.0),  # fs - f
        (27.5, 20.0, 7.5),  # f - fs
        (40.0, 20.0, 0.0),  # multiple of fs -> DC
        (33.0, 5.0, 2.0),  # 33 mod 5 = 3 -> 5 - 3
        (-3.0, 20.0, 3.0),  # sign ignored
    ],
)
def test_fold_frequency(f, fs, expected):
    assert fold_frequency(f, fs) == pytest.approx(expected, abs=1e-12)


def test_fold_matches_sampled_sinusoid():
    # independent check: the periodogram peak of a sampled cosine is at the folded frequency
    fs, n = 5.0, 4096
    t = np.arange(n) / fs
    for f in [1.1, 3.7, 7.3, 13.9]:
        spec = np.abs(np.fft.rfft(np.cos(2 * np.pi * f * t) * np.hanning(n)))
        peak = np.fft.rfftfreq(n, 1 / fs)[np.argmax(spec)]
        assert abs(peak - fold_frequency(f, fs)) <= fs / n


def test_default_bandwidth():
    assert default_bandwidth(20.0) == pytest.approx(0.06)  # seed 003 sec. 4.9, burst mode
    assert default_bandwidth(5.0) == pytest.approx(0.015)  # same number of bins


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1024, 6000), overlap=st.sampled_from([0.0, 0.1, 0.25, 0.5]))
def test_crossfade_weights_sum_to_one(n, overlap):
    starts = window_starts(n, 1024, overlap)
    w = crossfade_weights(starts, 1024, n)
    total = np.bincount((starts[:, None] + np.arange(1024)).ravel(), w.ravel(), minlength=n)
    np.testing.assert_allclose(total, 1.0, atol=1e-12)
    assert starts[0] == 0 and starts[-1] + 1024 == n
    assert np.all(np.diff(starts) <= 1024 - round(overlap * 1024))


def _wheel_scenario(seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    background = rotating_field(t) + red_noise(N, FS, PSD_1HZ, rng, floor=FLOOR)
    # four wheels (true rates in Hz, aliased into [0, 10] Hz) drifting slowly; table every 16 s
    table_t = np.arange(-64.0, t[-1] + 64.0, 16.0)
    base = np.array([23.7, 31.2, 14.4, 46.3])  # fold to 3.7, 8.8, 5.6, 6.3 Hz
    swing = np.array([0.10, 0.08, 0.10, 0.06])
    period = np.array([2500.0, 4000.0, 3100.0, 1700.0])
    table_f = base + swing * np.sin(2 * np.pi * table_t[:, None] / period)
    # the lines themselves: 1 nT amplitude, phase = integral of the interpolated rate
    f_inst = np.stack([np.interp(t, table_t, table_f[:, j]) for j in range(4)], axis=1)
    phase = 2 * np.pi * np.cumsum(f_inst, axis=0) / FS + rng.uniform(0, 2 * np.pi, 4)
    lap = 2.5  # a fixed LAP line (Hz)
    phase = np.column_stack([phase, 2 * np.pi * lap * t])
    directions = rng.normal(size=(5, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    lines = np.cos(phase) @ directions  # each line 1 nT amplitude along its direction
    lines_fn = interpolated_lines(table_t, table_f)

    def all_lines(tc):
        return np.column_stack([lines_fn(tc), np.full(np.size(tc), lap)])

    folded_range = [
        (fold_frequency(table_f[:, j], FS).min(), fold_frequency(table_f[:, j], FS).max())
        for j in range(4)
    ] + [(lap, lap)]
    return t, background, lines, phase, directions, all_lines, folded_range


@pytest.fixture(scope="module")
def wheel_case():
    t, bg, lines, phase, directions, fn, ranges = _wheel_scenario()
    res = remove_spectral_lines(bg + lines, FS, fn, times=t, seed=11)
    res_bg = remove_spectral_lines(bg, FS, fn, times=t, seed=11)
    return dict(
        t=t,
        bg=bg,
        x=bg + lines,
        y=res.values,
        y_bg=res_bg.values,
        phase=phase,
        directions=directions,
        ranges=ranges,
        res=res,
    )


def test_coherent_line_amplitude_drops_40db(wheel_case):
    # lock-in with the known line phase: coherent residual amplitude of each line
    for j in range(5):
        z = np.exp(-1j * wheel_case["phase"][:, j])
        a_in = 2 * np.abs(np.mean(wheel_case["x"] * z[:, None], axis=0))
        a_out = 2 * np.abs(np.mean(wheel_case["y"] * z[:, None], axis=0))
        big = a_in > 0.2  # components where the line is clearly present
        assert np.all(20 * np.log10(a_out[big] / a_in[big]) < -40)


def _band_mask(f, ranges, margin):
    m = np.zeros(f.size, bool)
    for a, b in ranges:
        m |= (f >= a - margin) & (f <= b + margin)
    return m


def test_line_power_drops_20db_and_outside_unchanged(wheel_case):
    f, p_in = welch(wheel_case["x"], FS, nperseg=1024, axis=0)
    _, p_out = welch(wheel_case["y"], FS, nperseg=1024, axis=0)
    _, p_bg = welch(wheel_case["bg"], FS, nperseg=1024, axis=0)
    # bands as swept by the lines, widened by delta_f/2 and the Hann main lobe (2 bins)
    in_bands = _band_mask(f, wheel_case["ranges"], 0.03 + 2 * FS / 1024)
    for j, (a, b) in enumerate(wheel_case["ranges"]):
        m = (f >= a - 0.07) & (f <= b + 0.07)
        # excess power over the background, summed over the three components
        line_in = p_in[m].sum() - p_bg[m].sum()
        line_out = p_out[m].sum() - p_bg[m].sum()
        # required: >= 20 dB drop of the line's excess power over the background
        assert abs(line_out) <= 0.01 * line_in, (j, line_in, line_out)
    outside = ~in_bands & (f > 0.05)
    change_db = 10 * np.log10(p_out[outside] / p_in[outside])
    assert np.max(np.abs(change_db)) < 1.0


def test_background_rms_change_bounded(wheel_case):
    # Bound: inside each replaced band the background (power P_band = PSD * band width)
    # is swapped for independent noise of the same level, which changes the series by
    # about sqrt(2 * sum P_band); the band is at most 5 bins wide (0.06 Hz + sweep within
    # a window).  We allow 2x that for the crossfade and level-estimate scatter.
    bins = 5 * FS / 1024
    centres = np.array([0.5 * (a + b) for a, b in wheel_case["ranges"]])
    p_band = np.sum(red_psd(centres, PSD_1HZ, FLOOR) * bins) * 3  # 3 components
    bound = 2 * np.sqrt(2 * p_band / 3)  # per component
    rms_change = np.sqrt(np.mean((wheel_case["y"] - wheel_case["bg"]) ** 2, axis=0))
    assert np.all(rms_change < bound), (rms_change, bound)
    assert bound < 0.07  # i.e. < 10 % of one line's rms (0.707 nT) for this background


def test_series_without_lines_changes_only_inside_bands(wheel_case):
    change = wheel_case["y_bg"] - wheel_case["bg"]
    f, p_change = welch(change, FS, nperseg=1024, axis=0)
    _, p_bg = welch(wheel_case["bg"], FS, nperseg=1024, axis=0)
    # bands widened by delta_f/2 + 4 bins: the Welch Hann main lobe (2 bins) plus the
    # spectral broadening of the in-band change by the crossfade ramps (~2 bins)
    in_bands = _band_mask(f, wheel_case["ranges"], 0.03 + 4 * FS / 1024)
    outside = ~in_bands & (f > 0.0)
    # outside the bands the change (crossfade leakage only) is >= 30 dB below background
    assert np.all(p_change[outside] < 1e-3 * p_bg[outside])
    # inside the bands it is of the order of the background (noise swapped for noise)
    core = _band_mask(f, wheel_case["ranges"], 0.0)
    ratio = p_change[core].sum(axis=0) / p_bg[core].sum(axis=0)
    assert np.all((ratio > 0.3) & (ratio < 4.0)), ratio


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(8, 3000),
    seed=st.integers(0, 2**31),
    fs=st.sampled_from([5.0, 20.0]),
)
def test_absent_lines_leave_series_identical(n, seed, fs):
    # law: with every line absent (NaN) nothing is touched, bit for bit
    x = np.random.default_rng(seed).normal(size=(n, 3)) * 10
    res = remove_spectral_lines(x, fs, [np.nan, np.nan])
    np.testing.assert_array_equal(res.values, x)


def test_reproducible_and_seeded():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(5000, 3))
    a = remove_spectral_lines(x, FS, [3.3], seed=5).values
    b = remove_spectral_lines(x, FS, [3.3], seed=5).values
    c = remove_spectral_lines(x, FS, [3.3], seed=6).values
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("fs", [5.0, 20.0])
def test_gap_splits_segments_and_short_series(fs):
    rng = np.random.default_rng(4)
    t = np.concatenate([np.arange(3000), np.arange(3020, 3720)]) / fs  # gap; 2nd part < 1024
    f_true = 13.3
    x = 0.01 * rng.normal(size=t.size) + np.cos(2 * np.pi * f_true * t)
    res = remove_spectral_lines(x, fs, [f_true], times=t)
    assert res.segments == [(0, 3000), (3000, 3700)]
    assert np.std(res.values[:3000]) < 0.02 and np.std(res.values[3000:]) < 0.02


def test_short_gaps_are_bridged():
    fs = 20.0
    rng = np.random.default_rng(5)
    keep = np.ones(6000, bool)
    keep[rng.choice(np.arange(10, 5990), 40, replace=False)] = False  # dropped vectors
    t = (np.arange(6000) / fs)[keep]
    x = 0.01 * rng.normal(size=t.size) + np.cos(2 * np.pi * 7.3 * t)
    res = remove_spectral_lines(x, fs, [7.3], times=t)
    assert res.segments == [(0, t.size)]  # one segment: the gaps were filled for the FFT
    assert res.values.shape == x.shape
    assert np.std(res.values) < 0.02
    assert any("filled" in note for note in res.notes)


def test_repeated_times_split_and_short_pieces_pass_through():
    t = np.arange(4000) / FS
    t[2000:2004] = t[1999]  # four repeated stamps: a break of the uniform sampling
    x = np.cos(2 * np.pi * 3.3 * np.arange(4000) / FS)
    res = remove_spectral_lines(x, FS, [3.3], times=t)
    # spacing 0 breaks the series; the last repeated stamp starts a new segment whose
    # first step (5 samples) is a short gap, bridged
    assert (0, 2000) in res.segments and (2003, 4000) in res.segments
    np.testing.assert_array_equal(res.values[2000:2003], x[2000:2003])
    assert "left unchanged" in res.notes[0]
    assert np.std(res.values[:2000]) < 0.02


def test_line_at_dc_never_touches_the_mean():
    # a wheel at exactly fs folds to 0 Hz: the DC bin (the field itself) is protected
    x = 5.0 + np.random.default_rng(1).normal(0, 0.1, 4096)
    y = remove_spectral_lines(x, FS, [20.0], bandwidth=0.001).values
    assert np.mean(y) == pytest.approx(np.mean(x), abs=1e-3)


def test_interpolated_lines_refuses_far_extrapolation():
    fn = interpolated_lines([0.0, 10.0], [[1.0], [2.0]], max_extrapolation=5.0)
    np.testing.assert_allclose(fn(np.array([5.0, 12.0])), [[1.5], [2.0]])
    with pytest.raises(InputFormatError, match="covers"):
        fn(np.array([20.0]))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        (dict(values=np.full(100, np.nan)), "values"),
        (dict(fs=0.0), "fs"),
        (dict(bandwidth=-1.0), "bandwidth"),
        (dict(overlap=0.9), "overlap"),
        (dict(times=np.full(100, np.inf)), "times"),
    ],
)
def test_argument_errors(kwargs, field):
    args = dict(values=np.zeros(100), fs=FS, line_frequencies=[1.0])
    args.update(kwargs)
    with pytest.raises(InputFormatError, match=field):
        remove_spectral_lines(**args)


def test_continuous_across_windows_and_days():
    # a 1 nT line on a slow field, cleaned as two separate "days": the cleaned series has
    # no step at any window boundary nor at the day boundary (the uncleaned line alone
    # changes by up to 2 pi 3.3 / 20 = 1 nT from one sample to the next)
    rng = np.random.default_rng(8)
    n = 2 * 20000
    t = np.arange(n) / FS
    slow = 5 + np.sin(2 * np.pi * t / 900)
    noise = 0.002 * rng.normal(size=n)
    x = slow + noise + np.cos(2 * np.pi * 3.3 * t + 0.3)
    day1 = remove_spectral_lines(x[: n // 2], FS, [3.3], times=t[: n // 2]).values
    day2 = remove_spectral_lines(x[n // 2 :], FS, [3.3], times=t[n // 2 :]).values
    resid = np.concatenate([day1, day2]) - slow - noise
    assert np.max(np.abs(np.diff(resid))) < 0.02
    assert abs(resid[n // 2] - resid[n // 2 - 1]) < 0.02


@pytest.mark.parametrize("fs", [5.0, 20.0])
def test_medium_and_burst_rates(fs):
    # MEDIUM (5 Hz) and BURST (20 Hz): default band width scales with fs
    rng = np.random.default_rng(int(fs))
    n = 16384
    t = np.arange(n) / fs
    bg = red_noise(n, fs, 1e-3, rng, floor=1e-5)[:, 0]
    lines = [13.1, 31.7]  # fold to 1.9/1.7 Hz at 5 Hz and 6.9/8.3 Hz at 20 Hz
    x = bg + sum(np.cos(2 * np.pi * f * t + k) for k, f in enumerate(lines))
    y = remove_spectral_lines(x, fs, lines).values
    for k, f in enumerate(lines):
        z = np.exp(-1j * (2 * np.pi * f * t + k))
        assert 2 * abs(np.mean(y * z)) < 0.01  # from 1 nT: > 40 dB
    assert np.sqrt(np.mean((y - bg) ** 2)) < 0.05
