"""Motion models against independent references: matrix exponentials and numerical
integration of the continuous-time models (scipy), ODE integration of the turn, and
finite differences for Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm
from skyfuse.fusion.models import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    Singer,
    from_common,
    singer_sigma_m2,
    to_common,
)


def _singer_continuous(alpha):
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -alpha]])
    B = np.array([[0.0], [0.0], [1.0]])
    return A, B


@pytest.mark.parametrize("alpha,T", [(0.1, 4.0), (1.0, 2.0), (0.5, 10.0), (1e-3, 4.0), (2.0, 0.01)])
def test_singer_F_and_Q_match_matrix_exponential_and_numerical_integration(alpha, T):
    sigma_m = 7.0
    A, B = _singer_continuous(alpha)
    model = Singer(tau=1 / alpha, sigma_m=sigma_m, ndim=1)
    np.testing.assert_allclose(model.F(T), expm(A * T), rtol=1e-10, atol=1e-12)
    qc = 2 * alpha * sigma_m**2
    integrand = lambda s: expm(A * s) @ B @ B.T @ expm(A * s).T * qc  # noqa: E731
    Qnum, _ = quad_vec(integrand, 0.0, T, epsabs=1e-13, epsrel=1e-11)
    np.testing.assert_allclose(model.Q(T), Qnum, rtol=1e-7, atol=1e-12)


def test_singer_q_tends_to_the_ca_white_jerk_limit_as_alpha_T_goes_to_zero():
    T = 4.0
    for alpha in (1e-4, 1e-6):
        sing = Singer(tau=1 / alpha, sigma_m=1.0, ndim=1)
        q_norm = sing.Q(T) / (2 * alpha)  # q(α, T)
        ca = ConstantAcceleration(q=1.0, ndim=1).Q(T)
        np.testing.assert_allclose(q_norm, ca, rtol=5 * alpha * T)
        np.testing.assert_allclose(sing.F(T), ConstantAcceleration(ndim=1).F(T), rtol=alpha * T)
    # away from the limit the exact Q differs from the CA form
    sing = Singer(tau=10.0, sigma_m=1.0, ndim=1)
    assert abs(sing.Q(4.0)[0, 0] / 0.2 - 4.0**5 / 20) / (4.0**5 / 20) > 0.05


def test_singer_sigma_from_maneuver_statistics():
    assert singer_sigma_m2(40.0, 0.9, 0.1) == pytest.approx(1600 * 4.5 / 3)
    assert Singer.from_maneuver(10, 40, 0.1, 0.9).sigma_m == pytest.approx(np.sqrt(1600 * 0.5 / 3))
    with pytest.raises(ValueError, match="p_max"):
        singer_sigma_m2(40.0, 1.5, 0.0)


@pytest.mark.parametrize(
    "model",
    [
        ConstantAcceleration(q=2.0, ndim=3),
        Singer(8.0, 5.0, ndim=3),
        ConstantVelocity(q=3.0, ndim=3),
    ],
)
def test_array_dt_equals_stacked_scalar_dt_and_blocks_per_axis(model):
    dts = np.array([0.5, 4.0, 11.0])
    F, Q = model.F(dts), model.Q(dts)
    assert F.shape == Q.shape == (3, model.dim, model.dim)
    for k, t in enumerate(dts):
        np.testing.assert_allclose(F[k], model.F(float(t)))
        np.testing.assert_allclose(Q[k], model.Q(float(t)))
    H = model.H()
    assert H.shape == (3, model.dim) and H.sum() == 3
    assert [model.labels[i] for i in model.position_index] == ["x", "y", "z"]


def test_ca_Q_matches_numerical_integration_of_white_jerk():
    A = np.diag([1.0, 1.0], k=1)
    B = np.array([[0.0], [0.0], [1.0]])
    T, q = 3.0, 2.5
    Qnum, _ = quad_vec(lambda s: expm(A * s) @ B @ B.T @ expm(A * s).T * q, 0, T, epsrel=1e-12)
    np.testing.assert_allclose(ConstantAcceleration(q=q, ndim=1).Q(T), Qnum, rtol=1e-9)
    np.testing.assert_allclose(ConstantAcceleration(ndim=1).F(T), expm(A * T), atol=1e-12)


def _ct_ode(t, s, w):
    _x, _y, psi, v = s
    return [v * np.cos(psi), v * np.sin(psi), w, 0.0]


@pytest.mark.parametrize("omega", [0.126, -0.05, 1e-9, 0.0])
def test_coordinated_turn_transition_matches_ode_integration_and_jacobian(omega):
    model = CoordinatedTurn(vertical=True)
    x0 = np.array([[1000.0, -500.0, 0.7, omega, 311.0, 3000.0, 5.0]])
    T = 4.0
    sol = solve_ivp(
        _ct_ode, (0, T), [1000.0, -500.0, 0.7, 311.0], args=(omega,), rtol=1e-11, atol=1e-9
    )
    xp, J = model.transition(x0, T)
    np.testing.assert_allclose(xp[0, :2], sol.y[:2, -1], atol=1e-5)
    assert xp[0, 2] == pytest.approx(0.7 + omega * T)
    assert xp[0, 5] == pytest.approx(3020.0)
    # Jacobian by central differences
    h = np.array([1e-3, 1e-3, 1e-7, 1e-7, 1e-4, 1e-3, 1e-4])
    Jn = np.zeros((7, 7))
    for k in range(7):
        d = np.zeros(7)
        d[k] = h[k]
        Jn[:, k] = (model.transition(x0 + d, T)[0][0] - model.transition(x0 - d, T)[0][0]) / (
            2 * h[k]
        )
    np.testing.assert_allclose(J[0], Jn, rtol=1e-5, atol=1e-4)
    Q = model.Q(T, x0)
    assert Q.shape == (1, 7, 7) and np.all(np.linalg.eigvalsh(Q[0]) > -1e-9)


def test_ct_common_format_conversion_round_trip_and_jacobians():
    model = CoordinatedTurn()
    rng = np.random.default_rng(0)
    x = np.column_stack(
        [
            rng.normal(0, 1e4, 5),
            rng.normal(0, 1e4, 5),
            rng.uniform(-3, 3, 5),
            rng.uniform(-0.1, 0.1, 5),
            rng.uniform(100, 300, 5),
        ]
    )
    A = rng.normal(size=(5, 5, 5))
    P = A @ np.swapaxes(A, -1, -2) * 1e-3
    xc, Pc = to_common(model, x, P)
    # [Dikić] eq. 22
    np.testing.assert_allclose(xc[:, 1], x[:, 4] * np.cos(x[:, 2]))
    np.testing.assert_allclose(xc[:, 5], x[:, 3] * xc[:, 1])
    np.testing.assert_allclose(xc[:, 2], -x[:, 3] * xc[:, 4])
    xb, Pb = from_common(model, xc, Pc)
    np.testing.assert_allclose(xb, x, atol=1e-9)
    # the two Jacobians are mutual inverses on the CT manifold: P survives the round trip
    np.testing.assert_allclose(Pb, P, rtol=1e-6, atol=1e-12)
    # to_common covariance equals a finite-difference Jacobian sandwich
    h = 1e-6
    Jn = np.zeros((6, 5))
    for k in range(5):
        d = np.zeros(5)
        d[k] = h
        Jn[:, k] = (
            to_common(model, x[:1] + d, P[:1])[0][0] - to_common(model, x[:1] - d, P[:1])[0][0]
        ) / (2 * h)
    np.testing.assert_allclose(Pc[0], Jn @ P[0] @ Jn.T, rtol=1e-5, atol=1e-9)


def test_cv_common_format_has_zero_acceleration():
    cv = ConstantVelocity(ndim=2)
    x = np.array([[1.0, 2.0, 3.0, 4.0]])
    P = np.diag([1.0, 2.0, 3.0, 4.0])[None]
    xc, Pc = to_common(cv, x, P)
    np.testing.assert_array_equal(xc, [[1.0, 2.0, 0.0, 3.0, 4.0, 0.0]])
    assert Pc[0, 2, 2] == 0 and Pc[0, 4, 4] == 4.0
    xb, Pb = from_common(cv, xc, Pc)
    np.testing.assert_array_equal(xb, x)
    np.testing.assert_array_equal(Pb, P)


def test_singer_transition_backwards_is_the_inverse_and_the_matrix_exponential():
    """F(−Δ) = F(Δ)⁻¹ = expm(−A Δ) for Singer's A = [[0,1,0],[0,0,1],[0,0,−α]] (closed
    form of an LTI system; retrodiction uses negative Δ)."""
    from skyfuse.fusion.models.singer import singer_axis_F

    alpha = 0.1
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -alpha]])
    dt = np.array([-12.0, -4.0, -0.5, -1e-4, 1e-4, 4.0])
    F = singer_axis_F(dt, alpha)
    for k, d in enumerate(dt):
        np.testing.assert_allclose(F[k], expm(A * d), rtol=1e-9, atol=1e-12)
    back = singer_axis_F(-dt, alpha)
    for k in range(dt.size):
        np.testing.assert_allclose(F[k] @ back[k], np.eye(3), atol=1e-10)


@pytest.mark.parametrize("ndim,q_vertical", [(2, None), (3, None), (3, 0.3)])
def test_cv_predict_equals_the_matrix_products(ndim, q_vertical):
    """ConstantVelocity.predict (one compiled loop, block structure of F written out)
    against F x and F P Fᵀ + Q with the model's own F and Q matrices, for per-state and
    scalar dt, including dt = 0 and a backward dt."""
    from skyfuse.fusion.filters.kalman import predict

    model = ConstantVelocity(q=2.5, ndim=ndim, q_vertical=q_vertical)
    rng = np.random.default_rng(ndim)
    n, d = 40, 2 * ndim
    x = rng.normal(0, 1e3, (n, d))
    A = rng.normal(size=(n, d, d))
    P = A @ np.swapaxes(A, -1, -2) * 50.0
    for dt in (rng.uniform(-2, 12, n), np.r_[0.0, rng.uniform(0, 5, n - 1)], 4.0):
        F, Q = model.F(dt), model.Q(dt)
        xr, Pr = predict(x, P, F, Q)
        xk, Pk = model.predict(x, P, dt)
        np.testing.assert_allclose(xk, xr, rtol=1e-14, atol=1e-9)
        np.testing.assert_allclose(Pk, Pr, rtol=1e-13, atol=1e-9)
        np.testing.assert_array_equal(Pk, np.swapaxes(Pk, -1, -2))


@pytest.mark.parametrize("vertical", [False, True])
def test_coordinated_turn_fused_prediction_equals_jacobian_sandwich(vertical):
    """CoordinatedTurn.predict (one compiled call) against f(x) and J P Jᵀ + Q(x) from
    its transition and process noise, in 2-D and 3-D, turning and straight states."""
    rng = np.random.default_rng(4)
    ct = CoordinatedTurn(vertical=vertical)
    n, d = 30, ct.dim
    x = rng.normal(size=(n, d)) * np.array([1e4, 1e4, 1.0, 0.05, 100.0, 1e3, 10.0][:d])
    x[:5, 3] = 0.0  # ω = 0: the series branch
    A = rng.normal(size=(n, d, d))
    P = A @ A.transpose(0, 2, 1) + np.eye(d)
    dt = rng.uniform(0.5, 12.0, n)
    xp, Pp = ct.predict(x, P, dt)
    fx, J = ct.transition(x, dt)
    ref = J @ P @ J.transpose(0, 2, 1) + ct.Q(dt, x)
    np.testing.assert_array_equal(xp, fx)
    np.testing.assert_allclose(Pp, 0.5 * (ref + ref.transpose(0, 2, 1)), rtol=1e-11, atol=1e-9)
    assert np.array_equal(Pp, Pp.transpose(0, 2, 1))
