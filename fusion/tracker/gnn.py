"""GNN association with existence: the single most probable joint event ([MZD] §5).

The score of giving plot i to track τ instead of nothing is the log of the ratio of the
joint-event factors of (6.2) *given that the tracks exist* (ψ = 1, the classical GNN: a
low-existence tentative track must still be able to take its plot):
L_τi = ln(P_D P_G p^τ_i/ρ_i) − ln(1 − P_D P_G). Maximising Σ L over one-to-one
assignments (with a zero-score "no plot" option per track) gives the MAP joint event;
the one sparse assignment of skyfuse (:func:`fusion.association.assign_sparse`, scipy's
Jonker–Volgenant per cluster of tracks sharing plots) solves it.
The chosen plot gets β = 1 and existence is updated with that plot alone:
Λ = 1 − P_D P_G + P_D P_G p_i/ρ_i (assigned) or 1 − P_D P_G (none), ψ by (5.18).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.assignment import assign_jv, assign_sparse

from .ipda import AssociationResult, existence_update, likelihood_ratio


def gnn_association(
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    tp_track: np.ndarray,
    tp_plot: np.ndarray,
    nplots: int,
    ratio: np.ndarray,
) -> AssociationResult:
    """One plot or none per track, each plot to at most one track, maximising Σ L_τi."""
    n = len(psi_pred)
    chosen = np.full(n, -1, dtype=np.int64)  # table row given to each track
    if len(tp_track):
        score = np.log(pdpg[tp_track] * ratio) - np.log(1.0 - pdpg[tp_track])
        # "no plot" costs 0 (the reference of the score)
        chosen = assign_sparse(tp_track, tp_plot, -score, np.zeros(n), n, nplots, assign_jv)
    has = chosen >= 0
    ratio_sum = np.zeros(n)
    ratio_sum[has] = ratio[chosen[has]]
    lam = likelihood_ratio(pdpg, ratio_sum)
    psi_post = existence_update(psi_pred, lam)
    beta0 = np.where(has, 0.0, 1.0)
    beta = np.zeros(len(tp_track))
    beta[chosen[has]] = 1.0
    return AssociationResult(psi_post, beta0, beta, {"assigned": int(has.sum())})
