"""The fusion service's saved state (``services.fusion.state_store``) round-trips: a core
stopped half-way through a simulated 3-radar scenario, saved and resumed into a new core,
then given the same batches as a core that never stopped, publishes exactly the same
feed (every delta and full message byte for byte, the epoch aside) and keeps the same
track ids. A state too old (or of another tracker configuration) is not resumed, but the
persisted next id is: no id is given twice. The reference is the uninterrupted run."""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.schemas import FeedKind, TrackBatch, TrackPicture
from skyfuse.services.fusion.pipeline import TrackPipeline
from skyfuse.services.fusion.service import FusionConfig, FusionCore
from skyfuse.services.fusion.state_store import STATE_FILE, Persistence, StateStore
from skyfuse.services.runtime.state_files import atomic_write


@pytest.fixture(scope="module")
def scenario():
    sc = build_scenario("regional", seed=5, duration=48.0, targets=8, radars=3)
    events = list(Simulator(sc, seed=5).run(truth=False))
    batches = sorted((e.message for e in events if e.kind == "plots"), key=lambda b: b.time_end)
    return sc.sites, batches


def make_core(tmp_path, sites, tracker: TrackerConfig | None = None, **kw) -> FusionCore:
    cfg = FusionConfig(
        sites=sites, future_tolerance=None, state_dir=tmp_path / "state", **kw
    )  # fmt: skip
    tcfg = tracker or TrackerConfig()
    return FusionCore(cfg, lambda frame: TrackPipeline(frame, tcfg, fusion_id="main"))


def feed(core: FusionCore, batches) -> list[bytes]:
    """Every feed message the core publishes for ``batches``, one cycle each, JSON with
    the epoch removed."""
    out = []
    for b in batches:
        assert core.on_plots(b, 0.0)
        for o in core.poll(flush=True):
            for msg in (o.tracks, o.full):
                if msg is not None:
                    d = json.loads(msg.to_json_bytes())
                    d.pop("epoch", None)
                    out.append(json.dumps(d, sort_keys=True).encode())
    return out


def test_saved_state_resumes_to_the_same_feed(tmp_path, scenario):
    sites, batches = scenario
    half = len(batches) // 2
    ref = make_core(tmp_path / "ref", sites)
    feed(ref, batches[:half])
    core = make_core(tmp_path, sites)
    p = Persistence.from_config(core)
    p.start()
    assert core.epoch == 1 and not p.resumed
    feed(core, batches[:half])
    confirmed = int(core.pipeline.picture().confirmed.sum())
    assert confirmed >= 3  # a picture worth resuming
    p.save()
    again = make_core(tmp_path, sites)
    q = Persistence.from_config(again)
    q.start()
    assert q.resumed and again.epoch == 2
    np.testing.assert_array_equal(again.pipeline.tracker.ids, ref.pipeline.tracker.ids)
    again._next_full = ref._next_full = float("inf")  # the full-picture timer is wall time
    a, b = feed(again, batches[half:]), feed(ref, batches[half:])
    assert len(a) == len(b) > 10
    assert a == b
    # the batches already applied are refused after the resume, not re-applied
    assert again.buffer.push(batches[half - 1], 0.0) in ("duplicate batch", "out of sequence")


def test_a_state_too_old_is_not_resumed_but_ids_are_never_reused(tmp_path, scenario):
    sites, batches = scenario
    third = len(batches) // 3
    core = make_core(tmp_path, sites)
    p = Persistence.from_config(core)
    p.start()
    used: set[int] = set()
    for i, b in enumerate(batches[:third]):
        feed(core, [b])
        p.guard_ids()  # before publishing (services.fusion.server)
        used |= set(core.pipeline.tracker.ids.tolist())
        if i == third // 2:
            p.save()  # the last snapshot: the tracks made after it are lost by a crash
    next_id = max(used) + 1
    assert len(used) > 10
    parts = (batches[third : 2 * third], batches[2 * third :])
    for kw, part in zip(({"resume_max_age": 0.0}, {"tracker": TrackerConfig(p_gate=0.995)}), parts):
        fresh = make_core(tmp_path, sites, **kw)
        q = Persistence.from_config(fresh)
        q.start()
        assert not q.resumed
        feed(fresh, part)
        ids = fresh.pipeline.tracker.ids
        assert len(ids) and ids.min() >= next_id  # never an id given before the crash
        q.save()
        next_id = int(fresh.pipeline.tracker._next_id)
    assert StateStore(tmp_path / "state", "main", max_age=1, id_horizon=1).read_ids().epoch == 3


