"""The IMAP MAG forward model's packet writer: vectors -> CCSDS science packets (bits).

Written from the IMAP MAG team's published packet description, sharing no code with
fluxcal's decoder (`fluxcal.missions.imap.vectors`, `fluxcal.missions.imap.packets`):
its own bit packer (`pack_bits`), Fibonacci coder and field table.  The layout:

* a 6-byte CCSDS primary header and a 21-byte secondary header (`HEADER`, the fields of
  the team's XTCE ``MAG_SCI_COMBINED.xml`` in order, most significant bit first);
  ``PKT_LEN`` is the bytes after the primary header minus one, so ``VECTORS`` holds
  ``PKT_LEN - 20`` bytes;
* ``VECTORS`` uncompressed: per vector x, y, z as 16-bit two's complement and a 2-bit
  range, the primary sensor's vectors then the secondary's, no padding between them,
  zero bits to the next byte at the end;
* ``VECTORS`` compressed: an 8-bit header (width ``W`` in 6 bits, a flag saying a
  range section follows, a spare bit); per sensor (primary, then secondary) a reference
  vector (x, y, z as ``W``-bit two's complement, a 2-bit range), then each following
  vector as three differences from the one before, each zig-zag mapped
  (0, -1, 1, -2 ... -> 0, 1, 2, 3 ...), plus one, Fibonacci coded (Zeckendorf bits of
  weights 1, 2, 3, 5, 8 ... lowest first, closed by a 1); after the first vector whose
  three codes take more than 60 bits, the sensor's remaining vectors in the packet are
  ``W``-bit two's complement values without range; then, when the flag is set, zero
  bits to the next byte and 2 range bits per vector after each sensor's reference
  (primary, then secondary); zero bits to the next byte.

References
----------
.. [1] IMAP-Science-Operations-Center/imap_processing (MIT License): the XTCE
   ``mag/packet_definitions/MAG_SCI_COMBINED.xml`` (header fields and widths,
   ``VECTORS`` of ``8 PKT_LEN - 160`` bits, APIDs 1052/1068), the docstrings of
   ``mag/l1a/mag_l1a_data.py`` (compressed layout, 60-bit switch, range section) and
   ``mag/constants.py`` (``PrimarySensor``: ``PRI_SENS`` 0 is MAGo).  Read for the
   layout only; this writer is fluxcal's own.
.. [2] CCSDS 133.0-B-2, Space Packet Protocol (primary header).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The packet header fields in order: (XTCE name, bits).
HEADER = (("VERSION", 3), ("TYPE", 1), ("SEC_HDR_FLG", 1), ("PKT_APID", 11),
          ("SEQ_FLGS", 2), ("SRC_SEQ_CTR", 14), ("PKT_LEN", 16), ("SHCOARSE", 32),
          ("PUS_SPARE1", 1), ("PUS_VERSION", 3), ("PUS_SPARE2", 4), ("PUS_STYPE", 8),
          ("PUS_SSUBTYPE", 8), ("COMPRESSION", 1), ("MAGO_ACT", 1), ("MAGI_ACT", 1),
          ("PRI_SENS", 1), ("SPARE1", 4), ("PRI_VECSEC", 3), ("SEC_VECSEC", 3),
          ("SPARE2", 2), ("PRI_COARSETM", 32), ("PRI_FNTM", 16), ("SEC_COARSETM", 32),
          ("SEC_FNTM", 16))
#: Bytes of the primary header, and of the secondary header before ``VECTORS``.
PRIMARY_BYTES, SECONDARY_BYTES = 6, 21
#: APIDs of the science packets by mode.
APIDS = {"norm": 1052, "burst": 1068}
#: A compressed vector longer than this makes the rest of its sensor's vectors plain.
LONG_VECTOR_BITS = 60
#: PUS service type of the MAG science packets (as in the team's ground-test packets).
PUS_SERVICE_TYPE = 21

_FIBONACCI = [1, 2]
while _FIBONACCI[-1] < 2**44:
    _FIBONACCI.append(_FIBONACCI[-1] + _FIBONACCI[-2])
FIBONACCI = np.array(_FIBONACCI, dtype=np.int64)


def pack_bits(values: np.ndarray, widths: np.ndarray) -> bytes:
    """Write each value in its width of bits, most significant first, one after another.

    ``values`` are non-negative integers below ``2**width`` (int64); a width of 0 writes
    nothing.  The total must be whole bytes.
    """
    values = np.asarray(values, dtype=np.int64).ravel()
    widths = np.asarray(widths, dtype=np.int64).ravel()
    total = int(widths.sum())
    if total % 8:
        raise ValueError(f"{total} bits is not whole bytes")
    ends = np.cumsum(widths)
    position = np.arange(total, dtype=np.int64) - np.repeat(ends - widths, widths)
    shift = np.repeat(widths, widths) - 1 - position
    bits = (np.repeat(values, widths) >> shift) & 1
    return np.packbits(bits.astype(np.uint8)).tobytes()


def twos_complement(counts: np.ndarray, width: int | np.ndarray) -> np.ndarray:
    """Signed counts as ``width``-bit two's complement (non-negative int64)."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.where(counts < 0, counts + (np.int64(1) << width), counts)


