"""Values of ASTERIX item bytes: the primitives the CAT010/CAT020/CAT021 decoders share.

Each decoder turns the bytes of one item (split by :mod:`.layout`, or unparsed from a
libasterix record by :func:`.records.item_bytes`) into physical values with its own LSB
table, so the fast path and the libasterix path run the same conversion.

* :func:`unsigned`, :func:`signed`: big-endian integers (two's complement for signed);
* :func:`icao_chars`: the ICAO 6-bit character set of aircraft identification (ICAO
  Annex 10 Vol. IV, 3.1.2.9: 1-26 = A-Z, 32 = space, 48-57 = 0-9; code 0 is no
  character and is dropped, any other code is returned as ``"?"``), trailing spaces
  removed, ``None`` when nothing is left;
* :func:`mode_3a`: the 12 code bits of a Mode-3/A item (V, G, L and spare above them)
  as an integer (octal 7777 = 4095), or ``None`` when V = 1 (not validated) or G = 1
  (garbled).
"""

from __future__ import annotations

NM = 1852.0
FT = 0.3048
#: ASTERIX time-of-day LSB (s): I010/140, I020/140, I021/030, I021/071..077.
TOD_LSB = 1.0 / 128.0
DAY_S = 86_400.0

_ICAO = (
    "\0ABCDEFGHIJKLMNOPQRSTUVWXYZ?????"  # 0-31
    " ???????????????0123456789??????"  # 32-63
)


def unsigned(b: bytes) -> int:
    return int.from_bytes(b, "big")


def signed(b: bytes) -> int:
    return int.from_bytes(b, "big", signed=True)


def signed_bits(value: int, bits: int) -> int:
    """Two's complement of the low ``bits`` bits of ``value``."""
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def icao_chars(b: bytes) -> str | None:
    """8 characters of 6 bits in 6 bytes (I010/245, I020/245, I021/170), trailing spaces
    removed; ``None`` if no character is left."""
    n = int.from_bytes(b[:6], "big")
    chars = [_ICAO[(n >> (42 - 6 * i)) & 0x3F] for i in range(8)]
    return "".join(chars).replace("\0", "").rstrip(" ") or None


def mode_3a(b: bytes) -> int | None:
    """The code of a 2-byte Mode-3/A item with V/G bits (I010/060, I020/070): ``None``
    unless validated and not garbled."""
    if b[0] & 0xC0:
        return None
    return unsigned(b) & 0x0FFF


def time_of_day(b: bytes) -> float:
    """A 3-byte time of day, LSB 1/128 s."""
    return unsigned(b) * TOD_LSB


def flight_level(b: bytes) -> float | None:
    """A 2-byte V/G + 14-bit flight level (LSB 1/4 FL): ``None`` unless V = 0 and G = 0."""
    raw = unsigned(b)
    if raw & 0xC000:
        return None
    return signed_bits(raw, 14) * 0.25
