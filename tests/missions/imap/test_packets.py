"""IMAP MAG L0: the team's decommutation (mag_l0_test_output.csv) reproduced exactly."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap import packets


def _team_l0(imap_data: Path) -> list[dict[str, str]]:
    with (imap_data / "mag_l0_test_output.csv").open(newline="") as fh:
        return list(csv.DictReader(fh))


def test_l0_header_fields_match_the_team(imap_data: Path) -> None:
    decoded = packets.read_packets(imap_data / "mag_l0_test_data.pkts")
    table = packets.l0_table(decoded)
    team = _team_l0(imap_data)
    assert len(decoded) == len(team) == 36
    for column in team[0]:
        if column == "CCSDS_HEX":
            continue
        assert [str(v) for v in table[column]] == [row[column] for row in team], column
    assert set(table["PHAPID"]) == {1052, 1068}  # normal and burst both present


def test_l0_packet_bytes_match_the_team(imap_data: Path) -> None:
    # the team's CCSDS_HEX is each packet without its last byte: that byte lies after the
    # 50-bit vectors (padding to the byte) and is zero in every packet
    decoded = packets.read_packets(imap_data / "mag_l0_test_data.pkts")
    n_pri, n_sec = packets.vector_counts(decoded)
    for i, row in enumerate(_team_l0(imap_data)):
        raw = decoded.raw[i]
        assert raw[:-1].hex().upper() == row["CCSDS_HEX"]
        assert raw[-1] == 0
        assert (n_pri[i] + n_sec[i]) * packets.VECTOR_BITS <= (len(decoded.vectors[i]) - 1) * 8
        # VECTORS is the packet after its 27 header bytes
        assert decoded.vectors[i] == raw[27:]


def _unpack_with_python_ints(data: bytes, count: int) -> list[tuple[int, int, int, int]]:
    """Independent unpacking: the field as one big integer, fields cut by shifts."""
    value = int.from_bytes(data, "big")
    total = len(data) * 8
    out = []
    for k in range(count):
        word = (value >> (total - (k + 1) * 50)) & ((1 << 50) - 1)
        axes = [(word >> (34 - 16 * j)) & 0xFFFF for j in range(3)]
        axes = [a - 65536 if a >= 32768 else a for a in axes]
        out.append((*axes, word & 3))
    return out


def test_burst_vectors_unpack_like_an_independent_bit_reader(imap_data: Path) -> None:
    decoded = packets.read_packets(imap_data / "mag_l0_test_data.pkts")
    i = int(np.flatnonzero(decoded.fields["PKT_APID"] == 1068)[0])
    (pc, pr), (sc, sr) = packets.packet_vectors(decoded, i)
    assert (len(pr), len(sr)) == (256, 32)  # 64 and 8 vectors/s, 4 s
    expected = _unpack_with_python_ints(decoded.vectors[i], 288)
    got = [(*c, r) for c, r in zip(np.vstack([pc, sc]).tolist(),
                                   np.concatenate([pr, sr]).tolist(), strict=True)]
    assert got == expected


def _first_packet(imap_data: Path) -> bytes:
    data = (imap_data / "mag_l1_test_data.pkts").read_bytes()
    return data[: int.from_bytes(data[4:6], "big") + 7]


def test_truncated_file_names_the_packet(imap_data: Path) -> None:
    one = _first_packet(imap_data)
    with pytest.raises(InputFormatError, match=r"packet 1 \(sequence count 5, APID 1052\)"
                       r".*truncated") as err:
        packets.read_packets(one + one[:100], name="cut.pkts")
    assert err.value.field == "PKT_LEN" and err.value.path == "cut.pkts"


def test_unknown_apid_names_the_packet(imap_data: Path) -> None:
    one = bytearray(_first_packet(imap_data))
    one[1] += 1  # APID 1053
    with pytest.raises(InputFormatError, match=r"packet 0 \(sequence count 5, APID 1053\)"):
        packets.read_packets(bytes(one))


def test_compressed_packet_is_refused_by_name(imap_data: Path) -> None:
    one = bytearray(_first_packet(imap_data))
    one[13] |= 0x80  # COMPRESSION = 1
    decoded = packets.read_packets(bytes(one), name="c.pkts")
    with pytest.raises(InputFormatError, match=r"packet 0 \(sequence count 5, APID 1052\)"
                       r": compressed") as err:
        packets.packet_vectors(decoded, 0)
    assert err.value.field == "COMPRESSION"


def test_short_vectors_field_names_the_packet(imap_data: Path) -> None:
    one = bytearray(_first_packet(imap_data))
    one[12] = 0x08  # PUS_SSUBTYPE 8: 9 s, more vectors than the field holds
    decoded = packets.read_packets(bytes(one))
    with pytest.raises(InputFormatError, match="sequence count 5.*VECTORS holds 1608 bits"):
        packets.packet_vectors(decoded, 0)
