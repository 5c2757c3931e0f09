"""``skyfuse fusion`` as a process: malformed input counted by reason (never a crash),
radars followed through liveliness, TrackBatches on the feed, the snapshot queryable, and
``skyfuse tracks --json`` / ``--snapshot`` as clients."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from service_support import make_batch, make_site, peer, skyfuse, stop
from skyfuse.schemas import Status, TrackBatch, keys
from skyfuse.services.runtime.transport import (
    Inbox,
    declare_liveliness,
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
    query,
    service_alive_key,
    wait_for_tokens,
    wall_stamp,
)

pytestmark = pytest.mark.service


def next_status(inbox: Inbox, pred, timeout: float = 8.0, others=None) -> Status:
    deadline = time.monotonic() + timeout
    st = None
    while time.monotonic() < deadline:
        item = inbox.get(0.1)
        if item is not None and item.tag != "status" and others is not None:
            others.append(item)
        if item is not None and item.tag == "status":
            st = Status.from_json_bytes(item.payload)
            if pred(st):
                return st
    raise AssertionError(f"no matching status; last {st}")


def test_fusion_service_inputs_liveliness_feed_and_clients(tmp_path):
    ep = loopback_endpoint(free_port())
    fusion = skyfuse(
        "fusion", "--listen", ep, "--reorder-wait", "0.1", "--status-interval", "0.2",
        "--frame-lat0", "45.0", "--frame-lon0", "20.0", log_path=tmp_path / "fusion.log",
    )  # fmt: skip
    feed = skyfuse("tracks", "--json", "--count", "3", "--connect", ep)  # starts meanwhile
    rng = np.random.default_rng(5)
    try:
        with open_session(peer(connect=ep)) as s:
            inbox = Inbox()
            inbox.subscribe(s, keys.fusion_status("main"), "status")
            inbox.subscribe(s, keys.fusion_tracks("main"), "tracks")
            assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
            site_pub = declare_publisher(s, keys.radar_site("R1"))
            plots = declare_publisher(s, keys.radar_plots("R1"))
            token = declare_liveliness(s, keys.radar_alive("R1"))
            time.sleep(0.3)
            site_pub.put(b'{"radar_id": "R1", "lat": 95}')  # invalid site
            plots.put(b"\xff\xfe not json")
            site_pub.put(make_site("R1", 45.0, 20.0).to_json_bytes())
            for k in range(8):
                plots.put(make_batch("R1", k // 4, k % 4, 4, 5, rng).to_json_bytes(),
                          attachment=wall_stamp())  # fmt: skip
            batches = []
            st = next_status(inbox, lambda st: st.counters.get("cycles", 0) >= 8, others=batches)
            assert st.rejected["invalid PlotBatch: not JSON"] == 1
            assert st.rejected["invalid RadarSite: lat"] == 1
            (r1,) = st.radars
            assert r1.radar_id == "R1" and r1.alive and r1.site_known and r1.batches == 8
            assert st.latency_ms.count == 8 and 0 < st.latency_ms.p50 < 2000
            batches += [i for i in inbox.drain() if i.tag == "tracks"]
            # the feed and the Status are two keys, with no delivery order between them:
            # the Status of cycle 8 can come before the deltas it counts
            deadline = time.monotonic() + 5.0
            while not batches and time.monotonic() < deadline:
                item = inbox.get(0.1)
                if item is not None and item.tag == "tracks":
                    batches.append(item)
            assert batches and TrackBatch.from_json_bytes(batches[-1].payload).fusion_id == "main"
            ((key, payload),) = query(s, f"{keys.PREFIX}/fusion/*/snapshot")
            assert key == keys.fusion_snapshot("main")
            assert TrackBatch.from_json_bytes(payload).source_radar == "R1"
            # clients: a snapshot, and the JSON-lines feed while more batches come in
            snap_file = tmp_path / "snapshot.jsonl"
            snap = skyfuse("tracks", "--snapshot", "--json", str(snap_file), "--connect", ep)
            k, deadline = 8, time.monotonic() + 25
            while feed.poll() is None and time.monotonic() < deadline:  # until it has 3
                plots.put(make_batch("R1", k // 4, k % 4, 4, 5, rng).to_json_bytes())
                k += 1
                time.sleep(0.2)
            out, _ = feed.communicate(timeout=5)
            snap.communicate(timeout=20)
            assert snap.returncode == 0  # --json FILE: the JSON lines go to the file
            assert json.loads(snap_file.read_text())["topic"] == keys.fusion_snapshot("main")
            # not a terminal: plain tab-separated text, nothing truncated
            plain = skyfuse("tracks", "--snapshot", "--all-tracks", "--connect", ep)
            plain_out = plain.communicate(timeout=20)[0].decode()
            assert plain.returncode == 0 and plain_out.startswith("id\tstatus\tlat °")
            assert "# fusion main cycle" in plain_out and "…" not in plain_out
            lines = [json.loads(x) for x in out.splitlines()]
            assert feed.returncode == 0 and len(lines) >= 3
            assert all(x["topic"] == keys.fusion_tracks("main") for x in lines)
            # the radar goes away: its liveliness token disappears
            token.undeclare()
            st = next_status(inbox, lambda st: not st.radars[0].alive)
            assert st.radars[0].site_known
    finally:
        if feed.poll() is None:
            feed.kill()
        rc, took = stop(fusion)
    assert rc == 0 and took < 5.0, (tmp_path / "fusion.log").read_text()[-3000:]
