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
import json
from pathlib import Path

import numpy as np
import pytest
from service_support import make_batch, make_site
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import PlotBatch, keys
from skyfuse.schemas.snapshot import SnapshotError
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
    # a rate not known yet: the jump is refused for 2 s of its data (batches 1 s apart),
    # then the numbering it starts is taken
    fresh = SeenBatches()
    assert (
        _stream(fresh, real_batches(1) + real_batches(4, 5000))
        == [None, "sequence jump", "sequence jump"] + [None] * 2
    )
    assert fresh.lost("R1") == 4999  # 1 … 4999 (the refused 5000 and 5001 arrived)
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
    # a radar switched off for an hour (same numbering): 2 s of its batches refused, then
    # taken
    seen = SeenBatches()
    resumed = [later(b) for b in real_batches(4, 9)]
    assert _stream(seen, real_batches(10) + resumed) == [None] * 10 + ["time jump"] * 2 + [None] * 2
    assert seen.lost("R1") == 0


def test_a_jump_is_taken_after_2_s_of_its_own_data_whatever_the_arrival():
    """A real jump's gapless continuation is taken once its batches' own times span 2 s,
    however they arrive (here all in one instant, as from a drained backlog); a real batch
    of the old numbering in between ends the claim (a gapless forged stream racing a live
    radar never gets through); copies of the latest batches sent now and then with a
    forged number never continue each other without a gap, however long the old
    numbering is silent."""
    seen = SeenBatches()
    moved = [b.model_copy(update={"seq": b.seq + 5000}) for b in real_batches(6, 10)]
    assert (
        _stream(seen, real_batches(10) + moved) == [None] * 10 + ["sequence jump"] * 2 + [None] * 4
    )  # 5010 at 11 s, 5011, 5012 at 13 s: taken
    assert seen.lost("R1") == 5000  # 10 … 5009
    live = SeenBatches()
    for b in real_batches(40):
        assert _stream(live, [b]) == [None]
        if b.seq >= 10:  # a forged continuation of a jump between every two real batches
            assert _stream(live, [forged(b)]) == ["sequence jump"]
    silent = SeenBatches()
    _stream(silent, real_batches(10))
    copies = [forged(b) for b in real_batches(200, 10)][::3]  # every 3rd, the radar silent
    assert _stream(silent, copies) == ["sequence jump"] * len(copies)
    assert silent.radars["R1"][EPOCH]["high"] == 9


