"""Batched filters: batch == loop of single tracks, NEES consistency on matched models
(Monte Carlo, chi-square bounds), IMM algebra against the explicit spec formulas and
against a plain KF, IMM mode probabilities during a manoeuvre, azimuth wrap-around."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.filters import (
    IMM,
    TYPICAL_TPM_IMM2,
    ConvertedMeasurementKF,
    GaussianState,
    PolarEKF,
    imm2_pcwpa,
    imm3_cv_singer_ct,
    kalman,
    wrap_angle,
)
from skyfuse.fusion.models import ConstantVelocity, CoordinatedTurn, Singer

G0 = 9.80665


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


def test_imm_of_identical_modes_equals_the_single_kf():
    model = ConstantVelocity(q=5.0)
    kf = ConvertedMeasurementKF(model)
    imm = IMM([kf, ConvertedMeasurementKF(model)], [[0.8, 0.2], [0.3, 0.7]])
    rng = np.random.default_rng(4)
    x = rng.normal(size=(3, 4)) * 100
    P = _spd(rng, 3, 4)
    st_kf = GaussianState(x, P)
    st = imm.initiate_common(x, P, mu0=[0.6, 0.4])
    for _ in range(4):
        z = rng.normal(size=(3, 2)) * 100
        R = _spd(rng, 3, 2, 10.0)
        st_kf, _, _, _ = kf.update(kf.predict(st_kf, 2.0), z, R)
        st, _ = imm.update(imm.predict(st, 2.0), z, R)
        est = imm.estimate(st)
        np.testing.assert_allclose(est.x, st_kf.x, rtol=1e-9)
        np.testing.assert_allclose(est.P, st_kf.P, rtol=1e-8)


def test_imm_mixing_matches_the_explicit_spec_formulas():
    """Spec 01 §5 step 1 written out with loops for one track."""
    imm = imm2_pcwpa(TYPICAL_TPM_IMM2)
    rng = np.random.default_rng(5)
    xs = [rng.normal(size=(1, 4)) * 50 for _ in range(2)]
    Ps = [_spd(rng, 1, 4) for _ in range(2)]
    mu = np.array([[0.3, 0.7]])
    p = np.asarray(TYPICAL_TPM_IMM2)
    from skyfuse.fusion.filters import IMMState

    x0, P0, c = imm.mix(IMMState(xs, Ps, mu))
    for j in range(2):
        cj = sum(p[i, j] * mu[0, i] for i in range(2))
        assert c[0, j] == pytest.approx(cj)
        w = [p[i, j] * mu[0, i] / cj for i in range(2)]
        xj = sum(w[i] * xs[i][0] for i in range(2))
        Pj = sum(w[i] * (Ps[i][0] + np.outer(xs[i][0] - xj, xs[i][0] - xj)) for i in range(2))
        np.testing.assert_allclose(x0[j][0], xj, rtol=1e-12)
        np.testing.assert_allclose(P0[j][0], Pj, rtol=1e-12)


def _turning_truth(n_runs, rng, T=4.0, steps=20, turn=(8, 11), accel=4 * G0):
    """Straight flight at 300 m/s, then a 4 g turn between scans turn[0] and turn[1]."""
    pos = np.array([0.0, 0.0])
    v = np.array([300.0, 0.0])
    out = []
    dt = 0.01
    for k in range(steps):
        for _ in range(int(T / dt)):
            if turn[0] <= k < turn[1]:
                a = accel * np.array([-v[1], v[0]]) / np.linalg.norm(v)
                v = v + a * dt
            pos = pos + v * dt
        out.append(pos.copy())
    truth = np.array(out)
    R = np.diag([50.0**2, 50.0**2])
    z = truth[None] + rng.normal(0, 50.0, (n_runs, steps, 2))
    return truth, z, R


@pytest.mark.parametrize(
    "make", [lambda: imm2_pcwpa(TYPICAL_TPM_IMM2), lambda: imm3_cv_singer_ct()]
)
def test_imm_mode_probability_of_the_manoeuvre_modes_rises_during_the_turn(make):
    imm = make()
    rng = np.random.default_rng(6)
    n = 100
    truth, z, R = _turning_truth(n, rng)
    st = imm.initiate_two_point(
        z[:, 0], R, z[:, 1], R, 4.0, mu0=[0.9] + [0.1 / (imm.r - 1)] * (imm.r - 1)
    )
    mus = []
    for k in range(2, z.shape[1]):
        st, _ = imm.update(imm.predict(st, 4.0), z[:, k], R)
        mus.append(st.mu.mean(axis=0))
    mus = np.array(mus)  # index k-2
    cv_before = mus[8 - 2 - 2 : 8 - 2, 0].mean()  # scans 4..5
    cv_during = mus[9 - 2 : 11 - 2, 0].mean()  # scans 9..10
    assert cv_before > 0.6
    assert cv_during < cv_before - 0.3
    # and the combined estimate tracks through the turn
    err = np.linalg.norm(imm.position(st) - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 200


def test_imm3_estimate_is_in_the_common_singer_format():
    imm = imm3_cv_singer_ct()
    st = imm.initiate_two_point(
        [[0.0, 0.0]], np.eye(2) * 100, [[1200.0, 0.0]], np.eye(2) * 100, 4.0
    )
    est = imm.estimate(imm.predict(st, 4.0))
    assert imm.labels == ("x", "vx", "ax", "y", "vy", "ay")
    assert est.x[0, 0] == pytest.approx(2400.0, abs=1.0) and est.x[0, 1] == pytest.approx(
        300.0, abs=0.1
    )
    assert np.all(np.linalg.eigvalsh(est.P) > -1e-6)


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


def test_imm3_from_a_one_point_initiation_converges_without_blowing_up():
    """Zero initial velocity makes the CT course undefined: the conversion must fall back
    to an uninformative course instead of exploding (seen as 1e7 m errors before)."""
    imm = imm3_cv_singer_ct()
    rng = np.random.default_rng(11)
    n, T = 50, 4.0
    R = np.diag([100.0**2, 100.0**2])
    v = np.array([-220.0, -220.0])
    truth = np.array([30_000.0, 30_000.0]) + np.arange(10)[:, None] * T * v
    z = truth[None] + rng.normal(0, 100.0, (n, 10, 2))
    st = imm.initiate(z[:, 0], R, velocity_sigma=350.0)
    for k in range(1, 10):
        st, _ = imm.update(imm.predict(st, T), z[:, k], R)
        assert all(np.isfinite(P).all() for P in st.P)
    err = np.linalg.norm(imm.position(st) - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 150


def test_imm3_with_the_altitude_channel_tracks_a_climbing_target():
    imm = imm3_cv_singer_ct(ndim=3)
    assert imm.labels == ("x", "vx", "ax", "y", "vy", "ay", "z", "vz", "az")
    rng = np.random.default_rng(12)
    n, T = 40, 4.0
    R = np.diag([80.0**2, 80.0**2, 30.0**2])
    v = np.array([250.0, -100.0, 10.0])
    truth = np.array([10_000.0, 20_000.0, 3000.0]) + np.arange(12)[:, None] * T * v
    z = truth[None] + rng.normal(size=(n, 12, 3)) * np.sqrt(np.diag(R))
    st = imm.initiate_two_point(z[:, 0], R, z[:, 1], R, T)
    for k in range(2, 12):
        st, _ = imm.update(imm.predict(st, T), z[:, k], R)
    est = imm.estimate(st)
    assert est.x.shape == (n, 9)
    np.testing.assert_allclose(est.x[:, 7].mean(), 10.0, atol=3.0)  # climb rate
    err = np.linalg.norm(imm.position(st) - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 100
