"""Coalescing of contiguous sector batches (services.fusion.coalesce): which batches form
a run, and a run applied as one step ≡ the same radar reporting wider sectors (the
simulator's own batches of 4 sectors per revolution against 16 coalesced by fours)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from service_support import make_batch
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.services.fusion import coalesce
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.system_frame import frame_for_sites

QUARTER = math.pi / 2


def batches_of(n_sectors: int, seed: int = 2, duration: float = 40.0):
    sc = build_scenario(
        "regional", seed=seed, duration=duration, targets=60, radars=3, n_sectors=n_sectors
    )
    sites, batches = {}, []
    for ev in Simulator(sc, seed=seed).run(truth=False):
        if ev.kind == "site":
            sites[ev.message.radar_id] = ev.message
        elif ev.kind == "plots":
            batches.append(ev.message)
    batches.sort(key=lambda b: b.time_end)  # the reorder buffer's order (stable)
    return sites, batches


def test_a_run_is_contiguous_sectors_of_one_radar_within_the_width():
    rng = np.random.default_rng(1)
    a = [make_batch("A", 0, s, 16, 3, rng) for s in range(6)]
    b = [make_batch("B", 0, s, 16, 3, rng) for s in range(2)]
    seq = [a[0], b[0], a[1], a[2], b[1], a[3], a[4], a[5]]
    runs = coalesce.plan(seq, [True] * len(seq), QUARTER)
    # A's first four sectors (90°) at the place of the fourth, B's two, then A's rest
    assert runs == [[1, 4], [0, 2, 3, 5], [6, 7]]
    # a late batch stays alone and breaks nothing else
    runs = coalesce.plan(seq, [True, True, False, True, True, True, True, True], QUARTER)
    assert [0] in runs and [2] in runs and [3, 5, 6, 7] in runs
    # a missing sector, a different epoch, other columns, another site: no run
    gap = [a[0], a[2]]
    assert coalesce.plan(gap, [True, True], QUARTER) == [[0], [1]]
    other_epoch = a[1].model_copy(update={"epoch": 1})
    assert coalesce.plan([a[0], other_epoch], [True, True], QUARTER) == [[0], [1]]
    no_alt = a[1].model_copy(update={"altitude": None})
    assert coalesce.plan([a[0], no_alt], [True, True], QUARTER) == [[0], [1]]
    # sweep times widened to a plot a little before the boundary still continue the run;
    # a batch from a later revolution of the next sector does not
    early = a[1].model_copy(update={"time_start": a[1].time_start - 10_000_000})
    assert coalesce.plan([a[0], early], [True, True], QUARTER) == [[0, 1]]
    later = make_batch("A", 1, 1, 16, 3, rng)
    assert coalesce.plan([a[0], later], [True, True], QUARTER) == [[0], [1]]
    s1, s2 = object(), object()
    assert coalesce.plan(a[:2], [True, True], QUARTER, [s1, s2]) == [[0], [1]]
    assert coalesce.plan(a[:2], [True, True], QUARTER, [s1, s1]) == [[0, 1]]


def test_a_run_never_covers_a_revolution_twice():
    rng = np.random.default_rng(2)
    rev = [make_batch("A", k // 4, k % 4, 4, 2, rng) for k in range(8)]
    runs = coalesce.plan(rev, [True] * 8, 2 * math.pi)
    assert runs == [[0, 1, 2, 3], [4, 5, 6, 7]]
    merged = coalesce.coalesced([rev[i] for i in runs[0]])
    assert merged.sector_start == 0.0 and merged.sector_width == pytest.approx(2 * math.pi)
    assert (merged.time_start, merged.time_end) == (rev[0].time_start, rev[3].time_end)
    assert merged.seq == rev[3].seq and len(merged) == 8
    assert merged.time == [t for b in rev[:4] for t in b.time]


def test_sixteen_sectors_coalesced_by_fours_track_as_four_sectors():
    sites, fine = batches_of(16)
    sites4, coarse = batches_of(4)
    frame = frame_for_sites(sites.values())
    cfg = TrackerConfig(motion="imm-cv-ct")
    ref = TrackPipeline(frame, cfg)
    for b in coarse:
        ref.process(sites4[b.radar_id], b)
    got = TrackPipeline(frame, cfg)
    items = [(sites[b.radar_id], b) for b in fine]
    msg, _, failed = got.process_group(items, coalesce_max=QUARTER)  # one group: all runs whole
    assert failed == [] and msg is not None
    assert got.coalesced["steps"] > 0.8 * len(coarse)
    assert got.coalesced["batches"] > 0.8 * len(fine)
    a, b = ref.tracker, got.tracker
    assert a.n == b.n and a.tracks.confirmed.sum() > 20
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.tracks.confirmed, b.tracks.confirmed)
    np.testing.assert_array_equal(a.tracks.t_last, b.tracks.t_last)
    np.testing.assert_array_equal(a.tracks.exist, b.tracks.exist)
    for u, v in zip(a.density.estimates_view(), b.density.estimates_view()):  # states, covariances
        np.testing.assert_array_equal(u, v)  # the same plots in the same steps: bitwise


@pytest.mark.parametrize("error", [ValueError, RuntimeError])
def test_a_refused_coalesced_step_is_applied_batch_by_batch(error):
    """A coalesced step refused as input (ValueError) is retried batch by batch; any
    other error may have left the tracker half-updated, so its batches all fail."""
    sites, fine = batches_of(16, duration=8.0)
    frame = frame_for_sites(sites.values())
    pipe = TrackPipeline(frame, TrackerConfig())
    real = pipe._track

    def track(converted, site, batch):
        if not any(batch is b for b in fine):  # a coalesced batch
            raise error("refused")
        return real(converted, site, batch)

    pipe._track = track
    items = [(sites[b.radar_id], b) for b in fine[:24]]
    msg, _, failed = pipe.process_group(items, coalesce_max=QUARTER)
    assert pipe.coalesced["steps"] > 0
    coalesced = pipe.coalesced["batches"]
    if error is ValueError:
        assert failed == [] and pipe.coalesced["retried"] == pipe.coalesced["steps"]
        assert msg.header["batches"] == len(items)
    else:
        assert len(failed) == coalesced and pipe.coalesced["retried"] == 0
        assert all(isinstance(e, RuntimeError) for _, e in failed)
        left = len(items) - coalesced  # the batches that were steps of their own
        assert (msg is None) if left == 0 else (msg.header["batches"] == left)
