"""FusionCore without the network: reorder buffer ordering and bounded wait, late and
duplicate batches, sites (message, config, unknown), malformed input counted by reason."""

from __future__ import annotations

import numpy as np
import pytest
from service_support import make_batch, make_site
from skyfuse.schemas import FrameKind, FrameSpec, TrackBatch, keys
from skyfuse.services.fusion.pipeline import GroupPart
from skyfuse.services.fusion.service import FusionConfig, FusionCore, ReorderBuffer


class RecordingPipeline:
    """Test double of the track pipeline: remembers the order batches arrive in and
    returns an empty delta TrackBatch per group."""

    def __init__(self, frame: FrameSpec) -> None:
        self.frame = frame
        self.seen: list[tuple[str, int]] = []
        self.rejected: dict[str, int] = {}

    def process_parts(self, items, part_s=None, **kw):
        self.seen += [(batch.radar_id, batch.time_end) for _, batch in items]
        last = items[-1][1]
        tb = TrackBatch(
            fusion_id="t", kind="delta", cycle=len(self.seen), time=last.time_end,
            frame=self.frame, state_labels=["x", "vx", "y", "vy"], source_radar=last.radar_id,
            source_seq=last.seq, batches=len(items),
        )  # fmt: skip
        yield GroupPart(tb, [], [b for _, b in items], [])

    def full(self):
        return None

    def snapshot(self):
        return None

    def picture(self):
        return []


def core(**kw) -> tuple[FusionCore, list[RecordingPipeline]]:
    made: list[RecordingPipeline] = []

    def factory(frame):
        made.append(RecordingPipeline(frame))
        return made[-1]

    return FusionCore(FusionConfig(**kw), factory), made


def test_reorder_buffer_orders_by_time_and_holds_for_the_wait():
    rng = np.random.default_rng(1)
    buf = ReorderBuffer(wait=0.5)
    b = [make_batch("R1", 0, k, 4, 3, rng) for k in range(4)]
    c = make_batch("R2", 0, 1, 4, 3, rng)
    assert buf.push(b[2], arrival=0.0) is None
    assert buf.push(b[0], arrival=0.1) is None
    assert buf.push(c, arrival=0.2) is None
    assert buf.pop_ready(0.49) == []  # head (b0, arrived 0.1) not due yet
    out = buf.pop_ready(0.61)  # b0 due at 0.6, then c due at 0.7: only b0
    assert [p.batch for p in out] == [b[0]]
    out = buf.pop_ready(0.71)
    assert [(p.batch.radar_id, p.batch.seq) for p in out] == [("R2", 1), ("R1", 2)]
    assert buf.push(b[1], arrival=0.8) == "out of sequence"  # older than what was applied
    assert buf.push(b[2], arrival=0.8) == "duplicate batch"
    assert buf.push(b[3], arrival=0.9) is None
    assert [p.batch for p in buf.flush()] == [b[3]]


def test_core_applies_in_time_order_and_counts_rejects():
    c, made = core(reorder_wait=0.3, frame_kind="stereographic", frame_lat0=45, frame_lon0=20)
    c.on_site(make_site("R1", 45.0, 20.0))
    c.on_site_payload(keys.radar_site("R2"), make_site("R2", 45.2, 20.0).to_json_bytes())
    rng = np.random.default_rng(2)
    batches = [
        make_batch(r, s, k, 4, 5, rng) for s in range(2) for k in range(4) for r in ("R1", "R2")
    ]
    shuffled = [batches[i] for i in rng.permutation(len(batches))]
    for i, b in enumerate(shuffled):  # all arrive within the wait, in random order
        assert c.on_plots_payload(keys.radar_plots(b.radar_id), b.to_json_bytes(), 0.01 * i)
    assert c.poll(0.2) == []
    outs = c.poll(10.0)
    assert sum(len(o.time_ends) for o in outs) == len(batches)
    assert len(outs) == 1  # all ready at once: one pass, one message
    times = [t for _, t in made[0].seen]
    assert times == sorted(times)
    assert made[0].frame == FrameSpec(kind=FrameKind.STEREOGRAPHIC, lat0=45, lon0=20)
    # bad inputs: counted by reason, never raised
    good = batches[-1]
    assert c.on_plots_payload(keys.radar_plots("R1"), b"{not json", 11.0) is None
    bad = good.model_dump()
    bad["range"][2] = -5.0
    import json

    assert c.on_plots_payload(keys.radar_plots("R2"), json.dumps(bad).encode(), 11.0) is None
    assert c.on_plots_payload(keys.radar_plots("R9"), good.to_json_bytes(), 11.0) is None
    assert c.on_plots_payload(keys.radar_plots("R2"), good.to_json_bytes(), 11.0) is None
    early = make_batch("R1", 0, 0, 4, 5, rng).model_copy(update={"seq": 8})  # new, but old
    assert c.on_plots_payload(keys.radar_plots("R1"), early.to_json_bytes(), 11.0) is None
    assert c.rejected == {
        "invalid PlotBatch: not JSON": 1,
        "invalid PlotBatch: range": 1,
        "batch radar_id does not match its key": 1,
        "duplicate batch": 1,
        "out of sequence": 1,
    }
    st = c.status()
    assert st.counters["batches_in"] == len(batches)
    assert [r.radar_id for r in st.radars] == ["R1", "R2"]
    assert all(r.site_known for r in st.radars)


