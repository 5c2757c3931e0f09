"""Status of a fusion service that falls behind and recovers (FusionCore, no network):
the backlog (batches and plots waiting, oldest wait), the "behind" flag, the point where
reading stops (back-pressure), plot rates in and out, and the bulk path when several
batches are ready at once."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import FeedKind, Status, TrackBatch, TrackPicture
from skyfuse.services.fusion.server import make_pipeline_factory
from skyfuse.services.fusion.service import FusionConfig, FusionCore


def scenario_batches():
    sc = build_scenario("regional", seed=6, duration=24.0, targets=6, radars=3)
    ev = Simulator(sc, seed=6).run(truth=False)
    batches = sorted((e.message for e in ev if e.kind == "plots"), key=lambda b: b.time_end)
    return sc.sites, batches


def test_backlog_behind_flag_and_recovery():
    sites, batches = scenario_batches()
    lat0 = float(np.mean([s.lat for s in sites]))
    lon0 = float(np.mean([s.lon for s in sites]))
    cfg = FusionConfig(reorder_wait=0.5, behind_after=1.0, max_backlog=2.0, frame_lat0=lat0,
                       frame_lon0=lon0, full_interval=1e-6, delta_split_s="off")  # fmt: skip
    core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), cfg.fusion_id))
    for s in sites:
        core.on_site(s)
    t0 = 1000.0
    for i, b in enumerate(batches):  # all arrive within 0.1 s and nothing is applied
        assert core.on_plots(b, arrival=t0 + 0.1 * i / len(batches))
    n_plots = sum(len(b) for b in batches)
    bl = core.backlog(now=t0 + 1.0)
    assert (bl.batches, bl.plots) == (len(batches), n_plots)
    assert abs(bl.oldest_wait_s - 1.0) < 1e-9 and not bl.behind  # 1.0 < 0.5 + 1.0
    bl = core.backlog(now=t0 + 1.6)
    assert bl.behind and not core.over_backlog(now=t0 + 1.6)
    assert core.over_backlog(now=t0 + 2.6)  # 2.6 > 0.5 + 2.0: stop reading
    assert bl.plots_per_s_in > 0 and bl.plots_per_s_out == 0
    # catching up: several batches ready at once go in groups of at most bulk_max
    outs = core.poll(now=t0 + 3.0)
    applied = sum(len(o.time_ends) for o in outs)
    assert applied == len(batches) and len(outs) == -(-len(batches) // cfg.bulk_max)
    bl = core.backlog(now=t0 + 3.0)
    assert (bl.batches, bl.plots, bl.oldest_wait_s, bl.behind) == (0, 0, 0.0, False)
    assert bl.plots_per_s_out > 0 and not core.over_backlog(now=t0 + 3.0)
    st = Status.from_json_bytes(core.status().to_json_bytes())
    assert st.backlog.batches == 0 and st.counters["plots_applied"] == n_plots
    assert st.counters["groups"] == len(outs) and st.tracks_confirmed >= 3
    # each group: one valid delta; a full picture is due after it (full_interval ~ 0)
    for o in outs:
        d = TrackBatch.from_json_bytes(o.tracks.to_json_bytes())
        assert d.kind is FeedKind.DELTA and d.batches == len(o.time_ends)
        assert TrackBatch.from_json_bytes(o.full.to_json_bytes()).kind is FeedKind.FULL
    snap = TrackBatch.from_json_bytes(core.snapshot_payload())
    assert snap.cycle == len(outs) and len(snap.tracks) == st.tracks_total


def test_coalescing_when_behind_applies_every_plot_in_fewer_steps():
    """With ``coalesce_max_deg`` the contiguous sectors of one radar that are ready
    together are one tracker step: every plot applied, the deltas count the batches they
    apply, Status counts the coalesced steps; without it nothing is coalesced."""
    sites, batches = scenario_batches()
    lat0 = float(np.mean([s.lat for s in sites]))
    lon0 = float(np.mean([s.lon for s in sites]))
    n_plots = sum(len(b) for b in batches)
    counts = {}
    for deg in (None, 90.0):
        cfg = FusionConfig(reorder_wait=0.5, frame_lat0=lat0, frame_lon0=lon0,
                           coalesce_max_deg=deg, bulk_max=1000, delta_split_s="off")  # fmt: skip
        core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), cfg.fusion_id))
        for s in sites:
            core.on_site(s)
        for i, b in enumerate(batches):
            assert core.on_plots(b, arrival=1000.0 + 0.1 * i / len(batches))
        outs = core.poll(now=1003.0)
        assert len(outs) == 1 and len(outs[0].time_ends) == len(batches)
        d = TrackBatch.from_json_bytes(outs[0].tracks.to_json_bytes())
        assert d.batches == len(batches)
        st = Status.from_json_bytes(core.status().to_json_bytes())
        assert st.counters["plots_applied"] == n_plots and st.tracks_confirmed >= 3
        counts[deg] = (st.counters["coalesced_steps"], st.counters["batches_coalesced"])
    assert counts[None] == (0, 0)
    steps, members = counts[90.0]
    # 16 sectors per revolution: runs of up to 4 (90°), most batches in one
    assert steps >= len(batches) // 8 and members >= len(batches) // 2
    assert members <= 4 * steps


def _run_group(split, coalesce_deg=None):
    """All batches of the scenario applied as one ready group; the outputs and core."""
    sites, batches = scenario_batches()
    lat0 = float(np.mean([s.lat for s in sites]))
    lon0 = float(np.mean([s.lon for s in sites]))
    cfg = FusionConfig(reorder_wait=0.5, frame_lat0=lat0, frame_lon0=lon0, bulk_max=1000,
                       delta_split_s=split, coalesce_max_deg=coalesce_deg)  # fmt: skip
    core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), cfg.fusion_id))
    for s in sites:
        core.on_site(s)
    for i, b in enumerate(batches):
        assert core.on_plots(b, arrival=1000.0 + 0.1 * i / len(batches))
    return core.poll(now=1003.0), core, batches


@pytest.mark.parametrize("coalesce_deg", [None, 90.0])
def test_a_long_group_is_published_in_parts_with_the_same_picture(coalesce_deg):
    """``delta_split_s``: a group whose steps take longer is published in parts, each
    delta the batches applied so far (here a split after every step: a bound of 1 ns is
    always exceeded); a client applying the deltas rebuilds the same picture as from the
    group's one delta, every batch counted once, and the tracks are the same."""
    whole, core1, batches = _run_group("off", coalesce_deg)
    parts, core, _ = _run_group(1e-9, coalesce_deg)
    assert len(whole) == 1 and len(parts) > 1
    c = core.status().counters
    assert len(parts) == len(batches) - c["batches_coalesced"] + c["coalesced_steps"]  # steps
    assert (c["coalesced_steps"] > 0) == (coalesce_deg is not None)
    assert c["groups"] == 1 and c["group_parts"] == len(parts) - 1
    assert sorted(t for o in parts for t in o.time_ends) == sorted(b.time_end for b in batches)
    pictures = []
    for outs in (whole, parts):
        pic = TrackPicture()
        for o in outs:
            d = TrackBatch.from_json_bytes(o.tracks.to_json_bytes())
            assert d.kind is FeedKind.DELTA and d.batches == len(o.time_ends)
            assert pic.apply(d)
        assert pic.complete
        pictures.append({i: t.model_dump() for i, t in pic.tracks.items()})
    assert pictures[0] == pictures[1] and len(pictures[0]) >= 3
    snap = TrackBatch.from_json_bytes(core.snapshot_payload())
    assert {t.track_id: t.model_dump() for t in snap.tracks} == pictures[1]
    assert core.status().counters["plots_applied"] == core1.status().counters["plots_applied"]