def fibonacci_code(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fibonacci codes of integers ``n >= 1``: (bit pattern, length), first bit highest.

    The code is ``n``'s Zeckendorf representation (greedy from the largest Fibonacci
    number), weight 1 first, then a closing 1; its pattern reads as written.
    """
    n = np.asarray(n, dtype=np.int64)
    rest = n.copy()
    top = int(np.searchsorted(FIBONACCI, max(int(n.max(initial=1)), 1), side="right"))
    digits = np.zeros((top,) + n.shape, dtype=np.int64)
    for k in range(top - 1, -1, -1):
        take = FIBONACCI[k] <= rest
        rest -= np.where(take, FIBONACCI[k], 0)
        digits[k] = take
    highest = top - 1 - np.argmax(digits[::-1], axis=0)
    length = highest + 2
    pattern = np.ones_like(n)
    for k in range(top):
        pattern |= digits[k] << np.maximum(length - 1 - k, 0)
    return pattern, length


def zigzag(d: np.ndarray) -> np.ndarray:
    """0, -1, 1, -2, 2 ... -> 0, 1, 2, 3, 4 ..."""
    d = np.asarray(d, dtype=np.int64)
    return np.where(d < 0, -2 * d - 1, 2 * d)


@dataclass(frozen=True)
class Section:
    """One sensor's vectors of a block of packets: counts (packet, vector, 3), range."""

    counts: np.ndarray
    ranges: np.ndarray


def _plain_fields(section: Section, width: int, with_range: bool) -> tuple[np.ndarray,
                                                                         np.ndarray]:
    """x, y, z (and range) per vector as fixed-width fields, (packet, field)."""
    n, v, _ = section.counts.shape
    values = twos_complement(section.counts, width)
    widths = np.full(values.shape, width, dtype=np.int64)
    if with_range:
        values = np.concatenate([values, section.ranges[..., None].astype(np.int64)], axis=2)
        widths = np.concatenate([widths, np.full((n, v, 1), 2, dtype=np.int64)], axis=2)
    return values.reshape(n, -1), widths.reshape(n, -1)


