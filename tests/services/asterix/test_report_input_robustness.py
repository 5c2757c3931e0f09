"""CAT010 / CAT020 / CAT021 input that decodes but breaks the wire contract is a counted
rejection, never an exception, and the good reports around it are kept (found by mutating
the LEBL recordings: a corrupted I041 latitude, I202 velocity or cycle time went through
decoding and crashed the batcher when the PlotBatch refused it)."""

from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from service_support import SHARED_DATA
from skyfuse.services.asterix import AsterixStreamDecoder, cat010, cat020, cat021
from skyfuse.services.asterix.pcap import Datagram
from skyfuse.services.asterix.record_reject import RecordReject
from skyfuse.services.asterix.report_batches import ReportBatcher


def _mlat(tod, track, **kw):
    r = cat010.Cat010Report(0, 107, tod, typ=1, x_m=100.0, y_m=200.0, track_number=track, **kw)
    r.time_ns = round(tod * 1e9)
    return r


def _cycle(tod):
    s = cat010.Cat010Status(0, 107, cat010.START_OF_UPDATE_CYCLE, tod)
    s.time_ns = round(tod * 1e9)
    return s


def _run(items):
    b = ReportBatcher()
    out = [batch for it in items for batch, _ in b.add(it)]
    return out + [batch for batch, _ in b.flush()], b


def test_a_report_the_wire_contract_refuses_is_dropped_and_its_batch_kept():
    notes = []
    b = ReportBatcher(note=notes.append)
    items = [_cycle(10.0), _mlat(10.1, 1, vx_ms=3.0, vy_ms=4.0),
             _mlat(10.2, 2, vx_ms=5000.0, vy_ms=0.0), _mlat(10.3, 3, vx_ms=1.0, vy_ms=1.0),
             _cycle(11.0)]  # fmt: skip
    out = [batch for it in items for batch, _ in b.add(it)] + [x for x, _ in b.flush()]
    assert [len(x) for x in out] == [2]
    assert list(out[0].v_east) == [3.0, 1.0]
    assert b.stats["report_invalid"] == 1 and b.stats["report_plots"] == 2
    dropped = [n for n in notes if "report dropped" in n]
    assert len(dropped) == 1 and "v_east" in dropped[0] and "5000" in dropped[0]


def test_a_cycle_message_timed_before_its_batch_is_counted():
    batches, b = _run([_cycle(10.0), _mlat(10.5, 1), _cycle(11.0), _cycle(5.0), _mlat(5.5, 2)])
    assert b.stats["report_cycle_time_backwards"] == 1
    assert all(x.time_start <= x.time_end for x in batches)
    assert sum(len(x) for x in batches) == 2


def test_an_adsb_sensor_without_a_wgs84_first_report_has_no_site_and_no_crash():
    r = _mlat(3.0, 1)
    r.typ = 2  # CAT010 ADS-B, but I042 only
    batches, b = _run([r])
    assert b.site_of(next(iter(b._sensors.values()))) is None
    assert sum(len(x) for x in batches) == 1


def _lat_lon(lat_deg: float, lon_deg: float, lsb: float) -> bytes:
    return round(lat_deg / lsb).to_bytes(4, "big", signed=True) + round(lon_deg / lsb).to_bytes(
        4, "big", signed=True
    )


@pytest.mark.parametrize(
    ("decode", "lsb", "reason"),
    [
        (cat010.decode_items, 180.0 / 2**31, "cat010_bad_position"),
        (cat020.decode_items, 180.0 / 2**25, "cat020_bad_position"),
    ],
)
def test_wgs84_positions_outside_their_ranges_are_rejected(decode, lsb, reason):
    base = {"010": bytes([0, 107]), "140": (3600 * 128).to_bytes(3, "big")}
    if decode is cat010.decode_items:
        base |= {"000": bytes([1]), "020": bytes([0x20])}
    good = decode({**base, "041": _lat_lon(41.3, 2.08, lsb)})
    assert not isinstance(good, RecordReject) and abs(good.lat - 41.3) < 1e-5
    bad = decode({**base, "041": _lat_lon(120.0 if lsb < 1e-7 else 900.0, 2.08, lsb)})
    assert isinstance(bad, RecordReject) and bad.reason == reason
    assert "041" in bad.detail and "outside WGS-84" in bad.detail
    assert reason in (cat010.REJECT_REASONS if "010" in reason else cat020.REJECT_REASONS)


def test_cat021_uses_the_same_reject():
    rec = cat021.decode_items({}, "2.7")
    assert isinstance(rec, RecordReject) and rec.reason == "cat021_no_data_source"


def _blocks(name: str, n: int) -> list[bytes]:
    data = (SHARED_DATA / name).read_bytes()[:300_000]
    out, pos = [], 0
    while pos + 3 <= len(data) and len(out) < n:
        length = int.from_bytes(data[pos + 1 : pos + 3], "big")
        out.append(data[pos : pos + length])
        pos += length
    return out


LEBL = [
    "lebl_20160510_2200_2215_smr.ast",
    "lebl_20160510_2200_2215_mlat.ast",
    "lebl_20160510_2200_2215_adsb.ast",
    "lebl_20201002_0800_0815_smr.ast",
]


@pytest.mark.skipif(not (SHARED_DATA / LEBL[0]).exists(), reason="shared LEBL data absent")
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(LEBL), seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_mutated_lebl_records_never_crash_the_reader(name, seed, n):
    rng = random.Random(seed)
    chunk = bytearray(b"".join(rng.sample(_blocks(name, 600), 8)))
    for _ in range(n):
        chunk[rng.randrange(len(chunk))] = rng.randrange(256)
    dec = AsterixStreamDecoder(dedup=True)
    batches = [b for b, _ in dec.feed_with_types(Datagram(bytes(chunk), 0))]
    batches += dec.flush()
    assert sum(len(b) for b in batches) == dec.stats["report_plots"]
