"""Compressed IMAP MAG vectors: an independent encoder written here from the description.

The encoder below follows the layout of the team's description (a 6-bit width, a range
section flag, the reference vector per sensor, Fibonacci codes of zig-zag differences,
the switch to uncompressed ``W``-bit values after a vector longer than 60 bits, the
range section after byte padding) with Python strings of '0'/'1' and shares no code
with `fluxcal.missions.imap.vectors`.  Packets are built on the header of one of the
team's real packets (``mag_l1_test_data.pkts``: 2 vectors/s per sensor) with the
``COMPRESSION`` bit set, the seconds (``PUS_SSUBTYPE``) and the length field changed.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap import l1b
from fluxcal.missions.imap.packets import read_packets
from fluxcal.missions.imap.vectors import decode_vectors
from tests.missions.imap.conftest import IMAP, XTCE

HEADER_BYTES = 27  # the VECTORS field starts after 27 bytes (test_packets)


def _fibonacci(n: int) -> str:
    """Fibonacci code of n >= 1: Zeckendorf bits, weight 1, 2, 3, 5, ... first, then '1'."""
    weights = [1, 2]
    while weights[-1] <= n:
        weights.append(weights[-1] + weights[-2])
    bits = ["0"] * len(weights)
    for k in range(len(weights) - 1, -1, -1):
        if weights[k] <= n:
            bits[k] = "1"
            n -= weights[k]
    return "".join(bits).rstrip("0") + "1"


def _zigzag(d: int) -> int:
    return 2 * d if d >= 0 else -2 * d - 1


def _twos(value: int, width: int) -> str:
    return format(value & ((1 << width) - 1), f"0{width}b")


def encode(sensors: list[tuple[list[tuple[int, int, int]], list[int]]], width: int,
           with_ranges: bool) -> tuple[bytes, list[bool]]:
    """The compressed VECTORS field of (counts, ranges) per sensor; and which sensors
    switched to uncompressed values."""
    out = _twos(width, 6) + ("1" if with_ranges else "0") + "0"
    switched = []
    for counts, ranges in sensors:
        out += "".join(_twos(c, width) for c in counts[0]) + format(ranges[0], "02b")
        packed = True
        for before, now in zip(counts[:-1], counts[1:], strict=True):
            if packed:
                code = "".join(_fibonacci(_zigzag(b - a) + 1)
                               for a, b in zip(before, now, strict=True))
                out += code
                packed = len(code) <= 60
            else:
                out += "".join(_twos(c, width) for c in now)
        switched.append(not packed)
    out += "0" * (-len(out) % 8)
    if with_ranges:
        out += "".join(format(r, "02b") for _, ranges in sensors for r in ranges[1:])
        out += "0" * (-len(out) % 8)
    return int(out, 2).to_bytes(len(out) // 8, "big") if out else b"", switched


def _packet(field: bytes, seconds: int, template: bytes) -> bytes:
    head = bytearray(template[:HEADER_BYTES])
    head[12] = seconds - 1  # PUS_SSUBTYPE
    head[13] |= 0x80  # COMPRESSION
    packet = bytes(head) + field
    head[4:6] = (len(packet) - 7).to_bytes(2, "big")
    return bytes(head) + field


@pytest.fixture(scope="module")
def template() -> bytes:
    path = IMAP / "mag_l1_test_data.pkts"
    if not path.is_file() or not XTCE.is_file():
        pytest.skip(f"IMAP MAG team data not found at {IMAP} (../shared beside the checkout)")
    data = path.read_bytes()
    return data[: int.from_bytes(data[4:6], "big") + 7]


def _sensor(draw, n: int, width: int, ranges_change: bool):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    step = st.integers(-(1 << min(width, 12)), 1 << min(width, 12))
    counts = [tuple(draw(st.integers(lo, hi)) for _ in range(3))]
    for _ in range(n - 1):
        # mostly small steps, sometimes a jump anywhere (forces the 60-bit switch)
        if draw(st.integers(0, 9)) == 0:
            counts.append(tuple(draw(st.integers(lo, hi)) for _ in range(3)))
        else:
            counts.append(tuple(min(hi, max(lo, c + draw(step))) for c in counts[-1]))
    first = draw(st.integers(0, 3))
    ranges = ([first] + [draw(st.integers(0, 3)) for _ in range(n - 1)] if ranges_change
              else [first] * n)
    return counts, ranges


@st.composite
def packets(draw):
    seconds = draw(st.integers(1, 8))
    width = draw(st.integers(1, 20))
    with_ranges = draw(st.booleans())
    return (seconds, width, with_ranges,
            [_sensor(draw, 2 * seconds, width, with_ranges) for _ in range(2)])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=packets())
def test_decoder_inverts_an_independent_encoder(case, template: bytes) -> None:
    seconds, width, with_ranges, sensors = case
    field, _ = encode(sensors, width, with_ranges)
    decoded = decode_vectors(read_packets(_packet(field, seconds, template), xtce=XTCE))
    assert decoded.width.tolist() == [width]
    for side, (counts, ranges) in enumerate(sensors):
        take = decoded.secondary == bool(side)
        assert decoded.counts[take].tolist() == [list(c) for c in counts]
        assert decoded.range[take].tolist() == ranges
        assert decoded.index[take].tolist() == list(range(2 * seconds))


def test_the_60_bit_switch_and_both_signs(template: bytes) -> None:
    # a jump of +-2**17 needs > 60 bits: every later vector of that sensor is W bits
    width = 20
    pri = [(0, 0, 0), (1, -1, 2), (131072, -131072, 5), (-7, 8, -9), (-8, 8, -9), (0, 0, 0)]
    sec = [(-5, 5, 0), (-6, 6, 1), (-6, 7, 1), (0, 0, 0), (524287, -524288, 3), (1, 1, 1)]
    sensors = [(pri, [0, 1, 2, 3, 0, 1]), (sec, [3, 3, 2, 2, 1, 1])]
    field, switched = encode(sensors, width, with_ranges=True)
    assert switched == [True, True]
    decoded = decode_vectors(read_packets(_packet(field, 3, template), xtce=XTCE))
    assert decoded.counts.tolist() == [list(c) for c in pri + sec]
    assert decoded.range.tolist() == [0, 1, 2, 3, 0, 1, 3, 3, 2, 2, 1, 1]


def test_l1b_rescales_compressed_counts_by_2_to_16_minus_w() -> None:
    import xarray as xr

    ds = xr.Dataset({"compression": ("time", np.array([0, 1, 1, 1])),
                     "compression_width": ("time", np.array([16, 18, 13, 16]))})
    np.testing.assert_array_equal(l1b.compression_scale(ds), [1.0, 0.25, 8.0, 1.0])


@pytest.mark.parametrize(("damage", "message"), [
    (lambda f: f[:12], "compressed VECTORS field of 96 bits ends inside primary vector"),
    (lambda f: bytes([0]) + f[1:], "compression width 0 bits is not 1..20"),
    (lambda f: bytes([21 << 2]) + f[1:], "compression width 21 bits is not 1..20"),
    (lambda f: f[:2] + b"\x00" * (len(f) - 2), "ends inside primary vector|code runs past"),
])
def test_damaged_compressed_packet_names_packet_and_field(damage, message,
                                                          template: bytes) -> None:
    sensors = [([(k, -k, 2 * k) for k in range(16)], [1] * 16)] * 2
    field, _ = encode(sensors, 16, with_ranges=False)
    packet = _packet(damage(field), 8, template)
    with pytest.raises(InputFormatError, match=message) as err:
        decode_vectors(read_packets(packet, xtce=XTCE, name="damaged.pkts"))
    assert err.value.field == "VECTORS" and err.value.path == "damaged.pkts"
    assert "packet 0 (sequence count 5, APID 1052)" in str(err.value)


def test_range_section_cut_short_is_named(template: bytes) -> None:
    sensors = [([(k, k, k) for k in range(16)], [k % 4 for k in range(16)])] * 2
    field, _ = encode(sensors, 16, with_ranges=True)  # 30 ranges: 60 bits in 8 bytes
    with pytest.raises(InputFormatError, match="range section needs 4 bits more"):
        decode_vectors(read_packets(_packet(field[:-1], 8, template), xtce=XTCE))


