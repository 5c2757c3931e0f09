"""A late subscriber of the live feed (subscribe, then the snapshot queryable, then the
deltas after it) rebuilds exactly the picture of a subscriber that listened from the
start — real Zenoh sessions on loopback, the fusion service loop in a thread, no full
message after the first one (``full_interval`` longer than the test)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import FeedKind, TrackBatch, TrackPicture, keys
from skyfuse.services.fusion.server import make_pipeline_factory, serve
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
    query,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service


def test_late_subscriber_rebuilds_the_early_subscribers_picture():
    sc = build_scenario("regional", seed=8, duration=40.0, targets=10, radars=3)
    ev = Simulator(sc, seed=8).run(truth=False)
    batches = sorted((e.message for e in ev if e.kind == "plots"), key=lambda b: b.time_end)
    lat0 = float(np.mean([s.lat for s in sc.sites]))
    lon0 = float(np.mean([s.lon for s in sc.sites]))
    cfg = FusionConfig(fusion_id="late", reorder_wait=0.05, full_interval=3600.0,
                       frame_lat0=lat0, frame_lon0=lon0, sites=list(sc.sites))  # fmt: skip
    core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), "late"))
    ep = loopback_endpoint(free_port())
    halt = threading.Event()
    early, late = TrackPicture(), TrackPicture()
    with (
        open_session(TransportConfig(mode="peer", listen=[ep])) as s_fusion,
        open_session(TransportConfig(mode="peer", connect=[ep])) as s_early,
        open_session(TransportConfig(mode="peer", connect=[ep])) as s_late,
    ):
        feed_early = Inbox()
        feed_early.subscribe(s_early, keys.fusion_tracks("late"), "tracks")
        t = threading.Thread(target=serve, args=(s_fusion, core, halt))
        t.start()
        try:
            assert wait_for_tokens(s_early, [service_alive_key("fusion")], 10.0) == []
            pubs = {s.radar_id: declare_publisher(s_early, keys.radar_plots(s.radar_id))
                    for s in sc.sites}  # fmt: skip
            half = len(batches) // 2
            for b in batches[:half]:
                pubs[b.radar_id].put(b.to_json_bytes())
                time.sleep(0.005)
            time.sleep(0.5)
            feed_late = Inbox()  # joins now: subscribe first, then ask the snapshot
            feed_late.subscribe(s_late, keys.fusion_tracks("late"), "tracks")
            time.sleep(0.3)
            ((_, snap),) = query(s_late, keys.fusion_snapshot("late"), timeout=3.0)
            snapshot = TrackBatch.from_json_bytes(snap)
            assert snapshot.kind is FeedKind.FULL and snapshot.cycle >= 1
            late.apply(snapshot)
            for b in batches[half:]:
                pubs[b.radar_id].put(b.to_json_bytes())
                time.sleep(0.005)
            deadline = time.monotonic() + 20
            while core.counters["cycles"] < len(batches) and time.monotonic() < deadline:
                time.sleep(0.1)
            time.sleep(0.5)
        finally:
            halt.set()
            t.join(10)
        msgs_early = [TrackBatch.from_json_bytes(i.payload) for i in feed_early.drain()]
        msgs_late = [TrackBatch.from_json_bytes(i.payload) for i in feed_late.drain()]
        feed_early.close()
        feed_late.close()
    assert core.counters["cycles"] == len(batches)
    # the one full message is the first group's (due at start): none after it
    assert [m.cycle for m in msgs_early if m.kind is FeedKind.FULL] == [1]
    for m in msgs_early:
        early.apply(m)
    for m in msgs_late:
        late.apply(m)
    assert len(snapshot.tracks) >= 3 and msgs_late[0].cycle > 1  # joined with a picture
    assert early.complete and late.complete
    assert len(early.tracks) >= 5 and early.cycle == late.cycle
    assert {i: t.model_dump() for i, t in late.tracks.items()} == {
        i: t.model_dump() for i, t in early.tracks.items()
    }
