import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fluxcal.calibration.gain_matrix import counts_to_nt, nt_to_counts, range_conversion
from fluxcal.calibration.rate_latency import correct_latency
from fluxcal.missions.messenger.calibration_data import load_calibration

CAL = load_calibration("2012-01-01")


def test_eq8_written_out():
    # eq. 8 component by component, fine range (Table 4)
    c = np.array([[1000.0, -2000.0, 300.0]])
    kx, ky, kz, a, b, g = 0.046769, 0.046673, 0.047997, -0.00462, 0.00053, -0.00736
    bx = kx * 1000
    by = a * kx * 1000 + ky * -2000
    bz = b * kx * 1000 + g * ky * -2000 + kz * 300
    np.testing.assert_allclose(counts_to_nt(c, np.array([0]), CAL.matrices)[0], [bx, by, bz])


@settings(max_examples=50, deadline=None)
@given(arrays(float, (20, 3), elements=st.floats(-30000, 30000)),
       arrays(np.int64, 20, elements=st.integers(0, 1)))
def test_round_trip(counts, flags):
    back = nt_to_counts(counts_to_nt(counts, flags, CAL.matrices), flags, CAL.matrices)
    np.testing.assert_allclose(back, counts, atol=1e-8)


def test_range_conversion_preserves_field():
    c_fine = np.array([-71.0, -178.2, 409.7])
    conv = range_conversion(CAL.matrices)
    c_coarse = conv[1] @ c_fine
    np.testing.assert_allclose(CAL.matrices[1] @ c_coarse, CAL.matrices[0] @ c_fine, atol=1e-12)
    # roughly the fine/coarse gain ratio (~1/33.5)
    np.testing.assert_allclose(c_coarse / c_fine, 0.046769 / 1.56513, rtol=0.02)


def test_latency_per_sample_rate():
    met = np.array([100.0, 100.0, 100.0])
    got = correct_latency(met, np.array([10, 7, 0]), CAL.net_lag_s)
    np.testing.assert_allclose(got, [100 - 0.042, 100 - 1.186, 100 - 2.358])
