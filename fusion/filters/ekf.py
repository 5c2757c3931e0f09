"""Batched extended-Kalman predict and update for linear or nonlinear models and
measurements ([Dikić] eq. 8-9 and 13-14), Joseph-form covariance.

* predict: the model's own ``predict(x, P, dt)`` of the same equations where it has one
  (CV, coordinated turn: compiled); otherwise linear models use F(dt), Q(dt)
  (:func:`fusion.filters.kalman.predict`) and nonlinear models (``model.nonlinear``)
  ``model.transition(x, dt) -> (f(x), ∂f/∂x)`` and ``model.Q(dt, x)``: P⁻ = J P Jᵀ + Q.
* update: ẑ, H = measurement.predict(x⁻); S = H P⁻ Hᵀ + R; K = P⁻ Hᵀ S⁻¹;
  ν = residual(z, ẑ) (azimuth wrapped for polar measurements); x = x⁻ + K ν;
  P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ.
Shapes: x (n, d), P (n, d, d), z (n, m), R (m, m) or (n, m, m), H (n, m, d).
"""

from __future__ import annotations

import numpy as np

from . import kalman


def predict(model, x: np.ndarray, P: np.ndarray, dt) -> tuple[np.ndarray, np.ndarray]:
    """Predict n states over dt (scalar or (n,)) seconds with ``model``."""
    fused = getattr(model, "predict", None)  # the CV and CT models' compiled predictions
    if fused is not None:
        return fused(x, P, dt)
    if getattr(model, "nonlinear", False):
        xp, J = model.transition(x, dt)
        Pp = J @ P @ J.swapaxes(-1, -2) + model.Q(dt, x)
        return xp, 0.5 * (Pp + Pp.swapaxes(-1, -2))
    return kalman.predict(x, P, model.F(dt), model.Q(dt))


def innovation(x, P, R, measurement):
    """Predicted measurement ẑ (n, m), its Jacobian H (n, m, d) and S = H P Hᵀ + R."""
    zhat, H = measurement.predict(x)
    S = H @ P @ H.swapaxes(-1, -2) + R
    return zhat, H, 0.5 * (S + S.swapaxes(-1, -2))


def update(x, P, z, R, measurement):
    """EKF/KF update of n states with n measurements; returns (x, P, ν, S)."""
    zhat, H, S = innovation(x, P, R, measurement)
    Ht = H.swapaxes(-1, -2)
    PHt = P @ Ht
    K = np.swapaxes(np.linalg.solve(S, PHt.swapaxes(-1, -2)), -1, -2)
    nu = measurement.residual(np.asarray(z, float), zhat)
    x_new = x + np.einsum("...ij,...j->...i", K, nu)
    A = np.eye(x.shape[-1]) - K @ H
    P_new = A @ P @ A.swapaxes(-1, -2) + K @ np.broadcast_to(R, S.shape) @ np.swapaxes(K, -1, -2)
    return x_new, 0.5 * (P_new + P_new.swapaxes(-1, -2)), nu, S
