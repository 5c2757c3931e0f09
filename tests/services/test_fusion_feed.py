"""The incremental track feed (``services.fusion.feed``, contract in ``schemas.tracks``)
on a simulated 3-radar scenario through the real pipeline:

* every delta/full message is a valid ``schemas.TrackBatch``;
* the rebuilt picture equals a brute-force reference built from the tracker outputs with
  plain dictionaries (per track, the row of the last cycle that changed it);
* a late subscriber (snapshot, or the next full message) rebuilds exactly the picture of
  a subscriber that listened from the start;
* the bulk path (several batches in one pass) gives the same picture as batch by batch.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import FeedKind, TrackBatch, TrackPicture
from skyfuse.services.fusion.pipeline import TrackPipeline


@pytest.fixture(scope="module")
def scenario():
    sc = build_scenario("regional", seed=4, duration=60.0, targets=12, radars=3)
    events = list(Simulator(sc, seed=4).run(truth=False))
    sites = {s.radar_id: s for s in sc.sites}
    batches = sorted((ev.message for ev in events if ev.kind == "plots"), key=lambda b: b.time_end)
    lat0 = float(np.mean([s.lat for s in sc.sites]))
    lon0 = float(np.mean([s.lon for s in sc.sites]))
    return sites, batches, SystemFrame("stereographic", lat0, lon0, 0.0)


def pipeline(frame, publish="confirmed"):
    return TrackPipeline(frame, TrackerConfig(), fusion_id="t", publish=publish)


def rows(picture: TrackPicture) -> dict[int, dict]:
    return {i: t.model_dump(mode="json") for i, t in picture.tracks.items()}


@pytest.mark.parametrize("publish", ["confirmed", "all"])
def test_deltas_rebuild_the_reference_picture(scenario, publish):
    sites, batches, frame = scenario
    pipe = pipeline(frame, publish)
    pic = TrackPicture()
    ref: dict[int, tuple] = {}  # id -> (last_update, confirmed, state) of its published row
    for b in batches:
        out = pipe.step(sites[b.radar_id], b)
        msg = pipe.track_batch(out, b)
        tb = TrackBatch.from_json_bytes(msg.to_json_bytes())  # strict validation
        assert tb.kind is FeedKind.DELTA and tb.batches == 1
        assert pic.apply(tb)
        shown = out.confirmed if publish == "confirmed" else np.ones(len(out), bool)
        now = {}
        for j in np.flatnonzero(shown):
            i, lu, cf = int(out.ids[j]), int(out.last_update_ns[j]), bool(out.confirmed[j])
            old = ref.get(i)
            if old is None or old[0] != lu or old[1] != cf:
                now[i] = (lu, cf, out.states[j].tolist())
            else:
                now[i] = old
        ref = now
    assert len(ref) >= 5  # not vacuous
    assert set(pic.tracks) == set(ref)
    for i, (_, cf, state) in ref.items():
        t = pic.tracks[i]
        assert t.status.value == ("confirmed" if cf else "tentative")
        np.testing.assert_allclose(t.state, state, rtol=0, atol=1e-9)
    # fewer rows on the wire than one full picture per cycle
    full = pipe.full()
    assert full is not None and len(full) == len(ref)


def test_late_subscriber_rebuilds_the_picture_of_an_early_one(scenario):
    sites, batches, frame = scenario
    pipe = pipeline(frame)
    early, by_snapshot, by_full = TrackPicture(), TrackPicture(), TrackPicture()
    join = len(batches) // 3
    waiting_full = False
    for k, b in enumerate(batches):
        msgs = [pipe.track_batch(pipe.step(sites[b.radar_id], b), b)]
        if k % 40 == 39:  # the service's periodic full picture
            msgs.append(pipe.full())
        if k == join:  # joins now: subscribes, then asks the snapshot
            snap = TrackBatch.from_json_bytes(pipe.snapshot().to_json_bytes())
            assert snap.kind is FeedKind.FULL
            by_snapshot.apply(snap)
            waiting_full = True
        for m in msgs:
            tb = TrackBatch.from_json_bytes(m.to_json_bytes())
            early.apply(tb)
            if k > join:
                by_snapshot.apply(tb)
            if waiting_full and (k > join) and (tb.kind is FeedKind.FULL or by_full.complete):
                by_full.apply(tb)
    assert early.complete and by_snapshot.complete and by_full.complete
    assert len(early.tracks) >= 5
    assert rows(by_snapshot) == rows(early)
    assert rows(by_full) == rows(early)


def test_lost_delta_marks_the_picture_incomplete_until_the_next_full(scenario):
    sites, batches, frame = scenario
    pipe = pipeline(frame)
    pic = TrackPicture()
    for k, b in enumerate(batches[:30]):
        m = pipe.track_batch(pipe.step(sites[b.radar_id], b), b)
        if k == 0:
            pic.apply(TrackBatch.from_json_bytes(pipe.snapshot().to_json_bytes()))
        elif k != 10:  # message 10 is lost
            pic.apply(TrackBatch.from_json_bytes(m.to_json_bytes()))
        assert pic.complete == (k <= 10)  # the gap shows with the next delta
    pic.apply(TrackBatch.from_json_bytes(pipe.full().to_json_bytes()))
    assert pic.complete
    assert not pic.apply(TrackBatch.from_json_bytes(m.to_json_bytes()))  # old delta: ignored


def test_bulk_path_gives_the_same_tracks_as_batch_by_batch(scenario):
    sites, batches, frame = scenario
    one, bulk = pipeline(frame), pipeline(frame)
    p_one, p_bulk = TrackPicture(), TrackPicture()
    rng = np.random.default_rng(7)
    k = 0
    groups = 0
    while k < len(batches):
        n = int(rng.integers(1, 12))
        group = batches[k : k + n]
        k += n
        for b in group:
            msg, _, failed = one.process_group([(sites[b.radar_id], b)])
            assert failed == []
            p_one.apply(TrackBatch.from_json_bytes(msg.to_json_bytes()))
        msg, _, failed = bulk.process_group([(sites[b.radar_id], b) for b in group])
        assert failed == [] and msg.header["batches"] == len(group)
        p_bulk.apply(TrackBatch.from_json_bytes(msg.to_json_bytes()))
        assert rows(p_bulk) == rows(p_one)  # after every group
        groups += 1
    assert groups < len(batches) and len(p_one.tracks) >= 5
    # the tracker itself saw the same batches: same totals, same full picture
    assert dict(one.tracker.totals) == dict(bulk.tracker.totals)
    a, b = (json.loads(p.full().to_json_bytes()) for p in (one, bulk))
    assert a["tracks"] == b["tracks"] and a["time"] == b["time"]
    assert (a["cycle"], b["cycle"]) == (len(batches), groups)  # one delta per group


def test_bulk_path_counts_a_bad_batch_and_applies_the_others(scenario):
    sites, batches, frame = scenario
    pipe = pipeline(frame)
    group = batches[:6]
    other = next(s for r, s in sites.items() if r != group[2].radar_id)
    items = [(sites[b.radar_id], b) for b in group]
    items[2] = (other, group[2])  # site of another radar: not convertible
    msg, _, failed = pipe.process_group(items)
    assert [b for b, _ in failed] == [group[2]]
    assert isinstance(failed[0][1], ValueError)
    assert msg.header["batches"] == 5


def test_bulk_conversion_splits_every_per_plot_field(scenario):
    """The plots of one radar's batches converted at once and split back are, field by
    field, the conversion of each batch alone (the per-plot arrays the registration and the
    near-radar counter read included)."""
    from skyfuse.fusion.registration import RegistrationConfig

    sites, batches, frame = scenario
    pipe = TrackPipeline(frame, TrackerConfig(), registration=RegistrationConfig(mode="frozen"))
    one_radar = [b for b in batches if b.radar_id == batches[0].radar_id][:6]
    items = [(sites[b.radar_id], b) for b in one_radar]
    for (site, b), got in zip(items, pipe._convert_all(items)):
        want = pipe._convert(site, b)
        assert len(got) == len(b)
        for name in ("z", "R", "time", "valid", "polar_jacobian", "slant_range", "near_radar"):
            a, e = getattr(got, name), getattr(want, name)
            assert (a is None) == (e is None), name
            if a is not None:
                np.testing.assert_array_equal(a, e, err_msg=name)
        assert got.reasons == want.reasons
