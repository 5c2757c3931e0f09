"""Data association: vectorised gating, optimal assignment (auction with ε-scaling and
scipy's Jonker-Volgenant, both with "no assignment" options) and the GNN tracker with
M-of-N confirmation (spec 01 §6)."""

from .assignment import Assignment, assign_auction, assign_jv, split_clusters, total_cost
from .gating import GateResult, gate, gate_threshold
from .gnn import CONFIRMED, TENTATIVE, GNNConfig, GNNTracker, ScanReport

__all__ = [
    "CONFIRMED",
    "TENTATIVE",
    "Assignment",
    "GNNConfig",
    "GNNTracker",
    "GateResult",
    "ScanReport",
    "assign_auction",
    "assign_jv",
    "gate",
    "gate_threshold",
    "split_clusters",
    "total_cost",
]
