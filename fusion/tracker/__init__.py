"""Existence-based multi-target trackers ([thesis]; [LM-IPF]): IPDA, ITS with Singer N-scan
memory, LM-IPDA/LM-ITS, JIPDA/JITS, GNN and the particle IPF/LM-IPF in one array-based
framework (docs/concepts/tracker-parts.md).

>>> from skyfuse.fusion.tracker import Tracker, TrackerConfig, MeasurementBatch
>>> tracker = Tracker(TrackerConfig(tracker="lmits", depth=3))
>>> out = tracker.step(batch)          # one radar sector/scan in the system frame

Parts (swappable, named in ``registry``): ``density`` (the TrackDensity interface;
Gaussian mixture with Singer memory, IMM mixture, particles), ``associators`` (single,
lm, joint, gnn over ``ipda`` (Λ, ψ, β), ``lm_its`` (modified clutter), ``jits`` (joint
events), ``gnn``), ``existence`` (Markov chains), ``clutter`` (known / estimated),
``coverage``, ``initiation``, ``management``, ``oosm_pass`` (late plots),
``reidentification``, ``identity`` (the secondary-surveillance identity of the tracks);
``its`` (component update) and ``components`` (mixture store, Singer merge, pruning)
serve the Gaussian-mixture density; ``store`` (the track store: every per-track state as
declared columns), ``phases`` (the steps the ordinary and the out-of-sequence updates
share), ``config`` (TrackerConfig), ``measurements`` (MeasurementBatch, SectorCoverage),
``events`` (the event record), ``tracker`` (the step). Gating is
:mod:`fusion.association.gating`, moment matching :mod:`fusion.filters.moment_matching`,
initial states :mod:`fusion.filters.initiation`. The wire adapter (PlotBatch →
MeasurementBatch) lives in ``skyfuse.services.fusion.adapter``.
"""

from .config import TrackerConfig
from .detections import batch_from_positions, batch_from_wgs84
from .events import TrackEventRecord
from .measurements import MeasurementBatch, SectorCoverage
from .tracker import Tracker, TrackerOutput

__all__ = [
    "MeasurementBatch",
    "SectorCoverage",
    "TrackEventRecord",
    "Tracker",
    "TrackerConfig",
    "TrackerOutput",
    "batch_from_positions",
    "batch_from_wgs84",
]
