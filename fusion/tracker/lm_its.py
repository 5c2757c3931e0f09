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

import numba
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
    clutter density the row's track uses, ``psi_pred``/``pdpg`` per track. One compiled
    pass (:func:`modified_density`)."""
    if prior not in ("canonical", "thesis"):
        raise ValueError(f"prior = {prior!r}: must be 'canonical' or 'thesis'")
    c = np.ascontiguousarray
    f = np.float64
    return modified_density(c(tp_track, dtype=np.int64), c(tp_plot, dtype=np.int64),
                            int(nplots), c(p, dtype=f), c(rho, dtype=f), c(psi_pred, dtype=f),
                            c(pdpg, dtype=f), prior == "thesis")  # fmt: skip


@numba.njit(cache=True, nogil=True, error_model="numpy")  # x/0 as in NumPy
def modified_density(tp_track, tp_plot, nplots, p, rho, psi_pred, pdpg, thesis):
    """The loops of :func:`modified_clutter_density`: the expected detection density
    P_D P_G ψ^σ p^σ_i of every row, the priors (6.12) with ρ' of (6.13) when ``thesis``,
    the modulation (6.14) of each row without its own track (sums in row order; the
    subtraction's rounding clipped at 0; a track whose gated plots all have likelihood 0
    gives them no prior probability, not 0/0)."""
    T = len(p)
    if T == 0:
        return rho.copy()
    rho_prior = rho
    if thesis:
        total = np.zeros(nplots)
        for r in range(T):
            total[tp_plot[r]] += pdpg[tp_track[r]] * psi_pred[tp_track[r]] * p[r]
        rho_prior = np.empty(T)
        for r in range(T):
            e = pdpg[tp_track[r]] * psi_pred[tp_track[r]] * p[r]
            rho_prior[r] = rho[r] + total[tp_plot[r]] - e
    ratio = np.empty(T)
    rsum = np.zeros(len(psi_pred))
    for r in range(T):
        ratio[r] = p[r] / rho_prior[r]
        rsum[tp_track[r]] += ratio[r]
    term = np.empty(T)
    per_plot = np.zeros(nplots)
    cap = 1.0 - 1e-12
    for r in range(T):
        t = tp_track[r]
        s = rsum[t]
        P = pdpg[t] * psi_pred[t] * ratio[r] / (s if s > 0.0 else 1.0)
        P = P if (P <= cap or P != P) else cap  # np.minimum
        term[r] = p[r] * P / (1.0 - P)
        per_plot[tp_plot[r]] += term[r]
    out = np.empty(T)
    for r in range(T):
        v = per_plot[tp_plot[r]] - term[r]
        out[r] = rho[r] + (v if (v > 0.0 or v != v) else 0.0)  # np.maximum(v, 0)
    return out
