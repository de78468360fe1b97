"""HK conversions against the nominal relations and Table 1 printed in seed 003."""

import numpy as np
import pytest

from fluxcal.calibration import thermal
from fluxcal.missions.rosetta import calib, hk

NOM = calib.load_nominal_conversion()
C = calib.load_ground_calibration("OB").thermistor


@pytest.mark.parametrize(
    ("tlm", "volts"),
    [(0x80, 4.673), (0x00, 5.00), (0x7F, 5.327)],  # sec. 4.2.2.3 nominal relation
)
def test_positive_supply_nominal_table(tlm, volts):
    # the printed relation is given to 1 mV and is itself ~1 LSB (2.56 mV) rough:
    # -128 * 0.002562 = -0.328 V, printed -0.327 V; so tolerate 2 mV.
    assert hk.positive_supply(np.array([tlm]), NOM)[0] == pytest.approx(volts, abs=2e-3)


@pytest.mark.parametrize(
    ("tlm", "volts"),
    [(0x80, -5.36), (0x00, -5.00), (0x7F, -4.64)],  # sec. 4.2.2.4 nominal relation
)
def test_negative_supply_nominal_table(tlm, volts):
    # printed to 10 mV
    assert hk.negative_supply(np.array([tlm]), NOM)[0] == pytest.approx(volts, abs=5e-3)


def test_supply_cal_factors_match_seed():
    # CAL_FACTOR printed as 0.002562 (sec. 4.2.2.3) and 0.002838 (sec. 4.2.2.4)
    assert hk.supply_cal_factor(NOM["hk_positive_supply"]) == pytest.approx(0.002562, abs=5e-7)
    assert hk.supply_cal_factor(NOM["hk_negative_supply"]) == pytest.approx(0.002838, abs=5e-7)
    # dividers printed as 0.476389 and 0.21503
    assert hk.divider(NOM["hk_positive_supply"]) == pytest.approx(0.476389, abs=1e-6)
    assert hk.divider(NOM["hk_negative_supply"]) == pytest.approx(0.21503, abs=1e-5)


def test_hk_field_nominal_relation():
    # sec. 4.2.2.1: converted 0000h <-> B_min, 8000h <-> 0, FFFFh <-> B_max; the TLM word
    # holds (ADC - 2^19) shr 4, so converted 0000h is TLM 8000h and converted 8000h is TLM 0.
    b = hk.hk_field(np.array([0x8000, 0x0000, 0x7FFF]), NOM)
    lsb = 32768 / 65535
    np.testing.assert_allclose(b, [-16384.0, 0.0, 16384.0], atol=lsb)


def test_reference_voltage_typical():
    # sec. 4.2.2.2: monitored 1.2497 V behind the 0.49996 divider means U_REF = 2.4996 V.
    adc = 2**19 + round(1.2497 / 2.5 * 2**19)
    tlm = adc - 2**19
    assert hk.reference_voltage(np.array([tlm]), NOM)[0] == pytest.approx(2.4996, abs=2e-5)


# Table 1 of seed 003 sec. 3.3.3: T [deg C], R(T) [Ohm], U(T) [V]
TABLE1 = np.array(
    [
        [-150.0, 423.219, 0.743420],
        [-140.0, 461.402, 0.789310],
        [-130.0, 499.567, 0.832850],
        [-120.0, 537.730, 0.874230],
        [-110.0, 575.906, 0.913610],
        [-100.0, 614.108, 0.951160],
        [-90.0, 652.351, 0.987000],
        [-80.0, 690.646, 1.02128],
        [-70.0, 729.005, 1.05408],
        [-60.0, 767.436, 1.08552],
        [-50.0, 805.950, 1.11569],
        [-40.0, 844.555, 1.14466],
        [-30.0, 883.256, 1.17251],
        [-20.0, 922.061, 1.19931],
        [-10.0, 960.974, 1.22512],
        [0.0, 1000.00, 1.25000],
        [10.0, 1039.14, 1.27399],
        [20.0, 1078.40, 1.29715],
        [30.0, 1117.77, 1.31951],
        [40.0, 1157.26, 1.34112],
        [50.0, 1196.86, 1.36201],
        [60.0, 1236.58, 1.38222],
        [70.0, 1276.41, 1.40178],
        [80.0, 1316.36, 1.42072],
        [90.0, 1356.43, 1.43907],
        [100.0, 1396.60, 1.45686],
        [110.0, 1436.90, 1.47411],
        [120.0, 1477.31, 1.49084],
        [130.0, 1517.84, 1.50708],
        [140.0, 1558.48, 1.52286],
        [150.0, 1599.24, 1.53818],
    ]
)


@pytest.mark.parametrize("row", TABLE1[1:], ids=[f"{t:g}C" for t in TABLE1[1:, 0]])
def test_thermistor_polynomial_table1(row):
    t, _, u = row
    # The cubic is a fit to the PT1000 curve; its residual against Table 1 over
    # -140..150 C peaks at 0.63 K (at 150 C) and stays below 0.4 K inside -140..140 C.
    tol = 0.65 if t > 140 else 0.4
    assert thermal.thermistor_temperature(np.array([u]), C)[0] == pytest.approx(t, abs=tol)


