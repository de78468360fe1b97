"""Quality flags on constructed cases, pre-V10 offsets, validation, averaging."""

import numpy as np
import pytest
import xarray as xr

from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.relaxation import DutyCycleChanges
from fluxcal.errors import FluxcalError, ValidationError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.products import average


@pytest.fixture(scope="module")
def lsk():
    with KernelPool([]) as pool:
        yield pool


def _et(utc):
    from fluxcal.geometry.time import utc_to_et

    return utc_to_et(np.array(utc))


# Table 5 (sec. 12) with the dates of sec. 7: boom 2005-03-08, V10 2007-03-09;
# V9 from 2006-03-08, the middle of the two (fluxcal decision, docs/decisions/messenger.md),
# so that the seed's own example '100' (deployed, sunlit, hardware regulation) exists.
@pytest.mark.parametrize(
    ("utc", "sun_y", "heater_applied", "flag"),
    [
        ("2004-10-01T00:00:00", -0.5, False, 1),    # stowed, V8, uncorrectable
        ("2004-10-01T00:00:00", 0.5, False, 1),     # stowed: S = 0 whatever the Sun side
        ("2005-06-01T00:00:00", 0.7, False, 100),   # the seed's example: sunlit, V8, clean
        ("2005-06-01T00:00:00", -0.7, False, 201),  # shadow, V8: uncorrectable
        ("2006-06-01T00:00:00", 0.7, False, 110),   # sunlight, V9, clean
        ("2006-06-01T00:00:00", -0.7, False, 211),  # shadow before V10: uncorrectable
        ("2008-01-14T00:00:00", -0.7, True, 222),   # shadow, V10, heater signal removed
        ("2008-01-14T00:00:00", -0.7, False, 220),  # shadow, V10, heater quiet
        ("2012-06-01T00:00:00", 0.2, False, 120),   # sunlight, V10
        ("2012-06-01T00:00:00", 0.2, True, 122),
    ],
)
def test_quality_flags(lsk, calibration, utc, sun_y, heater_applied, flag):
    q = levels.quality_flags(_et([utc]), np.array([sun_y]), np.array([heater_applied]),
                             calibration)
    assert q[0] == flag


def test_pre_v10_offset_is_table2_at_22_4(lsk, calibration):
    et = _et(["2006-05-01T00:00:00", "2006-05-01T01:00:00"])
    changes = DutyCycleChanges(time=np.array([et[0] - 100.0]), duty_cycle_ppt=np.array([400.0]))
    got = levels.offset_model(et, np.array([-50.0, 10.0]), changes, calibration,
                              sunlit=np.array([True, True]))
    # 22.4 C is above every T_m: A1 + B1 * 22.4 (Table 2)
    a1 = np.array([2.8435, -18.176, 455.4])
    b1 = np.array([2.5445, 6.6181, 2.016])
    np.testing.assert_allclose(got, np.tile(a1 + b1 * 22.4, (2, 1)), atol=1e-12)


def test_pre_v10_shadow_and_stowed_use_the_measured_temperature(lsk, calibration):
    # sec. 7: the 22.4 C rule is for deployed sunlit data; shadow (V9 regulation at
    # -50 C) and stowed data get Table 2 at the measured temperature (eq. 3a/3b, Table 2
    # written out here).  Before the fix every sample got cT(22.4): 130.9/308.3/90.9
    # counts = 6.1/14.4/4.4 nT off at -50 C.
    et = _et(["2004-10-01T00:00:00", "2006-05-01T00:00:00", "2006-05-01T01:00:00"])
    temps = np.array([0.0, -50.0, 10.0])
    changes = DutyCycleChanges(time=np.array([et[0] - 100.0]), duty_cycle_ppt=np.array([400.0]))
    got = levels.offset_model(et, temps, changes, calibration,
                              sunlit=np.array([False, False, True]))
    a0, b0 = np.array([-10.802, -76.138, 432.27]), np.array([1.2043, 2.042, 0.45175])
    a1, b1 = np.array([2.8435, -18.176, 455.4]), np.array([2.5445, 6.6181, 2.016])
    want = np.array([a1 + b1 * 0.0,    # 0 C is above every T_m (-10.2, -12.7, -14.8 C)
                     a0 + b0 * -50.0,  # below every T_m
                     a1 + b1 * 22.4])  # sunlit: 22.4 C, not the measured 10 C
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    with pytest.raises(FluxcalError, match="sunlit"):
        levels.offset_model(et, temps, changes, calibration)


def test_heater_off_follows_table2(lsk, calibration):
    et = _et(["2012-06-01T00:00:00"]) + np.arange(3) * 100.0
    temps = np.array([-60.0, -20.0, 15.0])
    no_changes = DutyCycleChanges(np.empty(0), np.empty(0))
    got = levels.offset_model(et, temps, no_changes, calibration)
    np.testing.assert_allclose(got, two_segment_offset(temps, calibration.temperature_coefficients))


def test_steady_state_is_eq5a(lsk, calibration):
    # long after a change to d = 400 at -50 C: cT(-50) + D0 d  ~= C0 + D0 d (eq. 5a)
    et0 = float(_et(["2012-06-01T00:00:00"])[0])
    changes = DutyCycleChanges(np.array([et0]), np.array([400.0]))
    got = levels.offset_model(np.array([et0 + 50 * 872.0]), np.array([-50.0]), changes,
                              calibration)[0]
    eq5a = calibration.duty_cycle_c0 + calibration.duty_cycle_d0 * 400
    np.testing.assert_allclose(got, eq5a, atol=0.05)  # C0 rounded to 0.1 count in Table 3


