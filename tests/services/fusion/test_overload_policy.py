"""The fusion service's overload policy (services.fusion.overload), driven through
``FusionCore`` with a simulated arrival clock and a fixed step-cost model (no timing in
the assertions): while it keeps up nothing changes — the published tracks are those of
per-batch processing, bit for bit, and Status says inactive; a backlog widens the steps
just enough for the group budget, Status says how much, and once the backlog is gone the
steps are single batches again and Status says inactive after its window."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import Status, TrackBatch, TrackPicture
from skyfuse.services.cli.cmd_fusion import make_pipeline_factory
from skyfuse.services.fusion import coalesce
from skyfuse.services.fusion.overload import OverloadPolicy, StepCost
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.service import FusionConfig, FusionCore

WAIT = 0.2


@pytest.fixture(scope="module")
def scenario():
    sc = build_scenario("regional", seed=4, duration=60.0, targets=40, radars=3)
    ev = Simulator(sc, seed=4).run(truth=False)
    batches = sorted((e.message for e in ev if e.kind == "plots"), key=lambda b: b.time_end)
    return {s.radar_id: s for s in sc.sites}, batches


def make_core(sites, cost: StepCost, **kw) -> FusionCore:
    lat0 = float(np.mean([s.lat for s in sites.values()]))
    lon0 = float(np.mean([s.lon for s in sites.values()]))
    cfg = FusionConfig(reorder_wait=WAIT, frame_lat0=lat0, frame_lon0=lon0,
                       delta_split_s="off", **kw)  # fmt: skip
    core = FusionCore(cfg, make_pipeline_factory(TrackerConfig(), cfg.fusion_id))
    core.overload.cost = cost
    for s in sites.values():
        core.on_site(s)
    return core


def arrivals(batches) -> list[float]:
    """Each batch arrives when its sweep ends (s from the first batch's end)."""
    t0 = batches[0].time_end
    return [(b.time_end - t0) / 1e9 for b in batches]


def rows(picture: TrackPicture) -> dict[int, tuple]:
    return {t.track_id: (t.status, t.time, tuple(t.state)) for t in picture.batch().tracks}


def test_keeping_up_publishes_the_tracks_of_per_batch_processing(scenario):
    sites, batches = scenario
    core = make_core(sites, StepCost(3e-3, 2e-5, learn=False))
    ref = TrackPipeline(core.cfg.frame_spec(list(sites.values())), TrackerConfig())
    pic, ref_pic, applied = TrackPicture(), TrackPicture(), 0
    for b, t in zip(batches, arrivals(batches)):
        assert core.on_plots(b, arrival=t)
        for out in core.poll(now=t):
            assert pic.apply(TrackBatch.from_json_bytes(out.tracks.to_json_bytes()))
            for end in out.time_ends:  # the same batches, one tracker step each
                nxt = batches[applied]
                assert nxt.time_end == end
                msg, _ = ref.process(sites[nxt.radar_id], nxt)
                ref_pic.apply(TrackBatch.from_json_bytes(msg.to_json_bytes()))
                applied += 1
            assert rows(pic) == rows(ref_pic)  # bit for bit, after every publication
    assert applied > 0.9 * len(batches) and len(rows(pic)) >= 20
    st = Status.from_json_bytes(core.status(now=arrivals(batches)[-1]).to_json_bytes())
    assert st.overload.enabled and not st.overload.active
    assert st.overload.batches_per_step == 1.0 and st.overload.groups_widened == 0
    assert st.counters["coalesced_steps"] == 0


def test_a_backlog_widens_the_steps_just_enough_and_they_narrow_after(scenario):
    sites, batches = scenario
    # 10 ms per step, nothing per plot: a group must be at most 10 steps (budget 0.1 s)
    core = make_core(sites, StepCost(0.01, 0.0, learn=False), group_budget_s=0.1)
    times = arrivals(batches)
    half = int(np.searchsorted(times, 6.0))  # 6 s of input delivered at once (a burst)
    for b in batches[:half]:
        assert core.on_plots(b, arrival=times[half] - WAIT)  # due, none overdue yet
    ready = [b for b in batches[:half]]
    k = core.overload.members(ready, [True] * half, [sites[b.radar_id] for b in ready])
    runs = coalesce.plan(ready, [True] * half, 2 * math.pi)
    steps = lambda m: sum(-(-len(r) // m) for r in runs)  # noqa: E731
    assert 1 < k and steps(k) <= 10 < steps(k - 1)  # the least widening that fits
    stall = times[half]
    outs = core.poll(now=stall)
    assert sum(len(o.time_ends) for o in outs) == half
    st = core.status(now=stall)
    assert st.overload.active and st.overload.groups_widened == 1
    assert st.overload.batches_per_step == pytest.approx(half / steps(k))
    assert st.overload.widest_deg > 360 / 16 and st.counters["batches_coalesced"] > 0
    widened = st.counters["coalesced_steps"]
    # caught up: the rest arrives in time, one batch per step again
    for b, t in zip(batches[half:], times[half:]):
        core.on_plots(b, arrival=t)
        core.poll(now=t)
    late = core.status(now=times[-1])
    assert late.counters["coalesced_steps"] == widened
    assert late.overload.groups_widened == 1
    assert not late.overload.active and late.overload.batches_per_step == 1.0
    core.poll(flush=True)  # the last batches' hold: every plot applied, none lost
    assert core.counters["plots_applied"] == sum(len(b) for b in batches)


def test_coalesce_max_deg_off_never_widens(scenario):
    sites, batches = scenario
    core = make_core(sites, StepCost(1.0, 0.0, learn=False), coalesce_max_deg="off")
    for b in batches[:200]:
        core.on_plots(b, arrival=0.0)
    core.poll(now=1.0)
    st = Status.from_json_bytes(core.status(now=1.0).to_json_bytes())
    assert not st.overload.enabled and st.overload.max_deg is None
    assert st.counters["coalesced_steps"] == 0 and st.counters["cycles"] == 200


def test_the_step_cost_model_is_the_least_squares_line():
    rng = np.random.default_rng(3)
    m = rng.integers(0, 400, 600)
    y = 4e-3 + 25e-6 * m + rng.normal(0, 2e-4, len(m))
    cost = StepCost(1e-3, 1e-5)
    for mi, yi in zip(m, y):
        cost.add_step(int(mi), float(yi))
    w = 0.995 ** np.arange(len(m))[::-1]  # the forgetting: weighted least squares
    X = np.column_stack([np.ones(len(m)), m]) * np.sqrt(w)[:, None]
    a, b = np.linalg.lstsq(X, y * np.sqrt(w), rcond=None)[0]
    assert cost.a == pytest.approx(a, rel=0.02) and cost.b == pytest.approx(b, rel=0.02)
    assert cost.a == pytest.approx(4e-3, rel=0.1) and cost.b == pytest.approx(25e-6, rel=0.05)


def test_the_policy_widens_only_past_the_budget():
    """Batch by batch while its predicted time fits the budget; 1 for a lone batch or
    when off."""
    from service_support import make_batch

    rng = np.random.default_rng(1)
    seq = [make_batch("A", 0, s, 16, 5, rng) for s in range(16)]
    ok = [True] * 16
    fits = OverloadPolicy(2 * math.pi, 0.1, cost=StepCost(0.006, 0.0, learn=False))
    assert fits.members(seq, ok) == 1  # 16 × 6 ms = 96 ms
    over = OverloadPolicy(2 * math.pi, 0.1, cost=StepCost(0.007, 0.0, learn=False))
    assert over.members(seq, ok) == 2  # 16 × 7 ms = 112 ms; 8 steps of 2 = 56 ms
    assert over.members(seq[:1], ok[:1]) == 1
    # overdue by two budgets: half the time (T²/lag), so wider steps: 6 steps of 3 = 42 ms
    assert over.budget(0.05) == 0.1 and over.budget(0.2) == pytest.approx(0.05)
    assert over.budget(10.0) == pytest.approx(0.025)  # at least a quarter
    assert over.members(seq, ok, lag=0.2) == 3
    off = OverloadPolicy(None, 0.1, cost=StepCost(1.0, 0.0, learn=False))
    assert off.members(seq, ok) == 1
    quarter = OverloadPolicy(math.pi / 2, 0.001, cost=StepCost(1.0, 0.0, learn=False))
    assert quarter.members(seq, ok) == 4  # nothing fits: the widest the bound allows
