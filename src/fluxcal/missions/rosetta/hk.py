"""Nominal conversion of RPC-MAG housekeeping ADC counts to physical values.

Pure functions, one per HK quantity, plus `hk_level_a` (``Dataset -> Dataset``).  The
nominal constants (ranges, voltage dividers, scale factors) come from
``data/nominal_conversion.toml`` via `fluxcal.missions.rosetta.calib.load_nominal_conversion`.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.1, 4.2.2.1-4.2.2.6.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from fluxcal.calibration import counts as cnt
from fluxcal.calibration.thermal import polynomial

KELVIN = 273.15


def hk_field(tlm: np.ndarray, nominal: dict) -> np.ndarray:
    """16-bit HK field words -> engineering nT (seed 003, sec. 4.2.2.1).

    ``converted = tlm + 8000h`` below 8000h, ``tlm - 8000h`` above;
    ``B = converted * (B_max - B_min) / (2^16 - 1) + B_min``.
    """
    p = nominal["hk_field"]
    conv = cnt.twos_complement_to_offset_binary(tlm, p["bits"])
    return conv * cnt.nominal_factor(p["b_min_nt"], p["b_max_nt"], p["bits"]) + p["b_min_nt"]


def divider(section: dict) -> float:
    """Voltage-divider ratio ``R_low / (R_low + R_high)`` of an HK channel (sec. 4.2.1)."""
    return section["divider_r_low_ohm"] / (
        section["divider_r_low_ohm"] + section["divider_r_high_ohm"]
    )


def reference_voltage(tlm: np.ndarray, nominal: dict) -> np.ndarray:
    """20-bit HK words -> ADC reference voltage in V (seed 003, sec. 4.2.2.2)."""
    p = nominal["hk_reference_voltage"]
    conv = cnt.twos_complement_to_offset_binary(tlm, p["bits"])
    u = conv * cnt.nominal_factor(p["u_min_v"], p["u_max_v"], p["bits"]) + p["u_min_v"]
    return u / divider(p)


def supply_cal_factor(section: dict) -> float:
    """``CAL_FACTOR = U_ref / ((2^20 - 1) * divider) * scale`` (sec. 4.2.2.3 / 4.2.2.4)."""
    return (
        section["u_ref_v"] / ((2 ** section["adc_bits"] - 1) * divider(section)) * section["scale"]
    )


def _supply(tlm: np.ndarray, section: dict) -> np.ndarray:
    conv = cnt.to_signed(tlm, section["bits"])
    return supply_cal_factor(section) * conv + section["u_center_v"]


def positive_supply(tlm: np.ndarray, nominal: dict) -> np.ndarray:
    """8-bit HK words -> +5 V supply voltage in V (seed 003, sec. 4.2.2.3)."""
    return _supply(tlm, nominal["hk_positive_supply"])


def negative_supply(tlm: np.ndarray, nominal: dict) -> np.ndarray:
    """8-bit HK words -> -5 V supply voltage in V (seed 003, sec. 4.2.2.4)."""
    return _supply(tlm, nominal["hk_negative_supply"])


def thermistor_voltage(tlm: np.ndarray, nominal: dict) -> np.ndarray:
    """16-bit thermistor words -> voltage: ``U = (TLM + 2^15) * 5 V / (2^16 - 1) - 2.5 V``.

    The same conversion serves the science files' thermistor columns (issue 4).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.2.5.
    """
    p = nominal["thermistor"]
    tlm = np.asarray(tlm, dtype=np.int64)
    top = 2 ** p["bits"] - 1
    if tlm.size and (tlm.min() < 0 or tlm.max() > top):
        raise ValueError(f"thermistor words must lie within 0..{top}")
    return (tlm + 2 ** (p["bits"] - 1)) * cnt.nominal_factor(
        p["u_min_v"], p["u_max_v"], p["bits"]
    ) + p["u_min_v"]


def thermistor_counts(voltage: np.ndarray, nominal: dict) -> np.ndarray:
    """Inverse of `thermistor_voltage` (nearest word), for forward models."""
    p = nominal["thermistor"]
    nf = cnt.nominal_factor(p["u_min_v"], p["u_max_v"], p["bits"])
    words = np.rint((np.asarray(voltage) - p["u_min_v"]) / nf) - 2 ** (p["bits"] - 1)
    return np.clip(words, 0, 2 ** p["bits"] - 1).astype(np.int64)


def hk_temperature(tlm: np.ndarray, coefficients: np.ndarray, nominal: dict) -> np.ndarray:
    """16-bit thermistor words -> raw sensor temperature in K (seed 003, sec. 4.2.2.5).

    The HK conversion applies the cubic without the thermistor offset T^O (as sec.
    4.2.2.5 prints it); science data use the calibrated temperature of sec. 4.2.3.2.
    """
    return polynomial(coefficients, thermistor_voltage(tlm, nominal)) + KELVIN


def hk_level_a(raw: xr.Dataset, thermistor: np.ndarray, nominal: dict) -> xr.Dataset:
    """Convert a raw HK dataset (see `fluxcal.missions.rosetta.io.read_hk_csv`) to LEVEL_A HK.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.2.6 (list of LEVEL_A HK quantities).
    """
    out = xr.Dataset(coords=raw.coords, attrs=dict(raw.attrs, level="A (HK)"))
    out["obt"] = raw["obt"]
    for name in ("t_ob", "t_ib"):
        out[name] = (
            "time",
            hk_temperature(raw[f"{name}_counts"].values, thermistor, nominal),
            {"units": "K"},
        )
    for name in ("stage_a_id", "stage_b_id", "filter_cfg"):
        out[name] = raw[name]
    out["ref_voltage"] = (
        "time",
        reference_voltage(raw["ref_voltage_counts"].values, nominal),
        {"units": "V"},
    )
    out["pos_voltage"] = (
        "time",
        positive_supply(raw["pos_voltage_counts"].values, nominal),
        {"units": "V"},
    )
    out["neg_voltage"] = (
        "time",
        negative_supply(raw["neg_voltage_counts"].values, nominal),
        {"units": "V"},
    )
    out["b_ob"] = (
        ("time", "component"),
        hk_field(raw["b_ob_counts"].values, nominal),
        {"units": "nT"},
    )
    return out
