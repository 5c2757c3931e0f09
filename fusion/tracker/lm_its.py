"""Linear multi-target (LM-IPDA / LM-ITS) clutter modulation ([thesis] §6.2.2-6.2.3, eq. 6.11-6.22).

Other tracks are treated as extra clutter: each track τ is updated as a single-target
ITS/IPDA track with ρ_i replaced by the modified density

    ρ̃^τ_i = ρ_i + Σ_{σ≠τ} p^σ_i P^σ_i / (1 − P^σ_i)                     (6.14)

where P^σ_i, the prior probability that plot i is track σ's detection, is

    P^σ_i = P_D P_G ψ^σ_{k|k−1} (p^σ_i/ρ'_i) / Σ_j (p^σ_j/ρ'_j)          (6.12)

with ρ' = ρ ("canonical", Mušicki & La Scala 2008) or ρ' = ρ^σ_i of (6.13), clutter plus the
other tracks' expected detection density ("thesis"). All P^σ come from the predictions
first (Jacobi order), then every ρ̃, so the cost is linear in tracks × gated plots.
Existence and β then follow (6.18-6.22) = :func:`fusion.tracker.ipda.single_target`.
"""

from __future__ import annotations

import numpy as np


def modified_clutter_density(
    tp_track: np.ndarray,
    tp_plot: np.ndarray,
    nplots: int,
    p: np.ndarray,
    rho: np.ndarray,
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    prior: str = "canonical",
) -> np.ndarray:
    """ρ̃ per track–plot row (6.14). ``p`` = track likelihood p^τ_i per row, ``rho`` = the
    clutter density the row's track uses, ``psi_pred``/``pdpg`` per track."""
    n = len(psi_pred)
    if len(p) == 0:
        return rho.copy()
    expected = pdpg[tp_track] * psi_pred[tp_track] * p  # P_D P_G ψ^σ p^σ_i
    if prior == "thesis":
        total = np.bincount(tp_plot, weights=expected, minlength=nplots)
        rho_prior = rho + total[tp_plot] - expected  # (6.13)
    elif prior == "canonical":
        rho_prior = rho
    else:
        raise ValueError(f"prior = {prior!r}: must be 'canonical' or 'thesis'")
    r = p / rho_prior
    rsum = np.bincount(tp_track, weights=r, minlength=n)[tp_track]
    # (6.12); a track whose gated plots all have likelihood 0 (a particle cloud far from
    # them, its likelihoods underflowed) gives them no prior probability, not 0/0
    P = pdpg[tp_track] * psi_pred[tp_track] * r / np.where(rsum > 0.0, rsum, 1.0)
    P = np.minimum(P, 1.0 - 1e-12)
    term = p * P / (1.0 - P)
    per_plot = np.bincount(tp_plot, weights=term, minlength=nplots)
    # (6.14): exclude the row's own track; clip the rounding of the subtraction
    return rho + np.maximum(per_plot[tp_plot] - term, 0.0)
