"""Gating of all (mixture component, plot) pairs at once (spec 02 §7 step 4, eq. 5.7).

A component c selects plot j when d² = νᵀ S⁻¹ ν < g with ν = z_j − ŷ^c and
S = H P^c Hᵀ + R_j (per-plot R). g is the chi-square quantile of the gate probability
P_G (spec 02 §10 [IMPL]: g = 9.21 ⇔ P_G = 0.99 in 2-D).

All pairs are never formed: a spatial pre-gate sorts the plots by their first coordinate
and takes, per component, the window ``searchsorted(x ± r)`` with the radius
r = √(g (tr HPHᵀ + max_j tr R_j)), which bounds √(g λ_max(S)); the other coordinates are
then checked against the same radius, and only the survivors get an exact d².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2


def gate_threshold(p_gate: float, ndim: int) -> float:
    """g such that a target's measurement falls in the gate with probability ``p_gate``."""
    return float(chi2.ppf(p_gate, ndim))


def gate_probability(g: float, ndim: int) -> float:
    """P_G = P(χ²_ndim < g); 2-D closed form 1 − e^{−g/2}."""
    return float(chi2.cdf(g, ndim))


def unit_ball_volume(ndim: int) -> float:
    """Volume of the unit ball: π (2-D), 4π/3 (3-D)."""
    return {1: 2.0, 2: np.pi, 3: 4.0 * np.pi / 3.0}[ndim]


def gate_volume(S: np.ndarray, g: float) -> np.ndarray:
    """Volume of the gate {νᵀS⁻¹ν < g}: c_n g^{n/2} √det S (spec 02 §4 [LIT]: π g √det S)."""
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
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    lo = np.searchsorted(xs, centres[:, 0] - radii, side="left")
    hi = np.searchsorted(xs, centres[:, 0] + radii, side="right")
    counts = hi - lo
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i = np.repeat(np.arange(n), counts)
    starts = np.repeat(lo - (np.cumsum(counts) - counts), counts)
    j = order[starts + np.arange(total)]
    if points.shape[1] > 1:
        keep = (np.abs(points[j, 1:] - centres[i, 1:]) <= radii[i, None]).all(axis=1)
        i, j = i[keep], j[keep]
    return i, j


@dataclass
class GatedPairs:
    """Gated (component, plot) pairs with their innovation statistics.

    comp, plot: indices; nu (p, k) innovations; S (p, k, k) innovation covariances;
    d2 (p,) squared Mahalanobis distances; log_pdf (p,) log N(ν; 0, S)."""

    comp: np.ndarray
    plot: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    d2: np.ndarray
    log_pdf: np.ndarray

    def __len__(self) -> int:
        return len(self.comp)


def gate(
    y_pred: np.ndarray, HPHt: np.ndarray, z: np.ndarray, R: np.ndarray, g: float
) -> GatedPairs:
    """Gate components (predicted measurements ``y_pred`` (n, k), ``HPHt`` (n, k, k))
    against plots ``z`` (m, k) with covariances ``R`` (m, k, k) (5.7-5.9)."""
    k = z.shape[1] if z.ndim == 2 else y_pred.shape[1]
    if len(y_pred) == 0 or len(z) == 0:
        e = np.zeros(0, np.int64)
        f = np.zeros(0)
        return GatedPairs(e, e, np.zeros((0, k)), np.zeros((0, k, k)), f, f)
    trR = np.trace(R, axis1=1, axis2=2).max()
    radius = np.sqrt(g * (np.trace(HPHt, axis1=1, axis2=2) + trR))
    ci, pj = window_pairs(y_pred, radius, z)
    S = HPHt[ci] + R[pj]
    nu = z[pj] - y_pred[ci]
    L = np.linalg.cholesky(S)
    w = np.linalg.solve(L, nu[..., None])[..., 0]
    d2 = np.einsum("pi,pi->p", w, w)
    keep = d2 < g
    ci, pj, S, nu, d2, L = ci[keep], pj[keep], S[keep], nu[keep], d2[keep], L[keep]
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    log_pdf = -0.5 * (d2 + logdet + k * np.log(2.0 * np.pi))
    return GatedPairs(ci, pj, nu, S, d2, log_pdf)
