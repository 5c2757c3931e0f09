"""A live ``skyfuse fusion`` process with online sensor registration: fed a
replay of a recording with two biased radars, it publishes ``RegistrationStatus`` on
``skyfuse/@v1/fusion/{id}/registration`` and the same estimates in ``Status``, with the
``plots_near_radar`` counter; its final estimates equal those of the offline
``skyfuse track`` of the same recording (registration is a deterministic function of
the batches in time order) and lie near the simulated biases."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from service_support import BIASED_REGIONAL, BIASED_TRUTH, peer, skyfuse, stop
from skyfuse.schemas import (
    FeedKind,
    FrameSpec,
    PlotBatch,
    RegistrationStatus,
    Status,
    TrackBatch,
    keys,
)
from skyfuse.services.cli.main import main as skyfuse_main
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.runtime.transport import (
    Inbox,
    free_port,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)
from skyfuse.services.sensors.replay import replay

pytestmark = pytest.mark.service

FIELDS = ("azimuth", "azimuth_sigma", "range", "range_sigma", "time", "time_sigma")


def _live(rec: Path, tmp_path: Path, n_batches: int) -> tuple[list, list, int, FrameSpec]:
    """(registration messages, statuses, plot batches applied, system frame) of a live run
    over ``rec``."""
    ep = loopback_endpoint(free_port())
    proc = skyfuse(
        # a reorder wait well above the inbox delays of a loaded CI machine: the replay is
        # as fast as it goes, and a batch applied out of order (OOSM) would differ from
        # the offline run, which the equality below assumes in time order; a replay as
        # fast as it goes overloads the service: batch by batch (no widened steps) here
        "fusion", "--listen", ep, "--reorder-wait", "3.0", "--status-interval", "0.5",
        "--registration-reference", "LYBE", "--coalesce-max-deg", "off",
        log_path=tmp_path / "fusion.log",
    )  # fmt: skip
    got: list = []
    try:
        with open_session(peer(connect=ep)) as s:
            inbox = Inbox()
            for key, tag in ((keys.fusion_registration("main"), "reg"),
                             (keys.fusion_status("main"), "status"),
                             (keys.fusion_tracks("main"), "tracks")):  # fmt: skip
                inbox.subscribe(s, key, tag)
            assert wait_for_tokens(s, [service_alive_key("fusion")], 20.0) == []
            assert replay(s, rec, fast=True).plot_batches == n_batches
            deadline = time.monotonic() + 120
            while _applied(got) < n_batches and time.monotonic() < deadline:
                got.extend(inbox.drain())
                time.sleep(0.05)
            rc, _ = stop(proc)  # the final Status and registration are published
            time.sleep(0.5)
            got.extend(inbox.drain())
            inbox.close()
    finally:
        stop(proc)
    assert rc == 0, (tmp_path / "fusion.log").read_text()[-3000:]
    frames = [TrackBatch.from_json_bytes(g.payload).frame for g in got if g.tag == "tracks"]
    assert frames and all(f == frames[0] for f in frames), frames[:1]
    regs = [RegistrationStatus.from_json_bytes(g.payload) for g in got if g.tag == "reg"]
    statuses = [Status.from_json_bytes(g.payload) for g in got if g.tag == "status"]
    return regs, statuses, _applied(got), frames[0]


def _applied(got: list) -> int:
    """Plot batches the received track feed has applied (a delta may carry several)."""
    feed = [TrackBatch.from_json_bytes(g.payload) for g in got if g.tag == "tracks"]
    return sum(b.batches for b in feed if b.kind is FeedKind.DELTA)


def test_live_fusion_publishes_registration_equal_to_offline(tmp_path, simulated_recording):
    rec = simulated_recording(*BIASED_REGIONAL)
    n_batches = sum(isinstance(r.message, PlotBatch) for r in iter_recording(rec))
    regs, statuses, n_tracks, frame = _live(rec, tmp_path, n_batches)
    assert n_tracks == n_batches
    assert regs and statuses
    final = regs[-1]
    assert final.fusion_id == "main" and final.mode == "on"
    last_status = statuses[-1]
    assert last_status.registration == final  # the same estimates in Status
    assert "plots_near_radar" in last_status.counters
    assert last_status.counters["plots_near_radar"] == 0
    live = {r.radar_id: r for r in final.radars}
    assert live["LYBE"].reference and live["LYBE"].azimuth == 0.0
    for rid, (az, rng) in BIASED_TRUTH.items():
        r = live[rid]
        assert r.pairs_used > 50
        assert abs(r.azimuth - math.radians(az)) <= 3.5 * r.azimuth_sigma
        assert abs(r.range - rng) <= 3.5 * r.range_sigma
    # the estimates grow more certain as pairs come in
    early = next(m for m in regs if any(r.radar_id == "LYVR" for r in m.radars))
    sig0 = next(r.azimuth_sigma for r in early.radars if r.radar_id == "LYVR")
    assert live["LYVR"].azimuth_sigma <= sig0
    out = tmp_path / "offline.json"
    args = ["track", str(rec), "--out", str(tmp_path / "o.mcap"), "--json", str(out)]
    assert skyfuse_main([*args, "--no-progress", "--registration-reference", "LYBE"]) == 0
    summary = json.loads(out.read_text())
    # the sites replayed first are all in the live frame, though Zenoh may deliver some of
    # them after the first plots (the reorder hold absorbs it: services.fusion.system_frame)
    assert frame == FrameSpec.model_validate(summary["frame"])
    offline = {r["radar_id"]: r for r in summary["registration"]["radars"]}
    assert set(offline) == set(live)
    for rid, r in live.items():
        want = [offline[rid][f] for f in FIELDS]
        np.testing.assert_allclose([getattr(r, f) for f in FIELDS], want, rtol=1e-9, atol=0)
        # on a mismatch, say whether the live run applied a batch out of time order
        order = {k: v for k, v in last_status.counters.items() if "late" in k or "oosm" in k}
        assert r.pairs_used == offline[rid]["pairs_used"], (rid, order, last_status.late)
