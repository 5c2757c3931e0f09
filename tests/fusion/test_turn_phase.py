"""Turn / straight split of truth samples (fusion.metrics.turn_phase) against closed forms."""

import numpy as np
from skyfuse.fusion.metrics.turn_phase import in_turn, phase_rmse, turn_rate


def test_turn_rate_of_a_coordinated_turn_is_its_omega():
    # v(t) = s (cos ωt, sin ωt): heading changes by ω per second, any speed, any sign
    for omega in (0.05, -0.1, np.radians(3.0)):
        t = np.arange(0.0, 20.0, 4.0)
        v = 180.0 * np.column_stack([np.cos(omega * t), np.sin(omega * t)])
        w = turn_rate(v[:-1], v[1:], np.diff(t))
        np.testing.assert_allclose(w, omega, rtol=1e-12)


def test_straight_flight_and_speed_change_are_not_turns():
    v0 = np.array([[200.0, 50.0], [200.0, 50.0]])
    v1 = np.array([[200.0, 50.0], [240.0, 60.0]])  # same heading, faster
    w = turn_rate(v0, v1, np.array([4.0, 4.0]))
    np.testing.assert_allclose(w, 0.0, atol=1e-15)
    assert not in_turn(w).any()


def test_threshold_unknown_and_zero_dt():
    w = turn_rate([[100.0, 0.0], [0.0, 0.0]], [[0.0, 100.0], [1.0, 0.0]], [0.0, 1.0])
    assert np.isnan(w).all()  # dt = 0, zero velocity
    assert not in_turn(w).any()
    deg = np.radians([0.4, 0.5, -0.6, 3.0])
    np.testing.assert_array_equal(in_turn(deg), [False, True, True, True])


def test_phase_rmse_splits_by_flag():
    sq = np.array([9.0, 16.0, 1.0, 1.0, 4.0])
    res = phase_rmse(sq, np.array([True, True, False, False, False]))
    assert res["turn"] == {"samples": 2, "rmse_m": np.sqrt(12.5)}
    assert res["straight"] == {"samples": 3, "rmse_m": np.sqrt(2.0)}
    assert phase_rmse(sq, np.zeros(5, bool))["turn"]["rmse_m"] is None
