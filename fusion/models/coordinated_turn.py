"""Nearly coordinated turn (CT) with polar velocity, spec 01 §4 (004, three-model IMM).

State X_T = (x, y, ψ, ω, v) (004), optionally followed by an altitude channel (z, vz)
with nearly constant vertical velocity. x east, y north (m); ψ the course measured
counter-clockwise from the x (east) axis (rad), so v_x = v cosψ, v_y = v sinψ as in
004 eq. 22; ω the turn rate (rad/s, positive counter-clockwise = left turn); v the
speed (m/s). Discrete transition over T (exact for constant ω and v):

    x' = x + v (sin(ψ + ωT) − sin ψ)/ω,   y' = y + v (cos ψ − cos(ψ + ωT))/ω,
    ψ' = ψ + ωT,   ω' = ω,   v' = v        (ω → 0: straight line, by series)

Process noise: white tangential acceleration (σ_a, m/s²) and white turn-rate
acceleration (σ_ω, rad/s²) held piecewise constant over T:
Q = G diag(σ_a², σ_ω²) Gᵀ, G = [[T²/2 cosψ, 0], [T²/2 sinψ, 0], [0, T²/2], [0, T], [T, 0]].
The model is nonlinear: :meth:`transition` returns the predicted state and its Jacobian
(used by the EKF predict in :mod:`fusion.filters.ekf`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import as_dt_array

_SMALL_OMEGA = 1e-6


@dataclass(frozen=True)
class CoordinatedTurn:
    """CT model; sigma_a (m/s²), sigma_omega (rad/s²); ``vertical`` adds (z, vz) with
    white-acceleration variance q_vertical (m²/s⁴)."""

    sigma_a: float = 1.0
    sigma_omega: float = 0.02
    vertical: bool = False
    q_vertical: float = 1.0

    nonlinear = True

    @property
    def ndim(self) -> int:
        return 3 if self.vertical else 2

    @property
    def dim(self) -> int:
        return 7 if self.vertical else 5

    @property
    def labels(self) -> tuple[str, ...]:
        base = ("x", "y", "psi", "omega", "v")
        return (*base, "z", "vz") if self.vertical else base

    @property
    def position_index(self) -> tuple[int, ...]:
        return (0, 1, 5) if self.vertical else (0, 1)

    def H(self) -> np.ndarray:
        H = np.zeros((self.ndim, self.dim))
        H[np.arange(self.ndim), list(self.position_index)] = 1.0
        return H

    def transition(self, x: np.ndarray, dt: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted states (n, d) and Jacobians ∂f/∂x (n, d, d) for states x (n, d)."""
        x = np.atleast_2d(np.asarray(x, float))
        t, _ = as_dt_array(dt)
        t = np.broadcast_to(t, (x.shape[0],))
        psi, w, v = x[:, 2], x[:, 3], x[:, 4]
        wt = w * t
        s0, c0 = np.sin(psi), np.cos(psi)
        s1, c1 = np.sin(psi + wt), np.cos(psi + wt)
        small = np.abs(w) < _SMALL_OMEGA
        A, B, dA, dB, J02, J12 = (
            _turn_terms_mixed(t, w, v, s0, c0, s1, c1, small)
            if small.any()
            else _turn_terms(t, w, v, s0, c0, s1, c1)
        )
        xp = x.copy()
        xp[:, 0] = x[:, 0] + v * A
        xp[:, 1] = x[:, 1] + v * B
        xp[:, 2] = psi + wt
        n, d = x.shape
        J = np.zeros((n, d, d))
        J[:, np.arange(d), np.arange(d)] = 1.0
        J[:, 0, 2] = J02
        J[:, 1, 2] = J12
        J[:, 0, 3] = v * dA
        J[:, 1, 3] = v * dB
        J[:, 0, 4] = A
        J[:, 1, 4] = B
        J[:, 2, 3] = t
        if self.vertical:
            xp[:, 5] = x[:, 5] + t * x[:, 6]
            J[:, 5, 6] = t
        return xp, J

    def Q(self, dt: float | np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """Process covariance (n, d, d) at states x (n, d) (the course ψ enters G)."""
        t, _scalar = as_dt_array(dt)
        if x is None:
            raise ValueError("CoordinatedTurn.Q needs the states x: G depends on the course ψ")
        x = np.atleast_2d(np.asarray(x, float))
        n = x.shape[0]
        t = np.broadcast_to(t, (n,))
        G = np.zeros((n, self.dim, 2))
        G[:, 0, 0] = t * t / 2 * np.cos(x[:, 2])
        G[:, 1, 0] = t * t / 2 * np.sin(x[:, 2])
        G[:, 4, 0] = t
        G[:, 2, 1] = t * t / 2
        G[:, 3, 1] = t
        Q = G @ np.diag([self.sigma_a**2, self.sigma_omega**2]) @ G.swapaxes(-1, -2)
        if self.vertical:
            Q[:, 5, 5] = self.q_vertical * t**4 / 4
            Q[:, 5, 6] = Q[:, 6, 5] = self.q_vertical * t**3 / 2
            Q[:, 6, 6] = self.q_vertical * t**2
        return Q


def _turn_terms(t, w, v, s0, c0, s1, c1):
    """A = (sin(ψ+ωT) − sinψ)/ω, B = (cosψ − cos(ψ+ωT))/ω, their ω-derivatives and
    ∂x'/∂ψ, ∂y'/∂ψ, for turn rates all away from 0."""
    A = (s1 - s0) / w
    B = (c0 - c1) / w
    return A, B, (t * c1 - A) / w, (t * s1 - B) / w, v * (c1 - c0) / w, v * (s1 - s0) / w


def _turn_terms_mixed(t, w, v, s0, c0, s1, c1, small):
    """:func:`_turn_terms` with the ω → 0 series where ``small``."""
    ws = np.where(small, 1.0, w)
    A = np.where(small, t * c0 - w * t * t * s0 / 2, (s1 - s0) / ws)
    B = np.where(small, t * s0 + w * t * t * c0 / 2, (c0 - c1) / ws)
    dA = np.where(small, -t * t * s0 / 2 - w * t**3 * c0 / 3, (t * c1 - A) / ws)
    dB = np.where(small, t * t * c0 / 2 - w * t**3 * s0 / 3, (t * s1 - B) / ws)
    J02 = v * (c1 - c0) * np.where(small, 0.0, 1.0) / ws + np.where(small, -v * t * s0, 0.0)
    J12 = v * (s1 - s0) * np.where(small, 0.0, 1.0) / ws + np.where(small, v * t * c0, 0.0)
    return A, B, dA, dB, J02, J12
