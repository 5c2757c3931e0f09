"""The tracks' identity out through the pipeline and the feed (services/fusion/feed.py,
feed_identity.py): on a simulated 3-radar scenario whose aircraft change codes (some to
7700) and garble replies, the published rows carry what the tracker attributed, every
message and event validates against the schemas, a track whose identity moved is in
the delta, snapshots keep it, coalesced batches keep the plots' identity, and tracks
without identity publish no identity field."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.fusion.tracker.identity import (
    CALLSIGN,
    MODE_3A,
    MODE_S,
    plot_identity,
    unpack_callsigns,
)
from skyfuse.schemas import Track, TrackBatch, TrackEvent, TrackPicture
from skyfuse.schemas.identity import EMERGENCY_CODES
from skyfuse.schemas.plots import IDENTITY_COLUMNS
from skyfuse.services.fusion import coalesce
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.state_codec import dumps, loads

KINEMATIC = frozenset(("track_id", "time", "status", "existence", "state", "covariance",
                       "lat", "lon", "alt", "vel_east", "vel_north", "vel_up", "speed",
                       "heading", "radars", "updates"))  # fmt: skip
IDENTITY_FIELDS = frozenset(Track.model_fields) - KINEMATIC


@pytest.fixture(scope="module")
def scenario():
    sc = build_scenario("regional", seed=4, duration=120.0, targets=14, radars=3,
                        code_change_fraction=0.6, emergency_fraction=0.5,
                        garble_probability=0.05)  # fmt: skip
    events = list(Simulator(sc, seed=4).run(truth=False))
    sites = {s.radar_id: s for s in sc.sites}
    batches = sorted((ev.message for ev in events if ev.kind == "plots"), key=lambda b: b.time_end)
    lat0 = float(np.mean([s.lat for s in sc.sites]))
    lon0 = float(np.mean([s.lon for s in sc.sites]))
    return sites, batches, SystemFrame("stereographic", lat0, lon0, 0.0)


def run(scenario, cfg=None, strip=False):
    """The pipeline over the scenario: (pipeline, picture, events, last output)."""
    sites, batches, frame = scenario
    pipe = TrackPipeline(frame, cfg or TrackerConfig(), fusion_id="t")
    pic, events, out = TrackPicture(), [], None
    for b in batches:
        if strip:
            b = b.model_copy(update={k: None for k in IDENTITY_COLUMNS})
        out = pipe.step(sites[b.radar_id], b)
        msg = pipe.track_batch(out, b)
        assert pic.apply(TrackBatch.from_json_bytes(msg.to_json_bytes()))  # strict
        events += [TrackEvent.from_json_bytes(e.to_json_bytes()) for e in pipe.track_events(out)]
    return pipe, pic, events, out


@pytest.fixture(scope="module")
def identified(scenario):
    return run(scenario)


def test_published_rows_show_the_tracker_identity(identified):
    pipe, pic, _, out = identified
    full = pipe.full().model()
    rows = {int(i): j for j, i in enumerate(out.ids)}
    assert len(full.tracks) >= 8
    with_callsign = 0
    for t in full.tracks:
        j = rows[t.track_id]
        code, addr, cs = out.identity.codes[j]
        assert t.mode_3a == (code if code >= 0 else None)
        assert t.mode_s == (addr if addr >= 0 else None)
        assert t.callsign == (unpack_callsigns(np.array([cs]))[0] if cs >= 0 else None)
        assert t.emergency == (EMERGENCY_CODES.get(int(code)) if code >= 0 else None)
        for name, k in (("mode_3a", MODE_3A), ("mode_s", MODE_S), ("callsign", CALLSIGN)):
            when = getattr(t, f"{name}_time")
            assert when == (out.identity.code_time[j, k] if getattr(t, name) else None)
            assert when is None or when <= t.time
        with_callsign += t.callsign is not None
    assert with_callsign >= len(full.tracks) // 2
    shown = IDENTITY_FIELDS - {"mode_3a_changed"}  # (CH depends on the time of the row)
    for t in full.tracks:  # the picture the deltas rebuilt shows the same identities
        row = pic.tracks[t.track_id]
        assert {k: getattr(row, k) for k in shown} == {k: getattr(t, k) for k in shown}


def test_code_changes_and_emergencies_are_published_events(identified):
    _, pic, events, _ = identified
    kinds = [e.kind.value for e in events]
    assert "identity_changed" in kinds and "emergency" in kinds
    for e in events:
        if e.kind.value == "emergency":
            assert e.attribute == "mode_3a" and e.value == "7700"
    assert any(t.emergency == "general" for t in pic.tracks.values())


def test_tracks_without_identity_publish_no_identity_field(scenario):
    for _, pic, events, _ in (run(scenario, TrackerConfig(identity=False)),
                              run(scenario, strip=True)):  # fmt: skip
        assert len(pic.tracks) >= 8
        for t in pic.tracks.values():
            assert IDENTITY_FIELDS.isdisjoint(t.model_fields_set)
        assert all(e.kind.value in ("confirmed", "terminated", "merged") for e in events)


def test_a_track_whose_identity_moved_is_in_the_delta(scenario):
    sites, batches, frame = scenario
    pipe = TrackPipeline(frame, TrackerConfig(), fusion_id="t")
    for b in batches[:60]:
        out = pipe.step(sites[b.radar_id], b)
        pipe.track_batch(out, b)
    tr = pipe.tracker
    j = int(np.flatnonzero(tr.tracks.confirmed)[0])
    t_late = int(tr.tracks.last_update[j]) - 1  # a late plot: last_update does not move
    level = plot_identity({"flight_level": np.array([123.0])}.get)
    tr.tracks.flight_level_time[j] = -1
    tr.identity.observe(level, np.array([j]), np.array([0]), np.array([t_late]))
    pipe.feed.record(tr.output())
    delta = pipe.feed.delta(None, None).model()
    assert [t.track_id for t in delta.tracks] == [int(tr.ids[j])]
    assert delta.tracks[0].flight_level == 123.0


def test_a_pipeline_snapshot_keeps_the_published_identity(scenario, identified):
    sites, batches, frame = scenario
    pipe = TrackPipeline(frame, TrackerConfig(), fusion_id="t")
    for b in batches[:200]:
        pipe.track_batch(pipe.step(sites[b.radar_id], b), b)
    copy = TrackPipeline(frame, TrackerConfig(), fusion_id="t")
    copy.from_snapshot(loads(dumps(pipe.to_snapshot())))
    assert copy.snapshot().to_json_bytes() == pipe.snapshot().to_json_bytes()
    for b in batches[200:260]:
        x = pipe.track_batch(pipe.step(sites[b.radar_id], b), b)
        y = copy.track_batch(copy.step(sites[b.radar_id], b), b)
        assert x.to_json_bytes() == y.to_json_bytes()


def test_coalesced_batches_keep_the_plots_identity(scenario):
    _, batches, _ = scenario
    radar = batches[0].radar_id
    run_ = [b for b in batches if b.radar_id == radar][:4]
    merged = coalesce.coalesced(run_)
    assert len(merged.time) == sum(len(b.time) for b in run_)
    got = plot_identity(merged.column)
    parts = [plot_identity(b.column) for b in run_]
    assert np.array_equal(got.codes, np.concatenate([p.codes for p in parts]))
    assert np.array_equal(got.shown, np.concatenate([p.shown for p in parts]))
    assert np.array_equal(got.flight_level, np.concatenate([p.flight_level for p in parts]),
                          equal_nan=True)  # fmt: skip
    assert (got.codes[:, MODE_S] >= 0).any()
