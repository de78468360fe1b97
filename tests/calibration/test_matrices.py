import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from fluxcal.calibration import matrices as mat


def test_orthogonal_angles_give_identity():
    m = mat.orthogonalisation_matrix(np.array([90.0]), np.array([90.0]), np.array([90.0]))
    np.testing.assert_allclose(m[0], np.eye(3), atol=1e-15)


@given(st.floats(80, 100), st.floats(80, 100), st.floats(80, 100))
def test_unit_columns_and_angles(xy, xz, yz):
    m = mat.orthogonalisation_matrix(np.array([xy]), np.array([xz]), np.array([yz]))[0]
    np.testing.assert_allclose(np.linalg.norm(m, axis=0), 1.0, atol=1e-12)
    g = m.T @ m  # Gram matrix of the axes = cosines of the angles between them
    np.testing.assert_allclose(
        [g[0, 1], g[0, 2], g[1, 2]], np.cos(np.deg2rad([xy, xz, yz])), atol=1e-12
    )


def test_apply_forms_agree():
    rng = np.random.default_rng(1)
    m, v = rng.normal(size=(50, 3, 3)), rng.normal(size=(50, 3))
    ref = np.array([m[i] @ v[i] for i in range(50)])
    np.testing.assert_allclose(mat.apply(m, v), ref, atol=1e-12)
    np.testing.assert_allclose(mat.apply(m[0], v), v @ m[0].T, atol=1e-12)
    index = rng.integers(0, 50, 200)
    vv = rng.normal(size=(200, 3))
    np.testing.assert_allclose(mat.apply_lookup(m, index, vv), mat.apply(m[index], vv), atol=1e-12)
    np.testing.assert_allclose(mat.solve(m, mat.apply(m, v)), v, atol=1e-9)
