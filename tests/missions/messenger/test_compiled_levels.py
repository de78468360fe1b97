"""The compiled passes of the MESSENGER levels against their numpy references.

`correct_heater_signal`, `correct_offsets` / `offset_model`,
`quality_flags` / `assign_quality` and `offset_step_report` each run one numba pass
(`fluxcal.missions.messenger._compiled`, `fluxcal.calibration._compiled`); the numpy
code they replaced stays as ``*_reference`` (or is written out below).  The kernels
repeat the reference's operations in the same order and the same libm ``exp`` (the
reference's relaxed offset is itself compiled), so every comparison here is exact
(``assert_array_equal``, NaN positions included) unless a tolerance is stated.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
import xarray as xr

from fluxcal.calibration.gain_matrix import range_conversion
from fluxcal.calibration.heater_signal import HeaterPeriods, heater_signal
from fluxcal.calibration.relaxation import DutyCycleChanges, steady_state_offset
from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel, utc_to_et
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-01-01")


@pytest.fixture(scope="module")
def lsk():
    with KernelPool([]) as pool:
        yield pool


@pytest.fixture(scope="module")
def dates(lsk):
    return {k: float(utc_to_et(np.array([str(CAL.date(k))]))[0])
            for k in ("boom_deployment", "heater_mode_v9", "heater_mode_v10")}


def _compiled_only(monkeypatch, name):
    """Return ``levels.<name>`` and make the compiled caller fail if it falls back to it."""
    ref = getattr(levels, name)

    def fallback(*args, **kwargs):
        raise AssertionError(f"{name} ran: the compiled path fell back")

    monkeypatch.setattr(_home(name), name, fallback)
    return ref


def _home(name):
    """The module of the levels package that defines ``name`` (where its callers look it up)."""
    return sys.modules[getattr(levels, name).__module__]


def _assert_same_dataset(got: xr.Dataset, ref: xr.Dataset) -> None:
    assert set(got.variables) == set(ref.variables)
    for name in ref.variables:
        assert got[name].dtype == ref[name].dtype, name
        assert got[name].dims == ref[name].dims, name
        np.testing.assert_array_equal(got[name].values, ref[name].values, err_msg=name)
        assert got[name].attrs == ref[name].attrs, name


# ----------------------------------------------------------------------------------------
# sec. 6: correct_heater_signal (V10 start inside the kernel)
# ----------------------------------------------------------------------------------------
def test_heater_signal_applies_from_equals_masking_afterwards(dates):
    rng = np.random.default_rng(3)
    v10 = dates["heater_mode_v10"]
    start = v10 - 5000.0 + np.arange(100) * 100.0  # periods across the V10 date
    periods = HeaterPeriods(start=start, end=start + 100.0,
                            duty_cycle=rng.uniform(0.05, 0.5, start.size),
                            on_duration=rng.uniform(0.0, 50.0, start.size),
                            applied=rng.random(start.size) < 0.8)
    t = np.sort(np.concatenate([rng.uniform(start[0] - 500.0, start[-1] + 600.0, 20000),
                                [v10, np.nextafter(v10, -np.inf), np.nan]]))
    ds = xr.Dataset({"et": ("time", t)})
    got = levels.correct_heater_signal(ds, periods, CAL)
    # the former body: signal everywhere, then masked before V10
    signal, applied = heater_signal(t, periods, CAL.heater_signal, CAL.heater_duty_bins_percent)
    applied &= t >= v10
    signal[~applied] = 0.0
    np.testing.assert_array_equal(got["heater_applied"].values, applied)
    np.testing.assert_array_equal(got["heater_signal"].values, signal)
    assert applied.any() and not applied[t < v10].any()
    assert got["heater_applied"].values[np.searchsorted(t, v10)] == applied[
        np.searchsorted(t, v10)]


# ----------------------------------------------------------------------------------------
# sec. 7: offset_model, correct_offsets
# ----------------------------------------------------------------------------------------
class _IdentityClock:
    """Stands in for the SCLK: the temperature stream's ``met`` is already ET."""

    @staticmethod
    def to_et(partition, met):
        return np.asarray(met, dtype=float)


