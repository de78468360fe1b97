"""Quality flags on constructed cases, pre-V10 offsets, validation, averaging."""

import numpy as np
import pytest
import xarray as xr

from fluxcal.calibration.offsets import two_segment_offset
from fluxcal.calibration.relaxation import DutyCycleChanges
from fluxcal.errors import ValidationError
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
# V9 from boom deployment (fluxcal decision, docs/decisions/messenger.md).
@pytest.mark.parametrize(
    ("utc", "sun_y", "heater_applied", "flag"),
    [
        ("2004-10-01T00:00:00", -0.5, False, 1),    # stowed, V8, uncorrectable
        ("2004-10-01T00:00:00", 0.5, False, 1),     # stowed: S = 0 whatever the Sun side
        ("2006-01-01T00:00:00", 0.7, False, 110),   # sunlight, V9, clean
        ("2006-01-01T00:00:00", -0.7, False, 211),  # shadow before V10: uncorrectable
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
    got = levels.offset_model(et, np.array([-50.0, 10.0]), changes, calibration)
    # 22.4 C is above every T_m: A1 + B1 * 22.4 (Table 2)
    a1 = np.array([2.8435, -18.176, 455.4])
    b1 = np.array([2.5445, 6.6181, 2.016])
    np.testing.assert_allclose(got, np.tile(a1 + b1 * 22.4, (2, 1)), atol=1e-12)


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
