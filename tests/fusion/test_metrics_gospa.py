"""GOSPA/OSPA against hand-worked configurations, brute force, Stone Soup and metric properties."""

from __future__ import annotations

import datetime
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skyfuse.fusion.metrics.gospa import UNASSIGNED, gospa, gospa_over_time
from skyfuse.fusion.metrics.ospa import ospa

E = np.zeros((0, 2))


# ---------------------------------------------------------------- GOSPA, hand-worked (c=10, p=2)
def test_gospa_empty_sets_is_zero():
    r = gospa(E, E, c=10)
    assert r.distance == 0 and r.n_missed == 0 and r.n_false == 0


def test_gospa_one_missed():
    # One truth, no estimate: missed = c^p/2 = 100/2 = 50; distance = sqrt(50).
    r = gospa([[0.0, 0.0]], E, c=10)
    assert r.missed == 50 and r.false == 0 and r.localisation == 0
    assert r.distance == pytest.approx(math.sqrt(50))
    assert r.assignment.tolist() == [UNASSIGNED]


def test_gospa_one_false():
    # No truth, one estimate: false = 50; distance = sqrt(50).
    r = gospa(E, [[7.0, -3.0]], c=10)
    assert (r.missed, r.false, r.n_false) == (0, 50, 1)
    assert r.distance == pytest.approx(math.sqrt(50))


def test_gospa_localisation_only():
    # Truth (0,0), estimate (3,4): distance 5 < c, localisation 25, GOSPA = 5.
    r = gospa([[0.0, 0.0]], [[3.0, 4.0]], c=10)
    assert r.localisation == pytest.approx(25) and r.missed == 0 and r.false == 0
    assert r.distance == pytest.approx(5)
    assert r.assignment.tolist() == [0]


def test_gospa_beyond_cutoff_is_one_missed_and_one_false():
    # Truth (0,0), estimate (30,40): distance 50 >= c = 10, so the pair is not assigned:
    # missed 50 + false 50 = 100 = c^p, GOSPA = c = 10.
    r = gospa([[0.0, 0.0]], [[30.0, 40.0]], c=10)
    assert (r.n_missed, r.n_false) == (1, 1)
    assert r.missed == 50 and r.false == 50 and r.localisation == 0
    assert r.distance == pytest.approx(10)
    assert r.assignment.tolist() == [UNASSIGNED]


def test_gospa_missed_false_and_localisation_together():
    # Truths (0,0), (100,0); estimates (3,4), (0,50), c = 10.
    # Assignment A: (0,0)-(3,4) d=5 -> 25, (100,0)-(0,50) d=111.8 -> cut to 10 -> 100: 125.
    # Assignment B: (0,0)-(0,50) d=50 -> 100, (100,0)-(3,4) d=97.1 -> 100: 200.  A wins.
    # The cut pair becomes one missed + one false: 25 + 50 + 50 = 125, GOSPA = sqrt(125).
    r = gospa([[0.0, 0.0], [100.0, 0.0]], [[3.0, 4.0], [0.0, 50.0]], c=10)
    assert r.localisation == pytest.approx(25)
    assert (r.missed, r.false) == (50, 50)
    assert r.distance == pytest.approx(math.sqrt(125))
    assert r.assignment.tolist() == [0, UNASSIGNED]


def test_gospa_assignment_is_optimal_not_greedy():
    # 1-D: truths 0 and 4, estimates 3 and 7, c = 10. Greedy nearest pairs 4-3 (1) then
    # 0-7 (49): 50. The optimum pairs 0-3 (9) and 4-7 (9): 18. GOSPA = sqrt(18).
    r = gospa([[0.0], [4.0]], [[3.0], [7.0]], c=10)
    assert r.localisation == pytest.approx(18)
    assert r.distance == pytest.approx(math.sqrt(18))
    assert r.assignment.tolist() == [0, 1]


def test_gospa_order_one():
    # p = 1, c = 10: truth (0,0) with estimate (3,4) at distance 5, plus a far false
    # estimate: 5 + c/2 = 10.
    r = gospa([[0.0, 0.0]], [[3.0, 4.0], [500.0, 0.0]], c=10, p=1)
    assert r.localisation == pytest.approx(5) and r.false == pytest.approx(5)
    assert r.distance == pytest.approx(10)