def test_ids_restart_from_one_after_the_horizon(tmp_path, scenario):
    sites, batches = scenario
    core = make_core(tmp_path, sites)
    p = Persistence.from_config(core)
    p.start()
    feed(core, batches[:20])
    p.save()
    fresh = make_core(tmp_path, sites, resume_max_age=0.0, id_horizon=0.0)
    Persistence.from_config(fresh).start()
    for b in batches[20:]:  # the first tracks it makes are numbered from 1 again
        feed(fresh, [b])
        if len(fresh.pipeline.tracker.ids):
            break
    assert fresh.pipeline.tracker.ids.min() == 1


def test_state_dir_writable_by_others_is_refused(tmp_path, scenario):
    d = tmp_path / "state"
    d.mkdir()
    os.chmod(d, 0o777)
    with pytest.raises(PermissionError, match="writable by group/others"):
        StateStore(d, "main", max_age=1, id_horizon=1)
    os.chmod(d, 0o700)
    core = make_core(tmp_path, scenario[0])
    p = Persistence.from_config(core)
    p.start()
    p.save()
    os.chmod(d / STATE_FILE, 0o666)  # a file others could have replaced: not loaded
    store = StateStore(d, "main", max_age=60, id_horizon=60)
    assert store.load()[0] is None and "writable" in store.load()[1]


def test_atomic_write_replaces_whole_files(tmp_path):
    path = tmp_path / "f.bin"
    atomic_write(path, b"a" * 1000)
    atomic_write(path, b"b" * 10)
    assert path.read_bytes() == b"b" * 10
    assert [p.name for p in tmp_path.iterdir()] == ["f.bin"]  # no temporary left


def _delta(cycle: int, epoch: int, ids: list[int], kind=FeedKind.DELTA) -> TrackBatch:
    return TrackBatch(
        fusion_id="main", cycle=cycle, epoch=epoch, time=1, kind=kind,
        frame={"kind": "stereographic"}, state_labels=["x"], removed=ids,
    )  # fmt: skip


def test_track_picture_applies_a_new_epoch_and_marks_it_incomplete():
    pic = TrackPicture()
    assert pic.apply(_delta(1, 1, []))
    assert pic.apply(_delta(2, 1, [])) and pic.complete
    assert not pic.apply(_delta(2, 1, []))  # an old delta of the same epoch
    assert pic.apply(_delta(2, 2, [])) and not pic.complete  # resumed behind: new epoch
    assert pic.apply(_delta(3, 2, [], FeedKind.FULL)) and pic.complete


def test_periodic_snapshots_are_written_by_the_writer_thread(tmp_path, scenario):
    sites, batches = scenario
    core = make_core(tmp_path, sites)
    p = Persistence.from_config(core)
    p.start()
    feed(core, batches[:60])
    p.tick(float("inf"))  # due: serialised here, written by the thread
    deadline = time.monotonic() + 10
    while core.counters["state_saves"] < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert core.counters["state_saves"] == 1
    ids = core.pipeline.tracker.ids.copy()
    feed(core, batches[60:80])  # after the snapshot: not in it
    again = make_core(tmp_path, sites)
    Persistence.from_config(again).start()
    np.testing.assert_array_equal(again.pipeline.tracker.ids, ids)
