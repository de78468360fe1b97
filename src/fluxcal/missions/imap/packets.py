"""IMAP MAG science packets (L0): XTCE decommutation and the packed vectors.

The packets are CCSDS space packets whose layout is the IMAP team's XTCE definition
``MAG_SCI_COMBINED.xml`` (shipped in ``data/``): normal mode ``P_MAG_SCI_NORM`` (APID
1052) and burst mode ``P_MAG_SCI_BURST`` (APID 1068).  The header fields are decoded by
``space_packet_parser`` driven by that file; the ``VECTORS`` field then holds the
primary sensor's vectors followed by the secondary's, each 50 bits: x, y, z as 16-bit
two's complement counts and a 2-bit range, packed without padding (the field ends on a
byte boundary).  ``PRI_VECSEC``/``SEC_VECSEC`` hold log2 of the vectors per second and
a packet holds ``PUS_SSUBTYPE + 1`` seconds of data.

Compressed packets (``COMPRESSION = 1``: a 6-bit width header, Fibonacci/zig-zag
differences, an optional range section) occur in none of the team's packet files, so
fluxcal cannot check a decoder against them; they are refused by name
(docs/decisions/imap.md).

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing, ``mag/packet_definitions`` and
   ``mag/l1a`` (MIT License), the team's decommutation.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import space_packet_parser as spp
from space_packet_parser.exceptions import UnrecognizedPacketTypeError
from space_packet_parser.generators import ccsds_generator

from fluxcal.errors import InputFormatError

#: APID -> mode of the MAG science packets.
MODES = {1052: "norm", 1068: "burst"}
#: Bits of one uncompressed vector: x, y, z (16 bits each) and the range (2 bits).
VECTOR_BITS = 50
#: Header fields kept per packet (XTCE names).
FIELDS = ("PKT_APID", "SRC_SEQ_CTR", "PKT_LEN", "SHCOARSE", "PUS_STYPE", "PUS_SSUBTYPE",
          "COMPRESSION", "MAGO_ACT", "MAGI_ACT", "PRI_SENS", "PRI_VECSEC", "SEC_VECSEC",
          "PRI_COARSETM", "PRI_FNTM", "SEC_COARSETM", "SEC_FNTM")
_BIT_WEIGHTS = 1 << np.arange(15, -1, -1, dtype=np.int64)


def data_file(name: str) -> Path:
    """Path of a file shipped in ``fluxcal/missions/imap/data``."""
    return Path(str(resources.files("fluxcal.missions.imap").joinpath("data", name)))


@functools.lru_cache(maxsize=4)
def packet_definition(path: str | None = None) -> spp.XtcePacketDefinition:
    """Return the XTCE definition (default: the shipped ``MAG_SCI_COMBINED.xml``), parsed once."""
    return spp.load_xtce(path or data_file("MAG_SCI_COMBINED.xml"))


@dataclass(frozen=True)
class MagPackets:
    """Decoded MAG science packets, in file order.

    Attributes
    ----------
    fields : dict of str -> ndarray of int64
        The header fields of `FIELDS` (XTCE names, raw values), one per packet.
    vectors : list of bytes
        The ``VECTORS`` field of each packet.
    raw : list of bytes
        Each whole packet as read.
    source : str
        The file (or a name) the packets came from.
    """

    fields: dict[str, np.ndarray]
    vectors: list[bytes]
    raw: list[bytes]
    source: str

    def __len__(self) -> int:
        return len(self.raw)

    def where(self, i: int) -> str:
        """Name packet ``i`` for messages: index, sequence count and APID."""
        return (f"packet {i} (sequence count {int(self.fields['SRC_SEQ_CTR'][i])}, "
                f"APID {int(self.fields['PKT_APID'][i])})")


def read_packets(source: Path | str | bytes, *, xtce: Path | str | None = None,
                 name: str | None = None) -> MagPackets:
    """Decode every MAG science packet of a file (or bytes) with the XTCE definition.

    Raises
    ------
    InputFormatError
        Naming the file, the packet (index, sequence count, APID) and the field: an APID
        that is not a MAG science packet, a packet cut short by the end of the file.
    """
    data = source if isinstance(source, bytes) else Path(source).read_bytes()
    where = name or ("<bytes>" if isinstance(source, bytes) else str(source))
    definition = packet_definition(None if xtce is None else str(xtce))
    rows: dict[str, list[int]] = {f: [] for f in FIELDS}
    vectors: list[bytes] = []
    raw: list[bytes] = []
    used = 0
    with warnings.catch_warnings():  # a short last packet: the check below names it
        warnings.filterwarnings("ignore", ".*bytes left to read", UserWarning)
        generated = list(ccsds_generator(data, show_progress=False))
    for i, packet in enumerate(generated):
        head = bytes(packet[:6])
        apid = int.from_bytes(head[:2], "big") & 0x7FF
        seq = int.from_bytes(head[2:4], "big") & 0x3FFF
        if apid not in MODES:
            raise InputFormatError(
                f"packet {i} (sequence count {seq}, APID {apid}): not a MAG science packet "
                f"(APID {sorted(MODES)})", path=where, field="PKT_APID")
        try:
            parsed = definition.parse_bytes(packet)
        except (UnrecognizedPacketTypeError, ValueError, IndexError) as exc:
            raise InputFormatError(
                f"packet {i} (sequence count {seq}, APID {apid}): not decodable with the "
                f"XTCE definition ({type(exc).__name__}: {exc})", path=where,
                field="VECTORS") from exc
        for f in FIELDS:
            rows[f].append(int(parsed[f]))
        vectors.append(bytes(parsed["VECTORS"]))
        raw.append(bytes(packet))
        used += len(packet)
    if used != len(data):
        rest = data[used:]
        seq = int.from_bytes(rest[2:4], "big") & 0x3FFF if len(rest) >= 4 else -1
        apid = int.from_bytes(rest[:2], "big") & 0x7FF if len(rest) >= 2 else -1
        need = int.from_bytes(rest[4:6], "big") + 7 if len(rest) >= 6 else 6
        raise InputFormatError(
            f"packet {len(raw)} (sequence count {seq}, APID {apid}): truncated, "
            f"{len(rest)} bytes left where the header needs {need}", path=where,
            field="PKT_LEN")
    fields = {f: np.asarray(v, dtype=np.int64) for f, v in rows.items()}
    return MagPackets(fields, vectors, raw, where)


def vectors_per_second(code: np.ndarray) -> np.ndarray:
    """Vectors per second from the 3-bit ``PRI_VECSEC``/``SEC_VECSEC`` code (``2**code``)."""
    return np.left_shift(1, np.asarray(code, dtype=np.int64))


def l0_table(packets: MagPackets) -> dict[str, np.ndarray]:
    """Return the team's L0 columns (``mag_l0_test_output.csv``) of decoded packets.

    ``PHAPID``, ``PHSEQCNT``, ``PHDLEN`` are the CCSDS APID, sequence count and length;
    ``FOB_ACT``/``FIB_ACT`` the MAGo/MAGi active flags; ``PRI_VECSEC``/``SEC_VECSEC`` in
    vectors per second; ``CCSDS_HEX`` each whole packet as upper-case hex.
    """
    f = packets.fields
    rename = {"PHAPID": "PKT_APID", "PHSEQCNT": "SRC_SEQ_CTR", "PHDLEN": "PKT_LEN",
              "FOB_ACT": "MAGO_ACT", "FIB_ACT": "MAGI_ACT"}
    table = {}
    for col in ("PHAPID", "PHSEQCNT", "PHDLEN", "SHCOARSE", "PUS_STYPE", "PUS_SSUBTYPE",
                "COMPRESSION", "FOB_ACT", "FIB_ACT", "PRI_SENS", "PRI_VECSEC", "SEC_VECSEC",
                "PRI_COARSETM", "PRI_FNTM", "SEC_COARSETM", "SEC_FNTM"):
        values = f[rename.get(col, col)]
        table[col] = vectors_per_second(values) if col.endswith("VECSEC") else values
    table["CCSDS_HEX"] = np.array([r.hex().upper() for r in packets.raw])
    return table


def vector_counts(packets: MagPackets) -> tuple[np.ndarray, np.ndarray]:
    """Primary and secondary vector counts of each packet (vectors/s times seconds)."""
    seconds = packets.fields["PUS_SSUBTYPE"] + 1
    return (vectors_per_second(packets.fields["PRI_VECSEC"]) * seconds,
            vectors_per_second(packets.fields["SEC_VECSEC"]) * seconds)


def unpack_vectors(vector_bytes: bytes, count: int, *, where: str = "",
                   source: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unpack ``count`` uncompressed 50-bit vectors: (counts (n, 3) int64, range (n,) int64).

    Raises
    ------
    InputFormatError
        When the field holds fewer than ``count`` vectors (names ``where``, ``VECTORS``).
    """
    bits = np.unpackbits(np.frombuffer(vector_bytes, dtype=np.uint8))
    need = count * VECTOR_BITS
    if bits.size < need:
        raise InputFormatError(
            f"{where}: VECTORS holds {bits.size} bits, {count} vectors need {need}",
            path=source, field="VECTORS")
    v = bits[:need].reshape(count, VECTOR_BITS).astype(np.int64)
    axes = v[:, :48].reshape(count, 3, 16) @ _BIT_WEIGHTS
    counts = np.where(axes >= 1 << 15, axes - (1 << 16), axes)
    return counts, 2 * v[:, 48] + v[:, 49]


def packet_vectors(packets: MagPackets, i: int) -> tuple[tuple[np.ndarray, np.ndarray],
                                                         tuple[np.ndarray, np.ndarray]]:
    """Return ((counts, range) of the primary, (counts, range) of the secondary) of packet i.

    Raises
    ------
    InputFormatError
        A compressed packet (``COMPRESSION``), or a ``VECTORS`` field too short.
    """
    where = packets.where(i)
    if packets.fields["COMPRESSION"][i]:
        raise InputFormatError(
            f"{where}: compressed vectors are not supported (none occur in the IMAP team's "
            "packet files to check a decoder against; docs/decisions/imap.md)",
            path=packets.source, field="COMPRESSION")
    n_pri, n_sec = (int(n[i]) for n in vector_counts(packets))
    counts, rng = unpack_vectors(packets.vectors[i], n_pri + n_sec, where=where,
                                 source=packets.source)
    return (counts[:n_pri], rng[:n_pri]), (counts[n_pri:], rng[n_pri:])
