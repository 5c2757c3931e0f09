"""Vectorised ellipsoidal gating of all track × plot pairs (spec 01 §6, 003 eq. 16-20).

For track i with predicted measurement ẑ_i and plot j: ν_ij = z_j − ẑ_i,
S_ij = S_i + R_j (S_i = H P_i⁻ Hᵀ; R_j the plot's covariance, or already inside S_i when
plots share one R), d²_ij = ν_ijᵀ S_ij⁻¹ ν_ij, and the pair is valid when d²_ij ≤ G with
G the chi-square quantile of P_G for the measurement dimension M (M = 2, P_G = 0.9997:
G = −2 ln(1 − P_G) = 16.2235). The cost of a valid pair is A_ij = d²_ij + ln det S_ij;
pairs outside the gate are forbidden (the source writes 0; here +inf).

Cheap pre-gate: the ellipsoid {ν : νᵀ S⁻¹ ν ≤ G} lies inside the box |ν_a| ≤ √(G S_aa),
so only pairs inside that box (an O(n k M) comparison) get the full Mahalanobis distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats


def gate_threshold(p_gate: float, dim: int) -> float:
    """G = chi-square quantile: P(χ²_dim ≤ G) = p_gate (dim 2: −2 ln(1 − p_gate))."""
    if not 0.0 < p_gate < 1.0:
        raise ValueError(f"p_gate = {p_gate}: must be a probability in (0, 1)")
    if dim < 1:
        raise ValueError(f"dim = {dim}: must be >= 1")
    return float(stats.chi2.ppf(p_gate, dim))


@dataclass
class GateResult:
    """Valid pairs (sparse): track index, plot index, d², ln det S and cost d² + ln det S."""

    track: np.ndarray
    plot: np.ndarray
    d2: np.ndarray
    logdet: np.ndarray
    n_tracks: int
    n_plots: int
    n_pregated: int

    @property
    def cost(self) -> np.ndarray:
        return self.d2 + self.logdet

    def cost_matrix(self) -> np.ndarray:
        """Dense (n_tracks, n_plots) cost with +inf for forbidden pairs."""
        C = np.full((self.n_tracks, self.n_plots), np.inf)
        C[self.track, self.plot] = self.cost
        return C


def gate(
    zhat: np.ndarray,
    S_track: np.ndarray,
    z: np.ndarray,
    threshold: float,
    R: np.ndarray | None = None,
) -> GateResult:
    """Gate n tracks (ẑ (n, m), S_track (n, m, m)) against k plots z (k, m) with optional
    per-plot covariances R (k, m, m) added to S (S_ij = S_track_i + R_j)."""
    zhat = np.atleast_2d(np.asarray(zhat, float))
    z = np.asarray(z, float).reshape(-1, zhat.shape[1])
    n, k = zhat.shape[0], z.shape[0]
    empty = np.zeros(0, int)
    if n == 0 or k == 0:
        return GateResult(empty, empty, np.zeros(0), np.zeros(0), n, k, 0)
    diag_t = np.diagonal(S_track, axis1=-2, axis2=-1)  # (n, m)
    diag_r = np.zeros((1, z.shape[1])) if R is None else np.diagonal(R, axis1=-2, axis2=-1)
    nu_abs = np.abs(z[None, :, :] - zhat[:, None, :])  # (n, k, m)
    box = (nu_abs * nu_abs <= threshold * (diag_t[:, None, :] + diag_r[None, :, :])).all(-1)
    ti, pj = np.nonzero(box)
    if ti.size == 0:
        return GateResult(empty, empty, np.zeros(0), np.zeros(0), n, k, 0)
    S = S_track[ti] if R is None else S_track[ti] + R[pj]
    nu = z[pj] - zhat[ti]
    L = np.linalg.cholesky(S)
    y = np.linalg.solve(L, nu[..., None])[..., 0]
    d2 = np.einsum("ci,ci->c", y, y)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1)
    ok = d2 <= threshold
    return GateResult(ti[ok], pj[ok], d2[ok], logdet[ok], n, k, int(ti.size))
