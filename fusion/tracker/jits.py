"""JIPDA / JITS: exact joint association per cluster ([thesis] §6.2.1, eq. 6.1-6.10).

Tracks that share gated plots form clusters (connected components of the track–plot
graph). In each cluster every feasible joint event e (each track takes at most one of its
gated plots, each plot goes to at most one track) has the probability (6.2)

    P(e) ∝ Π_{τ∈T₀(e)} (1 − P_D P_G ψ^τ) · Π_{τ∈T₁(e)} P_D P_G ψ^τ p^τ_{i(e,τ)} / ρ_{i(e,τ)}

and the marginals give ψ^τ_{k|k} (6.4-6.7) and β^τ_i (6.8). The events of a cluster are
built column by column as NumPy arrays; when their number would exceed ``max_events``
the cluster falls back to the LM approximation (counted in ``stats['lm_fallback']``).
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.assignment import track_clusters as clusters

from .ipda import AssociationResult, single_target

__all__ = ["clusters", "event_count", "feasible_events", "joint_association"]


def feasible_events(
    options: list[np.ndarray], option_plots: list[np.ndarray], max_events: int
) -> np.ndarray | None:
    """All feasible joint events of a cluster as an (E, T) array of table-row indices
    (−1 = the track gets no plot), or None if E would exceed ``max_events`` (6.1).

    options[a]: the table rows of track a; option_plots[a]: their plot indices."""
    T = len(options)
    rows = np.full((1, 0), -1, dtype=np.int64)
    plots = np.full((1, 0), -1, dtype=np.int64)
    for a in range(T):
        new_rows = [np.column_stack([rows, np.full(len(rows), -1)])]
        new_plots = [np.column_stack([plots, np.full(len(plots), -1)])]
        total = len(rows)
        for q, j in zip(options[a], option_plots[a]):
            free = ~(plots == j).any(axis=1)
            cnt = int(free.sum())
            if cnt == 0:
                continue
            total += cnt
            if total > max_events:
                return None
            new_rows.append(np.column_stack([rows[free], np.full(cnt, q)]))
            new_plots.append(np.column_stack([plots[free], np.full(cnt, j)]))
        rows = np.concatenate(new_rows)
        plots = np.concatenate(new_plots)
        if len(rows) > max_events:
            return None
    return rows


def event_count(n: int, m: int) -> int:
    """Feasible events of n tracks and m plots, all mutually gated (6.9-6.10):
    Σ_j C(n, j) C(m, j) j!."""
    from math import comb, factorial

    return sum(comb(n, j) * comb(m, j) * factorial(j) for j in range(min(n, m) + 1))


def joint_association(
    psi_pred: np.ndarray,
    pdpg: np.ndarray,
    tp_track: np.ndarray,
    tp_plot: np.ndarray,
    nplots: int,
    ratio: np.ndarray,
    max_events: int,
    fallback: AssociationResult | None = None,
) -> AssociationResult:
    """JIPDA marginals per cluster (6.2-6.8). Singleton clusters use the closed IPDA form
    (identical to enumeration for one track). ``fallback`` (the LM result for all tracks)
    is used for clusters with more than ``max_events`` events."""
    n = len(psi_pred)
    res = single_target(psi_pred, pdpg, tp_track, ratio)
    stats = {"clusters": 0, "events": 0, "lm_fallback": 0}
    if len(tp_track) == 0:
        res.stats = stats
        return res
    labels = clusters(tp_track, tp_plot, n, nplots)
    size = np.bincount(labels)
    multi = np.flatnonzero(size[labels] > 1)
    if len(multi) == 0:
        res.stats = stats
        return res
    # group table rows per track
    order = np.argsort(tp_track, kind="stable")
    starts = np.searchsorted(tp_track[order], np.arange(n + 1))
    member_order = multi[np.argsort(labels[multi], kind="stable")]
    lab_sorted = labels[member_order]
    bounds = np.flatnonzero(np.diff(lab_sorted)) + 1
    q_none = 1.0 - pdpg * psi_pred
    log_det = np.log(pdpg[tp_track] * psi_pred[tp_track] * ratio)
    for members in np.split(member_order, bounds):
        stats["clusters"] += 1
        opts = [order[starts[a] : starts[a + 1]] for a in members]
        events = feasible_events(opts, [tp_plot[o] for o in opts], max_events)
        if events is None:
            stats["lm_fallback"] += 1
            if fallback is None:
                raise ValueError("cluster exceeds max_events and no LM fallback was given")
            res.psi_post[members] = fallback.psi_post[members]
            res.beta0[members] = fallback.beta0[members]
            for o in opts:
                res.beta[o] = fallback.beta[o]
            continue
        stats["events"] += len(events)
        assigned = events >= 0
        lw = np.where(assigned, log_det[np.maximum(events, 0)], np.log(q_none[members])[None, :])
        lw = lw.sum(axis=1)
        Pe = np.exp(lw - lw.max())
        Pe /= Pe.sum()  # c_k (6.3)
        p0 = (Pe[:, None] * ~assigned).sum(axis=0)  # (6.4)
        psi = psi_pred[members]
        d = pdpg[members]
        p0_chi = p0 * (1.0 - d) * psi / (1.0 - d * psi)  # (6.5)
        acc = np.zeros(len(ratio))
        np.add.at(acc, events[assigned], np.broadcast_to(Pe[:, None], events.shape)[assigned])
        rows = np.concatenate(opts)
        owner = np.concatenate([np.full(len(o), k) for k, o in enumerate(opts)])
        p_rows = acc[rows]  # (6.6)
        psi_post = p0_chi + np.bincount(owner, weights=p_rows, minlength=len(members))  # (6.7)
        res.psi_post[members] = psi_post
        res.beta0[members] = p0_chi / psi_post  # (6.8)
        res.beta[rows] = p_rows / psi_post[owner]
    res.stats = stats
    return res
