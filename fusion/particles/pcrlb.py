"""Posterior Cramér–Rao lower bound, Tichavský recursion (Tichavský et al. 1998).

For x_{k+1} = f(x_k) + v, v ~ N(0, Q), y = h(x) + e, e ~ N(0, R), the Fisher information
J_k of the state (E[(x̂ − x)(x̂ − x)ᵀ] ≥ J_k⁻¹ for any estimator) recurses as

    J_{k+1} = D22 − D21 (J_k + D11)⁻¹ D12,
    D11 = E[F̃ᵀ Q⁻¹ F̃],  D12 = D21ᵀ = −E[F̃ᵀ] Q⁻¹,  D22 = Q⁻¹ + E[H̃ᵀ R⁻¹ H̃],

with F̃ = ∂f/∂x at x_k, H̃ = ∂h/∂x at x_{k+1}, expectations over the true trajectories
(Monte Carlo average). Linear-Gaussian case (3.81): V = D11 = FᵀQ⁻¹F, S = D12 = −FᵀQ⁻¹,
and J_k⁻¹ equals the Kalman filter's P_{k|k} exactly — the bound is tight.

The Tichavský form needs Q⁻¹. The CV model's Q = Γ q Γᵀ is singular (rank = number of
axes), so :func:`linear_gaussian` uses the equivalent information-filter form
J_{k+1} = (F J_k⁻¹ Fᵀ + Q)⁻¹ + HᵀR⁻¹H (matrix inversion lemma applied to the above),
which holds for any Q ⪰ 0. J_0 = P_0⁻¹. Units: J in inverse state units squared.

Missed detections [LIT] (information reduction factor, Niu et al.; Hernandez et al.):
with detection probability P_D and no clutter, the measurement term becomes
q HᵀR⁻¹H with q = P_D (the expected information of a scan). This is a bound on the
error averaged over detection sequences, lower than the bound obtained by enumerating them.
Clutter lowers q further (q < P_D, a numerical integral that is not implemented here), so
q = P_D is a valid, looser floor with clutter too.
"""

from __future__ import annotations

import numpy as np


def tichavsky_step(J: np.ndarray, D11: np.ndarray, D12: np.ndarray, D22: np.ndarray) -> np.ndarray:
    """J_{k+1} = D22 − D12ᵀ (J_k + D11)⁻¹ D12 (3.74)."""
    Jn = D22 - np.swapaxes(D12, -1, -2) @ np.linalg.solve(J + D11, D12)
    return 0.5 * (Jn + np.swapaxes(Jn, -1, -2))


def linear_gaussian_terms(
    F, Q, H, R, information_factor: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D11, D12, D22) of the linear-Gaussian model (3.81); Q must be invertible."""
    Qi = np.linalg.inv(Q)
    return F.T @ Qi @ F, -F.T @ Qi, Qi + information_factor * H.T @ np.linalg.solve(R, H)


def linear_gaussian(
    P0, F, Q, H, R, steps: int, form: str = "auto", information_factor: float = 1.0
) -> np.ndarray:
    """Bounds P_k = J_k⁻¹ for k = 1..steps, shape (steps, d, d).

    form: "tichavsky" (needs Q⁻¹), "information" (any Q ⪰ 0), or "auto" (Tichavský when Q
    is well conditioned, the information form otherwise). information_factor: q in
    (0, 1], e.g. P_D for missed detections (module docstring)."""
    if not 0.0 < information_factor <= 1.0:
        raise ValueError(f"information_factor = {information_factor}: must be in (0, 1]")
    if form == "auto":
        form = "tichavsky" if np.linalg.cond(Q) < 1e12 else "information"
    J = np.linalg.inv(P0)
    HtRiH = information_factor * H.T @ np.linalg.solve(R, H)
    terms = linear_gaussian_terms(F, Q, H, R, information_factor) if form == "tichavsky" else None
    out = np.empty((steps, *P0.shape))
    for k in range(steps):
        if terms is not None:
            J = tichavsky_step(J, *terms)
        elif form == "information":
            J = np.linalg.inv(F @ np.linalg.solve(J, F.T) + Q) + HtRiH
        else:
            raise ValueError(f"form = {form!r}: must be 'auto', 'tichavsky' or 'information'")
        out[k] = np.linalg.inv(J)
    return out


def additive_gaussian(J0, F_jac, H_jac, Q, R) -> np.ndarray:
    """Bounds J_k⁻¹ (steps, d, d) for a nonlinear model with additive Gaussian noise.

    F_jac (runs, steps, d, d): ∂f/∂x at the true x_{k−1} of each run (the step into k);
    H_jac (runs, steps, m, d): ∂h/∂x at the true x_k. Expectations are run averages."""
    Qi = np.linalg.inv(Q)
    Ri = np.linalg.inv(R)
    Ft = np.swapaxes(F_jac, -1, -2)
    D11 = (Ft @ Qi @ F_jac).mean(axis=0)
    D12 = -(Ft.mean(axis=0) @ Qi)
    D22 = Qi + (np.swapaxes(H_jac, -1, -2) @ Ri @ H_jac).mean(axis=0)
    J = np.asarray(J0, float)
    out = np.empty(D11.shape)
    for k in range(D11.shape[0]):
        J = tichavsky_step(J, D11[k], D12[k], D22[k])
        out[k] = np.linalg.inv(J)
    return out
