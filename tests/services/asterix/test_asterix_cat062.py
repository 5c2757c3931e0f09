"""CAT062 track output: encode → decode round trip, accuracies checked with pymap3d,
and the public CAT062 sample decoded without a crash."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pymap3d
import pytest
from service_support import SHARED_DATA
from skyfuse.schemas import FrameSpec, Track, TrackBatch
from skyfuse.services.asterix.cat062 import decode_cat062, read_cat062
from skyfuse.services.asterix.cat062_writer import Cat062Writer, build_record, pack_record
from skyfuse.services.asterix.pcap import build_pcap

T0 = int(dt.datetime(2026, 3, 1, 12, 0, tzinfo=dt.UTC).timestamp()) * 10**9
SAMPLE = SHARED_DATA / "cat062_sample.pcap"
LSB_DEG = 180 / 2**25


def make_track(i: int, rng, *, status="confirmed", alt=10_000.0, radars=("25-11",)) -> Track:
    cov = np.diag(rng.uniform([50, 2, 50, 2], [400, 10, 400, 10]) ** 2)
    cov[0, 2] = cov[2, 0] = rng.uniform(-0.5, 0.5) * math.sqrt(cov[0, 0] * cov[2, 2])
    ve, vn = rng.uniform(-250, 250, 2)
    return Track(
        track_id=i,
        time=T0 + i * 1_000_000,
        status=status,
        existence=0.9,
        state=[float(x) for x in rng.uniform(-3e5, 3e5, 4)],
        covariance=cov.tolist(),
        lat=float(rng.uniform(40, 50)),
        lon=float(rng.uniform(10, 20)),
        alt=alt,
        vel_east=float(ve),
        vel_north=float(vn),
        speed=float(math.hypot(ve, vn)),
        heading=float(math.atan2(ve, vn) % (2 * math.pi)),
        radars=list(radars),
    )


def batch_of(tracks, kind="stereographic", labels=("x", "vx", "y", "vy")) -> TrackBatch:
    return TrackBatch(
        fusion_id="f",
        cycle=1,
        time=T0,
        frame=FrameSpec(kind=kind, lat0=45.0, lon0=15.0),
        state_labels=list(labels),
        tracks=tracks,
    )


def test_round_trip_values():
    rng = np.random.default_rng(3)
    tracks = [make_track(i, rng) for i in range(60)]
    tracks.append(make_track(60, rng, status="tentative", alt=None, radars=("a", "b")))
    writer = Cat062Writer(sac=25, sic=100, service_id=7)
    blocks = writer.encode_batch(batch_of(tracks))
    assert all(len(b) <= 1400 for b in blocks) and len(blocks) > 1
    got = [t for b in blocks for t in decode_cat062(b)]
    assert len(got) == len(tracks)
    for tr, d in zip(tracks, got):
        assert (d.sac, d.sic, d.service_id, d.track_number) == (25, 100, 7, tr.track_id)
        tod = (tr.time % (86_400 * 10**9)) / 1e9
        assert abs(d.tod - tod) <= 1 / 256 + 1e-9
        assert abs(d.lat - tr.lat) <= LSB_DEG / 2 and abs(d.lon - tr.lon) <= LSB_DEG / 2
        assert abs(d.vx - tr.vel_east) <= 0.125 and abs(d.vy - tr.vel_north) <= 0.125
        assert abs(d.x - tr.state[0]) <= 0.25 and abs(d.y - tr.state[2]) <= 0.25
        if tr.alt is None:
            assert d.flight_level is None
        else:
            assert abs(d.flight_level * 30.48 - tr.alt) <= 0.125 * 30.48
        assert d.confirmed == (tr.status == "confirmed")
        assert d.mono == (len(tr.radars) == 1)
        assert d.first is True and d.last is False
        cov = np.asarray(tr.covariance)
        assert abs(d.sigma_x - math.sqrt(cov[0, 0])) <= 0.25
        assert abs(d.sigma_y - math.sqrt(cov[2, 2])) <= 0.25
        root = math.copysign(math.sqrt(abs(cov[0, 2])), cov[0, 2])
        assert abs(math.copysign(math.sqrt(abs(d.cov_xy)), d.cov_xy) - root) <= 0.25
        assert abs(d.sigma_vx - math.sqrt(cov[1, 1])) <= 0.125
        assert abs(d.sigma_vy - math.sqrt(cov[3, 3])) <= 0.125
        # APW: 1-sigma north/east offsets converted to degrees by pymap3d (independent)
        lat_n, _, _ = pymap3d.enu2geodetic(0.0, math.sqrt(cov[2, 2]), 0.0, tr.lat, tr.lon, 0.0)
        _, lon_e, _ = pymap3d.enu2geodetic(math.sqrt(cov[0, 0]), 0.0, 0.0, tr.lat, tr.lon, 0.0)
        assert d.sigma_lat == pytest.approx(lat_n - tr.lat, abs=LSB_DEG)
        assert d.sigma_lon == pytest.approx(lon_e - tr.lon, abs=LSB_DEG)


def test_status_flags_over_a_track_life():
    rng = np.random.default_rng(4)
    writer = Cat062Writer(sac=1, sic=2, simulated=True)
    tr = make_track(5, rng)
    first = decode_cat062(writer.encode_batch(batch_of([tr]))[0])[0]
    again = decode_cat062(writer.encode_batch(batch_of([tr]))[0])[0]
    end = tr.model_copy(update={"status": "terminated"})
    last = decode_cat062(writer.encode_batch(batch_of([end]))[0])[0]
    assert (first.first, again.first, last.last, again.last) == (True, False, True, False)
    assert first.simulated is True


@pytest.mark.parametrize(
    ("radars", "mono"), [((), True), (("25-11",), True), (("25-11", "25-12"), False)]
)
def test_monosensor_flag_follows_the_number_of_radars(radars, mono):
    """I062/080 MON = 1 (monosensor) unless two or more radars updated the track."""
    tr = make_track(3, np.random.default_rng(9), radars=radars)
    (dec,) = decode_cat062(Cat062Writer(sac=1, sic=2).encode_batch(batch_of([tr]))[0])
    assert dec.mono is mono


def test_ned_frame_axes_are_swapped_to_east_north():
    rng = np.random.default_rng(5)
    tr = make_track(1, rng)
    cov = np.diag([300.0**2, 9.0, 100.0**2, 1.0])  # x = north, y = east in NED
    tr = tr.model_copy(update={"covariance": cov.tolist()})
    d = decode_cat062(Cat062Writer(sac=1, sic=2).encode_batch(batch_of([tr], kind="ned"))[0])[0]
    assert (d.sigma_x, d.sigma_y, d.sigma_vx, d.sigma_vy) == (100.0, 300.0, 1.0, 3.0)
    assert d.x is None  # I100 only for a stereographic system plane


def test_pcap_round_trip_and_track_number_wrap(tmp_path):
    rng = np.random.default_rng(6)
    tracks = [make_track(70_000 + i, rng) for i in range(3)]
    writer = Cat062Writer(sac=25, sic=100)
    blocks = writer.encode_batch(batch_of(tracks))
    path = tmp_path / "tracks.pcap"
    path.write_bytes(build_pcap([(T0, b) for b in blocks]))
    got, stats = read_cat062(path)
    assert [g.track_number for g in got] == [(70_000 + i) % 65536 for i in range(3)]
    assert writer.stats["track_number_wrapped"] == 3 and stats["cat062_records"] == 3


@pytest.mark.skipif(not SAMPLE.exists(), reason="../shared/data/cat062_sample.pcap absent")
def test_public_sample_is_decoded_without_a_crash_and_fully_counted():
    """The sample's records do not follow the CAT062 edition 1.x UAP (its I070 follows
    I010 directly and its WGS-84 position has 3-byte fields), so no record yields a
    valid track; every one is counted as malformed or rejected, none crashes."""
    tracks, stats = read_cat062(SAMPLE)
    assert stats["pcap_packets"] == 100 and stats["blocks"] == 100
    assert stats["cat062_malformed_record"] + stats["cat062_records"] >= 100
    rejected = sum(v for k, v in stats.items() if k in ("cat062_bad_time", "cat062_empty_record"))
    assert rejected + len(tracks) == stats["cat062_records"]
    for t in tracks:  # whatever decodes must be plausible
        assert (t.sac, t.sic) == (25, 100) and 0 <= t.tod < 86_400


@pytest.mark.parametrize("kind", ["stereographic", "ned", "planar"])
def test_direct_encoder_matches_libasterix(kind):
    rng = np.random.default_rng(8)
    writer = Cat062Writer(sac=3, sic=4, simulated=True)
    for i in range(40):
        status = ("confirmed", "tentative", "terminated")[i % 3]
        tr = make_track(i * 2500, rng, status=status, alt=None if i % 4 == 0 else 9000.0)
        raw = writer.raw_items(tr, kind, ["x", "vx", "y", "vy"], first=i % 2 == 0, last=i % 5 == 0)
        assert pack_record(raw) == build_record(raw).unparse().to_bytes()
