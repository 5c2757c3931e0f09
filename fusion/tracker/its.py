"""ITS component update ([thesis] (5.12)-(5.15), (4.70)-(4.71); multi-target β: §6.2.1).

Every predicted component c spawns a "no plot" child (ξ^{c,0} = β_0 ξ^c, x̂ and P
unchanged, 5.12) and one child per plot i it gated (ξ^{c,i} = β_i ξ^c p^c_i / p^τ_i with the
Kalman update and Joseph covariance, 5.14). With IPDA/ITS β this is (5.15); with JIPDA or
LM-IPDA β it is the multi-target update. The child's plot history is the new plot's id
(0 for none) followed by the first N−1 entries of the parent's history ([thesis] §5.3).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.gating import GatedPairs
from skyfuse.fusion.filters.kalman import update_with_innovation

from .components import Mixture


def shift_history(hist: np.ndarray, new_ids: np.ndarray) -> np.ndarray:
    """h' = (new id, h[0], …, h[N−2]); an (C, 0) history stays empty (N = 0)."""
    if hist.shape[1] == 0:
        return hist
    return np.column_stack([new_ids, hist[:, :-1]])


def component_update(
    pred: Mixture,
    loc: np.ndarray,
    pairs: GatedPairs,
    p_pair: np.ndarray,
    row: np.ndarray,
    p_track: np.ndarray,
    beta0: np.ndarray,
    beta: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    plot_uid: np.ndarray,
) -> Mixture:
    """Children of the predicted components ``pred`` (before merging).

    loc (C,): each component's track in the association arrays; pairs: gated (component,
    plot) pairs; p_pair: p^c_i = N(ν; 0, S)/P_G per pair; row: each pair's track–plot table
    row; p_track: p^τ_i per row; beta0 per track; beta per row; H (k, d); R (m, k, k) plot
    covariances; plot_uid (m,) the plots' history ids (≥ 1)."""
    w0 = pred.w * beta0[loc]
    null = Mixture(
        pred.track,
        w0,
        pred.x,
        pred.P,
        shift_history(pred.hist, np.zeros(len(pred), np.int64)),
    )
    if len(pairs) == 0:
        children = null
    else:
        wi = pred.w[pairs.state] * beta[row] * p_pair / p_track[row]
        # children of weight 0 (GNN: all pairs but the chosen one) are dropped below:
        # no Kalman update for them
        live = np.flatnonzero(wi > 0.0)
        c, plot, wi, S, nu = (
            pairs.state[live],
            pairs.plot[live],
            wi[live],
            pairs.S[live],
            pairs.nu[live],
        )
        x, Pn = update_with_innovation(pred.x[c], pred.P[c], H, S, nu, R[plot])
        upd = Mixture(pred.track[c], wi, x, Pn, shift_history(pred.hist[c], plot_uid[plot]))
        children = Mixture.concat([null, upd])
    keep = children.w > 0.0
    return children.take(np.flatnonzero(keep)) if not keep.all() else children
