"""Nearly stationary target: constant velocity with a damped velocity (the "stopped" mode
of the surface-movement IMM, :mod:`fusion.tracker.density.surface_motion`).

Per axis the state is [p, v] (the CV layout ``[x, vx, y, vy(, z, vz)]``, metres and m/s)
and the velocity decays at the rate β (1/s) under a piecewise-constant white acceleration
a_k of variance q (m²/s⁴), held over each interval T (s): the continuous dynamics
ṗ = v, v̇ = −β v + a (a first-order Gauss-Markov velocity, as Singer 1970 models the
acceleration), discretised as the discrete white noise acceleration model of Bar-Shalom,
Li and Kirubarajan 2001 §6.3.2 is:

    F_T = [[1, b], [0, e]],   Γ_T = [c, b]ᵀ,   Q_T = q Γ_T Γ_Tᵀ,
    e = e^{−βT},   b = (1 − e^{−βT})/β,   c = (T − b)/β,

the exact response of [p, v] to a velocity v and to a unit acceleration held over T.
β → 0 gives the CV model (b → T, c → T²/2: :mod:`fusion.models.cv`, the same q); with
β ≈ 1/s and a small q a parked aircraft's estimate averages the plots instead of
following their noise: the velocity is pulled to 0 within a few seconds, and the
stationary velocity variance of the recursion, q b² / (1 − e²), stays a fraction of q.
For βT < 10⁻³ b and c use their series (c loses digits to cancellation otherwise).

The model is a :class:`~fusion.models.cv.ConstantVelocity` (same layout, labels and
position-measurement matrix; its ``q`` has the same meaning), so the IMM mixing and the
layout conversions treat it as CV; the prediction is one compiled loop
(:mod:`fusion.models.damped_velocity_kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import damped_velocity_kernels as kernels
from .base import as_dt_array, states_and_dt
from .cv import ConstantVelocity


@dataclass(frozen=True)
class DampedVelocity(ConstantVelocity):
    """CV with a velocity decaying at ``damping`` β (1/s, ≥ 0; 0 is CV); q, ndim,
    q_vertical as :class:`ConstantVelocity` (the vertical velocity decays at β too)."""

    damping: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.damping >= 0:
            raise ValueError(f"damping = {self.damping}: must be >= 0 1/s")

    def _terms(self, dt: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """(e, b, c) per interval (module docstring) and whether dt was a scalar."""
        t, scalar = as_dt_array(dt)
        e, b, c = kernels.axis_terms(np.ascontiguousarray(t), float(self.damping))
        return e, b, c, scalar

    def F(self, dt: float | np.ndarray) -> np.ndarray:
        """Transition matrix, (d, d) for scalar dt or (n, d, d) for an array of n dt [s]."""
        e, b, _, scalar = self._terms(dt)
        F = np.zeros((e.size, self.dim, self.dim))
        for a in range(self.ndim):
            i = 2 * a
            F[:, i, i] = 1.0
            F[:, i, i + 1] = b
            F[:, i + 1, i + 1] = e
        return F[0] if scalar else F

    def Q(self, dt: float | np.ndarray) -> np.ndarray:
        """Process covariance q Γ Γᵀ per axis, (d, d) or (n, d, d)."""
        _, b, c, scalar = self._terms(dt)
        Q = np.zeros((b.size, self.dim, self.dim))
        for a, qa in enumerate(self._axis_q()):
            i = 2 * a
            Q[:, i, i] = qa * c * c
            Q[:, i, i + 1] = Q[:, i + 1, i] = qa * c * b
            Q[:, i + 1, i + 1] = qa * b * b
        return Q[0] if scalar else Q

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float | np.ndarray):
        """x⁻ = F x, P⁻ = F P Fᵀ + Q of n states x (n, d), P (n, d, d) over dt (scalar or
        (n,)) s, one compiled loop (same values as :meth:`F` and :meth:`Q`)."""
        x, t = states_and_dt(x, dt)
        P = np.ascontiguousarray(P, dtype=np.float64)
        qv = self.q if self.q_vertical is None else self.q_vertical
        return kernels.predict(x, P, t, float(self.damping), float(self.q), float(qv))

    def stationary_velocity_variance(self, dt: float) -> float:
        """q b² / (1 − e²) (m²/s²): the velocity variance the prediction over steps of
        ``dt`` s tends to without measurements (β > 0)."""
        e, b, _, _ = self._terms(dt)
        return float(self.q * b[0] ** 2 / (1.0 - e[0] ** 2))
