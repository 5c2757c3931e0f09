"""Re-identification of terminated tracks (fusion/tracker/reidentification.py, R1-R3).

References are independent: the continuous white-noise acceleration covariance by
numerical integration of e^{Aτ} G Gᵀ e^{Aᵀτ}, the gate distance by a scalar loop, and
a tracker run where one aircraft is lost for 60 s.
"""

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import chi2
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.fusion.tracker import Tracker, TrackerConfig
from skyfuse.fusion.tracker.measurements import MeasurementBatch
from skyfuse.fusion.tracker.reidentification import (
    TerminatedTracks,
    white_noise_acceleration_q,
)

S = 1_000_000_000


def test_white_noise_q_is_the_integral_of_the_continuous_model():
    q, T = 3.0, 37.0
    Q = white_noise_acceleration_q(np.array([T]), q, 2)[0]
    # Q = ∫₀ᵀ Φ(τ) [0, 1]ᵀ q [0, 1] Φ(τ)ᵀ dτ with Φ(τ) = [[1, τ], [0, 1]]
    ref = np.array(
        [
            [quad(lambda s: q * s * s, 0, T)[0], quad(lambda s: q * s, 0, T)[0]],
            [quad(lambda s: q * s, 0, T)[0], quad(lambda s: q, 0, T)[0]],
        ]
    )
    np.testing.assert_allclose(Q[:2, :2], ref, rtol=1e-12)
    np.testing.assert_allclose(Q[2:, 2:], ref, rtol=1e-12)
    assert np.all(Q[:2, 2:] == 0)


def _store(max_gap=180.0, q=4.0):
    return TerminatedTracks(ConstantVelocity(q=25.0), max_gap, q=q, p_gate=0.99)


def test_distance_matches_a_hand_computed_prediction():
    st = _store()
    x0 = np.array([1000.0, 200.0, -500.0, 10.0])
    P0 = np.diag([50.0**2, 5.0**2, 60.0**2, 4.0**2])
    st.add(np.array([7]), x0[None], P0[None], np.array([10 * S]))
    dt = 90.0
    xn = np.array([1000.0 + 200 * dt + 800.0, 203.0, -500.0 + 10 * dt - 300.0, 8.0])
    Pn = np.diag([70.0**2, 10.0**2, 70.0**2, 10.0**2])
    d2 = st.distances(xn[None], Pn[None], np.array([100 * S]), np.array([95 * S]))[0, 0]
    # per axis by hand: predicted variance blocks of [[1, dt], [0, 1]] P [[1, 0], [dt, 1]]
    # + q [[dt³/3, dt²/2], [dt²/2, dt]]; axes independent
    ref = 0.0
    for a, (p, v) in enumerate([(50.0, 5.0), (60.0, 4.0)]):
        pp = p**2 + dt**2 * v**2 + 4.0 * dt**3 / 3
        pv = dt * v**2 + 4.0 * dt**2 / 2
        vv = v**2 + 4.0 * dt
        S2 = np.array([[pp + 70.0**2, pv], [pv, vv + 10.0**2]])
        e = xn[2 * a : 2 * a + 2] - np.array([x0[2 * a] + dt * x0[2 * a + 1], x0[2 * a + 1]])
        ref += e @ np.linalg.solve(S2, e)
    assert d2 == pytest.approx(ref, rel=1e-10)


def test_ambiguous_or_early_candidates_are_not_matched():
    st = _store()
    P = np.diag([100.0**2, 5.0**2, 100.0**2, 5.0**2])[None].repeat(2, 0)
    x_old = np.array([[0.0, 200.0, 0.0, 0.0], [0.0, 200.0, 300.0, 0.0]])
    st.add(np.array([1, 2]), x_old, P, np.array([0, 0]))
    x_new = np.array([[200.0 * 60, 200.0, 150.0, 0.0]])
    # both old tracks gate the new one (300 m apart, σ ≈ 0.5 km): ambiguous, no match
    got = st.match(x_new, P[:1], np.array([60 * S]), np.array([50 * S]))
    assert got.tolist() == [-1]
    # only one old track left: matched; a track started before its last fix never is
    st.rows.keep(np.array([True, False]))
    assert st.match(x_new, P[:1], np.array([60 * S]), np.array([-1 * S])).tolist() == [-1]
    assert st.match(x_new, P[:1], np.array([60 * S]), np.array([50 * S])).tolist() == [0]
    assert st.take(np.array([0])).tolist() == [1] and len(st) == 0


