"""IMAP MAG science packets (L0): streamed from the file, headers decoded with the XTCE.

The packets are CCSDS space packets whose layout is the IMAP MAG team's XTCE definition
``MAG_SCI_COMBINED.xml``: normal mode ``P_MAG_SCI_NORM`` (APID 1052) and burst mode
``P_MAG_SCI_BURST`` (APID 1068).  fluxcal does not ship that file: the user names it
(``--xtce``), or it is taken from the team's package ``imap-processing`` when installed
(``pip install 'fluxcal[imap]'``), `xtce_path`.  The header fields are decoded by
``space_packet_parser`` driven by that file; the ``VECTORS`` field is decoded by
`fluxcal.missions.imap.vectors`.

A file is read one packet at a time (`iter_packets`): each packet's primary header is
checked (APID, length) before its body is read, so a file that is not MAG science
packets (zero bytes, text, another instrument) is refused at its first packet, in
bounded memory, whatever its size (docs/decisions/imap.md).

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing, ``mag/packet_definitions`` and
   ``mag/l0`` (MIT License), the team's decommutation.
.. [2] CCSDS 133.0-B-2, Space Packet Protocol: the 6-byte primary header (APID in the
   low 11 bits of bytes 0-1, sequence count in the low 14 bits of bytes 2-3, packet
   data length - 1 in bytes 4-5).
"""

from __future__ import annotations

import functools
import importlib.util
import io
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import BinaryIO

import numpy as np
import space_packet_parser as spp
from space_packet_parser.exceptions import UnrecognizedPacketTypeError

from fluxcal.errors import InputFormatError

#: APID -> mode of the MAG science packets.
MODES = {1052: "norm", 1068: "burst"}
#: The IMAP MAG team's XTCE file name (in their package: ``mag/packet_definitions``).
XTCE_NAME = "MAG_SCI_COMBINED.xml"
#: Header fields kept per packet (XTCE names).
FIELDS = ("PKT_APID", "SRC_SEQ_CTR", "PKT_LEN", "SHCOARSE", "PUS_STYPE", "PUS_SSUBTYPE",
          "COMPRESSION", "MAGO_ACT", "MAGI_ACT", "PRI_SENS", "PRI_VECSEC", "SEC_VECSEC",
          "PRI_COARSETM", "PRI_FNTM", "SEC_COARSETM", "SEC_FNTM")
_HEADER = 6


def data_file(name: str) -> Path:
    """Path of a file of fluxcal's own in ``fluxcal/missions/imap/data``."""
    return Path(str(resources.files("fluxcal.missions.imap").joinpath("data", name)))


def team_package_xtce() -> Path | None:
    """Return the XTCE file of the installed ``imap-processing`` package, or None.

    Found from the package's location without importing it.
    """
    try:
        spec = importlib.util.find_spec("imap_processing")
    except (ImportError, ValueError):
        return None
    for folder in (spec.submodule_search_locations or []) if spec else []:
        path = Path(folder) / "mag" / "packet_definitions" / XTCE_NAME
        if path.is_file():
            return path
    return None


def xtce_path(xtce: Path | str | None = None) -> Path:
    """Return the XTCE definition to use: ``xtce`` if given, else the team's package's.

    Raises
    ------
    InputFormatError
        Neither given nor installed (names ``--xtce`` and the extra), or a named
        file that does not exist.
    """
    if xtce is not None:
        if not Path(xtce).is_file():
            raise InputFormatError("no such file (the IMAP MAG team's XTCE packet "
                                   f"definition {XTCE_NAME})", path=str(xtce))
        return Path(xtce)
    found = team_package_xtce()
    if found is None:
        raise InputFormatError(
            f"IMAP MAG packets need the team's packet definition {XTCE_NAME}: give "
            "--xtce PATH (e.g. ../shared/data/imap/MAG_SCI_COMBINED.xml) or install the "
            "team's package (pip install 'fluxcal[imap]')", field="--xtce")
    return found


@functools.lru_cache(maxsize=4)
def _definition(path: str) -> spp.XtcePacketDefinition:
    try:
        return spp.load_xtce(path)
    except Exception as exc:  # noqa: BLE001 - lxml and the parser raise many kinds
        raise InputFormatError(f"not a readable XTCE packet definition ({type(exc).__name__}:"
                               f" {exc})", path=path) from exc


