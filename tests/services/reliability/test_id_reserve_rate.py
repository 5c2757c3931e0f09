"""The id reserve of ``ids.json`` (state_store.Persistence.reserve): ``ID_RESERVE`` while
ids are given slowly, the ids of two snapshot intervals at the observed rate while they
are given fast (so the fsync'd ceiling write and the standby snapshot are not repeated
every 1,000 ids), never more than ``ID_RESERVE_MAX``; and the ceiling written stays
above every id the tracker gave."""

from __future__ import annotations

from types import SimpleNamespace

from skyfuse.services.fusion.state_store import (
    ID_RESERVE,
    ID_RESERVE_MAX,
    Persistence,
    StateStore,
)


def test_reserve_follows_the_id_rate(tmp_path):
    p = Persistence(None, None, interval=2.0)
    p._last_raise = (100.0, 1)
    assert p.reserve(201, 110.0) == ID_RESERVE  # 20 ids/s: 80 in two intervals < 1000
    assert p.reserve(5201, 111.0) == 20_000  # 5,000 ids/s × 4 s
    assert p.reserve(5201, 111.0) == ID_RESERVE  # no time elapsed: the floor
    assert p.reserve(10**9, 112.0) == ID_RESERVE_MAX


class _Tracker:
    def __init__(self) -> None:
        self._next_id = 1


def test_guard_keeps_the_ceiling_above_fast_ids(tmp_path, monkeypatch):
    import skyfuse.services.fusion.state_store as ss

    clock = [0.0]
    monkeypatch.setattr(ss.time, "monotonic", lambda: clock[0])
    store = StateStore(tmp_path / "s", "main", max_age=60, id_horizon=3600)
    tracker = _Tracker()
    core = SimpleNamespace(pipeline=SimpleNamespace(tracker=tracker), epoch=1, counters={})
    p = Persistence(core, store, interval=2.0)
    p.publish = None
    p._last_raise = (0.0, 1)
    writes = 0
    for step in range(1, 200):  # 1,000 ids per 0.1 s: 10,000 ids/s
        clock[0] = step * 0.1
        tracker._next_id += 1000
        before = store.read_ids()
        p.guard_ids()
        after = store.read_ids()
        writes += before is None or after.next_track_id != before.next_track_id
        assert after.next_track_id > tracker._next_id  # every id given is below it
    # a fixed 1,000-id reserve would write at each of the 199 steps; 40,000 ids (4 s at
    # 10,000/s) per write: one write per 4 steps at most
    assert writes <= 199 // 4 + 2
