"""Framing: ASTERIX datagrams out of pcap captures and raw ``.ast`` files, and data
blocks out of datagrams.

Two file forms are read:

* **pcap** (classic libpcap, either byte order, micro- or nanosecond timestamps) of
  ASTERIX over UDP. Link types: Ethernet (with 802.1Q VLAN tags), Linux cooked
  capture v1 (SLL) and v2 (SLL2), raw IPv4. Only IPv4/UDP is decoded; IP fragments,
  IPv6 and non-UDP packets are counted and skipped. The UDP payload length comes from
  the UDP header, not the frame length: Ethernet pads short frames to 60 bytes and the
  padding is not ASTERIX.
* **raw** ASTERIX (``.ast``, ``.asterix``, ``.raw``, ...): data blocks
  (``CAT``, 2-byte ``LEN``, records) concatenated with nothing in between. A raw file
  has no capture times, so the date comes from the caller.

pcapng is recognised and refused with a clear message (convert with
``editcap -F pcap in.pcapng out.pcap``).

Every problem is counted in a :class:`collections.Counter` under a short reason key
and the rest of the input is still used; nothing here raises on bad data.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

PCAP_MAGIC_US_LE = b"\xd4\xc3\xb2\xa1"
PCAP_MAGIC_US_BE = b"\xa1\xb2\xc3\xd4"
PCAP_MAGIC_NS_LE = b"\x4d\x3c\xb2\xa1"
PCAP_MAGIC_NS_BE = b"\xa1\xb2\x3c\x4d"
PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"

LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101
LINKTYPE_IPV4 = 228
LINKTYPE_LINUX_SLL = 113
LINKTYPE_LINUX_SLL2 = 276

ETHERTYPE_IPV4 = 0x0800
ETHERTYPE_VLAN = (0x8100, 0x88A8, 0x9100)

#: Categories whose blocks the framing accepts when it has to re-synchronise a raw file.
KNOWN_CATEGORIES = frozenset({1, 2, 8, 10, 19, 20, 21, 23, 34, 48, 62, 63, 65})


@dataclass(frozen=True, slots=True)
class Datagram:
    """One UDP payload (pcap) or a whole raw file's bytes.

    ``time_ns``: capture time, ns since the Unix epoch (UTC), or ``None`` (raw files).
    ``source``: ``"src_ip:port>dst_ip:port"`` for pcap packets, ``""`` otherwise.
    ``raw_stream``: True for a raw file, where a bad block triggers a re-sync scan
    instead of dropping the rest of the datagram."""

    payload: bytes
    time_ns: int | None
    source: str = ""
    raw_stream: bool = False


def detect_format(head: bytes) -> str:
    """``"pcap"``, ``"pcapng"`` or ``"raw"`` from the first bytes of a file."""
    magic = head[:4]
    if magic in (PCAP_MAGIC_US_LE, PCAP_MAGIC_US_BE, PCAP_MAGIC_NS_LE, PCAP_MAGIC_NS_BE):
        return "pcap"
    if magic == PCAPNG_MAGIC:
        return "pcapng"
    return "raw"


def iter_file_datagrams(path: str | Path, stats: Counter) -> Iterator[Datagram]:
    """Datagrams of a pcap or raw ASTERIX file (format detected from the magic number).

    Raises ``ValueError`` only for a pcapng file (unsupported container, clear message)."""
    data = Path(path).read_bytes()
    kind = detect_format(data)
    if kind == "pcapng":
        raise ValueError(
            f"{path}: pcapng captures are not supported; convert with "
            "'editcap -F pcap IN.pcapng OUT.pcap' (Wireshark tools)"
        )
    if kind == "pcap":
        yield from iter_pcap(data, stats)
    else:
        yield Datagram(data, None, "", raw_stream=True)


def iter_pcap(data: bytes, stats: Counter) -> Iterator[Datagram]:
    """UDP payloads of a classic pcap capture held in memory."""
    if len(data) < 24:
        stats["pcap_truncated_header"] += 1
        return
    magic = data[:4]
    endian = "<" if magic in (PCAP_MAGIC_US_LE, PCAP_MAGIC_NS_LE) else ">"
    nano = magic in (PCAP_MAGIC_NS_LE, PCAP_MAGIC_NS_BE)
    linktype = struct.unpack(endian + "I", data[20:24])[0] & 0x0FFFFFFF
    rec_hdr = struct.Struct(endian + "IIII")
    off = 24
    n = len(data)
    while off < n:
        if off + 16 > n:
            stats["pcap_truncated_record"] += 1
            return
        ts_sec, ts_frac, incl_len, _orig_len = rec_hdr.unpack_from(data, off)
        off += 16
        if off + incl_len > n:
            stats["pcap_truncated_record"] += 1
            return
        frame = data[off : off + incl_len]
        off += incl_len
        stats["pcap_packets"] += 1
        time_ns = ts_sec * 1_000_000_000 + (ts_frac if nano else ts_frac * 1000)
        result = udp_payload(frame, linktype)
        if isinstance(result, str):
            stats[result] += 1
            continue
        payload, source = result
        yield Datagram(payload, time_ns, source)


def udp_payload(frame: bytes, linktype: int) -> tuple[bytes, str] | str:
    """The UDP payload and ``"src>dst"`` of one captured frame, or a skip reason."""
    if linktype == LINKTYPE_ETHERNET:
        if len(frame) < 14:
            return "frame_truncated"
        ethertype = int.from_bytes(frame[12:14], "big")
        pos = 14
        while ethertype in ETHERTYPE_VLAN:
            if len(frame) < pos + 4:
                return "frame_truncated"
            ethertype = int.from_bytes(frame[pos + 2 : pos + 4], "big")
            pos += 4
    elif linktype == LINKTYPE_LINUX_SLL:
        if len(frame) < 16:
            return "frame_truncated"
        ethertype = int.from_bytes(frame[14:16], "big")
        pos = 16
    elif linktype == LINKTYPE_LINUX_SLL2:
        if len(frame) < 20:
            return "frame_truncated"
        ethertype = int.from_bytes(frame[0:2], "big")
        pos = 20
    elif linktype in (LINKTYPE_RAW, LINKTYPE_IPV4):
        ethertype = ETHERTYPE_IPV4 if frame[:1] and frame[0] >> 4 == 4 else -1
        pos = 0
    else:
        return f"unsupported_linktype_{linktype}"
    if ethertype != ETHERTYPE_IPV4:
        return "not_ipv4"
    ip = frame[pos:]
    if len(ip) < 20 or ip[0] >> 4 != 4:
        return "not_ipv4"
    ihl = (ip[0] & 0x0F) * 4
    total = int.from_bytes(ip[2:4], "big")
    if ihl < 20 or total < ihl or len(ip) < total:
        return "ip_truncated"
    flags_frag = int.from_bytes(ip[6:8], "big")
    if flags_frag & 0x3FFF:  # more-fragments flag or a fragment offset
        return "ip_fragment"
    if ip[9] != 17:
        return "not_udp"
    udp = ip[ihl:total]
    if len(udp) < 8:
        return "udp_truncated"
    ulen = int.from_bytes(udp[4:6], "big")
    if ulen < 8 or ulen > len(udp):
        return "udp_bad_length"
    src = f"{ip[12]}.{ip[13]}.{ip[14]}.{ip[15]}:{int.from_bytes(udp[0:2], 'big')}"
    dst = f"{ip[16]}.{ip[17]}.{ip[18]}.{ip[19]}:{int.from_bytes(udp[2:4], 'big')}"
    return udp[8:ulen], f"{src}>{dst}"


def split_datablocks(
    payload: bytes, stats: Counter, *, raw_stream: bool = False
) -> Iterator[tuple[int, bytes]]:
    """``(category, record bytes)`` for each data block of a datagram.

    A block header with a length below 3 or beyond the end of the data is counted
    (``block_bad_length`` / ``block_truncated``). In a UDP datagram the rest of the
    datagram is then dropped; in a raw stream the framing scans forward for the next
    offset where two consecutive plausible blocks of known categories start (or one
    that ends exactly at the end of the data), and counts the skipped bytes in
    ``resync_skipped_bytes``."""
    off = 0
    n = len(payload)
    while off < n:
        if n - off < 3:
            stats["block_truncated"] += 1
            if raw_stream:
                stats["resync_skipped_bytes"] += n - off
            return
        cat = payload[off]
        length = int.from_bytes(payload[off + 1 : off + 3], "big")
        if length < 3 or off + length > n:
            stats["block_bad_length" if length < 3 else "block_truncated"] += 1
            if not raw_stream:
                return
            nxt = _resync(payload, off + 1)
            stats["resync_skipped_bytes"] += nxt - off
            off = nxt
            continue
        stats["blocks"] += 1
        yield cat, payload[off + 3 : off + length]
        off += length


def _plausible_block(payload: bytes, off: int) -> int:
    """End offset of a plausible block of a known category at ``off``, or -1."""
    n = len(payload)
    if n - off < 4 or payload[off] not in KNOWN_CATEGORIES:
        return -1
    length = int.from_bytes(payload[off + 1 : off + 3], "big")
    if length < 4 or off + length > n:
        return -1
    return off + length


def _resync(payload: bytes, start: int) -> int:
    n = len(payload)
    for off in range(start, n):
        end = _plausible_block(payload, off)
        if end < 0:
            continue
        if end == n or _plausible_block(payload, end) >= 0:
            return off
    return n


def build_pcap(
    datagrams: list[tuple[int, bytes]],
    *,
    src: tuple[str, int] = ("127.0.0.1", 40000),
    dst: tuple[str, int] = ("127.0.0.1", 8600),
) -> bytes:
    """A classic pcap (microsecond, Ethernet) holding ``(time_ns, udp_payload)`` packets
    as IPv4/UDP from ``src`` to ``dst``: for tests and for writing replayable captures.
    The IPv4 header checksum is computed; the UDP checksum is 0 (allowed for IPv4)."""
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 262144, LINKTYPE_ETHERNET)]
    src_ip = bytes(int(x) for x in src[0].split("."))
    dst_ip = bytes(int(x) for x in dst[0].split("."))
    for ident, (time_ns, payload) in enumerate(datagrams):
        udp = struct.pack(">HHHH", src[1], dst[1], 8 + len(payload), 0) + payload
        ip = bytearray(
            struct.pack(">BBHHHBBH", 0x45, 0, 20 + len(udp), ident & 0xFFFF, 0, 64, 17, 0)
            + src_ip
            + dst_ip
        )
        csum = sum(int.from_bytes(ip[i : i + 2], "big") for i in range(0, 20, 2))
        while csum >> 16:
            csum = (csum & 0xFFFF) + (csum >> 16)
        ip[10:12] = (~csum & 0xFFFF).to_bytes(2, "big")
        frame = b"\x00" * 6 + b"\x02\x00\x00\x00\x00\x01" + b"\x08\x00" + bytes(ip) + udp
        sec, rem = divmod(int(time_ns), 1_000_000_000)
        out.append(struct.pack("<IIII", sec, rem // 1000, len(frame), len(frame)))
        out.append(frame)
    return b"".join(out)
