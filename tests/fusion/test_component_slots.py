"""The slot store of density components against the store it replaces (take and
concatenate after every operation), over random sequences of appends, replacements,
removals of tracks and compactions, with a snapshot round trip after each; and the
checks of a restored snapshot."""

import numpy as np
import pytest
from skyfuse.fusion.tracker.component_slots import ComponentSlots
from skyfuse.fusion.tracker.components import Mixture
from skyfuse.fusion.tracker.density.imm_mixture import IMMComponents
from skyfuse.schemas.snapshot import SnapshotError


def _imm(rng, tracks):
    c = len(tracks)
    return IMMComponents(
        np.asarray(tracks, np.int64), rng.random(c), rng.integers(0, 9, (c, 2)),
        rng.random((c, 2)), [rng.normal(size=(c, 4)), rng.normal(size=(c, 5))],
        [rng.normal(size=(c, 4, 4)), rng.normal(size=(c, 5, 5))],
    )  # fmt: skip


def _same(a, b):
    for name in ("track", "w", "hist", "mu"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    for j in range(2):
        np.testing.assert_array_equal(a.x[j], b.x[j])
        np.testing.assert_array_equal(a.P[j], b.P[j])


def test_slots_follow_the_take_and_concatenate_store(monkeypatch):
    import skyfuse.fusion.tracker.component_slots as cs

    monkeypatch.setattr(cs, "_COMPACT_MIN", 8)  # compaction often, not only past 1,024
    reallocations = []  # compactions on keep: a grow with nothing new
    real = cs.ComponentSlots._grow
    monkeypatch.setattr(
        cs.ComponentSlots, "_grow", lambda s, new: reallocations.append(len(new)) or real(s, new)
    )
    rng = np.random.default_rng(4)
    ref = _imm(rng, [])
    slots = ComponentSlots(ref)
    ntracks, compactions = 0, 0
    for _ in range(400):
        dead_before = slots.n - len(slots)
        op = rng.random()
        if op < 0.3 or ntracks == 0:  # new tracks, one component each
            k = int(rng.integers(1, 30))
            new = _imm(rng, ntracks + np.arange(k))
            ntracks += k
            ref = IMMComponents.concat([ref, new])
            slots.append(new)
        elif op < 0.8:  # a batch updates some tracks: their components replaced
            inside = rng.random(ntracks) < 0.2
            rows = np.flatnonzero(inside)
            new = _imm(rng, np.repeat(rows, rng.integers(1, 4, len(rows))))
            ref = IMMComponents.concat([ref.take(np.flatnonzero(~inside[ref.track])), new])
            slots.replace(inside, new)
        else:  # some tracks end; the others are renumbered
            mask = rng.random(ntracks) > 0.3
            ref = ref.take(np.flatnonzero(mask[ref.track]))
            ref.track = (np.cumsum(mask) - 1)[ref.track]
            ntracks = int(mask.sum())
            slots.keep(mask)
        compactions += dead_before > 0 and slots.n == len(slots)  # dead slots dropped
        assert len(slots) == len(ref)
        _same(slots.live(), ref)
        empty = ref.take(np.zeros(0, np.int64))
        _same(ComponentSlots.from_snapshot(slots.to_snapshot(), empty, ntracks).live(), ref)
        inside = rng.random(ntracks) < 0.5
        _same(slots.tracks(inside), ref.take(np.flatnonzero(inside[ref.track])))
    assert compactions > 0 and 0 in reallocations  # both compaction paths ran


def test_views_of_all_slots_stay_valid_after_writes():
    rng = np.random.default_rng(1)
    slots = ComponentSlots.holding(
        Mixture(np.arange(5), np.ones(5), rng.normal(size=(5, 4)), np.ones((5, 4, 4)),
                np.zeros((5, 1), np.int64))
    )  # fmt: skip
    view = slots.tracks(np.ones(5, bool))  # every slot: views, not copies
    before = view.track.copy(), view.x.copy()
    new = Mixture(np.array([1, 1]), np.ones(2), np.zeros((2, 4)), np.eye(4)[None].repeat(2, 0),
                  np.zeros((2, 1), np.int64))  # fmt: skip
    slots.replace(np.isin(np.arange(5), [1]), new)
    slots.keep(np.array([True, True, False, True, True]))
    np.testing.assert_array_equal(view.track, before[0])
    np.testing.assert_array_equal(view.x, before[1])
    assert list(slots.live().track) == [0, 2, 3, 1, 1]


def _snapshot_refused(snap, ntracks, match):
    empty = _imm(np.random.default_rng(0), [])
    with pytest.raises(SnapshotError, match=match):
        ComponentSlots.from_snapshot(snap, empty, ntracks)


def test_a_broken_snapshot_is_refused():
    rng = np.random.default_rng(2)
    snap = ComponentSlots.holding(_imm(rng, [0, 1, 1])).to_snapshot()
    assert len(ComponentSlots.from_snapshot(snap, _imm(rng, []), 2)) == 3
    _snapshot_refused(snap, 1, "track rows for 1 tracks")  # a component of row 1 of 1
    _snapshot_refused(snap, 3, "track rows for 3 tracks")  # row 2 without a component
    cols = snap["columns"]
    for name, value, match in (
        ("x1", cols["x1"][:2], "x1: shape"),
        ("mu", cols["mu"].astype(np.float32), "mu: dtype"),
        ("w", -cols["w"], "weights"),
        ("extra", cols["w"], "not declared"),
    ):
        _snapshot_refused({**snap, "columns": {**cols, name: value}}, 2, match)
    _snapshot_refused({**snap, "columns": {k: v for k, v in cols.items() if k != "P0"}}, 2, "P0")
