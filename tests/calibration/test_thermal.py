import numpy as np

from fluxcal.calibration import thermal


def test_polynomial_columns_and_trailing_zeros():
    c = np.array([[1.0, 2.0], [0.5, 0.0], [0.0, 1.0], [0.0, 0.0]])
    x = np.array([0.0, 2.0])
    np.testing.assert_allclose(thermal.polynomial(c, x), [[1.0, 2.0], [2.0, 6.0]])
    np.testing.assert_allclose(thermal.polynomial([1.0, 0.0, 0.0], x), [1.0, 1.0])


def test_linear_in_temperature():
    out = thermal.linear_in_temperature([[1.0, 2.0, 3.0], [0.1, 0.2, 0.3]], np.array([10.0]))
    np.testing.assert_allclose(out, [[2.0, 4.0, 6.0]])