def packet_definition(xtce: Path | str | None = None) -> spp.XtcePacketDefinition:
    """Return the parsed XTCE definition (`xtce_path`), parsed once per file."""
    return _definition(str(xtce_path(xtce)))


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


def iter_packets(stream: BinaryIO, where: str) -> Iterator[bytes]:
    """Yield the whole packets of a binary stream, one at a time.

    Each 6-byte primary header is checked before the packet's body is read: the APID
    must be a MAG science APID (`MODES`), and the body must be all there.

    Raises
    ------
    InputFormatError
        Naming the file, the packet (index, sequence count, APID) and the field: an
        empty file, an APID that is not a MAG science packet, a packet cut short.
    """
    i = 0
    while True:
        head = stream.read(_HEADER)
        if not head:
            if i == 0:
                raise InputFormatError("empty: no IMAP MAG science packet", path=where)
            return
        apid = int.from_bytes(head[:2], "big") & 0x7FF if len(head) >= 2 else -1
        seq = int.from_bytes(head[2:4], "big") & 0x3FFF if len(head) >= 4 else -1
        name = f"packet {i} (sequence count {seq}, APID {apid})"
        if len(head) < _HEADER:
            raise InputFormatError(f"{name}: truncated, {len(head)} bytes left where the "
                                   "header needs 6", path=where, field="PKT_LEN")
        if apid not in MODES:
            hint = (": the file is neither IMAP MAG science packets nor the team's L1A "
                    "CSV" if i == 0 else "")
            raise InputFormatError(f"{name}: not a MAG science packet (APID "
                                   f"{sorted(MODES)}){hint}", path=where, field="PKT_APID")
        need = int.from_bytes(head[4:6], "big") + 1
        body = stream.read(need)
        if len(body) < need:
            raise InputFormatError(f"{name}: truncated, {_HEADER + len(body)} bytes left "
                                   f"where the header needs {need + _HEADER}", path=where,
                                   field="PKT_LEN")
        yield head + body
        i += 1


def read_packets(source: Path | str | bytes, *, xtce: Path | str | None = None,
                 name: str | None = None) -> MagPackets:
    """Decode every MAG science packet of a file (or bytes), streamed (`iter_packets`).

    Raises
    ------
    InputFormatError
        From `iter_packets`; a packet the XTCE definition cannot decode; no XTCE
        definition (`xtce_path`).
    """
    where = name or ("<bytes>" if isinstance(source, bytes) else str(source))
    definition = packet_definition(xtce)
    rows: dict[str, list[int]] = {f: [] for f in FIELDS}
    vectors: list[bytes] = []
    raw: list[bytes] = []
    with (io.BytesIO(source) if isinstance(source, bytes) else open(source, "rb")) as fh:
        for i, packet in enumerate(iter_packets(fh, where)):
            try:
                parsed = definition.parse_bytes(packet)
                values = [int(parsed[f]) for f in FIELDS]
                vector_bytes = bytes(parsed["VECTORS"])
            except (UnrecognizedPacketTypeError, ValueError, IndexError, KeyError) as exc:
                apid = int.from_bytes(packet[:2], "big") & 0x7FF
                seq = int.from_bytes(packet[2:4], "big") & 0x3FFF
                raise InputFormatError(
                    f"packet {i} (sequence count {seq}, APID {apid}): not decodable with "
                    f"the XTCE definition ({type(exc).__name__}: {exc})", path=where,
                    field="VECTORS") from exc
            for f, v in zip(FIELDS, values, strict=True):
                rows[f].append(v)
            vectors.append(vector_bytes)
            raw.append(packet)
    fields = {f: np.asarray(v, dtype=np.int64) for f, v in rows.items()}
    return MagPackets(fields, vectors, raw, where)


def vectors_per_second(code: np.ndarray) -> np.ndarray:
    """Vectors per second from the 3-bit ``PRI_VECSEC``/``SEC_VECSEC`` code (``2**code``)."""
    return np.left_shift(1, np.asarray(code, dtype=np.int64))


def vector_counts(packets: MagPackets) -> tuple[np.ndarray, np.ndarray]:
    """Primary and secondary vector counts of each packet (vectors/s times seconds)."""
    seconds = packets.fields["PUS_SSUBTYPE"] + 1
    return (vectors_per_second(packets.fields["PRI_VECSEC"]) * seconds,
            vectors_per_second(packets.fields["SEC_VECSEC"]) * seconds)


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