def _offset_ds(offset, et):
    return xr.Dataset({"offset": (("time", "component"), offset), "et": ("time", et)})


def test_validation_passes_smooth_and_fails_step(lsk):
    et = _et(["2012-06-01T00:00:00"]) + np.arange(1000) * 0.05
    smooth = np.column_stack([np.linspace(0, 1, 1000)] * 3)
    rep = levels.validate_offsets(_offset_ds(smooth, et), 0.5)
    assert rep["x"]["step_counts"] == pytest.approx(1 / 999)
    stepped = smooth.copy()
    stepped[600:, 1] += 3.0
    with pytest.raises(ValidationError, match=r"offset y: step of 3\.00"):
        levels.validate_offsets(_offset_ds(stepped, et), 2.0)
    rep = levels.offset_step_report(_offset_ds(stepped, et))
    assert rep["y"]["index"] == 600


def test_validation_ignores_data_gaps(lsk):
    et = np.concatenate([np.arange(10.0), 1000.0 + np.arange(10.0)])
    off = np.zeros((20, 3))
    off[10:] = 50.0
    assert levels.validate_offsets(_offset_ds(off, et), 2.0)["x"]["step_counts"] == 0.0


# Table 1 sample rates (Hz) of rate settings 0..10, as `correct_time` attaches them
TABLE1_HZ = [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0]


def _rate_ds(offset, et, rate):
    ds = _offset_ds(offset, et)
    return ds.assign(rate=("time", np.full(et.size, rate, dtype=np.int8),
                           {"sample_rate_hz": TABLE1_HZ}))


@pytest.mark.parametrize("rate", [0, 1, 2])
def test_validation_at_sparse_rate_settings(lsk, rate):
    # issue 11: with spacings of 100/50/20 s every step was a "gap" (> 10 s) and the check
    # passed anything.  Now a gap is > max(10 s, 2.5 spacings) and a step over dt > 10 s
    # counts per 10 s.  Closed forms: a 60-count jump at spacing h counts 60 * 10 / h.
    h = 1.0 / TABLE1_HZ[rate]
    et = _et(["2012-06-01T00:00:00"]) + np.arange(200) * h
    # the smooth relaxation after a 30-count duty-cycle change (sec. 7, tau = 872 s)
    smooth = np.zeros((200, 3))
    smooth[:, 1] = 30.0 * (1.0 - np.exp(-np.maximum(et - et[0] - 10.0, 0.0) / 872.0))
    rep = levels.validate_offsets(_rate_ds(smooth, et, rate), 2.0)
    x = np.maximum(np.arange(200) * h - 10.0, 0.0)  # eq. 6f, written per step
    want = np.max(30.0 * (np.exp(-x[:-1] / 872.0) - np.exp(-x[1:] / 872.0))) * 10.0 / h
    assert want < 2.0  # legitimate relaxation passes (before the scaling: 2.9 at rate 0)
    assert rep["y"]["step_counts"] == pytest.approx(want, rel=1e-9)
    jump = smooth.copy()
    jump[120:, 0] += 60.0
    with pytest.raises(ValidationError, match="offset x"):
        levels.validate_offsets(_rate_ds(jump, et, rate), 2.0)
    rep = levels.offset_step_report(_rate_ds(jump, et, rate))
    assert rep["x"]["index"] == 120
    assert rep["x"]["step_counts"] == pytest.approx(60.0 * 10.0 / h)
    # a real gap (3 spacings, > 2.5) is still ignored
    gapped = np.delete(np.arange(200), [118, 119])
    assert levels.offset_step_report(_rate_ds(jump[gapped], et[gapped], rate))["x"][
        "step_counts"] == 0.0


def test_quality_c2_in_the_relaxation_hour(lsk, calibration):
    # the heater stopped (waveform no longer applied) but the duty-cycle offset still
    # relaxes: C = 2 while >= 1 count of it is removed (before the fix: C = 0 throughout)
    et = _et(["2012-06-01T00:00:00"]) + np.arange(4) * 600.0
    duty = np.array([[0.0, 131.0, 0.0], [0.0, 3.0, 0.0], [0.4, 0.99, 0.2], [0.0, 0.0, 0.0]])
    ds = xr.Dataset({"et": ("time", et),
                     "sun_sc": (("time", "component"), np.tile([0.0, -0.7, 0.7], (4, 1))),
                     "heater_applied": ("time", np.zeros(4, dtype=bool)),
                     "duty_cycle_offset": (("time", "component"), duty)})
    q = levels.assign_quality(ds, calibration)["quality"].values
    np.testing.assert_array_equal(q, [222, 222, 220, 220])


def test_average_against_loop():
    rng = np.random.default_rng(1)
    n = 500
    epoch = (np.arange(n) * 50_000_000 + 7).astype(np.int64)
    b = rng.normal(size=(n, 3))
    prod = xr.Dataset(
        {"b": (("time", "component"), b), "position": (("time", "component"), b * 10),
         "quality": ("time", rng.integers(0, 3, n))},
        coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]},
    )
    avg = average(prod, 5, 0)
    for k, centre in enumerate(avg["epoch"].values):
        sel = (epoch >= centre - 2_500_000_000) & (epoch < centre + 2_500_000_000)
        np.testing.assert_allclose(avg["b"].values[k], b[sel].mean(axis=0), atol=1e-12)
        np.testing.assert_allclose(avg["b_std"].values[k], b[sel].std(axis=0), atol=1e-9)
        assert avg["count"].values[k] == sel.sum()
