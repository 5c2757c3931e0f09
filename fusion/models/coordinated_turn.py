"""Nearly coordinated turn (CT) with polar velocity ([Dikić], three-model IMM).

State X_T = (x, y, ψ, ω, v) ([Dikić]), optionally followed by an altitude channel (z, vz)
with nearly constant vertical velocity. x east, y north (m); ψ the course measured
counter-clockwise from the x (east) axis (rad), so v_x = v cosψ, v_y = v sinψ as in
[Dikić] eq. 22; ω the turn rate (rad/s, positive counter-clockwise = left turn); v the
speed (m/s). Discrete transition over T (exact for constant ω and v):

    x' = x + v (sin(ψ + ωT) − sin ψ)/ω,   y' = y + v (cos ψ − cos(ψ + ωT))/ω,
    ψ' = ψ + ωT,   ω' = ω,   v' = v        (ω → 0: straight line, by series)

Process noise: white tangential acceleration (σ_a, m/s²) and white turn-rate
acceleration (σ_ω, rad/s²) held piecewise constant over T:
Q = G diag(σ_a², σ_ω²) Gᵀ, G = [[T²/2 cosψ, 0], [T²/2 sinψ, 0], [0, T²/2], [0, T], [T, 0]].
The model is nonlinear: :meth:`transition` returns the predicted state and its Jacobian
(used by the EKF predict in :mod:`fusion.filters.ekf`); for |ω| < 10⁻⁶ rad/s the
transition and its Jacobian use their ω → 0 series. Both loops over the states are
compiled (:mod:`fusion.models.coordinated_turn_kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import coordinated_turn_kernels as kernels
from .base import states_and_dt


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
        x, t = states_and_dt(x, dt)
        return kernels.transition(x, t, self.vertical)

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float | np.ndarray):
        """EKF prediction x⁻ = f(x), P⁻ = J P Jᵀ + Q(x) of n states over dt (scalar or
        (n,)) s: :meth:`transition` and :meth:`Q` as one compiled call
        (:func:`fusion.models.coordinated_turn_kernels.predict`)."""
        x, t = states_and_dt(x, dt)
        P = np.ascontiguousarray(P, dtype=np.float64)
        return kernels.predict(
            x, P, t, self.sigma_a**2, self.sigma_omega**2, self.vertical, float(self.q_vertical)
        )

    def Q(self, dt: float | np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """Process covariance (n, d, d) at states x (n, d) (the course ψ enters G)."""
        if x is None:
            raise ValueError("CoordinatedTurn.Q needs the states x: G depends on the course ψ")
        x, t = states_and_dt(x, dt)
        return kernels.process_noise(
            x, t, self.sigma_a**2, self.sigma_omega**2, self.vertical, float(self.q_vertical)
        )
