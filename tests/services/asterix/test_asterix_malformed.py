"""Bad input never crashes the ASTERIX reader: every problem is counted, the rest works."""

from __future__ import annotations

import struct
from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from skyfuse.services.asterix import AsterixStreamDecoder, cat034, cat048, read_asterix
from skyfuse.services.asterix.pcap import Datagram, build_pcap, iter_pcap, split_datablocks
from skyfuse.services.asterix.writer import datablock

T0 = 1_700_000_000 * 10**9  # 2023-11-14 22:13:20 UTC


def plot_block(n: int, sic: int = 11, tod0: float = 80_000.0) -> bytes:
    recs = [
        cat048.encode_record(
            sac=25, sic=sic, tod=tod0 + i / 128, rho_nm=10.0 + i, theta_deg=20.0 + i, typ=2
        )
        for i in range(n)
    ]
    return datablock(48, recs)


def crossing_block(sector_deg: float, tod: float, sic: int = 11) -> bytes:
    rec = cat034.encode_record(
        sac=25, sic=sic, message_type=cat034.SECTOR_CROSSING, tod=tod, sector_deg=sector_deg
    )
    return datablock(34, [rec])


def decode(payload: bytes, raw: bool = False) -> tuple[int, Counter]:
    dec = AsterixStreamDecoder(dedup=False)
    batches = dec.feed_with_types(Datagram(payload, T0, raw_stream=raw))
    batches += dec.flush_with_types()
    return sum(len(b) for b, _ in batches), dec.stats


def test_valid_reference_datagram():
    n, stats = decode(plot_block(3) + crossing_block(45.0, 80_001.0))
    assert n == 3 and stats["plots"] == 3 and stats["cat034_sector_crossings"] == 1


def test_truncated_block_keeps_the_blocks_before_it():
    good = plot_block(2)
    bad = plot_block(2)[:-4]  # length field says 4 bytes more than there are
    n, stats = decode(good + bad)
    assert n == 2 and stats["block_truncated"] == 1


def test_wrong_block_length_below_header_size():
    n, stats = decode(plot_block(2) + b"\x30\x00\x02" + plot_block(1))
    assert n == 2 and stats["block_bad_length"] == 1  # UDP: rest of datagram dropped


def test_raw_stream_resynchronises_after_garbage():
    garbage = b"\x30\xff\xff\x00\x01\x02\x03"
    n, stats = decode(plot_block(2) + garbage + plot_block(3, tod0=80_010.0), raw=True)
    assert n == 5
    assert stats["resync_skipped_bytes"] == len(garbage)


def test_truncated_record_inside_a_block():
    blk = plot_block(3)
    body = blk[3:-5]  # cut the third record short, fix the block length
    n, stats = decode(bytes([48]) + (len(body) + 3).to_bytes(2, "big") + body)
    assert n == 2 and stats["cat048_malformed_record"] == 1


def test_unknown_and_ignored_categories_are_counted():
    other = bytes([99, 0, 6, 1, 2, 3])
    tracks = bytes([62, 0, 5, 0, 0])
    n, stats = decode(other + plot_block(2) + tracks)
    assert n == 2
    assert stats["unknown_category_99"] == 1 and stats["ignored_category_62"] == 1


def test_time_of_day_beyond_one_day_is_rejected():
    raw = bytearray(cat048.encode_record(sac=25, sic=1, tod=0.0, rho_nm=1.0, theta_deg=1.0, typ=1))
    raw[3:6] = (86_500 * 128).to_bytes(3, "big")  # FSPEC(1) 010(2) then I140
    n, stats = decode(bytes([48]) + (len(raw) + 3).to_bytes(2, "big") + bytes(raw))
    assert n == 0 and stats["cat048_bad_time"] == 1


def test_pcap_truncated_and_foreign_packets(tmp_path):
    cap = build_pcap([(T0, plot_block(2)), (T0 + 10**8, plot_block(1, tod0=80_005.0))])
    frames = bytearray(cap)
    # append an ARP frame and a UDP fragment, then cut the file in a record
    arp = b"\xff" * 6 + b"\x02" * 6 + b"\x08\x06" + b"\x00" * 28
    frames += struct.pack("<IIII", 1, 0, len(arp), len(arp)) + arp
    frag = bytearray(build_pcap([(T0, b"xx")])[24 + 16 :])
    frag[14 + 6] = 0x20  # more-fragments flag
    frames += struct.pack("<IIII", 1, 0, len(frag), len(frag)) + frag
    frames += struct.pack("<IIII", 1, 0, 100, 100) + b"\x00" * 10  # truncated
    path = tmp_path / "bad.pcap"
    path.write_bytes(bytes(frames))
    result = read_asterix(path)
    assert result.n_plots == 3
    assert result.stats["not_ipv4"] == 1
    assert result.stats["ip_fragment"] == 1
    assert result.stats["pcap_truncated_record"] == 1