def test_gospa_alpha_one_cardinality_term():
    # alpha = 1, p = 2, c = 10: one truth at (0,0), estimates (6,8) and (0,1).
    # Assign truth to (0,1): 1; one left over: c^p/alpha = 100. GOSPA = sqrt(101).
    r = gospa([[0.0, 0.0]], [[6.0, 8.0], [0.0, 1.0]], c=10, alpha=1)
    assert r.distance == pytest.approx(math.sqrt(101))
    assert r.false == pytest.approx(100)


def test_gospa_rejects_bad_input():
    with pytest.raises(ValueError, match="c = -1"):
        gospa(E, E, c=-1)
    with pytest.raises(ValueError, match=r"p = 0\.5"):
        gospa(E, E, c=1, p=0.5)
    with pytest.raises(ValueError, match="alpha = 3"):
        gospa(E, E, c=1, alpha=3)
    with pytest.raises(ValueError, match="x\\[0, 1\\] = nan"):
        gospa([[0.0, np.nan]], E, c=1)
    with pytest.raises(ValueError, match="dimension 3"):
        gospa([[0.0, 0.0]], [[0.0, 0.0, 0.0]], c=1)


# ------------------------------------------------------------------------------- GOSPA over time
def test_gospa_over_time_swap_between_two_scans():
    # Truth 0 at (0,0), truth 1 at (100,0); tracks 5 and 6 one metre off. Scan 0: 5 on
    # truth 0, 6 on truth 1. Scan 1: the tracks swap. Scan 2: they stay swapped.
    # Each scan: localisation 1 + 1 = 2. Scan 1: both truths change track -> 2 full
    # switches; with gamma = 4, p = 2 each costs gamma^p/2 = 8: switching 16.
    # Total = sqrt(2 + 2 + 2 + 16) = sqrt(22).
    tids = [np.array([0, 1])] * 3
    tpos = [np.array([[0.0, 0.0], [100.0, 0.0]])] * 3
    eids = [np.array([5, 6])] * 3
    epos = [
        np.array([[1.0, 0.0], [101.0, 0.0]]),
        np.array([[101.0, 0.0], [1.0, 0.0]]),
        np.array([[101.0, 0.0], [1.0, 0.0]]),
    ]
    r = gospa_over_time(tids, tpos, eids, epos, c=10, switch_penalty=4)
    assert r.localisation == pytest.approx([2, 2, 2])
    assert r.full_switches.tolist() == [0, 2, 0]
    assert r.half_switches.tolist() == [0, 0, 0]
    assert r.switching == pytest.approx([0, 16, 0])
    assert r.distance_with_switching == pytest.approx([math.sqrt(2), math.sqrt(18), math.sqrt(2)])
    assert r.total == pytest.approx(math.sqrt(22))
    assert [a.tolist() for a in r.assigned_track] == [[5, 6], [6, 5], [6, 5]]


def test_gospa_over_time_half_switches_and_late_start():
    # One truth (id 3) at (0,0) for 5 scans, c = 10, gamma = 2, p = 2.
    # scan 0: no track      -> missed 50; not charged (no track yet)
    # scan 1: track 9 at 1 m -> localisation 1; first assignment, no switch
    # scan 2: no track      -> missed 50; track -> none: half switch, cost gamma^2/4 = 1
    # scan 3: truth absent, track 4 at (50,0) -> false 50; no change for the truth
    # scan 4: track 4 at (0,2) -> localisation 4; none -> track: half switch, cost 1
    tids = [np.array([3]), np.array([3]), np.array([3]), np.array([], dtype=int), np.array([3])]
    tpos = [np.zeros((1, 2))] * 3 + [E, np.zeros((1, 2))]
    eids = [np.array([], dtype=int), np.array([9]), np.array([], dtype=int)]
    eids += [np.array([4]), np.array([4])]
    epos = [E, np.array([[1.0, 0.0]]), E, np.array([[50.0, 0.0]]), np.array([[0.0, 2.0]])]
    r = gospa_over_time(tids, tpos, eids, epos, c=10, switch_penalty=2)
    assert r.missed.tolist() == [50, 0, 50, 0, 0]
    assert r.false.tolist() == [0, 0, 0, 50, 0]
    assert r.localisation == pytest.approx([0, 1, 0, 0, 4])
    assert r.half_switches.tolist() == [0, 0, 1, 0, 1]
    assert r.full_switches.tolist() == [0, 0, 0, 0, 0]
    assert r.switching == pytest.approx([0, 0, 1, 0, 1])
    assert r.total == pytest.approx(math.sqrt(50 + 1 + 50 + 50 + 4 + 2))


