"""The recorder's Foxglove track channels rebuild the picture from the delta/full feed:
a track that a delta does not name stays on the map, a removed one leaves it; the
GeoJSON channel names each track and draws its heading (checked with pymap3d)."""

from __future__ import annotations

import json
import math

import pymap3d
from skyfuse.schemas import TrackBatch, keys
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.recording.recorder import HEADING_LINE_S, Recorder, RecorderConfig
from skyfuse.services.runtime.transport import Received

T0 = 1_767_226_200 * 10**9


def track(i: int, lat: float, lon: float, heading_deg: float = 90.0) -> dict:
    h = math.radians(heading_deg)
    return {
        "track_id": i, "time": T0, "status": "confirmed", "existence": 0.99,
        "state": [0.0] * 4, "covariance": [[1.0 if r == c else 0.0 for c in range(4)]
                                           for r in range(4)],
        "lat": lat, "lon": lon, "alt": 9000.0, "vel_east": 200 * math.sin(h),
        "vel_north": 200 * math.cos(h), "speed": 200.0, "heading": h, "radars": ["R1"],
    }  # fmt: skip


def pb_fields(data: bytes) -> list[tuple[int, bytes]]:
    """Top-level length-delimited fields of a protobuf message (wire type 2)."""
    out, i = [], 0

    def varint() -> int:
        nonlocal i
        v = shift = 0
        while True:
            b = data[i]
            i += 1
            v |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                return v

    while i < len(data):
        key = varint()
        assert key & 7 == 2, "only length-delimited fields expected"
        n = varint()
        out.append((key >> 3, data[i : i + n]))
        i += n
    return out


def batch(kind: str, cycle: int, tracks: list[dict], removed=()) -> bytes:
    return TrackBatch(
        fusion_id="main", kind=kind, cycle=cycle, time=T0 + cycle * 10**9,
        frame={"kind": "stereographic", "lat0": 45.0, "lon0": 20.0},
        state_labels=["x", "vx", "y", "vy"], tracks=tracks, removed=list(removed),
    ).to_json_bytes()  # fmt: skip


def test_foxglove_tracks_follow_the_rebuilt_picture(tmp_path):
    out = tmp_path / "rec.mcap"
    rec = Recorder(RecorderConfig(out=out))
    feed = [
        batch("full", 1, [track(1, 45.0, 20.0), track(2, 45.1, 20.1)]),
        batch("delta", 2, [track(2, 45.2, 20.2, heading_deg=0.0)]),  # 1 not named: stays
        batch("delta", 3, [track(3, 45.3, 20.3)], removed=[1]),
    ]
    for k, payload in enumerate(feed):
        t = T0 + k * 10**9
        assert rec.handle(Received("tracks", keys.fusion_tracks("main"), payload, True, t))
    rec.close()
    fixes, geo = [], []
    for r in iter_recording(out, decode=False):
        if r.topic == "/foxglove/tracks":
            fixes.append(pb_fields(r.data))  # LocationFixes: 1 = repeated LocationFix
        elif r.topic == "/foxglove/tracks_geojson":
            ((field, text),) = pb_fields(r.data)  # GeoJSON: 1 = geojson (string)
            assert field == 1
            geo.append(json.loads(text))
    assert [len(f) for f in fixes] == [2, 2, 2]
    ids = [sorted({f["properties"]["track_id"] for f in g["features"]}) for g in geo]
    assert ids == [[1, 2], [1, 2], [2, 3]]
    # track 2 after the delta: heading 0 (north); its line ends 60 s × 200 m/s north
    feats = [f for f in geo[1]["features"] if f["properties"]["track_id"] == 2]
    line = next(f for f in feats if f["geometry"]["type"] == "LineString")
    (lo1, la1), (lo2, la2) = line["geometry"]["coordinates"]
    e, n, _ = pymap3d.geodetic2enu(la2, lo2, 0, la1, lo1, 0)
    assert abs(e) < 1.0 and abs(n - 200 * HEADING_LINE_S) < 1.0
    assert feats[0]["properties"]["name"] == "T2"
    assert feats[0]["properties"]["heading_deg"] == 0.0


def test_foxglove_tracks_drawn_once_per_period_and_the_last_at_close(tmp_path):
    """Deltas every 0.25 s of data time, period 1 s: pictures at 0, 1 and 2 s, and the
    last one (2.25 s, with the track the last delta added) when the recorder closes."""
    out = tmp_path / "rec.mcap"
    rec = Recorder(RecorderConfig(out=out, foxglove_track_period=1.0))
    for k in range(10):
        tracks = [track(1, 45.0, 20.0)] + ([track(2, 45.1, 20.1)] if k == 9 else [])
        payload = TrackBatch(
            fusion_id="main", kind="full" if k == 0 else "delta", cycle=k + 1,
            time=T0 + k * 250_000_000, frame={"kind": "stereographic", "lat0": 45.0,
            "lon0": 20.0}, state_labels=["x", "vx", "y", "vy"], tracks=tracks,
        ).to_json_bytes()  # fmt: skip
        t = T0 + k * 250_000_000
        assert rec.handle(Received("tracks", keys.fusion_tracks("main"), payload, True, t))
    rec.close()
    fixes = [pb_fields(r.data) for r in iter_recording(out, decode=False)
             if r.topic == "/foxglove/tracks"]  # fmt: skip
    assert [len(f) for f in fixes] == [1, 1, 1, 2]
    recorded = [r for r in iter_recording(out) if r.topic == keys.fusion_tracks("main")]
    assert len(recorded) == 10  # the feed itself is recorded whole
