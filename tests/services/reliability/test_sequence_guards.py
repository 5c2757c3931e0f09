"""One message cannot turn a radar's own numbering against it (finding of the live probe:
a single copy of a radar's latest batch with ``seq + 1,000,000`` made the fusion service
and the recorder refuse every later real batch as ``duplicate batch``, and the fusion's
saved state carried the block over a restart).

* the fusion core and the recorder refuse the forged number (``sequence jump``, counted)
  and keep applying / recording the radar's real batches;
* the saved state after it does not block the radar after a restart — nor does a state
  whose highest number *was* forged (saved by the earlier version);
* a real gap (batches lost beyond the publisher's cache) is accepted at the radar's
  measured rate, or after one refused batch when the rate is not known yet; gaps are
  counted as lost per radar; a new epoch restarts the numbering.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
from service_support import make_batch, make_site
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import PlotBatch, keys
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.fusion.state_store import Persistence
from skyfuse.services.recording.recorder import Recorder, RecorderConfig
from skyfuse.services.runtime.seen_batches import SeenBatches
from skyfuse.services.runtime.transport import Received

EPOCH = 7


def real_batches(n: int, start: int = 0, epoch: int = EPOCH) -> list[PlotBatch]:
    """Batches ``start`` … ``start + n - 1`` of radar R1 (4 sectors of 1 s per scan)."""
    rng = np.random.default_rng(start)
    out = []
    for seq in range(start, start + n):
        b = make_batch("R1", seq // 4, seq % 4, 4, 3, rng)
        out.append(b.model_copy(update={"epoch": epoch}))
    return out


def forged(b: PlotBatch, jump: int = 1_000_000) -> PlotBatch:
    return b.model_copy(update={"seq": b.seq + jump})


def make_core(tmp_path) -> FusionCore:
    cfg = FusionConfig(
        sites=[make_site("R1", 45.0, 20.0)], future_tolerance=None, state_dir=tmp_path,
        frame_lat0=45.0, frame_lon0=20.0,
    )  # fmt: skip
    core = FusionCore(cfg, lambda frame: TrackPipeline(frame, TrackerConfig(), fusion_id="main"))
    assert core.frame is not None  # saved with the state: the watermarks are restored
    return core


def test_fusion_refuses_a_forged_jump_and_keeps_the_radar_across_restarts(tmp_path):
    core = make_core(tmp_path)
    p = Persistence.from_config(core)
    p.start()
    for b in real_batches(10):
        assert core.on_plots(b, 0.0)
    assert not core.on_plots(forged(real_batches(1, 9)[0]), 0.0)
    assert core.rejected["sequence jump"] == 1
    assert all(core.on_plots(b, 0.0) for b in real_batches(10, 10))
    p.save()
    again = make_core(tmp_path)
    Persistence.from_config(again).start()
    assert again.buffer.seen.radars["R1"][EPOCH]["high"] == 19  # resumed, without the jump
    assert all(again.on_plots(b, 0.0) for b in real_batches(10, 20))
    assert not again.on_plots(real_batches(1, 25)[0], 0.0)  # a real repeat stays refused
    assert again.rejected == {"duplicate batch": 1}
    r = again.status().radars[0]
    assert (r.batches, r.batches_refused, r.batches_lost) == (10, 1, 0)


def test_a_state_saved_by_an_earlier_version_cannot_block_the_radar(tmp_path):
    """An earlier version adopted a forged highest number and saved it with its watermarks
    (b062918's ``state.npz``, ``tests/services/reliability/data``): that state is refused
    as a whole by its format version, so the radar's real batches are accepted after the
    restart."""
    blob = gzip.decompress((Path(__file__).parent / "data" / "state_b062918.npz.gz").read_bytes())
    (tmp_path / "state.npz").write_bytes(blob)
    tmp_path.chmod(0o700)
    (tmp_path / "state.npz").chmod(0o600)
    core = make_core(tmp_path)
    p = Persistence.from_config(core)
    p.start()
    assert not p.resumed
    assert all(core.on_plots(b, 0.0) for b in real_batches(10, 1_000))
    assert core.buffer.seen.resets == 0


def test_recorder_refuses_the_jump_and_records_the_radar(tmp_path):
    rec = Recorder(RecorderConfig(out=tmp_path / "r.mcap", foxglove=False))
    key = keys.radar_plots("R1")

    def handle(b: PlotBatch) -> bool:
        return rec.handle(Received("data", key, b.to_json_bytes(), True, b.time_end))

    assert all(handle(b) for b in real_batches(10))
    assert not handle(forged(real_batches(1, 9)[0]))
    assert all(handle(b) for b in real_batches(10, 10))
    assert not handle(real_batches(1, 3)[0])
    assert rec.rejected == {"sequence jump": 1, "duplicate batch": 1}
    assert rec.counts[key] == 20 and rec.lost() == {}
    rec.close()


def _stream(seen: SeenBatches, batches, horizon=None) -> list[str | None]:
    out = []
    for b in batches:
        reason = seen.check(b, horizon)
        out.append(reason)
        if reason is None:
            seen.add(b)
    return out


def test_real_gaps_are_accepted_and_counted_as_lost():
    seen = SeenBatches()
    # a rate known (1 batch/s of data time): 2,000 numbers lost in 2,000 s are plausible
    assert _stream(seen, real_batches(100)) == [None] * 100
    assert _stream(seen, real_batches(3, 2100)) == [None] * 3
    assert seen.lost("R1") == 2000
    # the same jump with no time passed is refused (a forged copy of the latest batch)
    copy = real_batches(1, 2102)[0].model_copy(update={"seq": 6000})
    assert _stream(seen, [copy]) == ["sequence jump"]
    # a rate not known yet: the jump is refused once, then the numbering it starts is taken
    fresh = SeenBatches()
    assert (
        _stream(fresh, real_batches(1) + real_batches(3, 5000))
        == [None, "sequence jump"] + [None] * 2
    )
    assert fresh.lost("R1") == 4999  # 1 … 4999 (the refused 5000 arrived)
    # a new epoch starts the numbering again
    assert _stream(fresh, real_batches(5, 0, epoch=EPOCH + 1)) == [None] * 5
    # numbers recovered later are no longer lost
    gappy = SeenBatches()
    bs = real_batches(20)
    _stream(gappy, bs[:5] + bs[9:])
    assert gappy.lost("R1") == 4
    _stream(gappy, bs[5:9])
    assert gappy.lost("R1") == 0


def test_numbers_refused_by_a_time_check_are_not_lost():
    seen = SeenBatches()
    bs = real_batches(10)
    _stream(seen, bs[:4])
    seen.received(bs[4])  # e.g. too late: refused, but it arrived
    _stream(seen, bs[5:])
    assert seen.lost("R1") == 0


HOUR = 3_600_000_000_000


def later(b: PlotBatch, ns: int = HOUR) -> PlotBatch:
    """The next number with every time ``ns`` later (one message of a radar replaying old
    data, dated an hour ahead: the clock check passes it, the data being older)."""
    return b.model_copy(update={
        "seq": b.seq + 1, "time_start": b.time_start + ns, "time_end": b.time_end + ns,
        "time": [t + ns for t in b.time],
    })  # fmt: skip


def test_a_time_jump_is_refused_and_cannot_carry_the_radar_away(tmp_path):
    for epoch in (EPOCH, 0):  # announced or not
        core = make_core(tmp_path / str(epoch))
        core.cfg.future_tolerance = 1.0
        bs = real_batches(12, epoch=epoch)
        assert all(core.on_plots(b, 0.0) for b in bs[:10])
        assert not core.on_plots(later(bs[9]), 0.0)
        assert core.rejected == {"time jump": 1}
        assert all(core.on_plots(b, 0.0) for b in bs[10:])
        for out in core.poll(10.0):  # released: the radar's time is its real one
            core.published(out)
        assert core.buffer.radar_time["R1"] == bs[-1].time_end
    rec = Recorder(RecorderConfig(out=tmp_path / "r.mcap", foxglove=False))
    key, bs = keys.radar_plots("R1"), real_batches(12)
    handle = lambda b: rec.handle(Received("data", key, b.to_json_bytes(), True, 0))  # noqa: E731
    assert all(handle(b) for b in bs[:10]) and not handle(later(bs[9]))
    assert all(handle(b) for b in bs[10:]) and rec.rejected == {"time jump": 1}
    rec.close()
    # a radar switched off for an hour (same numbering): one batch refused, then taken
    seen = SeenBatches()
    resumed = [later(b) for b in real_batches(3, 9)]
    assert _stream(seen, real_batches(10) + resumed) == [None] * 10 + ["time jump", None, None]


def test_a_jump_is_taken_only_after_its_continuation_lasted_and_the_old_numbering_is_silent():
    """With arrival times: a refused jump's continuation is taken after 2 s of it; a real
    batch of the old numbering in between ends the claim (forged copies racing a live
    radar never get through)."""
    S = 1_000_000_000
    seen = SeenBatches()
    old = real_batches(10)  # then the numbering moves on by 5,000 with the time going on
    moved = [b.model_copy(update={"seq": b.seq + 5000}) for b in real_batches(12, 10)]
    for k, b in enumerate(old):
        assert seen.check(b, recv_ns=k * S // 4) is None
        seen.add(b)
    got = []
    for k, b in enumerate(moved):  # 4 per second, the old numbering silent
        r = seen.check(b, recv_ns=(10 + k) * S // 4)
        got.append(r)
        if r is None:
            seen.add(b)
    assert got == ["sequence jump"] * 8 + [None] * 4  # 2 s of refusals, then taken
    live = SeenBatches()
    stream = real_batches(40)
    for k, b in enumerate(stream):
        assert live.check(b, recv_ns=k * S // 4) is None
        live.add(b)
        if k >= 10:  # a forged continuation of a jump between every two real batches
            f = b.model_copy(update={"seq": b.seq + 10**6})
            assert live.check(f, recv_ns=k * S // 4 + 1) == "sequence jump"