def test_gospa_over_time_rejects_bad_ids():
    with pytest.raises(ValueError, match="must be unique"):
        gospa_over_time([np.array([1, 1])], [np.zeros((2, 2))], [E[:, 0]], [E], c=1)
    with pytest.raises(ValueError, match="track_pos: 0 scans"):
        gospa_over_time([np.array([1])], [np.zeros((1, 2))], [np.array([2])], [], c=1)
    with pytest.raises(ValueError, match="alpha = 1"):
        gospa_over_time([], [], [], [], c=1, alpha=1, switch_penalty=1)


# ----------------------------------------------------------------------------- OSPA hand-worked
def test_ospa_hand_worked():
    # Both empty: 0. One empty, other has 2 points: every point costs c -> OSPA = c.
    assert ospa(E, E, c=10).distance == 0
    assert ospa(E, [[0.0, 0.0], [1.0, 1.0]], c=10).distance == pytest.approx(10)
    # X = {(0,0)}, Y = {(3,4), (100,0)}, c = 10, p = 2: m = 2,
    # (1/2)(5^2 + 10^2) = 62.5 -> sqrt(62.5); loc = sqrt(12.5), card = sqrt(50).
    r = ospa([[0.0, 0.0]], [[3.0, 4.0], [100.0, 0.0]], c=10)
    assert r.distance == pytest.approx(math.sqrt(62.5))
    assert r.localisation == pytest.approx(math.sqrt(12.5))
    assert r.cardinality == pytest.approx(math.sqrt(50))
    # Same sets, p = 1: (5 + 10)/2 = 7.5.
    assert ospa([[0.0, 0.0]], [[3.0, 4.0], [100.0, 0.0]], c=10, p=1).distance == pytest.approx(7.5)


# -------------------------------------------------------------------- brute force and properties
coord = st.integers(min_value=-30, max_value=30).map(float)
point = st.tuples(coord, coord)
pset = st.lists(point, min_size=0, max_size=4).map(
    lambda v: np.array(v, dtype=float).reshape(-1, 2)
)


def _brute_gospa_p(x, y, c, p, alpha):
    """Definition 1 by enumeration of all injections of the smaller set into the larger."""
    if len(x) > len(y):
        x, y = y, x
    n, m = len(x), len(y)
    best = math.inf
    for perm in itertools.permutations(range(m), n):
        s = sum(min(float(np.linalg.norm(x[i] - y[j])), c) ** p for i, j in enumerate(perm))
        best = min(best, s)
    return best + c**p / alpha * (m - n)


@settings(max_examples=150, deadline=None)
@given(pset, pset, st.sampled_from([1.0, 2.0, 3.0]), st.sampled_from([0.5, 1.0, 2.0]))
def test_gospa_matches_brute_force(x, y, p, alpha):
    c = 12.0
    r = gospa(x, y, c=c, p=p, alpha=alpha)
    assert r.distance**p == pytest.approx(_brute_gospa_p(x, y, c, p, alpha), rel=1e-9, abs=1e-9)
    assert r.localisation + r.missed + r.false == pytest.approx(r.distance**p, abs=1e-9)


@settings(max_examples=150, deadline=None)
@given(pset, pset)
def test_gospa_symmetric_missed_false_swap_and_bound(x, y):
    c, p = 12.0, 2.0
    a, b = gospa(x, y, c=c, p=p), gospa(y, x, c=c, p=p)
    assert a.distance == pytest.approx(b.distance)
    assert (a.missed, a.false) == pytest.approx((b.false, b.missed))
    assert a.localisation == pytest.approx(b.localisation)
    # Each truth/estimate contributes at most c^p/2 when alpha = 2.
    assert a.distance**p <= c**p * (len(x) + len(y)) / 2 + 1e-9
    assert a.distance <= c * (len(x) + len(y)) ** (1 / p) + 1e-9


