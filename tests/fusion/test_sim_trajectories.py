"""Trajectory segments against independent references: numerical ODE integration,
circle geometry of a g-load turn, waypoint geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from skyfuse.fusion.sim.trajectories import G0, TargetSet, TrajectoryBuilder, propagate


def _ode(omega, acc):
    def f(_t, s):
        _, _, _, vx, vy, vz = s
        return [vx, vy, vz, -omega * vy + acc[0], omega * vx + acc[1], acc[2]]

    return f


@pytest.mark.parametrize(
    ("omega", "acc"),
    [
        (0.0, (0, 0, 0)),
        (0.12, (0, 0, 0)),
        (-0.03, (0, 0, 0)),
        (0.0, (0.7, -0.4, 0.1)),
        (1e-9, (0, 0, 0)),
    ],
)
def test_propagate_matches_numerical_integration(omega, acc):
    p0 = np.array([100.0, -50.0, 3000.0])
    v0 = np.array([200.0, 35.0, -5.0])
    tau = 23.0
    sol = solve_ivp(_ode(omega, acc), (0, tau), [*p0, *v0], rtol=1e-11, atol=1e-9)
    p, v = propagate(p0, v0, omega, np.array(acc, float), tau)
    np.testing.assert_allclose(p, sol.y[:3, -1], atol=1e-4)
    np.testing.assert_allclose(v, sol.y[3:, -1], atol=1e-6)


def test_turn_by_g_load_is_a_circle_of_radius_v2_over_a():
    v, g = 250.0, 2.0
    b = TrajectoryBuilder(0.0, (0, 0, 1000), (v, 0, 0)).turn_by(math.pi, g_load=g)
    ts = TargetSet.from_builders([b])
    t = np.linspace(0, b.t, 50)
    p, vel = ts.state(t, 0)
    r = v * v / (g * G0)
    # left turn from heading east: centre is r to the north of the start
    np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 1] - r), r, rtol=1e-9)
    np.testing.assert_allclose(np.hypot(vel[:, 0], vel[:, 1]), v, rtol=1e-12)
    np.testing.assert_allclose(b.v[:2], [-v, 0.0], atol=1e-9)  # half circle: heading west
    np.testing.assert_allclose(b.t, math.pi * r / v)


@pytest.mark.parametrize("wp", [(30_000.0, 20_000.0), (-5_000.0, 40_000.0), (10_000.0, -25_000.0)])
def test_fly_to_passes_through_the_waypoint_at_the_altitude(wp):
    b = TrajectoryBuilder(0.0, (0, 0, 5000), (180.0, 60.0, 0.0))
    assert b.fly_to(*wp, 7000.0, g_load=0.8, max_climb_rate=50.0)
    np.testing.assert_allclose(b.p, [wp[0], wp[1], 7000.0], atol=1e-6)
    ts = TargetSet.from_builders([b])
    t = np.linspace(0, b.t, 4000)
    p, v = ts.state(t, 0)
    # the last straight leg points at the waypoint
    to_wp = np.array(wp) - p[-200, :2]
    cosang = np.dot(to_wp, v[-200, :2]) / (np.linalg.norm(to_wp) * np.linalg.norm(v[-200, :2]))
    assert cosang > 1 - 1e-12
    # lateral acceleration never exceeds the g-load
    acc = np.diff(v[:, :2], axis=0) / np.diff(t)[:, None]
    assert np.hypot(acc[:, 0], acc[:, 1]).max() <= 0.8 * G0 * (1 + 1e-3)


def test_fly_to_limits_the_climb_rate_and_rejects_unreachable_waypoints():
    b = TrajectoryBuilder(0.0, (0, 0, 1000), (200.0, 0.0, 0.0))
    assert b.fly_to(20_000.0, 0.0, 11_000.0, g_load=1.0, max_climb_rate=10.0)
    assert b.p[2] == pytest.approx(1000.0 + 10.0 * 100.0)
    r = 200.0**2 / G0
    before = len(b.segments)
    assert not b.fly_to(b.p[0], b.p[1] + 1.5 * r, 1000.0, g_load=1.0, max_climb_rate=10.0)
    assert len(b.segments) == before


def test_segments_join_continuously_and_birth_death_mask():
    b = (
        TrajectoryBuilder(5.0, (0, 0, 100), (30, 0, 2))
        .straight(10)
        .turn(6, 0.2)
        .accelerate(4, (1, 2, 0))
    )
    ts = TargetSet.from_builders([b], t_birth=[5.0], t_death=[25.0])
    for tb in (15.0, 21.0):
        p1, v1 = ts.state(np.array([tb - 1e-9]), 0)
        p2, v2 = ts.state(np.array([tb]), 0)
        np.testing.assert_allclose(p1, p2, atol=1e-6)
        np.testing.assert_allclose(v1, v2, atol=1e-6)
    alive = ts.alive(np.array([4.9, 5.0, 24.9, 25.0]), 0)
    assert alive.tolist() == [False, True, True, False]
    with pytest.raises(ValueError, match="duration"):
        b.straight(-1)
