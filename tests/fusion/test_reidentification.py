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
