"""LEVEL_A formulas (seed 003 sec. 3.3, 4.2.3): the seed's own tables and closed forms."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration import matrices as mat
from fluxcal.missions.rosetta import calib, level_a
from fluxcal.missions.rosetta.calib import DailyOffsetModel

T1 = 17.39  # deg C, reference temperature of sec. 3.3.1.2 / 3.3.2.2
# sec. 3.3.x.2 tables: sigma^1_0 (off-centre), sigma^1_1, k, sigma^0(T1) at CoC
TABLES = {
    "IB": dict(
        s10=[1.09026, 1.09354, 1.09336],
        s11=[-1.42e-5, -9.29e-6, -8.55e-6],
        k=[0.99959, 0.99927, 0.99929],
        s0t1=[1.09045, 1.09418, 1.09398],
        xi0t1=[90.0463, 89.9416, 89.9500],
    ),
    "OB": dict(
        s10=[1.09066, 1.09251, 1.09217],
        s11=[-1.18e-5, -8.20e-6, -6.97e-6],
        k=[0.99969, 0.99907, 0.99934],
        s0t1=[1.09079, 1.09338, 1.09277],
        xi0t1=[90.0711, 90.0187, 90.0576],
    ),
}


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_sigma0_is_sigma1_over_k(sensor):
    cal = calib.load_ground_calibration(sensor)
    tab = TABLES[sensor]
    # SIGMA_00 = sigma^1_0 / k, SIGMA_01 = sigma^1_1 / k; tables printed to 5 decimals
    # (sigma) and 3 significant digits (slopes), so agree to one unit of the last digit.
    np.testing.assert_allclose(cal.sensitivity[0], np.divide(tab["s10"], tab["k"]), atol=1.0e-5)
    np.testing.assert_allclose(cal.sensitivity[1], np.divide(tab["s11"], tab["k"]), atol=0.02e-6)


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_sigma0_at_T1(sensor):
    cal = calib.load_ground_calibration(sensor)
    sigma = level_a.sensitivity(np.array([T1]), cal)[0]
    # sigma^0(T1) of the tables, printed to 5 decimals
    np.testing.assert_allclose(sigma, TABLES[sensor]["s0t1"], atol=1.0e-5)
    # and k = sigma^1(T1) / sigma^0(T1) within the rounding of the printed k (5 decimals)
    s1 = np.add(TABLES[sensor]["s10"], np.multiply(TABLES[sensor]["s11"], T1))
    np.testing.assert_allclose(s1 / sigma, TABLES[sensor]["k"], atol=2e-5)


def test_omega_forms_differ_negligibly_and_unit_columns():
    cal = calib.load_ground_calibration("OB")
    t = np.linspace(-140, 40, 19)
    unit = level_a.misalignment(t, cal, form="unit")
    sec321 = level_a.misalignment(t, cal, form="sec321")
    # only omega[0,2] differs: cos(xi_xz) (1/sin(xi_xy) - 1) ~ 6e-4 * 7e-7 ~ 5e-10
    diff = np.abs(unit - sec321)
    assert diff.max() < 1e-9 and diff.max() > 0
    b = np.array([15000.0, 15000.0, 15000.0])  # full scale on every axis
    db = np.abs(np.einsum("nij,j->ni", unit - sec321, b)).max()
    assert db < 2e-5  # nT: 1000x below the 20-bit LSB (0.029 nT)
    # the chosen form has unit columns (sensor axes expressed in an orthogonal frame)
    xi = cal.angles[0] + t[:, None] * cal.angles[1]
    om1 = mat.orthogonalisation_matrix(xi[:, 0], xi[:, 1], xi[:, 2])
    np.testing.assert_allclose(np.linalg.norm(om1, axis=1), 1.0, atol=1e-15)
    # and the column angles are the xi's: cos(angle between axis i and j) = col_i . col_j
    cosines = np.einsum("nki,nkj->nij", om1, om1)
    np.testing.assert_allclose(cosines[:, 0, 1], np.cos(np.deg2rad(xi[:, 0])), atol=1e-15)
    np.testing.assert_allclose(cosines[:, 0, 2], np.cos(np.deg2rad(xi[:, 1])), atol=1e-15)
    np.testing.assert_allclose(cosines[:, 1, 2], np.cos(np.deg2rad(xi[:, 2])), atol=1e-15)


@pytest.mark.parametrize("sensor", ["OB", "IB"])
def test_K_reproduces_coc_angles_at_T1(sensor):
    # K = omega0(T1)^-1 omega1(T1): omega1(T1) K^-1 must approximate omega0(T1) built from the
    # CoC reference angles (xi0t1).  K^-1 is printed to 5 decimals -> agree to ~1e-5.
    cal = calib.load_ground_calibration(sensor)
    om0 = level_a.misalignment(np.array([T1]), cal)[0]
    ref = mat.orthogonalisation_matrix(*[np.array([v]) for v in TABLES[sensor]["xi0t1"]])[0]
    np.testing.assert_allclose(om0, ref, atol=1.5e-5)


def test_ground_calibration_closed_form_one_vector():
    cal = calib.load_ground_calibration("OB")
    t = 20.0
    b_raw = np.array([[1000.0, -2000.0, 500.0]])
    # written out by hand from sec. 4.2.3.2 items 2-6
    boff = np.array([214.5 - 1.053 * t - 0.0, -79.9 + 0.073 * t - 4.0, 384.7 - 1.657 * t + 20.0])
    sig = np.array([1.09100 - 1.18e-5 * t, 1.09352 - 8.21e-6 * t, 1.09289 - 6.97e-6 * t])
    xy, xz, yz = np.deg2rad([90.0666 - 6.04e-5 * t, 90.0366 - 1.11e-4 * t, 90.0370 - 8.12e-5 * t])
    w12 = (np.cos(yz) - np.cos(xy) * np.cos(xz)) / np.sin(xy)
    om1 = np.array(
        [
            [1, np.cos(xy), np.cos(xz)],
            [0, np.sin(xy), w12],
            [0, 0, np.sqrt(np.sin(xz) ** 2 - w12**2)],
        ]
    )
    kinv = np.array([[1, -0.0001, 0.00028], [0, 1, -0.00038], [0, 0, 1]])
    expected = om1 @ kinv @ (sig * (b_raw[0] - boff))
    got = level_a.ground_calibrate(b_raw, np.array([t]), cal)[0]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-140, 40),
    st.lists(st.floats(-14000, 14000), min_size=3, max_size=3),
)
def test_uncalibrate_inverts_calibrate(t, b):
    cal = calib.load_ground_calibration("IB")
    b = np.array([b])
    raw = level_a.ground_uncalibrate(b, np.array([t]), cal)
    np.testing.assert_allclose(level_a.ground_calibrate(raw, np.array([t]), cal), b, atol=1e-8)


def test_counts_nominal_relation():
    nom = calib.load_nominal_conversion()
    # sec. 4.2.3.1: signed -2^19 <-> -15000 nT, 0 <-> ~0, 2^19-1 <-> +15000 nT
    b = level_a.field_counts_to_nt(np.array([-(2**19), 0, 2**19 - 1]), nom)
    np.testing.assert_allclose(b, [-15000, 0, 15000], atol=30000 / (2**20 - 1))
    assert b[0] == -15000 and b[2] == 15000


def test_quality_bits():
    q = np.array([0, 1, 2, 4, 7, 0])
    np.testing.assert_array_equal(level_a.good_vectors(q), [1, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(level_a.good_vectors(q + 8), [1, 0, 0, 0, 0, 1])
    assert not level_a.wrong_quality(q, "OB").any()
    assert level_a.wrong_quality(q, "IB").all()
    assert level_a.wrong_quality(np.array([16]), "OB").all()


def test_filter_time_shift_tables():
    table = calib.load_time_shift_table()
    sid = np.array([1, 2, 3, 4, 5, 6])
    np.testing.assert_array_equal(
        level_a.filter_time_shift(sid, table, sensor="OB"), [223.7, 8.2, 0, 1.35, 27.7, 0]
    )
    np.testing.assert_array_equal(
        level_a.filter_time_shift(sid[:5], table, sensor="IB"),
        [1023.95, 31.95, 15.95, 31.95, 127.95],
    )
    # IB primary: IB takes the primary table, OB the secondary
    np.testing.assert_array_equal(
        level_a.filter_time_shift(sid[:2], table, sensor="IB", primary="IB"), [223.7, 8.2]
    )
    with pytest.raises(KeyError) as info:
        level_a.filter_time_shift(np.array([2, 6]), table, sensor="IB")
    assert info.value.args == (1, 6)
    with pytest.raises(KeyError):
        level_a.filter_time_shift(np.array([7]), table, sensor="OB")


def _models(coeffs_by_day):
    return {
        np.datetime64(d): DailyOffsetModel(np.datetime64(d), "OB", np.asarray(c, float), d)
        for d, c in coeffs_by_day.items()
    }


def test_midnight_stitching_removes_jump():
    """Sec. 4.2.3.3 as written: day 2 is shifted so that its first vector gets the offset
    stored for day 1's last vector; the applied offset has no jump at midnight."""
    ns = 1_000_000_000
    # two days, 1-minute sampling across midnight; temperature drifts linearly
    epoch = np.arange(-3600, 3600, 60, dtype=np.int64) * ns
    temperature = np.linspace(-100, -90, epoch.size)
    day_index = (epoch >= 0).astype(int)
    days = [np.datetime64("2014-08-01"), np.datetime64("2014-08-02")]
    c1 = np.zeros((6, 3))
    c1[0] = [1, 2, 3]
    c1[1] = [0.1, 0.0, -0.1]
    c2 = np.zeros((6, 3))
    c2[0] = [5, -2, 0]
    c2[1] = [0.2, 0.05, 0.0]
    c2[2] = [1e-3, 0, 0]
    models = _models({"2014-08-01": c1, "2014-08-02": c2})
    off, state, sources = level_a.extended_offset(epoch, temperature, day_index, days, models)
    i = np.flatnonzero(epoch >= 0)[0]
    # closed form: day 2 shifted by P2(T_first) - P1(T_last)
    p1 = lambda t: c1[0] + c1[1] * t  # noqa: E731
    p2 = lambda t: c2[0] + c2[1] * t + c2[2] * t**2  # noqa: E731
    shift = p2(temperature[i]) - p1(temperature[i - 1])
    np.testing.assert_allclose(off[:i], np.array([p1(t) for t in temperature[:i]]), atol=1e-12)
    np.testing.assert_allclose(
        off[i:], np.array([p2(t) for t in temperature[i:]]) - shift, atol=1e-12
    )
    np.testing.assert_allclose(off[i], off[i - 1], atol=1e-12)  # no jump at all
    np.testing.assert_allclose(state.correction, shift, atol=1e-12)
    np.testing.assert_allclose(state.offset, off[-1], atol=1e-12)
    assert len(sources) == 2


