"""The offline ``skyfuse track FILE.mcap`` and a live replay of the same recording through
the ``skyfuse fusion`` process give the same tracks: the pictures rebuilt from both feeds
(``schemas.TrackPicture``) have the same confirmed track ids after every live delta
(which may apply several batches at once) and the same final states."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from service_support import confirmed_ids, feed_pictures, peer, skyfuse, stop
from skyfuse.schemas import (
    FeedKind,
    PlotBatch,
    RadarSite,
    Status,
    TrackBatch,
    keys,
)
from skyfuse.services.cli.main import main as skyfuse_main
from skyfuse.services.fusion.system_frame import frame_for_sites
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime.transport import (
    Inbox,
    free_port,
    loopback_endpoint,
    open_session,
    query,
    service_alive_key,
    wait_for_tokens,
)
from skyfuse.services.sensors.replay import replay

pytestmark = pytest.mark.service


def wait_for_sites(session, sites: list[RadarSite], timeout: float = 20.0) -> None:
    """Publish ``sites`` and wait until the fusion's Status reports every one known."""
    for site in sites:
        session.put(keys.radar_site(site.radar_id), site.to_json_bytes())
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for _, payload in query(session, keys.fusion_status("main"), 1.0):
            known = {r.radar_id for r in Status.from_json_bytes(payload).radars if r.site_known}
            if known >= {site.radar_id for site in sites}:
                return
        time.sleep(0.2)
    raise AssertionError("the fusion never reported every site known")


def test_live_replay_through_fusion_equals_offline_track(tmp_path: Path, simulated_recording):
    rec = simulated_recording(
        "--scenario", "regional", "--seed", "3", "--duration", "20", "--targets", "5",
        "--param", "radars=3",
    )  # fmt: skip
    # no frame is configured: live and offline place it by the one rule (frame_for_sites)
    sites = [r.message for r in iter_recording(rec) if isinstance(r.message, RadarSite)]
    expected = frame_for_sites(sites)
    ep = loopback_endpoint(free_port())
    # (the fusion process starts up while the offline tracker runs; the replay, as fast
    # as it goes, overloads it: batch by batch here, no widened steps)
    proc = skyfuse(
        "fusion", "--listen", ep, "--reorder-wait", "0.3", "--coalesce-max-deg", "off",
        log_path=tmp_path / "fusion.log",
    )  # fmt: skip
    offline = tmp_path / "offline.mcap"
    assert skyfuse_main(["track", str(rec), "--out", str(offline), "--no-progress"]) == 0
    off = [r.message for r in iter_recording(offline) if isinstance(r.message, TrackBatch)]
    n_batches = sum(isinstance(r.message, PlotBatch) for r in iter_recording(rec))
    live: list[TrackBatch] = []
    try:
        with open_session(peer(connect=ep)) as s:
            inbox = Inbox()
            inbox.subscribe(s, keys.fusion_tracks("main"), "tracks")
            assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
            # the frame is fixed when the first plot batch is applied, from the sites known
            # then; the fusion's reorder hold absorbs the race of sites and plots published
            # back to back (test_service_registration_live relies on it). Here every site is
            # known first, so this test is about the tracks, not the race
            wait_for_sites(s, sites)
            result = replay(s, rec, fast=True)
            assert result.plot_batches == n_batches
            deadline = time.monotonic() + 40
            applied = 0
            while applied < n_batches and time.monotonic() < deadline:
                item = inbox.get(0.2)
                if item is not None:
                    live.append(TrackBatch.from_json_bytes(item.payload))
                    applied += live[-1].batches
            inbox.close()
    finally:
        rc, took = stop(proc)
    assert rc == 0 and took < 5.0, (tmp_path / "fusion.log").read_text()[-3000:]
    pl, po = feed_pictures(live), dict(feed_pictures(off))
    assert len(po) == n_batches and pl[-1][0] == n_batches
    assert live[0].frame == off[0].frame == expected
    assert [(b.source_radar, b.source_seq) for b in off if b.kind is FeedKind.DELTA] == [
        (b.source_radar, b.source_seq) for b in off
    ]  # offline: one delta per batch
    assert [confirmed_ids(b) for _, b in pl] == [confirmed_ids(po[n]) for n, _ in pl]
    final_live, final_off = pl[-1][1], po[n_batches]
    assert len(confirmed_ids(final_off)) >= 2  # the comparison is not vacuous
    assert [t.track_id for t in final_live.tracks] == [t.track_id for t in final_off.tracks]
    for a, b in zip(final_live.tracks, final_off.tracks):
        np.testing.assert_allclose(a.state, b.state, rtol=0, atol=1e-6)