def test_gate_threshold_and_uninformative_fixes():
    st = _store()
    assert st.gate == pytest.approx(chi2.ppf(0.99, 4))
    P_bad = np.diag([100.0**2, 300.0**2, 100.0**2, 300.0**2])  # a coasting guess
    st.add(np.array([3]), np.zeros((1, 4)), P_bad[None], np.array([0]))
    d2 = st.distances(np.zeros((1, 4)), np.eye(4)[None], np.array([30 * S]), np.array([0]))
    assert np.isinf(d2[0, 0])  # σ of the prediction ≈ 9 km > max_sigma
    st.add(np.array([4]), np.zeros((1, 4)), np.eye(4)[None], np.array([0]))
    st.expire(181 * S)
    assert len(st) == 0


def _batch(t_s, z):
    z = np.asarray(z, float).reshape(-1, 2)
    R = np.repeat((30.0**2 * np.eye(2))[None], len(z), 0)
    return MeasurementBatch(
        time_ns=int(t_s * S), radar_id="R", z=z, R=R, p_detection=0.9, clutter_density=1e-10
    )


@pytest.mark.parametrize("reid", [True, False])
def test_an_aircraft_lost_for_60_s_keeps_its_id(reid):
    cfg = TrackerConfig(motion="cv", reid_max_gap=180.0 if reid else None, max_coast=20.0)
    trk = Tracker(cfg)
    v = np.array([150.0, 40.0])
    ids = {}
    for k in range(60):
        t = 4.0 * k
        if 10 <= k < 25:  # 60 s without plots
            out = trk.step(_batch(t, np.zeros((0, 2))))
            continue
        out = trk.step(_batch(t, v * t))
        conf = out.ids[out.confirmed]
        if len(conf):
            ids.setdefault("before" if k < 10 else "after", set()).update(conf.tolist())
    assert len(ids["before"]) == 1 and len(ids["after"]) == 1
    assert (ids["before"] == ids["after"]) is reid
    assert trk.totals.get("reidentified", 0) == (1 if reid else 0)


def test_a_weak_fix_does_not_replace_a_good_one():
    from skyfuse.fusion.tracker.reidentification import FIX_HORIZON, keeps_fix

    q, H = 4.0, FIX_HORIZON
    good = np.diag([50.0**2, 5.0**2, 50.0**2, 5.0**2])[None]

    def pos_var(p, v, dt):  # by hand, per axis: p² + dt² v² + q dt³/3
        return p**2 + dt**2 * v**2 + q * dt**3 / 3

    old = pos_var(50.0, 5.0, 20.0 + H)
    for p_new, v_new in [(60.0, 250.0), (40.0, 4.0), (300.0, 5.0)]:
        new = np.diag([p_new**2, v_new**2, p_new**2, v_new**2])[None]
        got = keeps_fix(good, np.array([0]), new, np.array([20 * S]), q)
        assert got.tolist() == [old < pos_var(p_new, v_new, H)]
    # the weak post-coast estimate (velocity σ 250 m/s) keeps the old fix, a good new
    # one replaces it
    weak = np.diag([60.0**2, 250.0**2, 60.0**2, 250.0**2])[None]
    sharp = np.diag([40.0**2, 4.0**2, 40.0**2, 4.0**2])[None]
    assert keeps_fix(good, np.array([0]), weak, np.array([20 * S]), q).tolist() == [True]
    assert keeps_fix(good, np.array([0]), sharp, np.array([20 * S]), q).tolist() == [False]


@pytest.mark.parametrize("ndim", [2, 3])
def test_predicted_position_variances_are_the_diagonal_of_the_matrix_prediction(ndim):
    from skyfuse.fusion.tracker.reidentification import predicted_position_variances

    rng = np.random.default_rng(ndim)
    d, q = 2 * ndim, 4.0
    A = rng.normal(size=(7, d, d)) * np.array([300.0, 20.0] * ndim)
    P = A @ np.swapaxes(A, 1, 2)  # full SPD covariances, cross-axis terms included
    dt = rng.uniform(0.0, 200.0, 7)
    model = ConstantVelocity(q=25.0, ndim=ndim)
    F = model.F(dt)
    full = F @ P @ np.swapaxes(F, 1, 2) + white_noise_acceleration_q(dt, q, ndim)
    ref = full[:, list(model.position_index), list(model.position_index)]
    np.testing.assert_allclose(predicted_position_variances(P, dt, q), ref, rtol=1e-12)