def test_stitching_across_gap_with_temperature_change():
    """Issue 11: across a 2 h gap with a 10 C temperature change the earlier matching of
    both polynomials at the last temperature left the day-2 slope times 10 C at midnight
    (0.5 nT here); stored-offset matching (sec. 4.2.3.3) leaves 0 nT."""
    ns = 1_000_000_000
    epoch = np.array([-3 * 3600, -3600, 3600, 2 * 3600], dtype=np.int64) * ns  # 2 h gap
    t = np.array([-100.0, -100.0, -90.0, -90.0])  # +10 C across the gap
    c1 = np.zeros((6, 3))
    c1[0] = [1.0, -2.0, 3.0]
    c2 = np.zeros((6, 3))
    c2[0] = [4.0, 0.0, -1.0]
    c2[1] = [0.05, -0.05, 0.02]  # nT/C: 10 C -> 0.5, -0.5, 0.2 nT
    models = _models({"2014-08-01": c1, "2014-08-02": c2})
    days = [np.datetime64("2014-08-01"), np.datetime64("2014-08-02")]
    off, state, _ = level_a.extended_offset(epoch, t, np.array([0, 0, 1, 1]), days, models)
    # before (P2(Te) - P1(Te) matching): off[2] - off[1] = [0.5, -0.5, 0.2] nT
    np.testing.assert_allclose(off[2] - off[1], 0.0, atol=1e-12)
    np.testing.assert_allclose(off[1], c1[0], atol=1e-12)
    np.testing.assert_allclose(off[3], off[2], atol=1e-12)  # same temperature within day 2


