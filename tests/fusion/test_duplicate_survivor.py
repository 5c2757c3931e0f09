"""Duplicate removal: which track, and whose id, survives (``duplicate_survivor``)."""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.management import duplicates

R = 25.0 * np.eye(2)
NS = 10**9


def cfg(**kw):
    base = dict(q=0.75, v_max=50.0, clutter="known", motion="cv", tracker="ipda")
    base.update(kw, initiation="none")
    return TrackerConfig(**base)


def established_and_young(rule: str):
    """A confirmed track with three scans of plots at 10 m/s along x, then four misses
    (its existence falls to ≈ 0.005), and a confirmed track started at t = 7 s about 70 m away
    with a 50 m σ (a young track) and existence 0.9999; at t = 8 s one plot on the first
    track, which both take. After the update the young track has the larger ψ."""
    tr = Tracker(cfg(duplicate_survivor=rule))
    old = tr.add_track([0, 10, 0, 0], np.diag([25.0, 4, 25, 4]), 0, existence=0.9, confirmed=True)
    for k in range(1, 8):
        z = np.array([[10.0 * k, 0.0]]) if k <= 3 else np.zeros((0, 2))
        tr.step(MeasurementBatch(k * NS, "r", z, R, 0.9, 1e-9))
    young = tr.add_track(
        [130, 10, 30, 0], np.diag([2500.0, 100, 2500, 100]), 7 * NS, existence=0.9999,
        confirmed=True,
    )  # fmt: skip
    out = tr.step(MeasurementBatch(8 * NS, "r", np.array([[80.0, 0.0]]), R, 0.9, 1e-9))
    return old, young, out


def test_established_rule_keeps_the_older_confirmed_track_and_its_id():
    old, young, out = established_and_young("established")
    assert list(out.ids) == [old]
    assert out.stats["duplicates_removed"] == 1
    merged = [e for e in out.events if e.kind == "merged"]
    assert [(e.track_id, e.other_track_id) for e in merged] == [(young, old)]
    # the survivor is still on the target: its estimate is the plot's neighbourhood
    assert np.hypot(*(out.states[0, [0, 2]] - [80.0, 0.0])) < 15.0


def test_existence_rule_keeps_the_larger_existence():
    """The same scene under the thesis's rule (keep the largest ψ): the young track."""
    _, young, out = established_and_young("existence")
    assert list(out.ids) == [young]


def test_genuine_duplicates_are_still_merged_under_both_rules():
    for rule in ("existence", "established"):
        tr = Tracker(cfg(duplicate_survivor=rule))
        a = tr.add_track([0, 10, 0, 0], np.diag([25.0] * 4), 0, existence=0.9, confirmed=True)
        tr.add_track([2, 10, 1, 0], np.diag([25.0] * 4), 0, existence=0.95)
        out = tr.step(MeasurementBatch(NS, "r", np.array([[10.0, 0.0]]), R, 0.9, 1e-6))
        assert list(out.ids) == [a] and out.stats["duplicates_removed"] == 1


def test_duplicates_ranking_by_hand():
    """Three mutually coincident tracks: row 0 confirmed with 40 scans and ψ 0.3, row 1
    confirmed with 3 scans and ψ 0.99, row 2 tentative with ψ 0.999."""
    x = np.zeros((3, 4))
    P = np.broadcast_to(np.eye(4), (3, 4, 4)).copy()
    psi = np.array([0.3, 0.99, 0.999])
    conf = np.array([True, True, False])
    scans = np.array([40, 3, 5])
    a, b = np.array([0, 0, 1]), np.array([1, 2, 2])
    lo, wi = duplicates(a, b, x, P, psi, conf, None, 13.3)
    assert dict(zip(lo.tolist(), wi.tolist())) == {0: 1, 2: 1}  # by ψ, confirmed first
    lo, wi = duplicates(a, b, x, P, psi, conf, scans, 13.3)
    assert dict(zip(lo.tolist(), wi.tolist())) == {1: 0, 2: 0}  # most scans survives
    # estimates 10 σ apart are not duplicates under either rule
    x[1, 0] = 10.0 * np.sqrt(2.0)
    lo, _ = duplicates(np.array([0]), np.array([1]), x, P, psi, conf, scans, 13.3)
    assert len(lo) == 0