def _compressed_fields(section: Section, width: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Write a reference vector, then Fibonacci-coded differences (plain after a long one).

    Returns the fields (packet, field) and the number of vectors written plain.
    """
    ref_values, ref_widths = _plain_fields(Section(section.counts[:, :1],
                                                   section.ranges[:, :1]), width, True)
    if section.counts.shape[1] == 1:
        return ref_values, ref_widths, 0
    diff = np.diff(section.counts, axis=1)
    code, length = fibonacci_code(zigzag(diff) + 1)
    long = length.sum(axis=2) > LONG_VECTOR_BITS
    # vectors after the first long one of their packet are written plain
    after = np.zeros_like(long)
    after[:, 1:] = np.logical_or.accumulate(long, axis=1)[:, :-1]
    plain = twos_complement(section.counts[:, 1:], width)
    values = np.where(after[..., None], plain, code)
    widths = np.where(after[..., None], width, length)
    n = section.counts.shape[0]
    return (np.concatenate([ref_values, values.reshape(n, -1)], axis=1),
            np.concatenate([ref_widths, widths.reshape(n, -1)], axis=1), int(after.sum()))


def _pad(bits: np.ndarray) -> np.ndarray:
    return (-bits) % 8


def vector_fields(primary: Section, secondary: Section, width: int
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """Return the ``VECTORS`` field of a block of packets as fields (packet, field).

    ``width`` 0: uncompressed; otherwise compressed with that ``W``.  Returns values,
    widths and the number of vectors written plain inside compressed packets.
    """
    n = primary.counts.shape[0]
    if width == 0:
        pv, pw = _plain_fields(primary, 16, True)
        sv, sw = _plain_fields(secondary, 16, True)
        values, widths = np.concatenate([pv, sv], 1), np.concatenate([pw, sw], 1)
        pad = _pad(widths.sum(axis=1))
        return (np.concatenate([values, np.zeros((n, 1), np.int64)], 1),
                np.concatenate([widths, pad[:, None]], 1), 0)
    pv, pw, p_plain = _compressed_fields(primary, width)
    sv, sw, s_plain = _compressed_fields(secondary, width)
    changes = np.concatenate([primary.ranges[:, 1:] != primary.ranges[:, :1],
                              secondary.ranges[:, 1:] != secondary.ranges[:, :1]], axis=1)
    has_section = changes.any(axis=1)
    header = (width << 2) | (has_section.astype(np.int64) << 1)
    values = np.concatenate([header[:, None], pv, sv], axis=1)
    widths = np.concatenate([np.full((n, 1), 8, np.int64), pw, sw], axis=1)
    pad1 = np.where(has_section, _pad(widths.sum(axis=1)), 0)
    ranges = np.concatenate([primary.ranges[:, 1:], secondary.ranges[:, 1:]], axis=1)
    range_widths = np.where(has_section[:, None], 2, 0) * np.ones_like(ranges)
    values = np.concatenate([values, np.zeros((n, 1), np.int64), ranges.astype(np.int64)], 1)
    widths = np.concatenate([widths, pad1[:, None], range_widths], axis=1)
    pad2 = _pad(widths.sum(axis=1))
    return (np.concatenate([values, np.zeros((n, 1), np.int64)], 1),
            np.concatenate([widths, pad2[:, None]], 1), p_plain + s_plain)


def packets(header: dict[str, np.ndarray], primary: Section, secondary: Section,
            width: int) -> tuple[bytes, int]:
    """Whole packets of a block (one mode, shape and ``width``); return bytes, plain count.

    ``header`` gives every field of `HEADER` but ``PKT_LEN`` (computed here) and
    ``COMPRESSION`` (from ``width``), one value per packet (or a scalar).
    """
    n = primary.counts.shape[0]
    values, widths, n_plain = vector_fields(primary, secondary, width)
    vector_bytes = widths.sum(axis=1) // 8
    fields = {**header, "PKT_LEN": SECONDARY_BYTES + vector_bytes - 1,
              "COMPRESSION": int(width != 0)}
    head_values = np.stack([np.broadcast_to(np.asarray(fields[name], dtype=np.int64), (n,))
                            for name, _ in HEADER], axis=1)
    head_widths = np.broadcast_to(np.array([b for _, b in HEADER], dtype=np.int64),
                                  head_values.shape)
    return (pack_bits(np.concatenate([head_values, values], axis=1),
                      np.concatenate([head_widths, widths], axis=1)), n_plain)


def xtce_text() -> str:
    """Return an XTCE definition of the science packets, written by fluxcal from `HEADER`.

    fluxcal's own description of the layout (not the team's file), for reading the
    simulated packets where the team's ``MAG_SCI_COMBINED.xml`` is not at hand.
    """
    ns = "xtce"
    sizes = sorted({b for _, b in HEADER})
    types = "\n".join(
        f'   <{ns}:IntegerParameterType name="uint{b}" signed="false">'
        f'<{ns}:IntegerDataEncoding sizeInBits="{b}" encoding="unsigned"/>'
        f"</{ns}:IntegerParameterType>" for b in sizes)
    types += (f'\n   <{ns}:BinaryParameterType name="vector_bytes"><{ns}:BinaryDataEncoding>'
              f"<{ns}:SizeInBits><{ns}:DynamicValue>"
              f'<{ns}:ParameterInstanceRef parameterRef="PKT_LEN"/>'
              f'<{ns}:LinearAdjustment intercept="{-8 * (SECONDARY_BYTES - 1)}" slope="8"/>'
              f"</{ns}:DynamicValue></{ns}:SizeInBits></{ns}:BinaryDataEncoding>"
              f"</{ns}:BinaryParameterType>")
    params = "\n".join(f'   <{ns}:Parameter name="{name}" parameterTypeRef="uint{b}"/>'
                       for name, b in HEADER)
    params += f'\n   <{ns}:Parameter name="VECTORS" parameterTypeRef="vector_bytes"/>'

    def entries(names: list[str]) -> str:
        return "".join(f'<{ns}:ParameterRefEntry parameterRef="{n}"/>' for n in names)

    primary = [name for name, _ in HEADER[:7]]
    rest = [name for name, _ in HEADER[7:]] + ["VECTORS"]
    containers = [f'   <{ns}:SequenceContainer name="CCSDSPacket" abstract="true">'
                  f"<{ns}:EntryList>{entries(primary)}</{ns}:EntryList>"
                  f"</{ns}:SequenceContainer>"]
    for mode, apid in APIDS.items():
        containers.append(
            f'   <{ns}:SequenceContainer name="mag_science_{mode}">'
            f'<{ns}:BaseContainer containerRef="CCSDSPacket"><{ns}:RestrictionCriteria>'
            f'<{ns}:Comparison parameterRef="PKT_APID" value="{apid}" '
            f'useCalibratedValue="false"/></{ns}:RestrictionCriteria></{ns}:BaseContainer>'
            f"<{ns}:EntryList>{entries(rest)}</{ns}:EntryList></{ns}:SequenceContainer>")
    return (f"<?xml version='1.0' encoding='utf-8'?>\n"
            f'<{ns}:SpaceSystem xmlns:{ns}="http://www.omg.org/space/xtce" '
            f'name="fluxcal_imap_mag_science_sim">\n'
            f'  <{ns}:Header version="1" author="fluxcal forward model (simulated packets; '
            f'not the IMAP team file)"/>\n'
            f"  <{ns}:TelemetryMetaData>\n  <{ns}:ParameterTypeSet>\n{types}\n"
            f"  </{ns}:ParameterTypeSet>\n  <{ns}:ParameterSet>\n{params}\n"
            f"  </{ns}:ParameterSet>\n  <{ns}:ContainerSet>\n" + "\n".join(containers)
            + f"\n  </{ns}:ContainerSet>\n  </{ns}:TelemetryMetaData>\n</{ns}:SpaceSystem>\n")
