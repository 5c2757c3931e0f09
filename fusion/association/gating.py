"""Gating of all (predicted state, plot) pairs at once — the one gating of skyfuse
([MZD] §5, eq. 16-20; [thesis] (5.7)).

A predicted state c (a track, or one mixture component / IMM mode of a track) selects
plot j when d² = νᵀ S⁻¹ ν < g with ν = z_j − ŷ^c and S = H P^c Hᵀ + R_j (per-plot R).
g is the chi-square quantile of the gate probability P_G for the measurement dimension
([IMPL]: g = 9.21 ⇔ P_G = 0.99 in 2-D; [MZD]: P_G = 0.9997, g = 16.2235).
Returned per pair: ν, S, d², ln det S, log N(ν; 0, S) (the IPDA likelihood p = N/P_G,
4.17) and the GNN cost d² + ln det S ([MZD] eq. 20).

All pairs are never formed: a spatial pre-gate sorts the plots by their first coordinate
and takes, per state, the window ``searchsorted(x ± r)`` with the radius
r = √(g (tr HPHᵀ + max_j tr R_j)), which bounds √(g λ_max(S)); the other coordinates are
then checked against the same radius, and only the survivors get an exact d². The whole
gate is one compiled call (:mod:`fusion.association.gating_kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammainc, gammaincinv

from .gating_kernels import gate_pairs, windows


def gate_threshold(p_gate: float, ndim: int) -> float:
    """g such that a target's measurement falls in the gate with probability ``p_gate``:
    the χ²_ndim quantile, 2 P⁻¹(ndim/2, p_gate) with P the regularised lower incomplete
    gamma function (2-D: g = −2 ln(1 − P_G)). The one χ² threshold of skyfuse (plot
    gates, duplicate and re-identification tests, the registration's pair gate).
    ``scipy.special`` rather than ``scipy.stats.chi2``: the same function (bitwise), without
    the 0.5 s import of ``scipy.stats`` at every command's start."""
    if not 0.0 < p_gate < 1.0:
        raise ValueError(f"p_gate = {p_gate}: must be a probability in (0, 1)")
    if ndim < 1:
        raise ValueError(f"dim = {ndim}: must be >= 1")
    return float(2.0 * gammaincinv(0.5 * ndim, p_gate))


def gate_probability(g: float, ndim: int) -> float:
    """P_G = P(χ²_ndim < g) = P(ndim/2, g/2); 2-D closed form 1 − e^{−g/2}."""
    return float(gammainc(0.5 * ndim, 0.5 * g))


def unit_ball_volume(ndim: int) -> float:
    """Volume of the unit ball: π (2-D), 4π/3 (3-D)."""
    return {1: 2.0, 2: np.pi, 3: 4.0 * np.pi / 3.0}[ndim]


def gate_volume(S: np.ndarray, g: float) -> np.ndarray:
    """Volume of the gate {νᵀS⁻¹ν < g}: c_n g^{n/2} √det S ([LIT]: π g √det S in 2-D)."""
    n = S.shape[-1]
    return unit_ball_volume(n) * g ** (n / 2) * np.sqrt(np.maximum(np.linalg.det(S), 0.0))


def window_pairs(
    centres: np.ndarray, radii: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """All (i, j) with |points[j] − centres[i]| ≤ radii[i] in every coordinate (a box test).

    centres (n, k), radii (n,), points (m, k). Cost O((n + m) log m + pairs in windows)."""
    n, m = len(centres), len(points)
    if n == 0 or m == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    c = np.ascontiguousarray
    return windows(c(centres, dtype=np.float64), c(radii, dtype=np.float64),
                   c(points, dtype=np.float64))  # fmt: skip


@dataclass
class GatedPairs:
    """Gated (state, plot) pairs with their innovation statistics.

    state, plot (p,): indices; nu (p, k) innovations; S (p, k, k) innovation covariances;
    d2 (p,) squared Mahalanobis distances; logdet (p,) ln det S; n_states, n_plots: the
    problem size; n_pregated: pairs that survived the pre-gate."""

    state: np.ndarray
    plot: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    d2: np.ndarray
    logdet: np.ndarray
    n_states: int = 0
    n_plots: int = 0
    n_pregated: int = 0

    def __len__(self) -> int:
        return len(self.state)

    @property
    def log_pdf(self) -> np.ndarray:
        """log N(ν; 0, S) = −(d² + ln det S + k ln 2π)/2."""
        k = self.nu.shape[1]
        return -0.5 * (self.d2 + self.logdet + k * np.log(2.0 * np.pi))

    @property
    def cost(self) -> np.ndarray:
        """GNN cost d² + ln det S ([MZD] eq. 20)."""
        return self.d2 + self.logdet

    def cost_matrix(self) -> np.ndarray:
        """Dense (n_states, n_plots) cost with +inf for pairs outside the gate."""
        C = np.full((self.n_states, self.n_plots), np.inf)
        C[self.state, self.plot] = self.cost
        return C


def gate(
    y_pred: np.ndarray, HPHt: np.ndarray, z: np.ndarray, R: np.ndarray | None, g: float
) -> GatedPairs:
    """Gate states (predicted measurements ``y_pred`` (n, k), ``HPHt`` (n, k, k)) against
    plots ``z`` (m, k) with covariances ``R`` (m, k, k) (None: already inside HPHt)."""
    y_pred = np.atleast_2d(np.asarray(y_pred, dtype=np.float64))
    k = y_pred.shape[1]
    z = np.asarray(z, dtype=np.float64).reshape(-1, k)
    n, m = len(y_pred), len(z)
    if n == 0 or m == 0:
        e = np.zeros(0, np.int64)
        f = np.zeros(0)
        return GatedPairs(e, e, np.zeros((0, k)), np.zeros((0, k, k)), f, f, n, m, 0)
    c = np.ascontiguousarray
    state, plot, nu, S, d2, logdet, pregated = gate_pairs(
        c(y_pred),
        c(HPHt, dtype=np.float64),
        c(z),
        np.zeros((1, k, k)) if R is None else c(R, dtype=np.float64),
        R is not None,
        float(g),
    )
    return GatedPairs(state, plot, nu, S, d2, logdet, n, m, pregated)
