"""PCRLB (Tichavský et al. 1998): in the linear-Gaussian case the bound J_k⁻¹ equals the
Kalman filter's P_{k|k} (fusion.filters.kalman, an independent implementation), in the
Tichavský form (invertible Q) and the information form (the CV model's singular Q)."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.filters import kalman
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles import pcrlb


def _kalman_covariances(P0, F, Q, H, R, steps):
    x, P, out = np.zeros((1, len(P0))), P0[None], []
    for _ in range(steps):
        x, P = kalman.predict(x, P, F, Q)
        x, P, _, _ = kalman.update(x, P, x @ H.T, H, R)
        out.append(P[0])
    return np.array(out)


def _white_noise_cv(T=2.0, q=3.0):
    F = np.array([[1.0, T], [0.0, 1.0]])
    Q = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])  # invertible
    return F, Q, np.array([[1.0, 0.0]]), np.array([[25.0]])


def test_tichavsky_equals_kalman_for_invertible_q():
    F, Q, H, R = _white_noise_cv()
    P0 = np.diag([100.0, 400.0])
    bound = pcrlb.linear_gaussian(P0, F, Q, H, R, 30, form="tichavsky")
    assert np.allclose(bound, _kalman_covariances(P0, F, Q, H, R, 30), rtol=1e-9, atol=1e-9)


def test_information_form_equals_kalman_for_singular_cv_q():
    cv = ConstantVelocity(q=0.75, ndim=2)
    F, Q, H = cv.F(1.0), cv.Q(1.0), cv.H()
    assert np.linalg.matrix_rank(Q) == 2  # Γ q Γᵀ per axis: singular
    R = np.array([[25.0, 5.0], [5.0, 16.0]])
    P0 = np.diag([25.0, 100.0, 16.0, 100.0])
    bound = pcrlb.linear_gaussian(P0, F, Q, H, R, 40)
    assert np.allclose(bound, _kalman_covariances(P0, F, Q, H, R, 40), rtol=1e-8, atol=1e-8)


def test_additive_gaussian_with_linear_jacobians_equals_linear_form():
    F, Q, H, R = _white_noise_cv()
    P0 = np.diag([100.0, 400.0])
    Fj = np.broadcast_to(F, (5, 12, 2, 2))
    Hj = np.broadcast_to(H, (5, 12, 1, 2))
    a = pcrlb.additive_gaussian(np.linalg.inv(P0), Fj, Hj, Q, R)
    b = pcrlb.linear_gaussian(P0, F, Q, H, R, 12, form="tichavsky")
    assert np.allclose(a, b, rtol=1e-10)


def test_unknown_form_is_rejected():
    F, Q, H, R = _white_noise_cv()
    with pytest.raises(ValueError, match="form"):
        pcrlb.linear_gaussian(np.eye(2), F, Q, H, R, 2, form="x")


def test_missed_detection_bound_lies_below_the_kalman_average():
    """With P_D = 0.7 the Kalman P_{k|k} averaged over 2000 random detection sequences
    (exact covariances, no sampling error in P itself) must dominate the q = P_D bound
    (Jensen: E[J⁻¹] ⪰ (E J)⁻¹), and the bound must lie above the P_D = 1 bound."""
    cv = ConstantVelocity(q=0.75, ndim=1)
    F, Q, H, R = cv.F(1.0), cv.Q(1.0), cv.H(), np.array([[25.0]])
    P0, steps, pd = np.diag([25.0, 100.0]), 20, 0.7
    rng = np.random.default_rng(0)
    det = rng.random((2000, steps)) < pd
    P = np.tile(P0, (2000, 1, 1))
    x = np.zeros((2000, 2))
    avg = []
    for k in range(steps):
        x, P = kalman.predict(x, P, F, Q)
        _, Pu, _, _ = kalman.update(x, P, x @ H.T, H, R)
        P = np.where(det[:, k, None, None], Pu, P)
        avg.append(P.mean(axis=0))
    bound = pcrlb.linear_gaussian(P0, F, Q, H, R, steps, information_factor=pd)
    full = pcrlb.linear_gaussian(P0, F, Q, H, R, steps)
    for A, B, C in zip(avg, bound, full):
        assert np.linalg.eigvalsh(A - B).min() >= -1e-9
        assert np.linalg.eigvalsh(B - C).min() >= -1e-9
    assert bound[-1, 0, 0] > 1.05 * full[-1, 0, 0]
    with pytest.raises(ValueError, match="information_factor"):
        pcrlb.linear_gaussian(P0, F, Q, H, R, 2, information_factor=0.0)
