"""Data association: vectorised gating and optimal assignment (auction with ε-scaling and
scipy's Jonker-Volgenant, both with "no assignment" options; [MZD] §5). The trackers
that use them are in :mod:`fusion.tracker` (the GNN of [MZD] is its ``gnn`` kind)."""

from .assignment import (
    Assignment,
    assign_auction,
    assign_jv,
    assign_sparse,
    split_clusters,
    total_cost,
    track_clusters,
)
from .gating import GatedPairs, gate, gate_threshold

__all__ = [
    "Assignment",
    "GatedPairs",
    "assign_auction",
    "assign_jv",
    "assign_sparse",
    "gate",
    "gate_threshold",
    "split_clusters",
    "total_cost",
    "track_clusters",
]