def test_still_aircraft_are_not_reidentified():
    st = _store()
    P = np.diag([20.0**2, 2.0**2, 20.0**2, 2.0**2])[None]
    # a taxiing aircraft (10 m/s) lost, a parked one (0 m/s) 100 m further: kinematically
    # consistent (d² small) but below min_speed = 15 m/s, so never joined
    st.add(np.array([5]), np.array([[0.0, 10.0, 0.0, 0.0]]), P, np.array([0]))
    new = np.array([[300.0, 0.0, 0.0, 0.0]])
    assert st.min_speed == 15.0
    assert np.isinf(st.distances(new, P, np.array([20 * S]), np.array([10 * S]))).all()
    fast = TerminatedTracks(ConstantVelocity(q=25.0), 180.0, q=4.0, min_speed=0.0)
    fast.add(np.array([5]), np.array([[0.0, 10.0, 0.0, 0.0]]), P, np.array([0]))
    assert np.isfinite(fast.distances(new, P, np.array([20 * S]), np.array([10 * S]))).all()


def test_a_live_fix_is_predicted_with_its_own_q():
    from skyfuse.fusion.tracker.reidentification import fix_distances

    st = _store()
    x0 = np.array([0.0, 100.0, 0.0, 0.0])
    P0 = np.diag([10.0**2, 4.0**2, 10.0**2, 4.0**2])
    dt, q_live = 5.0, 600.0
    xn = np.array([100.0 * dt + 120.0, 110.0, -90.0, -25.0])
    Pn = np.diag([15.0**2, 8.0**2, 15.0**2, 8.0**2])
    ok = np.ones((1, 1), bool)
    args = (xn[None], Pn[None], np.array([int(dt * S)]), x0[None], P0[None], np.array([0]), ok)
    ref = {}
    for q in (4.0, q_live):  # by hand, axis by axis as in the test above
        d2 = 0.0
        for a in range(2):
            p, v = np.sqrt(P0[2 * a, 2 * a]), np.sqrt(P0[2 * a + 1, 2 * a + 1])
            pp = p**2 + dt**2 * v**2 + q * dt**3 / 3 + Pn[2 * a, 2 * a]
            pv = dt * v**2 + q * dt**2 / 2
            vv = v**2 + q * dt + Pn[2 * a + 1, 2 * a + 1]
            e = xn[2 * a : 2 * a + 2] - np.array([x0[2 * a] + dt * x0[2 * a + 1], x0[2 * a + 1]])
            d2 += e @ np.linalg.solve(np.array([[pp, pv], [pv, vv]]), e)
        ref[q] = d2
    assert fix_distances(st, *args)[0, 0] == pytest.approx(ref[4.0], rel=1e-10)
    assert fix_distances(st, *args, q=q_live)[0, 0] == pytest.approx(ref[q_live], rel=1e-10)
    # 120 m and 25 m/s off after 5 s: outside the terminated-track gate, inside the live one
    assert ref[4.0] > st.gate > ref[q_live]


def _mlat(t_s, z, pd=0.7, sigma=10.0):
    z = np.asarray(z, float).reshape(-1, 2)
    R = np.repeat((sigma**2 * np.eye(2))[None], len(z), 0)
    return MeasurementBatch(
        time_ns=int(t_s * S), radar_id="M", z=z, R=R, p_detection=pd, clutter_density=1e-10
    )