def test_pcapng_is_refused_clearly(tmp_path):
    path = tmp_path / "x.pcapng"
    path.write_bytes(b"\x0a\x0d\x0d\x0a" + b"\x00" * 40)
    with pytest.raises(ValueError, match="pcapng"):
        read_asterix(path)


def test_udp_length_not_frame_length_bounds_the_payload():
    """Ethernet pads short frames to 60 bytes; the padding must not be read as ASTERIX."""
    cap = bytearray(build_pcap([(T0, crossing_block(45.0, 100.0))]))
    frame_len = struct.unpack_from("<I", cap, 24 + 8)[0]
    pad = 60 - frame_len
    assert pad > 0
    cap[24 + 8 : 24 + 16] = struct.pack("<II", 60, 60)
    cap += b"\x88" * pad
    stats: Counter = Counter()
    payloads = [d.payload for d in iter_pcap(bytes(cap), stats)]
    assert payloads == [crossing_block(45.0, 100.0)]
    assert list(split_datablocks(payloads[0], stats)) and stats["block_truncated"] == 0


def _check_never_crashes(data: bytes, raw: bool) -> None:
    dec = AsterixStreamDecoder(dedup=True)
    batches = dec.feed(data, T0) if not raw else None
    if raw:
        batches = [b for b, _ in dec.feed_with_types(Datagram(data, None, raw_stream=True))]
    batches += dec.flush()
    assert sum(len(b) for b in batches) == dec.stats["plots"]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300), st.booleans())
def test_random_bytes_never_crash(data, raw):
    _check_never_crashes(data, raw)


BLOCKS = [plot_block(4), crossing_block(22.5, 80_001.0), plot_block(2, tod0=80_002.0)]
VALID = b"".join(BLOCKS)
BLOCK_ENDS = {sum(len(b) for b in BLOCKS[:k]) for k in range(len(BLOCKS) + 1)}


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(VALID) - 1), st.integers(0, 255)), max_size=6))
def test_mutated_valid_data_never_crashes(mutations):
    data = bytearray(VALID)
    for pos, value in mutations:
        data[pos] = value
    _check_never_crashes(bytes(data), raw=False)
    _check_never_crashes(bytes(data), raw=True)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, len(VALID)))
def test_truncation_anywhere_is_counted(cut):
    dec = AsterixStreamDecoder()
    dec.feed(VALID[:cut], T0)
    dec.flush()
    problems = sum(v for k, v in dec.stats.items() if "truncated" in k or "malformed" in k)
    assert problems == (0 if cut in BLOCK_ENDS else 1)


def _pcap_with_linktype(linktype: int, frames: list[bytes], nano: bool = False) -> bytes:
    magic = 0xA1B23C4D if nano else 0xA1B2C3D4
    out = [struct.pack("<IHHiIII", magic, 2, 4, 0, 0, 262144, linktype)]
    for i, frame in enumerate(frames):
        out.append(struct.pack("<IIII", 1_700_000_000 + i, 5, len(frame), len(frame)) + frame)
    return b"".join(out)


def test_linux_cooked_vlan_and_raw_ip_links():
    payload = plot_block(1)
    eth = build_pcap([(T0, payload)])[24 + 16 :]  # one Ethernet frame
    ip_udp = eth[14:]
    sll = b"\x00\x00\x00\x01\x00\x06" + b"\x02" * 6 + b"\x00\x00" + b"\x08\x00" + ip_udp
    sll2 = b"\x08\x00\x00\x00" + b"\x00" * 16 + ip_udp
    vlan = eth[:12] + b"\x81\x00\x00\x07" + eth[12:]
    for linktype, frame in ((113, sll), (276, sll2), (101, ip_udp), (1, vlan)):
        stats: Counter = Counter()
        got = list(iter_pcap(_pcap_with_linktype(linktype, [frame], nano=True), stats))
        assert [d.payload for d in got] == [payload], linktype
        assert got[0].time_ns == 1_700_000_000 * 10**9 + 5  # nanosecond pcap
    stats = Counter()
    assert list(iter_pcap(_pcap_with_linktype(147, [ip_udp]), stats)) == []
    assert stats["unsupported_linktype_147"] == 1
