"""Batched filters: batch == loop of single tracks, NEES consistency on matched models
(Monte Carlo, chi-square bounds), the converted KF against the Kalman primitives, azimuth
wrap-around of the polar EKF. (The IMM is the track density's: tests/fusion/
test_imm_interaction.py, test_source_motions.py, test_tracker_imm.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.filters import (
    ConvertedMeasurementKF,
    GaussianState,
    PolarEKF,
    kalman,
    wrap_angle,
)
from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn, Singer


def _spd(rng, n, d, scale=1.0):
    A = rng.normal(size=(n, d, d))
    return (A @ np.swapaxes(A, -1, -2) + d * np.eye(d)) * scale


@pytest.mark.parametrize(
    "make",
    [
        lambda: ConvertedMeasurementKF(ConstantVelocity(q=4.0)),
        lambda: ConvertedMeasurementKF(Singer(10.0, 20.0)),
        lambda: ConvertedMeasurementKF(CoordinatedTurn(2.0, 0.02)),
        lambda: PolarEKF(ConstantVelocity(q=4.0, ndim=3), [100.0, -50.0, 10.0], ndim=3),
    ],
)
def test_batched_filter_equals_a_loop_of_single_track_filters(make):
    f = make()
    rng = np.random.default_rng(1)
    n, d = 6, f.dim
    x = rng.normal(0, 1000, (n, d))
    if f.labels[2] == "psi":
        x[:, 2] = rng.uniform(-3, 3, n)
        x[:, 3] = rng.uniform(-0.1, 0.1, n)
        x[:, 4] = rng.uniform(100, 300, n)
    x[:, list(f.model.position_index)] += 20_000
    P = _spd(rng, n, d, 10.0)
    dt = rng.uniform(1, 5, n)
    m = f.measurement.ndim
    z, _ = f.measurement.predict(x)
    polar = m == 3
    z = z + rng.normal(size=z.shape) * (np.array([10.0, 1e-4, 1e-4]) if polar else 10.0)
    R = np.diag([100.0, 1e-8, 1e-8]) if polar else _spd(rng, n, m, 5.0)
    pred = f.predict(GaussianState(x, P), dt)
    upd, _nu, _S, ll = f.update(pred, z, R)
    for i in range(n):
        pi = f.predict(GaussianState(x[i : i + 1], P[i : i + 1]), dt[i])
        Ri = R[i : i + 1] if R.ndim == 3 else R
        ui, _nui, _Si, lli = f.update(pi, z[i : i + 1], Ri)
        np.testing.assert_allclose(pred.x[i], pi.x[0], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(upd.x[i], ui.x[0], rtol=1e-10, atol=1e-8)
        np.testing.assert_allclose(upd.P[i], ui.P[0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(ll[i], lli[0], rtol=1e-10)


def test_linear_converted_kf_matches_the_kalman_primitives():
    """The converted-measurement KF on a linear model is exactly the textbook KF."""
    model = ConstantVelocity(q=2.0)
    f = ConvertedMeasurementKF(model)
    rng = np.random.default_rng(2)
    x = rng.normal(size=(4, 4)) * 100
    P = _spd(rng, 4, 4)
    R = _spd(rng, 4, 2)
    z = rng.normal(size=(4, 2)) * 100
    xp, Pp = kalman.predict(x, P, model.F(3.0), model.Q(3.0))
    xu, Pu, _, _ = kalman.update(xp, Pp, z, model.H(), R)
    s, _, _, _ = f.update(f.predict(GaussianState(x, P), 3.0), z, R)
    np.testing.assert_allclose(s.x, xu, rtol=1e-12)
    np.testing.assert_allclose(s.P, Pu, rtol=1e-10)


def _simulate_linear(model, n, steps, T, R, rng):
    F, Q = model.F(T), model.Q(T)
    Lq = np.linalg.cholesky(Q + 1e-12 * np.eye(model.dim))
    x = np.zeros((n, model.dim))
    x[:, list(model.position_index)] = rng.normal(0, 1000, (n, model.ndim))
    xs, zs = [], []
    H = model.H()
    Lr = np.linalg.cholesky(R)
    for _ in range(steps):
        x = x @ F.T + rng.normal(size=(n, model.dim)) @ Lq.T
        xs.append(x.copy())
        zs.append(x @ H.T + rng.normal(size=(n, H.shape[0])) @ Lr.T)
    return xs, zs


@pytest.mark.parametrize("model", [ConstantVelocity(q=9.0), Singer(tau=10.0, sigma_m=15.0)])
def test_kf_nees_is_consistent_on_the_matched_model(model):
    """Matched model: the NEES summed over n tracks is chi-square(n·d) at every scan
    (99.9% two-sided bounds at scans 5, 15, 25)."""
    rng = np.random.default_rng(3)
    n, steps, T = 400, 25, 4.0
    R = np.array([[400.0, 150.0], [150.0, 900.0]])
    xs, zs = _simulate_linear(model, n, steps, T, R, rng)
    f = ConvertedMeasurementKF(model)
    # initial estimate drawn from its own stated covariance P0 around the truth
    per_axis = [100.0, 400.0, 25.0] if model.dim == 6 else [100.0, 400.0]
    P0 = np.diag(per_axis * 2)
    err0 = rng.normal(size=xs[0].shape) @ np.linalg.cholesky(P0).T
    state = GaussianState(xs[0] + err0, np.broadcast_to(P0, (n, model.dim, model.dim)).copy())
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n * model.dim)
    for k in range(1, steps):
        state = f.predict(state, T)
        state, _, _, _ = f.update(state, zs[k], R)
        if k in (5, 15, 24):
            e = xs[k] - state.x
            nees = np.einsum("ni,ni->", e, np.linalg.solve(state.P, e[..., None])[..., 0])
            assert lo < nees < hi, (k, nees / n, lo / n, hi / n)


def test_polar_ekf_wraps_the_azimuth_innovation_at_north():
    model = ConstantVelocity(q=1.0)
    f = PolarEKF(model, [0.0, 0.0])
    # target due north, slightly west: predicted azimuth ≈ 2π − 0.001
    x = np.array([[-50.0, 0.0, 50_000.0, 0.0]])
    P = np.diag([1e4, 100.0, 1e4, 100.0])[None]
    z = np.array([[50_000.0, 0.0005]])  # measured just east of north
    R = np.diag([20.0**2, 0.0025**2])
    s, nu, _, _ = f.update(GaussianState(x, P), z, R)
    assert abs(nu[0, 1]) < 0.01
    assert abs(s.x[0, 0] - 0.0) < 60  # moved toward x ≈ +25 m, not around the circle
    assert wrap_angle(np.array([3 * np.pi, -np.pi, 0.1]))[0] == pytest.approx(np.pi)


def test_polar_ekf_nees_is_consistent_at_moderate_noise():
    """Polar EKF on a matched CV truth, σ_θ = 1 mrad at 20-30 km: NEES within bounds."""
    model = ConstantVelocity(q=1.0)
    f = PolarEKF(model, [0.0, 0.0])
    rng = np.random.default_rng(8)
    n, T = 300, 4.0
    R = np.diag([20.0**2, 1e-3**2])
    xs, _ = _simulate_linear(model, n, 12, T, np.eye(2), rng)
    offset = np.array([15_000.0, 0.0, 20_000.0, 0.0])
    P0 = np.diag([400.0, 100.0, 400.0, 100.0])
    st = GaussianState(
        xs[0] + offset + rng.normal(size=(n, 4)) @ np.linalg.cholesky(P0).T,
        np.broadcast_to(P0, (n, 4, 4)).copy(),
    )
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n * 4)
    for k in range(1, 12):
        st = f.predict(st, T)
        zt, _ = f.measurement.predict(xs[k] + offset)
        z = zt + rng.normal(size=(n, 2)) * np.sqrt(np.diag(R))
        st, _, _, _ = f.update(st, z, R)
    e = xs[11] + offset - st.x
    nees = np.einsum("ni,ni->", e, np.linalg.solve(st.P, e[..., None])[..., 0])
    assert lo < nees < hi