def test_no_stitching_across_long_gap():
    ns = 1_000_000_000
    epoch = np.array([-4 * 3600, -3 * 3600 - 1, 600, 1200], dtype=np.int64) * ns  # 3 h + 10 min gap
    t = np.array([-100.0, -100.0, -100.0, -100.0])
    c1 = np.zeros((6, 3))
    c1[0] = 1
    c2 = np.zeros((6, 3))
    c2[0] = 4
    models = _models({"2014-08-01": c1, "2014-08-02": c2})
    days = [np.datetime64("2014-08-01"), np.datetime64("2014-08-02")]
    off, _, _ = level_a.extended_offset(epoch, t, np.array([0, 0, 1, 1]), days, models)
    np.testing.assert_allclose(off[2:], 4.0)  # not stitched: 3h10m > 3h
    off, _, _ = level_a.extended_offset(
        epoch, t, np.array([0, 0, 1, 1]), days, models, stitch_gap_s=4 * 3600
    )
    np.testing.assert_allclose(off[2:], 1.0)  # stitched with a 4 h limit


def test_stitch_state_carried_between_calls():
    ns = 1_000_000_000
    c1 = np.zeros((6, 3))
    c1[0] = 1
    c1[1] = 0.1
    c2 = np.zeros((6, 3))
    c2[0] = 4
    c2[1] = -0.2
    m1 = _models({"2014-08-01": c1})
    m2 = _models({"2014-08-02": c2})
    d1, d2 = [np.datetime64("2014-08-01")], [np.datetime64("2014-08-02")]
    _, state, _ = level_a.extended_offset(
        np.array([-10 * ns]), np.array([0.0]), np.array([0]), d1, m1
    )
    state = level_a.StitchState.from_attrs(state.to_attrs())
    off, _, _ = level_a.extended_offset(
        np.array([10 * ns, 20 * ns]), np.array([5.0, 10.0]), np.array([0, 0]), d2, m2,
        previous=state,
    )
    # first vector of day 2 gets day 1's end offset (1 nT); the second follows P2's slope
    np.testing.assert_allclose(off[:, 0], [1.0, 1.0 - 0.2 * 5.0])
    with pytest.raises(ValueError, match="not before"):  # a state of the same/later day
        level_a.extended_offset(
            np.array([-20 * ns]), np.array([0.0]), np.array([0]), d2, m2, previous=state
        )


