"""Singer (1970) exponentially correlated acceleration model ([MZD] eq. 8-10).

Per axis the state is [p, v, a]; the acceleration is a first-order Markov process
ȧ = −α a + w with α = 1/τ (τ: manoeuvre time constant, s) and stationary variance σ_m²,
so w is white with spectral density 2ασ_m². Exact discretisation (Singer 1970):

    F_T = [[1, T, (αT − 1 + e^{−αT})/α²], [0, 1, (1 − e^{−αT})/α], [0, 0, e^{−αT}]]
    Q_T = 2ασ_m² · q(α, T),   q_ij of Singer 1970 Table I:
      q11 = (1 − e^{−2αT} + 2αT + 2α³T³/3 − 2α²T² − 4αT e^{−αT}) / (2α⁵)
      q12 = (e^{−2αT} + 1 − 2e^{−αT} + 2αT e^{−αT} − 2αT + α²T²) / (2α⁴)
      q13 = (1 − e^{−2αT} − 2αT e^{−αT}) / (2α³)
      q22 = (4e^{−αT} − 3 − e^{−2αT} + 2αT) / (2α³)
      q23 = (e^{−2αT} + 1 − 2e^{−αT}) / (2α²)
      q33 = (1 − e^{−2αT}) / (2α)

(The source prints the CA matrix as Singer's F: that is the αT → 0 limit.) For αT < 0.05
the closed form loses digits to cancellation, so q is summed from the power series of
∫₀ᵀ g(s) g(s)ᵀ ds, g(s) = e^{As}B, instead (same function, exact to rounding).
σ_m² from the manoeuvre statistics (Singer 1970): σ_m² = A_max² (1 + 4 P_max − P_0) / 3.
Interleaved state [x, vx, ax, y, vy, ay(, z, vz, az)].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .base import as_dt_array
from .ca import PositionVelocityAcceleration, block_diag_axes

_SERIES_BELOW = 0.05
_SERIES_TERMS = 14


def singer_sigma_m2(a_max: float, p_max: float, p_0: float) -> float:
    """Singer's acceleration variance σ_m² = A_max² (1 + 4 P_max − P_0) / 3, m²/s⁴."""
    for name, p in (("p_max", p_max), ("p_0", p_0)):
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"{name} = {p}: must be a probability in [0, 1]")
    if p_max + p_0 > 1.0:
        raise ValueError(f"p_max + p_0 = {p_max + p_0}: must be <= 1")
    return a_max**2 * (1.0 + 4.0 * p_max - p_0) / 3.0


def singer_axis_F(t: np.ndarray, alpha: float) -> np.ndarray:
    """(n, 3, 3) exact per-axis Singer transition."""
    x = alpha * t
    e = np.exp(-x)
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, 0, 1] = t
    small = np.abs(x) < 1e-4  # series near 0 (either sign: F(-Δ) retrodicts)
    F[:, 0, 2] = np.where(small, t * t / 2 - alpha * t**3 / 6, (x - 1 + e) / alpha**2)
    F[:, 1, 2] = -np.expm1(-x) / alpha
    F[:, 2, 2] = e
    return F


def _q_closed(alpha: float, t: np.ndarray) -> np.ndarray:
    a, x = alpha, alpha * t
    e1, e2 = np.exp(-x), np.exp(-2 * x)
    q = np.empty((t.size, 3, 3))
    q[:, 0, 0] = (1 - e2 + 2 * x + 2 * x**3 / 3 - 2 * x**2 - 4 * x * e1) / (2 * a**5)
    q[:, 0, 1] = (e2 + 1 - 2 * e1 + 2 * x * e1 - 2 * x + x**2) / (2 * a**4)
    q[:, 0, 2] = (1 - e2 - 2 * x * e1) / (2 * a**3)
    q[:, 1, 1] = (4 * e1 - 3 - e2 + 2 * x) / (2 * a**3)
    q[:, 1, 2] = (e2 + 1 - 2 * e1) / (2 * a**2)
    q[:, 2, 2] = (1 - e2) / (2 * a)
    q[:, 1, 0], q[:, 2, 0], q[:, 2, 1] = q[:, 0, 1], q[:, 0, 2], q[:, 1, 2]
    return q


def _q_series(alpha: float, t: np.ndarray) -> np.ndarray:
    """q_ij = Σ_k Σ_l c_ik c_jl T^{k+l+1}/(k+l+1), with g_i(s) = Σ_k c_ik s^k:
    c_1k = (−α)^{k−2}/k! (k ≥ 2), c_2k = (−α)^{k−1}/k! (k ≥ 1), c_3k = (−α)^k/k!."""
    K = _SERIES_TERMS
    c = np.zeros((3, K))
    for k in range(K):
        fk = math.factorial(k)
        if k >= 2:
            c[0, k] = (-alpha) ** (k - 2) / fk
        if k >= 1:
            c[1, k] = (-alpha) ** (k - 1) / fk
        c[2, k] = (-alpha) ** k / fk
    kl = np.add.outer(np.arange(K), np.arange(K)) + 1  # k + l + 1
    powers = t[:, None, None] ** kl[None] / kl[None]  # (n, K, K)
    return np.einsum("ik,jl,nkl->nij", c, c, powers)


def singer_axis_q(t: np.ndarray, alpha: float) -> np.ndarray:
    """(n, 3, 3) Singer q(α, T) (Q = 2ασ_m² q)."""
    q = np.empty((t.size, 3, 3))
    small = alpha * t < _SERIES_BELOW
    if small.any():
        q[small] = _q_series(alpha, t[small])
    if (~small).any():
        q[~small] = _q_closed(alpha, t[~small])
    return q


@dataclass(frozen=True)
class Singer(PositionVelocityAcceleration):
    """Singer model over ``ndim`` axes. tau: manoeuvre time constant (s);
    sigma_m: acceleration standard deviation (m/s²). Use :meth:`from_maneuver` for the
    source's parametrisation (τ = 10 s, A_max = 40 m/s², P_max, P_0)."""

    tau: float = 10.0
    sigma_m: float = 10.0
    ndim: int = 2
    sigma_m_vertical: float | None = None

    def __post_init__(self) -> None:
        self._check_ndim()
        if not self.tau > 0:
            raise ValueError(f"tau = {self.tau}: must be > 0 s")
        if not self.sigma_m >= 0:
            raise ValueError(f"sigma_m = {self.sigma_m}: must be >= 0 m/s²")

    @classmethod
    def from_maneuver(
        cls, tau: float, a_max: float, p_max: float, p_0: float, ndim: int = 2
    ) -> Singer:
        return cls(tau=tau, sigma_m=math.sqrt(singer_sigma_m2(a_max, p_max, p_0)), ndim=ndim)

    @property
    def alpha(self) -> float:
        return 1.0 / self.tau

    def F(self, dt: float | np.ndarray) -> np.ndarray:
        t, scalar = as_dt_array(dt)
        F = block_diag_axes([singer_axis_F(t, self.alpha)] * self.ndim)
        return F[0] if scalar else F

    def Q(self, dt: float | np.ndarray) -> np.ndarray:
        t, scalar = as_dt_array(dt)
        q = singer_axis_q(t, self.alpha)
        sig = [self.sigma_m] * self.ndim
        if self.ndim == 3 and self.sigma_m_vertical is not None:
            sig[2] = self.sigma_m_vertical
        Q = block_diag_axes([2 * self.alpha * s * s * q for s in sig])
        return Q[0] if scalar else Q

    def H(self) -> np.ndarray:
        H = np.zeros((self.ndim, self.dim))
        H[np.arange(self.ndim), list(self.position_index)] = 1.0
        return H
