"""The surface-movement motion ``imm-surface`` and its stopped mode (damped velocity).

References: the damped-velocity model's F and Q against the exact response of
ṗ = v, v̇ = −βv + a (a held over T) by matrix exponential and numerical integration
(scipy); the stopped mode's steady-state covariance against the discrete algebraic
Riccati equation (scipy); the mode probabilities and the estimate on a simulated
taxi-stop-taxi trajectory with a tight turn (truth integrated here), against the
default ``imm-cv-ct`` on the same plots. Snapshots: ``tests/fusion/test_density_protocol.py``.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm, solve_discrete_are
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.models.damped_velocity import DampedVelocity
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig
from skyfuse.fusion.tracker.density.surface_motion import MODES
from skyfuse.fusion.tracker.registry import make_density

NS = 10**9


@pytest.mark.parametrize("beta,T", [(1.0, 1.0), (0.3, 4.0), (2.0, 0.5), (1e-5, 4.0), (5.0, 12.0)])
def test_damped_velocity_F_and_Q_are_the_exact_response(beta, T):
    q = 0.7
    A = np.array([[0.0, 1.0], [0.0, -beta]])
    gamma, _ = quad_vec(lambda s: expm(A * s) @ np.array([0.0, 1.0]), 0.0, T, epsabs=1e-13)
    model = DampedVelocity(q=q, ndim=1, damping=beta)
    np.testing.assert_allclose(model.F(T), expm(A * T), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(model.Q(T), q * np.outer(gamma, gamma), rtol=1e-8, atol=1e-13)


def test_damped_velocity_predicts_as_F_and_Q_and_tends_to_cv():
    rng = np.random.default_rng(1)
    m = DampedVelocity(q=0.5, ndim=3, q_vertical=0.1, damping=0.8)
    x = rng.normal(0, 10, (4, 6))
    L = rng.normal(0, 3, (4, 6, 6))
    P = L @ L.swapaxes(1, 2)
    t = np.array([0.5, 1.0, 4.0, 1e-6])
    xp, Pp = m.predict(x, P, t)
    F, Q = m.F(t), m.Q(t)
    np.testing.assert_allclose(xp, np.einsum("nij,nj->ni", F, x), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Pp, F @ P @ F.swapaxes(1, 2) + Q, rtol=1e-10, atol=1e-10)
    cv, still = ConstantVelocity(q=0.5, ndim=2), DampedVelocity(q=0.5, ndim=2, damping=1e-9)
    np.testing.assert_allclose(still.F(3.0), cv.F(3.0), rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(still.Q(3.0), cv.Q(3.0), rtol=1e-8, atol=1e-8)
    with pytest.raises(ValueError, match="damping"):
        DampedVelocity(damping=-1.0)


def test_stopped_mode_steady_state_covariance_is_the_riccati_solution():
    """``imm-surface`` held in its stopped mode (Π = I, μ₀ = (0, 1, 0)) fed a plot every
    T: the track's posterior covariance tends to the steady state of the stopped mode's
    Kalman filter, P = P⁻ − P⁻Hᵀ(HP⁻Hᵀ + R)⁻¹HP⁻, P⁻ the solution of the discrete
    algebraic Riccati equation."""
    T, sigma = 1.0, 7.0
    cfg = TrackerConfig(
        tracker="gnn", motion="imm-surface", initiation="none", reach_gate=False,
        imm_tpm_period=T, surface_tpm=np.eye(3).ravel().tolist(), surface_mu0=[0.0, 1.0, 0.0],
    )  # fmt: skip
    tr = Tracker(cfg)
    stopped = tr.density.models[MODES.index("stopped")]
    assert isinstance(stopped, DampedVelocity)
    R = sigma**2 * np.eye(2)
    tid = tr.add_track(np.zeros(4), np.diag([100.0, 4.0] * 2), 0, existence=0.99, confirmed=True)
    z = np.zeros((1, 2))  # the covariance does not depend on the plots' values
    for k in range(1, 700):  # the filter's P is within 10⁻⁸ of the steady state
        out = tr.step(MeasurementBatch(k * NS, "r", z, R, 1.0, 1e-12))
    P = out.covariances[list(out.ids).index(tid)]
    F, Q, H = stopped.F(T), stopped.Q(T), stopped.H()
    Pm = solve_discrete_are(F.T, H.T, Q, R)
    Pss = Pm - Pm @ H.T @ np.linalg.solve(H @ Pm @ H.T + R, H @ Pm)
    np.testing.assert_allclose(P, Pss, rtol=1e-6, atol=1e-9)
    # what the mode is for: a parked target's position known far better than one plot's
    assert math.sqrt(P[0, 0]) < 0.35 * sigma


def _taxi(rng, sigma=6.0):
    """A taxiing aircraft, 1 s plots (σ = 6 m): 40 s east at 10 m/s, a 90° left turn of
    radius 40 m (0.25 rad/s), 20 s north, braking to a stop (2 m/s²), 120 s stopped,
    accelerating (1 m/s²) to 10 m/s north. Returns times (s), truths (n, 2), plots
    (n, 2) and the phase of each scan."""
    dt = 0.01
    p, heading, v = np.zeros(2), 0.0, 10.0
    t_turn = (math.pi / 2) / 0.25
    times, truth, phase = [], [], []
    t, stop_start, stop_end = 0.0, None, None
    for k in range(1, 280):
        while t < k - 1e-9:
            if 40 <= t < 40 + t_turn:
                heading += 0.25 * dt
            elif t >= 60 + t_turn and stop_start is None:
                v = max(v - 2.0 * dt, 0.0)
                if v == 0.0:
                    stop_start = t
            elif stop_start is not None and t >= stop_start + 120:
                stop_end = stop_end or t
                v = min(v + 1.0 * dt, 10.0)
            p = p + v * dt * np.array([math.cos(heading), math.sin(heading)])
            t += dt
        times.append(float(k))
        truth.append(p.copy())
        stopped = stop_start is not None and stop_end is None and v == 0.0
        phase.append("turn" if 40 <= k < 40 + t_turn else "stopped" if stopped else "moving")
    truth = np.array(truth)
    return np.array(times), truth, truth + rng.normal(0, sigma, truth.shape), np.array(phase)


def _run(motion, times, plots, sigma=6.0):
    """Track the plots with one confirmed track started on the first two plots; the
    estimates (n, 2) and the stopped-mode probabilities (n,) (NaN for other motions)."""
    cfg = TrackerConfig(tracker="gnn", motion=motion, initiation="none")
    tr = Tracker(cfg)
    v0 = plots[1] - plots[0]
    x0 = np.array([plots[1][0], v0[0], plots[1][1], v0[1]])
    tid = tr.add_track(x0, np.diag([sigma**2, 2 * sigma**2] * 2), NS, existence=0.99,
                       confirmed=True)  # fmt: skip
    R = sigma**2 * np.eye(2)
    est, mu_stop = [], []
    for t, z in zip(times[2:], plots[2:]):
        out = tr.step(MeasurementBatch(round(t * NS), "r", z[None], R, 0.95, 1e-9))
        i = list(out.ids).index(tid)  # the one track lives throughout
        est.append(out.states[i, 0::2])
        one = np.array([0])  # the only track's row
        mu = tr.density.mode_probabilities(one)[0] if motion == "imm-surface" else [math.nan] * 3
        mu_stop.append(mu[MODES.index("stopped")])
    return np.array(est), np.array(mu_stop)


def test_mode_probabilities_follow_a_stop_and_the_estimate_of_a_parked_target_is_better():
    rng = np.random.default_rng(5)
    times, truth, plots, phase = _taxi(rng)
    est, mu_stop = _run("imm-surface", times, plots)
    ref, _ = _run("imm-cv-ct", times, plots)
    truth, phase = truth[2:], phase[2:]
    stop = np.flatnonzero(phase == "stopped")
    moving = np.flatnonzero(phase != "stopped")
    settled = stop[stop >= stop[0] + 10]  # 10 s after the stop
    assert np.mean(mu_stop[settled]) > 0.85  # the ceiling of surface_tpm: ≈ 0.92
    after = moving[moving > stop[-1] + 8]  # 8 s after it starts again (≈ 32 m moved)
    assert np.mean(mu_stop[after]) < 0.1
    taxi = moving[(moving > 10) & (moving < stop[0] - 8)]
    assert np.mean(mu_stop[taxi]) < 0.1
    err = np.linalg.norm(est - truth, axis=1)
    err_ref = np.linalg.norm(ref - truth, axis=1)
    rms = lambda e, idx: math.sqrt(np.mean(e[idx] ** 2))  # noqa: E731
    still, still_ref = rms(err, settled), rms(err_ref, settled)
    assert still < 0.7 * still_ref, (still, still_ref)
    turn = np.flatnonzero(phase == "turn")
    assert len(settled) > 100 and len(after) > 60 and len(taxi) > 20 and len(turn) > 5
    assert rms(err, turn) < 1.2 * rms(err_ref, turn), (rms(err, turn), rms(err_ref, turn))


def test_surface_settings_load_from_toml_and_bad_ones_are_refused():
    doc = tomllib.loads(
        'motion = "imm-surface"\nsurface_stop_damping = 0.5\nsurface_mu0 = [0.6, 0.3, 0.1]\n'
    )
    cfg = TrackerConfig(**doc)
    models = make_density(cfg).models
    assert models[MODES.index("stopped")].damping == 0.5
    assert make_density(cfg).mu0 == pytest.approx([0.6, 0.3, 0.1])
    with pytest.raises(ValueError, match="surface_tpm"):
        TrackerConfig(motion="imm-surface", surface_tpm=[0.5, 0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="row-stochastic"):
        make_density(TrackerConfig(motion="imm-surface", surface_tpm=[0.5] * 9))
