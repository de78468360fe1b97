"""IMAP MAG L0: the team's decommutation reproduced exactly; files streamed, refused early."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap import packets
from fluxcal.missions.imap.vectors import VECTOR_BITS, decode_vectors
from tests.missions.imap.conftest import XTCE


def _read(source, **kw) -> packets.MagPackets:
    return packets.read_packets(source, xtce=XTCE, **kw)


def _team_l0(imap_data: Path) -> list[dict[str, str]]:
    with (imap_data / "mag_l0_test_output.csv").open(newline="") as fh:
        return list(csv.DictReader(fh))


def test_l0_header_fields_match_the_team(imap_data: Path) -> None:
    decoded = _read(imap_data / "mag_l0_test_data.pkts")
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
    decoded = _read(imap_data / "mag_l0_test_data.pkts")
    n_pri, n_sec = packets.vector_counts(decoded)
    for i, row in enumerate(_team_l0(imap_data)):
        raw = decoded.raw[i]
        assert raw[:-1].hex().upper() == row["CCSDS_HEX"]
        assert raw[-1] == 0
        assert (n_pri[i] + n_sec[i]) * VECTOR_BITS <= (len(decoded.vectors[i]) - 1) * 8
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
    decoded = _read(imap_data / "mag_l0_test_data.pkts")
    vectors = decode_vectors(decoded)
    for i in np.flatnonzero(decoded.fields["PKT_APID"] == 1068)[:3]:
        take = vectors.packet == i
        assert np.count_nonzero(take & ~vectors.secondary) == 256  # 64 vectors/s, 4 s
        assert np.count_nonzero(take & vectors.secondary) == 32  # 8 vectors/s
        got = [(*c, r) for c, r in zip(vectors.counts[take].tolist(),
                                       vectors.range[take].tolist(), strict=True)]
        assert got == _unpack_with_python_ints(decoded.vectors[i], 288)


def _first_packet(imap_data: Path) -> bytes:
    data = (imap_data / "mag_l1_test_data.pkts").read_bytes()
    return data[: int.from_bytes(data[4:6], "big") + 7]


def test_truncated_file_names_the_packet(imap_data: Path) -> None:
    one = _first_packet(imap_data)
    with pytest.raises(InputFormatError, match=r"packet 1 \(sequence count 5, APID 1052\)"
                       r".*truncated") as err:
        _read(one + one[:100], name="cut.pkts")
    assert err.value.field == "PKT_LEN" and err.value.path == "cut.pkts"


def test_unknown_apid_names_the_packet(imap_data: Path) -> None:
    one = bytearray(_first_packet(imap_data))
    one[1] += 1  # APID 1053
    with pytest.raises(InputFormatError, match=r"packet 0 \(sequence count 5, APID 1053\)"):
        _read(bytes(one))


def test_short_vectors_field_names_the_packet(imap_data: Path) -> None:
    one = bytearray(_first_packet(imap_data))
    one[12] = 0x08  # PUS_SSUBTYPE 8: 9 s, more vectors than the field holds
    with pytest.raises(InputFormatError, match="sequence count 5.*uncompressed VECTORS field "
                       "of 1608 bits ends inside secondary vector 14"):
        decode_vectors(_read(bytes(one)))


def test_empty_and_packetless_files_are_refused_by_name(imap_data: Path,
                                                         tmp_path: Path) -> None:
    empty = tmp_path / "empty.pkts"
    empty.write_bytes(b"")
    with pytest.raises(InputFormatError, match="empty.pkts: empty: no IMAP MAG science"):
        _read(empty)
    text = tmp_path / "notes.bin"
    text.write_text("hello, world\n" * 10)
    with pytest.raises(InputFormatError, match="notes.bin, field 'PKT_APID': packet 0 .*"
                       "neither IMAP MAG science packets nor the team's L1A CSV"):
        _read(text)


_SPARSE = """
import resource, sys, time
from fluxcal.errors import InputFormatError
from fluxcal.missions.imap.packets import read_packets
start = time.perf_counter()
try:
    read_packets(sys.argv[1], xtce=sys.argv[2])
except InputFormatError as exc:
    print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    print(exc)
"""


def test_a_gigabyte_of_zero_bytes_is_refused_in_seconds_and_little_memory(
        imap_data: Path, tmp_path: Path) -> None:
    # a sparse file: 1 GiB of zero bytes that takes no disk
    zeros = tmp_path / "zeros.pkts"
    with zeros.open("wb") as fh:
        fh.truncate(1 << 30)
    assert zeros.stat().st_size == 1 << 30
    run = subprocess.run([sys.executable, "-c", _SPARSE, str(zeros), str(XTCE)],
                         capture_output=True, text=True, timeout=120, check=True)
    seconds, max_rss_kib = (float(v) for v in run.stdout.splitlines()[0].split())
    assert "packet 0 (sequence count 0, APID 0): not a MAG science packet" in run.stdout
    assert seconds < 5.0  # it stops at the first header (the import is not timed)
    assert max_rss_kib < 1 << 20  # < 1 GiB: the file is never held (the process ~300 MiB)


def test_xtce_missing_says_what_to_do(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(packets, "team_package_xtce", lambda: None)
    with pytest.raises(InputFormatError, match="field '--xtce': IMAP MAG packets need the "
                       r"team's packet definition .*--xtce PATH.*fluxcal\[imap\]"):
        packets.read_packets(b"")


def test_xtce_from_the_team_package_when_installed(imap_data: Path, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    # a stand-in of the installed package: only its layout matters (found, not imported)
    folder = tmp_path / "site" / "imap_processing" / "mag" / "packet_definitions"
    folder.mkdir(parents=True)
    (tmp_path / "site" / "imap_processing" / "__init__.py").write_text("raise ImportError\n")
    (folder / packets.XTCE_NAME).write_bytes(XTCE.read_bytes())
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    assert packets.xtce_path() == folder / packets.XTCE_NAME
    assert len(packets.read_packets(_first_packet(imap_data))) == 1


