"""Data association: vectorised gating, optimal assignment (auction with ε-scaling and
scipy's Jonker-Volgenant, both with "no assignment" options) and the GNN tracker with
M-of-N confirmation (spec 01 §6)."""

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
from .gnn import CONFIRMED, TENTATIVE, GNNConfig, GNNTracker, ScanReport

__all__ = [
    "CONFIRMED",
    "TENTATIVE",
    "Assignment",
    "GNNConfig",
    "GNNTracker",
    "GatedPairs",
    "ScanReport",
    "assign_auction",
    "assign_jv",
    "assign_sparse",
    "gate",
    "gate_threshold",
    "split_clusters",
    "total_cost",
    "track_clusters",
]
