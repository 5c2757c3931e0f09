"""Nearly constant velocity (CV / PCWPA: piecewise-constant white acceleration).

[MZD] eq. 5-7 and [thesis] (3.38-3.39): per axis F_T = [[1, T], [0, 1]] and
Q_T = q [[T⁴/4, T³/2], [T³/2, T²]] = Γ q Γᵀ with Γ = [T²/2, T]ᵀ, so q is the variance of
the piecewise-constant acceleration (m²/s⁴). The state is interleaved per axis,
``[x, vx, y, vy]`` (2-D) or ``[x, vx, y, vy, z, vz]`` (3-D), metres and m/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cv_kernels
from .base import as_dt_array, states_and_dt


@dataclass(frozen=True)
class ConstantVelocity:
    """CV model over ``ndim`` axes (2 or 3).

    q: acceleration variance of the horizontal axes, m²/s⁴ (thesis: 0.75).
    q_vertical: acceleration variance of the vertical axis (3-D only); defaults to q.
    """

    q: float = 0.75
    ndim: int = 2
    q_vertical: float | None = None

    def __post_init__(self) -> None:
        if self.ndim not in (1, 2, 3):
            raise ValueError(f"ndim = {self.ndim}: must be 1, 2 or 3")
        if not self.q >= 0:
            raise ValueError(f"q = {self.q}: must be >= 0 m²/s⁴")

    @property
    def dim(self) -> int:
        return 2 * self.ndim

    @property
    def labels(self) -> tuple[str, ...]:
        return ("x", "vx", "y", "vy", "z", "vz")[: self.dim]

    @property
    def position_index(self) -> tuple[int, ...]:
        return tuple(range(0, self.dim, 2))

    def _axis_q(self) -> np.ndarray:
        qs = [self.q] * self.ndim
        if self.ndim == 3 and self.q_vertical is not None:
            qs[2] = self.q_vertical
        return np.asarray(qs)

    def F(self, dt: float | np.ndarray) -> np.ndarray:
        """Transition matrix, (d, d) for scalar dt or (n, d, d) for an array of n dt [s]."""
        t, scalar = as_dt_array(dt)
        F = np.zeros((t.size, self.dim, self.dim))
        idx = np.arange(self.dim)
        F[:, idx, idx] = 1.0
        for a in range(self.ndim):
            F[:, 2 * a, 2 * a + 1] = t
        return F[0] if scalar else F

    def Q(self, dt: float | np.ndarray) -> np.ndarray:
        """Process covariance Γ q Γᵀ per axis, (d, d) or (n, d, d)."""
        t, scalar = as_dt_array(dt)
        Q = np.zeros((t.size, self.dim, self.dim))
        for a, qa in enumerate(self._axis_q()):
            i = 2 * a
            Q[:, i, i] = qa * t**4 / 4
            Q[:, i, i + 1] = Q[:, i + 1, i] = qa * t**3 / 2
            Q[:, i + 1, i + 1] = qa * t**2
        return Q[0] if scalar else Q

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float | np.ndarray):
        """x⁻ = F x, P⁻ = F P Fᵀ + Q of n states x (n, d), P (n, d, d) over dt (scalar or
        (n,)) s: the same as :func:`fusion.filters.kalman.predict` with :meth:`F` and
        :meth:`Q`, as one compiled loop (:mod:`fusion.models.cv_kernels`)."""
        x, t = states_and_dt(x, dt)
        P = np.ascontiguousarray(P, dtype=np.float64)
        qv = self.q if self.q_vertical is None else self.q_vertical
        return cv_kernels.predict(x, P, t, float(self.q), float(qv))

    def H(self) -> np.ndarray:
        """Position measurement matrix (ndim, d): picks x, y (, z)."""
        H = np.zeros((self.ndim, self.dim))
        H[np.arange(self.ndim), list(self.position_index)] = 1.0
        return H
