"""Existence-based multi-target trackers (spec 02, spec 03): IPDA, ITS with Singer N-scan
memory, LM-IPDA/LM-ITS, JIPDA/JITS and GNN in one array-based framework.

>>> from skyfuse.fusion.tracker import Tracker, TrackerConfig, MeasurementBatch
>>> tracker = Tracker(TrackerConfig(tracker="lmits", depth=3))
>>> out = tracker.step(batch)          # one radar sector/scan in the system frame

Modules: ``config`` (TrackerConfig), ``measurements`` (MeasurementBatch, SectorCoverage),
``existence`` (Markov chains), ``gating``, ``ipda`` (Λ, ψ, β), ``lm_its`` (modified
clutter), ``jits`` (clusters, joint events), ``gnn``, ``its`` (component update),
``components`` (mixture store, Singer merge, pruning), ``initiation``, ``management``,
``tracker`` (the step). The wire adapter (PlotBatch → MeasurementBatch) lives in
``skyfuse.services.fusion.adapter``.
"""

from .config import TrackerConfig
from .measurements import MeasurementBatch, SectorCoverage
from .tracker import Tracker, TrackerOutput, TrackEventRecord

__all__ = [
    "MeasurementBatch",
    "SectorCoverage",
    "TrackEventRecord",
    "Tracker",
    "TrackerConfig",
    "TrackerOutput",
]
