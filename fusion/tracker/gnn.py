"""GNN association with existence: the single most probable joint event (spec 01 §6).

The score of giving plot i to track τ instead of nothing is the log of the ratio of the
joint-event factors of (6.2) *given that the tracks exist* (ψ = 1, the classical GNN: a
low-existence tentative track must still be able to take its plot):
L_τi = ln(P_D P_G p^τ_i/ρ_i) − ln(1 − P_D P_G). Maximising Σ L over one-to-one
assignments (with a zero-score "no plot" option per track) gives the MAP joint event;
the Jonker–Volgenant solver of :func:`fusion.association.assign_jv` (scipy's
``linear_sum_assignment`` with "no assignment" columns) solves it per cluster of tracks
sharing plots.
The chosen plot gets β = 1 and existence is updated with that plot alone:
Λ = 1 − P_D P_G + P_D P_G p_i/ρ_i (assigned) or 1 − P_D P_G (none), ψ by (5.18).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association import assign_jv

from .ipda import AssociationResult, existence_update, likelihood_ratio
from .jits import clusters


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
        labels = clusters(tp_track, tp_plot, n, nplots)
        size = np.bincount(labels)
        single = size[labels[tp_track]] == 1
        # singleton clusters: the best positive-score row of the track
        rows = np.flatnonzero(single & (score > 0))
        if len(rows):
            order = rows[np.lexsort((-score[rows], tp_track[rows]))]
            first = np.r_[True, tp_track[order][1:] != tp_track[order][:-1]]
            chosen[tp_track[order[first]]] = order[first]
        multi_rows = np.flatnonzero(~single)
        lab = labels[tp_track[multi_rows]]
        for lbl in np.unique(lab):
            r = multi_rows[lab == lbl]
            trk, ti = np.unique(tp_track[r], return_inverse=True)
            plt, pi = np.unique(tp_plot[r], return_inverse=True)
            cost = np.full((len(trk), len(plt)), np.inf)  # +inf: not gated
            cost[ti, pi] = -score[r]
            # "no plot" costs 0 (the reference of the score); fusion.association's JV
            t2p = assign_jv(cost, np.zeros(len(trk))).track_to_plot
            for a in np.flatnonzero(t2p >= 0):
                if cost[a, t2p[a]] < 0:
                    chosen[trk[a]] = r[(ti == a) & (pi == t2p[a])][0]
    has = chosen >= 0
    ratio_sum = np.zeros(n)
    ratio_sum[has] = ratio[chosen[has]]
    lam = likelihood_ratio(pdpg, ratio_sum)
    psi_post = existence_update(psi_pred, lam)
    beta0 = np.where(has, 0.0, 1.0)
    beta = np.zeros(len(tp_track))
    beta[chosen[has]] = 1.0
    return AssociationResult(psi_post, beta0, beta, {"assigned": int(has.sum())})
