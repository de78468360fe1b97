"""The compiled geometry loops against independent numpy / scipy computations.

Tolerances: the loops evaluate the same formulas as the numpy references in a different
order of operations, so results agree to a few ulp of the inputs (1e-12 relative on unit
quaternions and rotated unit-scale vectors; 1e-9 km on positions of ~1e8 km).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from fluxcal.geometry import compiled
from fluxcal.geometry.frames import _continuous, slerp
from fluxcal.geometry.positions import hermite, hermite_coefficients


def _leg(rng: np.random.Generator, m: int, span: float = 1000.0):
    nodes = np.sort(rng.uniform(0.0, span, m))
    nodes[0], nodes[-1] = 0.0, span
    quats = _continuous(Rotation.random(m, random_state=rng).as_quat())
    return nodes, quats


def _epochs(rng: np.random.Generator, n: int, span: float, order: str) -> np.ndarray:
    et = rng.uniform(-0.05 * span, 1.05 * span, n)  # includes extrapolation at both ends
    if order == "sorted":
        et.sort()
    return et


@pytest.mark.parametrize("order", ["sorted", "shuffled"])
@pytest.mark.parametrize("m", [2, 3, 50])
def test_slerp_quaternions_match_numpy_slerp(order, m):
    rng = np.random.default_rng(m)
    nodes, quats = _leg(rng, m)
    et = _epochs(rng, 5000, 1000.0, order)
    out = np.empty((et.size, 4))
    compiled.slerp_quaternions(*compiled.slerp_table(nodes, quats), et, out)
    np.testing.assert_allclose(out, slerp(nodes, quats, et), rtol=0, atol=1e-12)


def _reference_rotation(source, target, et, vectors, inverse):
    """R(J2000 -> target) R(source -> J2000) via scipy matrices of the numpy SLERP."""
    m = np.broadcast_to(np.eye(3), (et.size, 3, 3))
    if source is not None:
        m = Rotation.from_quat(slerp(*source, et)).as_matrix()
    if target is not None:
        m = np.transpose(Rotation.from_quat(slerp(*target, et)).as_matrix(), (0, 2, 1)) @ m
    if inverse:
        m = np.transpose(m, (0, 2, 1))
    return np.einsum("nij,nj->ni", m, vectors)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    legs=st.sampled_from(["source", "target", "both", "none"]),
    order=st.sampled_from(["sorted", "shuffled"]),
    inverse=st.tuples(st.booleans(), st.booleans()),
)
def test_slerp_rotate_matches_matrix_composition(seed, legs, order, inverse):
    rng = np.random.default_rng(seed)
    source = _leg(rng, int(rng.integers(2, 40))) if legs in ("source", "both") else None
    target = _leg(rng, int(rng.integers(2, 40))) if legs in ("target", "both") else None
    et = _epochs(rng, 400, 1000.0, order)
    vectors = [rng.normal(size=(et.size, 3)) for _ in range(2)]
    outs = [np.empty_like(v) for v in vectors]
    tables = [compiled.IDENTITY_TABLE if leg is None else compiled.slerp_table(*leg)
              for leg in (source, target)]
    compiled.slerp_rotate(*tables[0], *tables[1], et, tuple(vectors), inverse, tuple(outs))
    for v, out, inv in zip(vectors, outs, inverse, strict=True):
        expected = _reference_rotation(source, target, et, v, inv)
        np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)


def test_single_node_leg_is_a_constant_rotation():
    rng = np.random.default_rng(7)
    q = Rotation.random(random_state=rng).as_quat()[None]
    et = np.linspace(-5.0, 5.0, 11)
    v = rng.normal(size=(et.size, 3))
    out = np.empty_like(v)
    compiled.slerp_rotate(*compiled.slerp_table(np.array([0.0]), q), *compiled.IDENTITY_TABLE,
                          et, (v,), (False,), (out,))
    np.testing.assert_allclose(out, Rotation.from_quat(q[0]).apply(v), rtol=0, atol=1e-13)


@pytest.mark.parametrize("order", ["sorted", "shuffled"])
def test_hermite_positions_match_numpy_hermite(order):
    rng = np.random.default_rng(3)
    nodes = np.concatenate([[0.0], np.sort(rng.uniform(0, 86400, 60)), [86400.0]])
    # a heliocentric-scale orbit: 6e7 km, 50 km/s
    states = np.hstack([6e7 * rng.normal(size=(nodes.size, 3)),
                        50.0 * rng.normal(size=(nodes.size, 3))])
    et = _epochs(rng, 20000, 86400.0, order)
    coefficients = np.ascontiguousarray(hermite_coefficients(nodes, states))
    out = np.empty((et.size, 3))
    compiled.hermite_positions(nodes, coefficients, et, out)
    np.testing.assert_allclose(out, hermite(nodes, states, et), rtol=1e-13, atol=1e-6)


def test_hermite_positions_reproduce_a_cubic_exactly():
    """A cubic trajectory is its own Hermite interpolant (closed form, no reference code)."""
    nodes = np.array([0.0, 10.0, 25.0, 60.0])
    a = np.array([[1.0, -2.0, 3.0], [0.5, 0.1, -0.2], [0.01, 0.02, 0.03], [1e-4, -2e-4, 3e-4]])

    def pos(t):
        return a[0] + np.outer(t, a[1]) + np.outer(t**2, a[2]) + np.outer(t**3, a[3])

    def vel(t):
        return a[1] + np.outer(2 * t, a[2]) + np.outer(3 * t**2, a[3])

    states = np.hstack([pos(nodes), vel(nodes)])
    et = np.linspace(0.0, 60.0, 1201)
    out = np.empty((et.size, 3))
    compiled.hermite_positions(nodes, np.ascontiguousarray(hermite_coefficients(nodes, states)),
                               et, out)
    np.testing.assert_allclose(out, pos(et), rtol=0, atol=1e-11)


def test_rtn_rotate_against_explicit_basis():
    rng = np.random.default_rng(11)
    sun = rng.normal(size=(300, 3)) * 5e7
    pole = np.array([[0.1, -0.2, 0.97]])
    pole /= np.linalg.norm(pole)
    v = rng.normal(size=sun.shape)
    out = np.empty_like(v)
    compiled.rtn_rotate(sun, pole, v, out)
    for k in range(0, sun.shape[0], 37):  # brute force, one sample at a time
        r = sun[k] / np.linalg.norm(sun[k])
        t = np.cross(pole[0], r)
        t /= np.linalg.norm(t)
        basis = np.vstack([r, t, np.cross(r, t)])
        np.testing.assert_allclose(out[k], basis @ v[k], rtol=0, atol=1e-12)
    # the basis is orthonormal: norms are kept
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), np.linalg.norm(v, axis=1),
                               rtol=1e-13)


def test_unit_rows_and_norms():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(100, 3)) * 1e8
    out = np.empty_like(v)
    compiled.unit_rows(v, -1.0, out)
    norms = np.linalg.norm(v, axis=1)
    np.testing.assert_allclose(out, -v / norms[:, None], rtol=1e-15, atol=1e-16)
    got = np.empty(v.shape[0])
    compiled.row_norms(v, got)
    np.testing.assert_allclose(got, norms, rtol=1e-15)


def test_apply_matrix_is_a_matrix_product():
    rng = np.random.default_rng(2)
    m = Rotation.random(random_state=rng).as_matrix()
    v = rng.normal(size=(500, 3))
    out = np.empty_like(v)
    compiled.apply_matrix(m, v, out)
    np.testing.assert_allclose(out, v @ m.T, rtol=0, atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-540.0, 540.0, allow_nan=False), min_size=0, max_size=60),
       st.sampled_from([None, 2]))
def test_unwrap_degrees_is_numpys_unwrap_bit_for_bit(values, stride):
    # expected: numpy's own unwrap; steps of exactly +-180 and multiples of 360 included
    # by the edge list below, any sign; strided input as the products pass a column
    base = np.array(values + [180.0, 0.0, -180.0, 0.0, 360.0, -359.5, 179.75, -180.25])
    x = np.repeat(base, 2)[::stride] if stride else base
    out = np.empty(x.size)
    compiled.unwrap_degrees(x, out)
    np.testing.assert_array_equal(out, np.unwrap(x, period=360.0))
    assert np.array_equal(np.signbit(out), np.signbit(np.unwrap(x, period=360.0)))


def test_unwrap_degrees_on_a_day_of_azimuths():
    # a wrapped linear drift crossing +-180 many times, with noise: exactly numpy's
    rng = np.random.default_rng(7)
    true = np.cumsum(rng.normal(0.05, 3.0, 200_000))
    wrapped = (true + 180.0) % 360.0 - 180.0
    out = np.empty(wrapped.size)
    compiled.unwrap_degrees(wrapped, out)
    np.testing.assert_array_equal(out, np.unwrap(wrapped, period=360.0))
    compiled.unwrap_degrees(np.zeros(0), np.zeros(0))  # empty: nothing to do, no error


def test_unwrap_degrees_nan_as_numpy():
    # np.unwrap: a NaN step is not below the discontinuity, so all later values are NaN
    x = np.array([0.0, 10.0, np.nan, 350.0, -170.0, 200.0])
    out = np.empty(x.size)
    compiled.unwrap_degrees(x, out)
    np.testing.assert_array_equal(out, np.unwrap(x, period=360.0))
    assert np.isnan(out[2:]).all()


def _rtn_spherical_numpy(sun, et, grid, lat, az):
    """The numpy expressions `spherical_rtn` used before the compiled pass (the reference)."""
    out = np.empty((et.size, 3))
    out[:, 0] = np.linalg.norm(sun, axis=1)
    out[:, 1] = np.interp(et, grid, lat)
    a = np.interp(et, grid, np.unwrap(az, period=360.0))
    out[:, 2] = np.where(np.abs(a) > 180.0, (a + 180.0) % 360.0 - 180.0, a)
    return out


@pytest.mark.parametrize("order", ["sorted", "shuffled"])
@pytest.mark.parametrize("m", [1, 2, 7, 1000])
def test_rtn_spherical_interp_is_numpy_bit_for_bit(order, m):
    # expected: np.interp and numpy's wrap; epochs outside the grid on both sides, on the
    # nodes themselves, at the last node; azimuths wrapped and far beyond +-180 (both signs)
    rng = np.random.default_rng(m)
    grid = np.linspace(0.0, 1000.0, m) if m > 1 else np.array([500.0])
    lat = rng.uniform(-90.0, 90.0, m)
    az = np.cumsum(rng.normal(0.0, 200.0, m)) + rng.choice([-720.0, 0.0, 720.0])
    et = np.concatenate([rng.uniform(-50.0, 1050.0, 5000), grid, [grid[-1]] * 3])
    if order == "sorted":
        et.sort()
    sun = rng.normal(size=(et.size, 3)) * 5e7
    out = np.empty((et.size, 3))
    compiled.rtn_spherical_interp(sun, et, grid, lat, az, out)
    expected = _rtn_spherical_numpy(sun, et, grid, lat, az)
    np.testing.assert_array_equal(out[:, 1:], expected[:, 1:])
    # |sun|: the same sum of squares as row_norms (np.linalg.norm may sum differently)
    norms = np.empty(et.size)
    compiled.row_norms(sun, norms)
    np.testing.assert_array_equal(out[:, 0], norms)
    np.testing.assert_allclose(out[:, 0], expected[:, 0], rtol=1e-15)


def test_interp_into_non_finite_cases_as_numpy():
    # NaN epoch -> NaN; an infinite value at a node: numpy's fall-back from the right node
    grid = np.array([0.0, 1.0, 2.0, 3.0])
    lat = np.array([0.0, np.inf, np.inf, 1.0])
    az = np.array([10.0, 20.0, 30.0, 40.0])
    et = np.array([np.nan, 0.5, 1.0, 1.5, 2.5, 3.0, -1.0, 4.0])
    sun = np.ones((et.size, 3))
    out = np.empty((et.size, 3))
    with np.errstate(invalid="ignore"):
        expected = _rtn_spherical_numpy(sun, et, grid, lat, az)
    compiled.rtn_spherical_interp(sun, et, grid, lat, az, out)
    np.testing.assert_array_equal(out[:, 1:], expected[:, 1:])


def _table(rng: np.random.Generator, kind: str):
    if kind == "identity":
        return compiled.IDENTITY_TABLE
    if kind == "single":
        return compiled.slerp_table(np.array([500.0]), Rotation.random(
            1, random_state=rng).as_quat())
    return compiled.slerp_table(*_leg(rng, int(rng.integers(2, 40))))


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    attitude=st.sampled_from(["moving", "single"]),
    leg=st.sampled_from(["moving", "single", "identity"]),
    order=st.sampled_from(["sorted", "shuffled"]),
    write=st.tuples(st.booleans(), st.booleans(), st.booleans(), st.booleans()),
)
def test_attitude_frames_is_the_separate_passes_bit_for_bit(seed, attitude, leg, order, write):
    # expected: slerp_rotate (itself checked against scipy matrices above) and unit_rows,
    # each in its own pass; equality, not a tolerance (a frame computed later from the
    # J2000 field with Rotator must equal the one computed in the single pass)
    rng = np.random.default_rng(seed)
    et = _epochs(rng, 300, 1000.0, order)
    n = et.size
    source = _table(rng, attitude)
    table = _table(rng, leg)
    field = rng.normal(size=(n, 3)) * 3e4
    sun = rng.normal(size=(n, 3)) * 5e7
    planet = rng.normal(size=(n, 3)) * 1e4
    write_inertial, write_sun, write_pos, write_field = write
    empty = np.empty((0, 3))

    def buffer(wanted):
        return np.full((n, 3), np.nan) if wanted else empty

    got = {"inertial": buffer(write_inertial), "sun": buffer(write_sun)}
    pos_out, field_out = buffer(write_pos), buffer(write_field)
    compiled.attitude_frames(source, table, et, field, sun, planet, got["inertial"],
                             got["sun"], (pos_out, field_out))

    unit = np.empty_like(sun)
    compiled.unit_rows(sun, -1.0, unit)
    inertial, sun_body = np.empty_like(field), np.empty_like(field)
    compiled.slerp_rotate(*source, *compiled.IDENTITY_TABLE, et, (field, unit), (False, True),
                          (inertial, sun_body))
    if write_inertial:
        np.testing.assert_array_equal(got["inertial"], inertial)
    if write_sun:
        np.testing.assert_array_equal(got["sun"], sun_body)
    pos, rotated = np.empty_like(field), np.empty_like(field)
    compiled.slerp_rotate(*compiled.IDENTITY_TABLE, *table, et, (planet, inertial),
                          (False, False), (pos, rotated))
    if write_pos:
        np.testing.assert_array_equal(pos_out, pos)
    if write_field:
        np.testing.assert_array_equal(field_out, rotated)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_windows=st.integers(1, 6),
       order=st.sampled_from(["sorted", "shuffled"]))
def test_first_outside_matches_the_numpy_window_test(seed, n_windows, order):
    # expected: the numpy test it replaces (searchsorted on the window starts); epochs on
    # the window edges, between windows, before/after all windows, and NaN
    rng = np.random.default_rng(seed)
    edges = np.sort(rng.choice(np.arange(0.0, 100.0, 0.5), 2 * n_windows, replace=False))
    starts, ends = edges[0::2].copy(), edges[1::2].copy()
    et = np.concatenate([rng.uniform(-5.0, 105.0, 40), edges, [np.nan]])
    if order == "sorted":
        et.sort()
    else:
        rng.shuffle(et)
    for size in range(et.size + 1):
        part = et[:size]
        idx = np.searchsorted(starts, part, side="right") - 1
        ok = (idx >= 0) & (part <= ends[np.clip(idx, 0, None)])
        expected = int(np.flatnonzero(~ok)[0]) if not ok.all() else -1
        assert compiled.first_outside(starts, ends, part) == expected