def test_table1_voltage_is_the_divider():
    # sec. 4.2.1: U = U_ref / (R_ser / R + 1) with U_ref = 2.5 V, R_ser = 1 kOhm
    u = thermal.pt_divider_voltage(TABLE1[:, 1], 2.5, 1000.0)
    np.testing.assert_allclose(u, TABLE1[:, 2], atol=6e-6)  # table printed to 6 digits


def test_thermistor_counts_nominal():
    # sec. 4.2.1: 1.25 V (0 C) is ADC 2^19 + 2^18, TLM (ADC - 2^19) shr 4 = 16384
    assert hk.thermistor_voltage(np.array([16384]), NOM)[0] == pytest.approx(1.25, abs=1e-4)
    u = np.linspace(0.5, 1.6, 50)
    back = hk.thermistor_voltage(hk.thermistor_counts(u, NOM), NOM)
    assert np.abs(back - u).max() <= 5 / 65535 / 2 + 1e-12  # half an LSB


def test_hk_temperature_kelvin():
    t = hk.hk_temperature(np.array([16384]), C, NOM)[0]
    # 1.25 V -> 0 C on the Table-1 curve; cubic fit error at 0 C ~0.2 K
    assert t == pytest.approx(273.15, abs=0.3)


def test_thermistor_inverse():
    t = np.linspace(-140, 40, 31)
    u = thermal.thermistor_voltage(t, C, -2.7)
    np.testing.assert_allclose(thermal.thermistor_temperature(u, C, -2.7), t, atol=1e-9)


def test_reference_divider_is_printed_value():
    # sec. 4.2.2.2 prints VOLT_DIVIDER = 0.49996 (see docs/decisions/rosetta.md)
    assert hk.divider(NOM["hk_reference_voltage"]) == pytest.approx(0.49996, abs=1e-5)


# ---------------------------------------------------------------------------------------
# The whole chain voltage -> 20-bit ADC -> PIU operation -> TLM word -> physical value, with
# the PIU operations written out from sec. 4.2.2.3-4.2.2.5 (independent of fluxcal's code):
# 80000h <-> 0 V, FFFFFh <-> +2.5 V (sec. 4.2.1).
# ---------------------------------------------------------------------------------------
def _adc(volts):
    """20-bit bipolar ADC count of an input voltage (sec. 4.2.1)."""
    return 2**19 + np.rint(np.asarray(volts) * (2**20 - 1) / 5.0).astype(np.int64)


@pytest.mark.parametrize("supply", np.linspace(4.70, 5.30, 13))
def test_positive_supply_through_piu(supply):
    # sec. 4.2.2.3: monitored behind 90956/(99972+90956); TLM = (((ADC-2^19) shr 4) - 79F7h) shr 4,
    # 8 bits kept.  Two floor shifts lose < 1 LSB of the printed CAL_FACTOR (2.562 mV).
    adc = _adc(supply * 90956 / (99972 + 90956))
    tlm = ((((adc - 2**19) >> 4) - 0x79F7) >> 4) & 0xFF
    got = hk.positive_supply(np.array([tlm]), NOM)[0]
    assert supply - 0.002562 - 1e-3 <= got <= supply + 1e-3


@pytest.mark.parametrize("supply", np.linspace(-5.30, -4.70, 13))
def test_negative_supply_through_piu(supply):
    # sec. 4.2.2.4: behind 27400/(100024+27400); TLM = (((ADC-2^19) shr 4) + 370Eh) shr 3, 8 bits
    adc = _adc(supply * 27400 / (100024 + 27400))
    tlm = ((((adc - 2**19) >> 4) + 0x370E) >> 3) & 0xFF
    got = hk.negative_supply(np.array([tlm]), NOM)[0]
    assert supply - 0.002838 - 1e-3 <= got <= supply + 1e-3


@pytest.mark.parametrize("row", TABLE1[1:], ids=[f"{t:g}C" for t in TABLE1[1:, 0]])
def test_table1_through_thermistor_words(row):
    # Table 1 voltage -> ADC -> TLM = (ADC - 2^19) shr 4 (sec. 4.2.2.5) -> fluxcal's science
    # conversion (word -> U -> cubic - T_OFF) + T_OFF: the Table-1 temperature within the cubic's
    # fit error (see test_thermistor_polynomial_table1) plus one 16-bit word (76 uV, < 0.03 K).
    from fluxcal.missions.rosetta import level_a

    t, _, u = row
    word = (_adc(u) - 2**19) >> 4
    cal = calib.load_ground_calibration("IB")
    got = level_a.sensor_temperature(np.array([word]), cal, NOM)[0] + cal.thermistor_offset
    tol = (0.65 if t > 140 else 0.4) + 0.03
    assert got == pytest.approx(t, abs=tol)


def test_reference_voltage_nominal_relation():
    # sec. 4.2.2.2: TLM = ADC - 2^19 as unsigned 20-bit; converted 00000h <-> -2.5 V,
    # 80000h <-> 0, FFFFFh <-> +2.5 V, then divided by VOLT_DIVIDER (0.49996)
    tlm = np.array([0x80000, 0x00000, 0x7FFFF])
    lsb = 5.0 / (2**20 - 1)
    np.testing.assert_allclose(
        hk.reference_voltage(tlm, NOM) * 0.49996, [-2.5, 0.0, 2.5], atol=lsb + 2e-5
    )
