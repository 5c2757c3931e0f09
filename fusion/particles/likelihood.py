"""Per-particle Gaussian likelihoods of gated plots, all pairs × particles in one expression
([LM-IPF] eq. 7-8; [thesis] (3.43–3.45)).

For gated pair (track τ, plot j) and particle i of τ's predicted cloud:

    ϑ_{ij} = z_j − H x^i,   p^i_j = exp(−½ ϑᵀ R_j⁻¹ ϑ) / √det(2π R_j)  ([LM-IPF] eq. 8, typos fixed)

The plot's own R_j is used, not one R for all plots: in skyfuse every polar plot is
converted into the system plane with its own covariance (it depends on the plot's range,
azimuth and the radar's accuracy, so two radars' plots of one aircraft differ by an order
of magnitude), and the particles live in that plane. Evaluating each plot with its own
converted R keeps p^τ_j on the same scale as the Gaussian trackers' likelihoods and the
clutter density ρ_j, and the conversion's linearisation error is negligible over a cloud
whose extent (tens to hundreds of metres) is far below the range. (The alternative, the
likelihood in each radar's polar coordinates, needs a per-particle polar transform per
radar and gives the same result at the ranges and accuracies of air surveillance.)

Computed by whitening with R_j = L Lᵀ: ϑ L⁻ᵀ is one batched matmul over (pairs, N, k).
"""

from __future__ import annotations

import numpy as np


def plot_whitening(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L⁻¹ (m, k, k) with R = L Lᵀ and log √det(2πR) (m,) per plot."""
    L = np.linalg.cholesky(R)
    Linv = np.linalg.inv(L)
    k = R.shape[-1]
    half_logdet = np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1) + 0.5 * k * np.log(
        2.0 * np.pi
    )
    return Linv, half_logdet


#: particle-pair evaluations per block: bounds the temporaries to ~50 MB whatever the
#: number of gated pairs (2-D: 2^20 × (2 + 2 + 1) doubles)
BLOCK = 1 << 20


def pair_likelihoods(
    zp: np.ndarray, z: np.ndarray, R: np.ndarray, tp_track: np.ndarray, tp_plot: np.ndarray
) -> np.ndarray:
    """p^i_j (pairs, N) for predicted measurements of the particles zp (s, N, k), plots
    z (m, k) with covariances R (m, k, k) and gated pairs (tp_track into zp, tp_plot).
    Pairs are processed in blocks of ``BLOCK`` particle evaluations (bounded memory)."""
    P, N = len(tp_track), zp.shape[1]
    out = np.empty((P, N))
    if P == 0:
        return out
    Linv, half_logdet = plot_whitening(R)
    step = max(1, BLOCK // max(N, 1))
    for a in range(0, P, step):
        t, j = tp_track[a : a + step], tp_plot[a : a + step]
        nu = z[j][:, None, :] - zp[t]  # (p, N, k)
        white = nu @ np.swapaxes(Linv[j], -1, -2)
        d2 = np.einsum("pnk,pnk->pn", white, white)
        np.exp(-0.5 * d2 - half_logdet[j][:, None], out=out[a : a + step])
    return out
