"""Bipolar ADC counts <-> physical values (nominal linear conversion).

An ``n``-bit bipolar ADC maps ``0 .. 2**n - 1`` linearly onto ``vmin .. vmax``; telemetry
usually carries the count minus ``2**(n-1)`` (a signed value) or that value in two's
complement.  These pure functions do the conversion both ways.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.1, 4.2.2.1, 4.2.3.1.
"""

from __future__ import annotations

import numpy as np


def nominal_factor(vmin: float, vmax: float, bits: int) -> float:
    """Return ``(vmax - vmin) / (2**bits - 1)``, the value of one count (seed 003, sec. 4.2.3.1)."""
    return (vmax - vmin) / (2**bits - 1)


def signed_to_value(counts: np.ndarray, vmin: float, vmax: float, bits: int) -> np.ndarray:
    """Convert signed counts ``-2**(bits-1) .. 2**(bits-1)-1`` to physical values.

    ``value = (counts + 2**(bits-1)) * (vmax - vmin) / (2**bits - 1) + vmin``.

    Parameters
    ----------
    counts : array_like of int
        Signed counts (the EDITED RAW science field data of seed 003).
    vmin, vmax : float
        Physical values of the lowest and highest count.
    bits : int
        ADC resolution.

    Returns
    -------
    ndarray of float64

    Raises
    ------
    ValueError
        If a count lies outside the signed range.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.1.
    """
    counts = np.asarray(counts)
    half = 2 ** (bits - 1)
    if counts.size and (counts.min() < -half or counts.max() > half - 1):
        raise ValueError(f"counts must lie within {-half}..{half - 1} for a {bits}-bit ADC")
    return (counts + half) * nominal_factor(vmin, vmax, bits) + vmin


def value_to_signed(value: np.ndarray, vmin: float, vmax: float, bits: int) -> np.ndarray:
    """Inverse of `signed_to_value`: nearest signed count, clipped to the ADC range."""
    half = 2 ** (bits - 1)
    counts = (
        np.rint((np.asarray(value, dtype=float) - vmin) / nominal_factor(vmin, vmax, bits)) - half
    )
    return np.clip(counts, -half, half - 1).astype(np.int64)


def twos_complement_to_offset_binary(tlm: np.ndarray, bits: int) -> np.ndarray:
    """Add ``2**(bits-1)`` below half range, subtract it above (seed 003, sec. 4.2.2.1).

    Turns an unsigned TLM word holding ``ADC - 2**(bits-1)`` in two's complement back
    into the ADC's offset-binary count ``0 .. 2**bits - 1``.
    """
    tlm = np.asarray(tlm, dtype=np.int64)
    half = 2 ** (bits - 1)
    if tlm.size and (tlm.min() < 0 or tlm.max() > 2 * half - 1):
        raise ValueError(f"TLM words must lie within 0..{2 * half - 1} for {bits} bits")
    return np.where(tlm < half, tlm + half, tlm - half)


def to_signed(tlm: np.ndarray, bits: int) -> np.ndarray:
    """Read unsigned ``bits``-bit words as two's complement signed integers.

    Words ``>= 2**(bits-1)`` become negative (80h -> -128 for 8 bits, as the nominal
    relations of seed 003, sec. 4.2.2.3/4.2.2.4 print).
    """
    tlm = np.asarray(tlm, dtype=np.int64)
    full = 2**bits
    if tlm.size and (tlm.min() < 0 or tlm.max() > full - 1):
        raise ValueError(f"TLM words must lie within 0..{full - 1} for {bits} bits")
    return np.where(tlm >= full // 2, tlm - full, tlm)