def _replay(trk, plots_at, steps):
    """Run ``trk`` over ``steps`` 1-s batches of ``plots_at(k)``; the confirmed ids seen,
    the events, and a consumer's picture rebuilt from the events alone (an id confirmed
    while the picture holds it is recorded as a clash)."""
    seen, events, alive, clashes = set(), [], set(), []
    for k in range(steps):
        out = trk.step(_mlat(float(k), plots_at(k)))
        assert len(np.unique(out.ids)) == len(out.ids)  # one row per id in every output
        seen |= set(out.ids[out.confirmed].tolist())
        for e in out.events:
            events.append((k, e.kind, e.track_id, e.reason))
            if e.kind == "confirmed":
                if e.track_id in alive:
                    clashes.append((k, e.track_id))
                alive.add(e.track_id)
            elif e.kind in ("terminated", "merged"):
                alive.discard(e.track_id)
        assert alive == set(out.ids[out.confirmed].tolist())
    return seen, events, clashes


@pytest.mark.parametrize("live", [True, False])
def test_a_track_continued_while_it_coasts_keeps_its_id(live):
    # one aircraft at 150 m/s, unseen for 4 s while it turns (velocity +(-30, 30) m/s):
    # its plots then lie outside the coasting track's gate and start a new track before
    # the old one ends. One aircraft: one id when the live take-over is on.
    trk = Tracker(TrackerConfig(reid_live_gap=10.0 if live else None))
    v0, v1 = np.array([150.0, 0.0]), np.array([120.0, 30.0])

    def plots_at(k):
        if 20 <= k < 24:
            return np.zeros((0, 2))
        return v0 * min(k, 19) + v1 * max(k - 19, 0)

    seen, events, clashes = _replay(trk, plots_at, 60)
    assert clashes == []
    assert len(seen) == (1 if live else 2)
    assert trk.totals.get("taken_over", 0) == (1 if live else 0)
    if live:
        (tid,) = seen
        kinds = [(e[1], e[2]) for e in events]
        # the old track's end comes before its id's confirmation on the new track
        assert kinds == [("confirmed", tid), ("terminated", tid), ("confirmed", tid)]
        assert events[1][0] == events[2][0]
        assert events[1][3].startswith("continued by tentative id")
        assert events[2][3].startswith("re-identified (tentative id")


@pytest.mark.parametrize("offset", [(-60.0, 0.0), (0.0, 50.0)], ids=["in-line", "side-by-side"])
def test_two_aircraft_close_together_keep_two_ids(offset):
    # two aircraft at 20 m/s (above reid_min_speed: kinematics alone would not keep them
    # apart), 60 m in line or 50 m side by side; the second is first seen at 10 s while
    # the first keeps being detected, so it never continues the first (L1)
    trk = Tracker(TrackerConfig())
    v = np.array([20.0, 0.0])

    def plots_at(k):
        lead = v * k
        return lead[None] if k < 10 else np.array([lead, lead + np.array(offset)])

    seen, _, clashes = _replay(trk, plots_at, 40)
    assert clashes == [] and len(seen) == 2
    assert trk.totals.get("taken_over", 0) == 0
    out = trk.step(_mlat(40.0, np.array([v * 40, v * 40 + np.array(offset)])))
    assert out.confirmed.sum() == 2


@pytest.mark.parametrize("level", [0.1, 1.0])
def test_a_track_that_only_missed_a_few_scans_is_not_continued_by_a_neighbour(level):
    # two aircraft side by side, 100 m apart at 150 m/s; the second is first seen at 10 s
    # while the first misses three scans (P_D 0.7): kinematically the second's new track
    # continues the first (d² ≈ 1 with reid_live_q), but the first keeps ψ ≈ 0.97 (L3)
    trk = Tracker(TrackerConfig(reid_live_existence=level))
    v, side = np.array([150.0, 0.0]), np.array([0.0, 100.0])

    def plots_at(k):
        first = v * k
        if k < 10:
            return first[None]
        return (first + side)[None] if k < 13 else np.array([first, first + side])

    seen, events, clashes = _replay(trk, plots_at, 30)
    assert clashes == []
    first_id = events[0][2]
    out = trk.step(_mlat(30.0, np.array([v * 30, v * 30 + side])))
    xy = out.states[:, [0, 2]]
    on_first = out.ids[np.argmin(np.hypot(*(xy - v * 30).T))]
    # with (L3) the first aircraft keeps its id throughout; without it, its id goes to
    # the second aircraft's track and it gets a new one: the join (L3) prevents
    assert bool(on_first == first_id) == (level < 1)
    assert trk.totals.get("taken_over", 0) == (0 if level < 1 else 1)
    assert len(seen) == 2
