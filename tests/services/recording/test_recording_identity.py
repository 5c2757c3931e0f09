"""Secondary-surveillance plot columns travel unchanged: simulator → ``skyfuse simulate``
MCAP → ``skyfuse replay`` payloads, and → CAT048 (``simulate --format asterix``) → read
back; the Foxglove map labels tracks by callsign (or squawk) and flight level."""

from __future__ import annotations

import datetime as dt
import json
from collections import Counter

from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.schemas import PlotBatch, Track
from skyfuse.schemas.plots import IDENTITY_COLUMNS
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.recording.recorder import track_features, track_label
from skyfuse.services.sensors import replay as replay_mod

ARGS = ("--scenario", "regional", "--duration", "40", "--targets", "12", "--seed", "3",
        "--param", "ehs_fraction=1,code_change_fraction=0.5,garble_probability=0.05")  # fmt: skip


def _simulated() -> list[PlotBatch]:
    sc = build_scenario("regional", seed=3, duration=40.0, targets=12, ehs_fraction=1.0,
                        code_change_fraction=0.5, garble_probability=0.05)  # fmt: skip
    return [e.message for e in Simulator(sc).run() if e.kind == "plots"]


def test_identity_columns_survive_the_recording_and_the_replay(simulated_recording, monkeypatch):
    path = simulated_recording(*ARGS)
    recorded = [r.message for r in iter_recording(path) if isinstance(r.message, PlotBatch)]
    sent = _simulated()
    assert recorded == sent
    carried = {c for b in recorded for c in IDENTITY_COLUMNS if getattr(b, c) is not None}
    assert {"callsign", "flight_level", "mode_3a_garbled", "ground_speed"} <= carried
    assert any(c for b in recorded for c in (b.callsign or []))

    published = []

    class Pub:
        matching_status = type("M", (), {"matching": True})()

        def __init__(self, topic):
            self.topic = topic

        def put(self, data, attachment=None):
            published.append((self.topic, bytes(data)))

        def undeclare(self):
            pass

    monkeypatch.setattr(replay_mod, "declare_publisher", lambda s, topic: Pub(topic))
    monkeypatch.setattr(replay_mod, "declare_cached_publisher", lambda s, topic, cache: Pub(topic))
    monkeypatch.setattr(replay_mod, "declare_liveliness", lambda s, key: Pub(key))
    replay_mod.replay(None, path, fast=True)
    replayed = [PlotBatch.from_json_bytes(d) for t, d in published if t.endswith("/plots")]
    assert replayed == recorded


def test_identity_columns_through_simulate_asterix(tmp_path):
    from skyfuse.services.asterix import load_sites, read_asterix
    from skyfuse.services.cli.main import main

    out = tmp_path / "sim.ast"
    assert main(["simulate", *ARGS, "--format", "asterix", "--out", str(out), "--no-progress"]) == 0
    sites = load_sites(f"{out}.sites.toml")
    result = read_asterix(out, sites=sites, date=dt.date(2026, 1, 1))
    got = Counter(cs for b in result.batches for cs in b.callsign or [] if cs)
    sent = Counter(cs for b in _simulated() for cs in b.callsign or [] if cs)
    assert got == sent and len(got) >= 5  # every reply of every aircraft
    ehs = sum(v is not None for b in result.batches for v in (b.ground_speed or []))
    assert ehs > 50 and result.stats.get("cat048_bds_decoded_5_0", 0) > 50


def _track(i: int, **identity) -> Track:
    return Track(
        track_id=i, time=10**18, status="confirmed", existence=0.9, state=[0.0] * 4,
        covariance=[[float(r == c) for c in range(4)] for r in range(4)], lat=41.3, lon=2.1,
        vel_east=0.0, vel_north=100.0, speed=100.0, heading=0.0, **identity,
    )  # fmt: skip


def test_foxglove_labels_show_callsign_or_squawk_and_flight_level():
    tracks = [
        _track(1, callsign="ROT415", mode_3a=0o4004, flight_level=370.0, mode_s=0x4A08EB),
        _track(2, mode_3a=0o4004, flight_level=95.25),
        _track(3, mode_3a=0o7700, emergency="general"),
        _track(4, flight_level=5.0),
        _track(5),
    ]
    assert [track_label(t) for t in tracks] == [
        "ROT415 FL370", "4004 FL095", "7700!", "T4 FL005", "T5"]  # fmt: skip
    feats = json.loads(_geojson_text(track_features(tracks).encode()))["features"]
    props = [f["properties"] for f in feats if f["geometry"]["type"] == "Point"]
    assert props[0]["callsign"] == "ROT415" and props[0]["squawk"] == "4004"
    assert props[0]["mode_s"] == "4A08EB" and props[0]["flight_level"] == 370.0
    assert props[2]["emergency"] == "general"
    # a track without identity: the label and properties it always had
    assert set(props[4]) == {"name", "track_id", "heading_deg", "speed_mps", "alt_m",
                             "existence", "radars"}  # fmt: skip


def _geojson_text(data: bytes) -> str:
    """Field 1 (the GeoJSON string) of an encoded foxglove.GeoJSON protobuf message."""
    assert data[0] == 0x0A  # field 1, length-delimited
    n, shift, i = 0, 0, 1
    while True:
        n |= (data[i] & 0x7F) << shift
        shift += 7
        i += 1
        if not data[i - 1] & 0x80:
            return data[i : i + n].decode()