def test_old_stitch_state_attributes_are_converted():
    c = np.zeros((6, 3))
    c[0] = [1.0, 2.0, 3.0]
    c[1] = [0.1, 0.2, 0.3]
    old = {"stitch_epoch": 5, "stitch_temperature_c": 10.0,
           "stitch_coefficients": c.ravel().tolist(), "stitch_correction_nt": [0.5, 0.5, 0.5]}
    state = level_a.StitchState.from_attrs(old)
    np.testing.assert_allclose(state.offset, [1.5, 3.5, 5.5])


def test_word_lookup_equals_per_vector_formula():
    nom = calib.load_nominal_conversion()
    cal = calib.load_ground_calibration("OB")
    rng = np.random.default_rng(0)
    words = rng.integers(6000, 20000, 5000)
    b_raw = rng.uniform(-15000, 15000, (5000, 3))
    fast, t = level_a.ground_calibrate_words(b_raw, words, cal, nom)
    slow = level_a.ground_calibrate(b_raw, level_a.sensor_temperature(words, cal, nom), cal)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(t, level_a.sensor_temperature(words, cal, nom))


def test_extended_model_fifth_order_closed_form():
    # sec. 4.2.3.3: the daily files carry P_0 .. P_5 ("5th order polynomials"); every order
    # must be used.  Expected value written out term by term.
    c = np.array(
        [
            [1.5, -2.0, 0.5],
            [0.01, 0.02, -0.03],
            [1e-4, -2e-4, 3e-4],
            [1e-6, 2e-6, -1e-6],
            [1e-8, -1e-8, 2e-8],
            [1e-10, 3e-10, -2e-10],
        ]
    )
    t = np.array([-140.0, -60.0, 0.0, 25.0, 40.0])
    expected = sum(np.outer(t**k, c[k]) for k in range(6))
    day = np.datetime64("2014-08-01")
    off, _, sources = level_a.extended_offset(
        np.arange(5, dtype=np.int64), t, np.zeros(5, dtype=int), [day], _models({str(day): c})
    )
    np.testing.assert_allclose(off, expected, rtol=1e-13, atol=1e-12)
    assert sources == ["2014-08-01"]
    # the fifth-order term matters at -140 C: 1e-10 * (-140)^5 = -5.4 nT in x
    assert abs(expected[0, 0] - sum(t[0] ** k * c[k, 0] for k in range(5))) > 5.0


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-50, 50), min_size=8, max_size=8),  # P_0, P_1 of both days, x y z
    st.floats(-150, 40),
    st.floats(-150, 40),
    st.integers(1, 6 * 3600),
)
def test_stitching_continuity_any_models(coefs, t_last, t_first, gap_s):
    """Sec. 4.2.3.3 for any pair of daily polynomials (both signs, any temperatures): within
    the gap limit the first vector of the new day gets exactly the stored offset of the last
    one; beyond it, the new day's own polynomial."""
    ns = 1_000_000_000
    c1, c2 = np.zeros((6, 3)), np.zeros((6, 3))
    c1[0], c1[1] = coefs[0:3], [coefs[3] * 0.01] * 3
    c2[0], c2[1] = coefs[4:7], [coefs[7] * 0.01] * 3
    last = -((gap_s + 1) // 2)  # last vector of day 1 before midnight, first of day 2 after
    epoch = np.array([last - 10, last, last + gap_s, last + gap_s + 10], dtype=np.int64) * ns
    day_index = (epoch >= 0).astype(int)
    t = np.array([t_last, t_last, t_first, t_first])
    days = [np.datetime64("2014-08-01"), np.datetime64("2014-08-02")]
    models = _models({"2014-08-01": c1, "2014-08-02": c2})
    off, state, _ = level_a.extended_offset(epoch, t, day_index, days, models)
    p2 = c2[0] + c2[1] * t_first
    if gap_s <= 3 * 3600:
        np.testing.assert_allclose(off[2], off[1], rtol=0, atol=1e-9)
    else:
        np.testing.assert_allclose(off[2], p2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(state.offset, off[3], rtol=0, atol=0)