def _backlog(epoch: int) -> list[tuple[PlotBatch, int]]:
    """The hostile soak's recorder running behind (``docs/reliability.md``), as
    ``(batch, arrival ns)``: radar R1 keeps up for 40 batches (4 a second); then its
    batches 40 … 99 wait in the backlog while copies of its latest batches (as a live
    fuzzer sees them) get through: with ``seq`` + 10⁶ every 2-5 numbers, one arriving
    2.5 s after the one before (the receiver's delivery stalled by back-pressure), and a
    repeat of batch 50; then the backlog drains, its 60 batches in one instant."""
    S = 1_000_000_000
    real = real_batches(100, epoch=epoch)
    out = [(b, k * S // 4) for k, b in enumerate(real[:40])]
    t = 10 * S
    for k in (42, 44, 49, 51, 54, 56, 61, 63, 66, 70, 73, 77):
        out.append((forged(real[k]), t))
        t += 5 * S // 2 if k == 42 else S // 3
        if k == 51:
            out.append((real[50], t))  # a repeat of an older batch, before the real one
    out += [(b, t + 1000 * i) for i, b in enumerate(real[40:])]
    return out


def test_a_backlog_cannot_make_the_recorder_take_a_forged_jump(tmp_path):
    """The recorder behind (arrivals bunched and stretched): every real batch is recorded
    once, every forged copy refused and counted, nothing lost — the same with an
    announced epoch and without. (Before: the copy arriving 2.5 s after the one before
    it was taken as the radar's numbering, with the forged copies after it; with an
    epoch announced, the late real batches 40 … 44 were then refused as ``duplicate
    batch`` and 10⁶ numbers counted lost.)"""
    for epoch in (EPOCH, 0):
        rec = Recorder(RecorderConfig(out=tmp_path / f"r{epoch}.mcap", foxglove=False))
        key = keys.radar_plots("R1")
        recorded = []
        for b, recv in _backlog(epoch):
            if rec.handle(Received("data", key, b.to_json_bytes(), True, recv)):
                recorded.append(b.seq)
        assert sorted(recorded) == list(range(100)), epoch
        assert rec.rejected == {"sequence jump": 12, "duplicate batch": 1}, epoch
        assert rec.lost() == {} and rec.seen.resets == 0
        rec.close()


def test_the_fusion_core_takes_no_forged_jump_from_a_backlog(tmp_path):
    core = make_core(tmp_path)
    applied = [b.seq for b, recv in _backlog(EPOCH) if core.buffer.push(b, 0.0, None, recv) is None]
    assert sorted(applied) == list(range(100))
    assert core.buffer.seen.lost("R1") == 0 and core.buffer.seen.resets == 0


def test_after_a_forged_stream_was_taken_the_old_numbering_wins_back():
    """The limit of the guard (``docs/reliability.md``): a gapless forged stream spanning
    2 s, while the radar's own batches wait in a backlog, is taken. The radar's late
    batches are then not repeats (their numbers were skipped by the jump): accepted and
    counted; the first one dated after the forged stream began takes the radar back to
    its numbering (``resets``), and nothing of it is counted lost."""
    seen = SeenBatches()
    real = real_batches(40)
    stream = [forged(b) for b in real[20:24]]  # 1000020 … 1000023: 3 s of data
    assert _stream(seen, real[:10] + stream) == [None] * 10 + ["sequence jump"] * 2 + [None] * 2
    assert seen.radars["R1"][EPOCH]["high"] == 1_000_023
    assert _stream(seen, real[10:]) == [None] * 30  # 10 … 19 late, 20 dated after: back
    st = seen.radars["R1"][EPOCH]
    assert (st["high"], st["prior"], seen.resets) == (39, None, 1)
    assert seen.lost("R1") == 0
    assert _stream(seen, [real[15], forged(real[39])]) == ["duplicate batch", "sequence jump"]
    # taken numbers skipped by a real jump that arrive late are accepted and not lost
    gap = SeenBatches()
    moved = [b.model_copy(update={"seq": b.seq + 5000}) for b in real_batches(4, 10)]
    _stream(gap, real[:10] + moved)
    late = real_batches(5, 4000)  # numbered in the gap, dated before the jump
    late = [b.model_copy(update={"time_end": real[9].time_end}) for b in late]
    assert _stream(gap, late + late[:1]) == [None] * 5 + ["duplicate batch"]
    assert gap.lost("R1") == 5000 - 5


def test_the_guard_state_survives_a_snapshot_and_an_earlier_version_is_refused():
    seen = SeenBatches()
    real = real_batches(40)
    _stream(seen, real[:10] + [forged(b) for b in real[20:24]] + real[10:12])
    assert _stream(seen, [forged(real[30], 5 * 10**6)]) == ["sequence jump"]  # a claim
    assert seen.radars["R1"][EPOCH]["pending"] is not None
    assert seen.radars["R1"][EPOCH]["prior"]["fill"] == {10, 11}
    snap = json.loads(json.dumps(seen.to_snapshot()))
    again = SeenBatches()
    again.from_snapshot(snap)
    assert again.radars == seen.radars and again.resets == seen.resets
    assert _stream(again, real[12:]) == [None] * 28 and again.lost("R1") == 0
    with pytest.raises(SnapshotError, match="version 3"):
        SeenBatches().from_snapshot({**snap, "version": 3})
    # version 1 (no version; pending claims [seq, time, arrival]): read, its claims dropped
    v1 = json.loads(json.dumps(snap))
    del v1["version"]
    for _, epochs in v1["radars"]:
        for _, st in epochs:
            st["pending"] = [5_000_030, 0, 5]
            del st["prior"]
    older = SeenBatches()
    older.from_snapshot(v1)
    assert older.radars["R1"][EPOCH]["pending"] is None
    assert older.radars["R1"][EPOCH]["high"] == seen.radars["R1"][EPOCH]["high"]