@settings(max_examples=150, deadline=None)
@given(pset, pset, st.randoms(use_true_random=False))
def test_gospa_zero_iff_identical(x, y, rnd):
    perm = list(range(len(x)))
    rnd.shuffle(perm)
    assert gospa(x, x[perm], c=12).distance == 0
    same = len(x) == len(y) and sorted(map(tuple, x)) == sorted(map(tuple, y))
    assert (gospa(x, y, c=12).distance == 0) == same


@settings(max_examples=200, deadline=None)
@given(pset, pset, pset)
def test_triangle_inequality(x, y, z):
    c = 12.0
    for p in (1.0, 2.0):
        assert ospa(x, z, c, p).distance <= (
            ospa(x, y, c, p).distance + ospa(y, z, c, p).distance + 1e-9
        )
        assert gospa(x, z, c, p).distance <= (
            gospa(x, y, c, p).distance + gospa(y, z, c, p).distance + 1e-9
        )


@settings(max_examples=150, deadline=None)
@given(pset, pset)
def test_ospa_range_and_symmetry(x, y):
    a, b = ospa(x, y, c=12), ospa(y, x, c=12)
    assert 0 <= a.distance <= 12 + 1e-12
    assert a.distance == pytest.approx(b.distance)
    assert a.distance**2 == pytest.approx(a.localisation**2 + a.cardinality**2)


# ----------------------------------------------- Stone Soup as an independent reference
def test_gospa_and_switches_agree_with_stone_soup():
    ss = pytest.importorskip("stonesoup.metricgenerator.ospametric")
    from stonesoup.types.array import StateVector
    from stonesoup.types.state import State

    rng = np.random.default_rng(7)
    t0 = datetime.datetime(2026, 1, 1)
    c, p, gamma = 15.0, 2.0, 3.0
    gen = ss.GOSPAMetric(c=c, p=p, switching_penalty=gamma)
    ospa_gen = ss.OSPAMetric(c=c, p=p)
    # 12 scans, 4 truths on a line, 0-5 tracks near random truths (ids drawn from 0..6 so
    # track ids recur and switch).
    tids, tpos, eids, epos = [], [], [], []
    truth_states, truth_ids, track_states, track_ids = [], [], [], []
    for k in range(12):
        ts = t0 + datetime.timedelta(seconds=k)
        present = np.flatnonzero(rng.random(4) < 0.85)
        xt = np.column_stack([present * 20.0 + k, np.zeros(len(present))])
        m = int(rng.integers(0, 6))
        ids = rng.choice(7, size=m, replace=False)
        xe = rng.uniform(-5, 80, size=(m, 2))
        tids.append(present), tpos.append(xt), eids.append(ids), epos.append(xe)
        for i, pos in zip(present, xt):
            truth_states.append(State(StateVector(pos), timestamp=ts))
            truth_ids.append(int(i))
        for i, pos in zip(ids, xe):
            track_states.append(State(StateVector(pos), timestamp=ts))
            track_ids.append(int(i))
        mine = gospa(xt, xe, c=c, p=p)
        ref, _ = gen.compute_gospa_metric(
            [State(StateVector(v), timestamp=ts) for v in xe],
            [State(StateVector(v), timestamp=ts) for v in xt],
        )
        assert mine.distance == pytest.approx(ref.value["distance"])
        assert mine.localisation == pytest.approx(ref.value["localisation"])
        assert mine.missed == pytest.approx(ref.value["missed"])
        assert mine.false == pytest.approx(ref.value["false"])
        ref_ospa = ospa_gen.compute_OSPA_distance(
            [State(StateVector(v), timestamp=ts) for v in xe],
            [State(StateVector(v), timestamp=ts) for v in xt],
        )
        assert ospa(xt, xe, c=c, p=p).distance == pytest.approx(ref_ospa.value)
    mine_t = gospa_over_time(tids, tpos, eids, epos, c=c, p=p, switch_penalty=gamma)
    ref_t = gen.compute_over_time(track_states, track_ids, truth_states, truth_ids)
    ref_counts = [(m.value["switching"] / gamma) ** p for m in ref_t.value]
    # Stone Soup counts s = full + half/2 per scan and reports gamma * s^(1/p).
    assert mine_t.full_switches + 0.5 * mine_t.half_switches == pytest.approx(ref_counts)
    assert sum(ref_counts) > 0  # the scripted sequence does contain switches