def test_radar_without_site_is_reported_not_guessed():
    c, made = core(reorder_wait=0.0)
    rng = np.random.default_rng(3)
    b = make_batch("R5", 0, 0, 4, 5, rng)
    c.on_plots(b, arrival=0.0)
    assert c.poll(1.0) == []
    assert c.rejected["no site for radar"] == 1
    assert made == []  # no frame could be chosen: nothing guessed
    assert c.status().radars[0].site_known is False
    # a configured site makes the next batch usable; the frame defaults to that site
    c.on_site(make_site("R5", 44.0, 21.0), configured=True)
    c.on_plots(make_batch("R5", 0, 1, 4, 5, rng), arrival=1.0)
    assert len(c.poll(2.0)) == 1
    assert (made[0].frame.lat0, made[0].frame.lon0) == (44.0, 21.0)


@pytest.mark.parametrize("alive", [True, False])
def test_liveliness_updates_radar_health(alive):
    c, _ = core()
    c.on_alive(keys.radar_alive("R3"), alive)
    assert c.status().radars[0].alive is alive


def test_assumed_altitude_lets_primary_only_plots_through_the_real_pipeline():
    """2-D plots without a flight level: tracked at the site's height by default
    and at an assumed altitude when the fusion configuration gives one; never
    rejected."""
    from skyfuse.fusion.tracker.config import TrackerConfig
    from skyfuse.services.fusion.server import make_pipeline_factory

    rng = np.random.default_rng(5)
    batch = make_batch("R1", 0, 0, 4, 6, rng)
    batch = batch.model_copy(update={"altitude": [None] * len(batch)})
    results = {}
    for assumed in (None, 3000.0):
        cfg = FusionConfig(reorder_wait=0.0, assumed_altitude=assumed, frame_lat0=45,
                           frame_lon0=20)  # fmt: skip
        c = FusionCore(
            cfg,
            make_pipeline_factory(TrackerConfig(), cfg.fusion_id, assumed_altitude=assumed),
        )
        c.on_site(make_site("R1", 45.0, 20.0))
        assert c.on_plots_payload(keys.radar_plots("R1"), batch.to_json_bytes(), 0.0)
        c.poll(1.0)
        results[assumed] = sum(
            n for reason, n in c.status().rejected.items() if reason.startswith("plot:")
        )
    assert results[None] == 0
    assert results[3000.0] == 0


def test_each_group_is_handed_out_before_the_next_group_runs():
    """``ready_cycles`` yields a group's output before it takes the next group, so the
    service publishes it at once: a group's batches never wait for later groups."""
    c, made = core(reorder_wait=0.0, bulk_max=2)
    c.on_site(make_site("R1", 45.0, 20.0))
    rng = np.random.default_rng(5)
    for k in range(5):
        c.on_plots(make_batch("R1", 0, k, 8, 3, rng), arrival=0.0)
    cycles = c.ready_cycles(1.0)
    first = next(cycles)
    assert len(first.time_ends) == 2 and len(made[0].seen) == 2  # the next group not run
    assert len(c.buffer) == 3
    rest = list(cycles)
    assert [len(o.time_ends) for o in rest] == [2, 1] and len(c.buffer) == 0