def _changes(rng, t0, t1, m, *, minus_inf=False):
    t = np.sort(rng.uniform(t0, t1, m))
    if minus_inf:
        t[0] = -np.inf
    return DutyCycleChanges(time=t, duty_cycle_ppt=rng.choice([0.0, 50.0, 120.0, 300.0, 400.0], m))


def _offset_case(dates, rng, n, *, counts_dtype=np.int32, m=30):
    """Samples across V10 (with NaN and both ranges), a temperature stream, changes."""
    v10 = dates["heater_mode_v10"]
    et = np.sort(rng.uniform(v10 - 20000.0, v10 + 40000.0, n))
    et[:: max(n // 7, 1)] = np.floor(et[:: max(n // 7, 1)])  # some on temperature nodes
    et = np.sort(np.concatenate([et, [v10, np.nextafter(v10, -np.inf)]]))
    n = et.size
    t_et = np.arange(v10 - 20100.0, v10 + 40100.0, 20.0)
    t_c = np.round(rng.uniform(-60.0, 40.0, t_et.size), 1)
    t_c[5] = t_c[6]  # a flat piece
    counts = rng.integers(-30000, 30000, (n, 3)).astype(counts_dtype)
    rng_flag = (rng.random(n) < 0.3).astype(np.int8)
    heater = np.where(rng.random((n, 1)) < 0.5, rng.normal(0.0, 5.0, (n, 3)), 0.0)
    ds = xr.Dataset({
        "et": ("time", et), "counts": (("time", "component"), counts),
        "range": ("time", rng_flag), "heater_signal": (("time", "component"), heater),
        "sunlit": ("time", rng.random(n) < 0.5),  # before V10: 22.4 C or measured
    })
    temp = xr.Dataset({"partition": ("t", np.ones(t_et.size, np.int8)), "met": ("t", t_et),
                       "temperature_c": ("t", t_c)})
    return ds, temp, _changes(rng, v10 - 30000.0, v10 + 40000.0, m)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("counts_dtype", [np.int32, np.float64])
def test_correct_offsets_matches_reference(monkeypatch, dates, seed, counts_dtype):
    rng = np.random.default_rng(seed)
    ds, temp, changes = _offset_case(dates, rng, 20000, counts_dtype=counts_dtype)
    clock = _IdentityClock()
    reference = _compiled_only(monkeypatch, "correct_offsets_reference")
    monkeypatch.setattr(_home("interpolate_temperature"), "interpolate_temperature",
                        None)  # interpolated in the pass
    got = levels.correct_offsets(ds, temp, changes, CAL, clock)
    monkeypatch.undo()
    _assert_same_dataset(got, reference(ds, temp, changes, CAL, clock))
    before = ds["et"].values < dates["heater_mode_v10"]
    assert before.any() and (~before).any() and (ds["range"].values == 1).any()


def test_correct_offsets_against_a_per_sample_loop(dates):
    """Independent of the numpy chain: sec. 7 written per sample in Python.

    Eq. 6a-6f by explicit recursion over the last five changes, ``math.exp`` (libm, as
    the kernel), the range conversion as a matrix product: rounding differences only
    (different association of the look-back sums and the 3x3 product), offsets
    <= ~1e3 counts and counts <= 3e4, hence 1e-9 counts.
    """
    import math

    rng = np.random.default_rng(11)
    ds, temp, changes = _offset_case(dates, rng, 300, m=12)
    got = levels.correct_offsets(ds, temp, changes, CAL, _IdentityClock())
    rel = CAL.constants["relaxation"]
    tau, delay, depth = rel["tau_s"], rel["delay_s"], int(rel["look_back"])
    span = rel["look_back_s"]
    target = steady_state_offset(changes.duty_cycle_ppt, CAL.duty_cycle_d0,
                                 rel["min_duty_cycle_ppt"])
    coef = CAL.temperature_coefficients
    t_m = (coef[:, 0] - coef[:, 2]) / (coef[:, 3] - coef[:, 1])
    conv = range_conversion(CAL.matrices)[1]
    t_et, t_c = temp["met"].values, temp["temperature_c"].values
    v10 = dates["heater_mode_v10"]
    for i, t in enumerate(ds["et"].values):
        temp_i = float(np.interp(t, t_et, t_c))
        assert got["temperature"].values[i] == temp_i
        tt = temp_i if (t >= v10 or not ds["sunlit"].values[i]) else 22.4
        ct = np.where(tt <= t_m, coef[:, 0] + coef[:, 1] * tt, coef[:, 2] + coef[:, 3] * tt)
        delta = np.zeros(3)
        k = int(np.searchsorted(changes.time, t, side="right")) - 1
        if t >= v10 and k >= 0:
            # at least five changes back and back to a change >= 5000 s before t_0
            old = [c for c in range(k + 1) if changes.time[c] <= changes.time[k] - span]
            first = max(min(k - depth, old[-1] if old else -1), 0)
            state = np.zeros(3)  # zero before t_5
            for c in range(first, k):  # relax from change c to change c + 1 (eq. 6a-6e)
                dt = max(changes.time[c + 1] - changes.time[c] - delay, 0.0)
                decay = math.exp(-dt / tau)  # 0 after a change at -inf
                state = target[c] - (target[c] - state) * decay
            decay = math.exp(-max(t - changes.time[k] - delay, 0.0) / tau)
            delta = target[k] - (target[k] - state) * decay  # eq. 6f
        offset = ct + delta
        np.testing.assert_allclose(got["offset"].values[i], offset, rtol=0, atol=1e-9)
        fine = offset + ds["heater_signal"].values[i]
        applied = conv @ fine if ds["range"].values[i] == 1 else fine
        np.testing.assert_allclose(got["offset_applied"].values[i], applied, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got["counts_corrected"].values[i],
                                   ds["counts"].values[i] - applied, rtol=0, atol=1e-9)


def test_correct_offsets_edges(dates):
    clock = _IdentityClock()
    rng = np.random.default_rng(5)
    ds, temp, changes = _offset_case(dates, rng, 500)

    def same(d, tmp, ch):
        _assert_same_dataset(levels.correct_offsets(d, tmp, ch, CAL, clock),
                             levels.correct_offsets_reference(d, tmp, ch, CAL, clock))

    # empty input
    same(ds.isel(time=slice(0, 0)), temp, changes)
    # NaN sample times (fixed temperature, no error on the cover check), range 2 = fine
    d = ds.copy(deep=True)
    d["et"].values[[3, 200]] = np.nan
    d["range"].values[10:20] = 2
    same(d, temp, changes)
    # no duty-cycle changes; a change at -inf (steady since the distant past)
    same(ds, temp, DutyCycleChanges(np.empty(0), np.empty(0)))
    same(ds, temp, _changes(rng, dates["heater_mode_v10"] - 30000.0,
                            dates["heater_mode_v10"] + 40000.0, 8, minus_inf=True))
    # every sample before V10 / after V10
    before = ds["et"].values < dates["heater_mode_v10"]
    same(ds.isel(time=np.flatnonzero(before)), temp, changes)
    same(ds.isel(time=np.flatnonzero(~before)), temp, changes)
    # np.interp's own cases: one temperature record, unsorted temperature times
    one = temp.isel(t=slice(0, 1))
    near = ds.isel(time=slice(0, 5)).copy(deep=True)
    near["et"].values[:] = one["met"].values[0] + np.arange(5.0)
    same(near, one, changes)
    shuffled = temp.isel(t=np.r_[1, 0, 2:temp.sizes["t"]])
    same(ds, shuffled, changes)
    # samples beyond the temperature stream by more than 60 s
    late = ds.copy(deep=True)
    late["et"].values[-1] = temp["met"].values[-1] + 60.5
    for fn in (levels.correct_offsets, levels.correct_offsets_reference):
        with pytest.raises(InputFormatError, match="beyond the temperature stream"):
            fn(late, temp, changes, CAL, clock)
    late["et"].values[-1] = temp["met"].values[-1] + 59.5  # within the margin: end value
    same(late, temp, changes)
    with pytest.raises(InputFormatError, match="empty"):
        levels.correct_offsets(ds, temp.isel(t=slice(0, 0)), changes, CAL, clock)
    # decreasing change times: the reference's error
    bad = DutyCycleChanges(changes.time[::-1].copy(), changes.duty_cycle_ppt)
    with pytest.raises(ValueError, match="increasing"):
        levels.correct_offsets(ds, temp, bad, CAL, clock)


def test_correct_offsets_before_boom_deployment(dates):
    """Early mission (stowed, V8): fixed-temperature offsets, no duty-cycle term."""
    rng = np.random.default_rng(6)
    ds, temp, changes = _offset_case(dates, rng, 2000)
    shift = dates["heater_mode_v10"] - dates["boom_deployment"] + 5000.0
    ds = ds.assign(et=ds["et"] - shift, sunlit=ds["sunlit"] & False)  # stowed: not sunlit
    temp = temp.assign(met=temp["met"] - shift)
    got = levels.correct_offsets(ds, temp, changes, CAL, _IdentityClock())
    _assert_same_dataset(got, levels.correct_offsets_reference(ds, temp, changes, CAL,
                                                               _IdentityClock()))
    # Table 2 at the measured temperature (sec. 7: the 22.4 C rule is for sunlit data)
    t = got["temperature"].values[:, None]
    a0, b0 = np.array([-10.802, -76.138, 432.27]), np.array([1.2043, 2.042, 0.45175])
    a1, b1 = np.array([2.8435, -18.176, 455.4]), np.array([2.5445, 6.6181, 2.016])
    t_m = (a0 - a1) / (b1 - b0)
    expected = np.where(t <= t_m, a0 + b0 * t, a1 + b1 * t)
    np.testing.assert_allclose(got["offset"].values, expected, rtol=0, atol=1e-9)
    assert np.all(got["duty_cycle_offset"].values == 0.0)


@pytest.mark.parametrize("seed", range(3))
def test_offset_model_matches_reference(dates, seed):
    rng = np.random.default_rng(100 + seed)
    ds, _temp, changes = _offset_case(dates, rng, 20000, m=1 + 20 * seed)
    et = ds["et"].values
    temps = np.concatenate([rng.uniform(-80.0, 80.0, et.size - 3), [np.nan, np.inf, -50.0]])
    sunlit = ds["sunlit"].values
    np.testing.assert_array_equal(levels.offset_model(et, temps, changes, CAL, sunlit),
                                  levels.offset_model_reference(et, temps, changes, CAL, sunlit))
    assert levels.offset_model(et[:0], temps[:0], changes, CAL, sunlit[:0]).shape == (0, 3)


@pytest.mark.filterwarnings("ignore:invalid value encountered")
def test_offset_model_nan_change_time_defers_to_the_reference(dates):
    et = dates["heater_mode_v10"] + np.arange(0.0, 5000.0, 10.0)
    changes = DutyCycleChanges(np.array([et[0] + 100.0, np.nan]), np.array([400.0, 300.0]))
    temps = np.full(et.size, -20.0)
    np.testing.assert_array_equal(levels.offset_model(et, temps, changes, CAL),
                                  levels.offset_model_reference(et, temps, changes, CAL))


def test_correct_offsets_simulated_day_matches_reference(messenger_kernels, simulated,
                                                         calibration):
    """The 2-h simulated day: coarse range 0.3-0.38, heater on and off, T_m crossings."""
    with KernelPool(messenger_kernels):
        sclk = SclkKernel.from_pool(-236)
        ds = levels.correct_time(simulated["science"], calibration, sclk)
        periods, changes = levels.find_heater_periods(simulated["heater"], calibration, sclk)
        ds = levels.correct_heater_signal(ds, periods, calibration)
        got = levels.correct_offsets(ds, simulated["temperature"], changes, calibration, sclk)
        ref = levels.correct_offsets_reference(ds, simulated["temperature"], changes,
                                               calibration, sclk)
    _assert_same_dataset(got, ref)
    assert (ds["range"].values == 1).any() and ds["heater_applied"].values.any()


# ----------------------------------------------------------------------------------------
# sec. 12: quality flags
# ----------------------------------------------------------------------------------------
def _quality_inputs(dates, rng, n):
    anchors = np.array(list(dates.values()))
    et = np.concatenate([
        rng.uniform(anchors.min() - 1e7, anchors.max() + 1e7, n),
        anchors, np.nextafter(anchors, -np.inf), [np.nan, np.inf, -np.inf],
    ])
    sun_y = rng.uniform(-1.0, 1.0, et.size)
    sun_y[rng.random(et.size) < 0.05] = 0.0  # on the terminator: not sunlit
    sun_y[::97] = np.nan
    heater = rng.random(et.size) < 0.5
    return et, sun_y, heater


def test_quality_flags_match_reference(monkeypatch, dates):
    rng = np.random.default_rng(9)
    et, sun_y, heater = _quality_inputs(dates, rng, 50000)
    reference = _compiled_only(monkeypatch, "quality_flags_reference")
    got = levels.quality_flags(et, sun_y, heater, CAL)
    ref = reference(et, sun_y, heater, CAL)
    assert got.dtype == ref.dtype
    np.testing.assert_array_equal(got, ref)
    assert {1, 110, 120, 122, 211, 220, 222} <= set(np.unique(got))  # Table 5 cases
    # integer heater flags and lists, as the reference accepts them
    np.testing.assert_array_equal(
        levels.quality_flags(list(et[:50]), list(sun_y[:50]), heater[:50].astype(int), CAL),
        ref[:50])
    assert levels.quality_flags(et[:0], sun_y[:0], heater[:0], CAL).shape == (0,)


def test_assign_quality_matches_reference(dates):
    rng = np.random.default_rng(10)
    et, sun_y, heater = _quality_inputs(dates, rng, 5000)
    sun = rng.normal(size=(et.size, 3))
    sun[:, 1] = sun_y  # a strided column, as the kernel reads it
    ds = xr.Dataset({"et": ("time", et), "sun_sc": (("time", "component"), sun),
                     "heater_applied": ("time", heater)})
    q = levels.assign_quality(ds, CAL)["quality"]
    assert q.dtype == np.int16
    np.testing.assert_array_equal(
        q.values, levels.quality_flags_reference(et, sun_y, heater, CAL).astype(np.int16))


# ----------------------------------------------------------------------------------------
# sec. 13: offset_step_report (gaps split inside the kernel)
# ----------------------------------------------------------------------------------------
def _former_report(ds, max_gap_s):
    """The former body: segments from diff/cumsum, then the numpy largest step."""
    from fluxcal.calibration.offset_steps import largest_steps_reference

    et = ds["et"].values
    segment = np.concatenate([[0], np.cumsum(np.diff(et) > max_gap_s)])
    rep = largest_steps_reference(ds["offset"].values, segment)
    return {axis: {"step_counts": float(rep.largest_step[j]), "index": int(rep.index[j]),
                   "et": float(et[min(rep.index[j], et.size - 1)])}
            for j, axis in enumerate(levels.COMPONENT)}


@pytest.mark.parametrize("n", [1, 2, 3, 5000])
@pytest.mark.parametrize("max_gap", [0.05, 10.0])
def test_offset_step_report_matches_former_body(n, max_gap):
    rng = np.random.default_rng(n)
    et = np.cumsum(np.where(rng.random(n) < 0.01, rng.uniform(10.0, 100.0, n), 0.05))
    if n > 10:
        et[5] = et[4] + 10.0  # exactly max_gap for max_gap = 10: not a gap
        et[6:] += et[5] - et[4]
    off = np.round(rng.normal(size=(n, 3)), 1)  # ties: the first maximum wins
    ds = xr.Dataset({"offset": (("time", "component"), off), "et": ("time", et)})
    assert levels.offset_step_report(ds, max_gap) == _former_report(ds, max_gap)


@pytest.mark.filterwarnings("ignore:invalid value encountered")
def test_offset_step_report_nan_times_and_offsets():
    et = np.array([0.0, 1.0, np.nan, 3.0, 100.0, 101.0, 102.0])
    off = np.zeros((7, 3))
    off[4:, 0] = 50.0  # across the 97-s gap: ignored
    off[3:, 1] = 5.0  # the step after the NaN time: no gap (NaN > max_gap is False)
    off[6, 2] = np.nan
    ds = xr.Dataset({"offset": (("time", "component"), off), "et": ("time", et)})
    got = levels.offset_step_report(ds)
    ref = _former_report(ds, 10.0)
    assert got["x"] == ref["x"] and got["y"] == ref["y"]
    assert np.isnan(got["z"]["step_counts"]) and np.isnan(ref["z"]["step_counts"])
    assert got["z"]["index"] == ref["z"]["index"] == 6
    assert got["x"]["step_counts"] == 0.0
    assert got["y"] == {"step_counts": 5.0, "index": 3, "et": 3.0}
