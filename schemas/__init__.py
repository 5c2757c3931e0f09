"""skyfuse wire contract: pydantic v2 models for every message on Zenoh and in MCAP.

Payloads are compact JSON (``model.to_json_bytes()`` / ``Model.from_json_bytes()``).
The key space is in :mod:`schemas.keys`; each key's payload model is
:func:`model_for_key`.
"""

from __future__ import annotations

from . import keys
from .base import SCHEMA_VERSION, WireModel
from .identity import Emergency
from .plots import PlotBatch
from .registration import RadarBiasEstimate, RegistrationStatus
from .site import Detection, RadarKind, RadarSite
from .status import (
    Backlog,
    IdentityStatus,
    LatencyStats,
    LateStats,
    OverloadStatus,
    RadarHealth,
    Status,
)
from .tracks import (
    FeedKind,
    FrameKind,
    FrameSpec,
    MeasuredPlot,
    Track,
    TrackBatch,
    TrackEvent,
    TrackEventKind,
    TrackPicture,
    TrackPictures,
    TrackStatus,
)
from .truth import RadarBias, Truth

MODELS: dict[str, type[WireModel]] = {
    "site": RadarSite,
    "plots": PlotBatch,
    "tracks": TrackBatch,
    "events": TrackEvent,
    "status": Status,
    "snapshot": TrackBatch,
    "truth": Truth,
    "registration": RegistrationStatus,
    "service-status": Status,
    "standby-status": Status,
}


def model_for_key(key: str) -> type[WireModel]:
    """The payload model of a concrete v1 key (``ValueError`` for liveliness/unknown keys)."""
    info = keys.parse(key)
    try:
        return MODELS[info.kind]
    except KeyError:
        raise ValueError(f"key {key!r} ({info.kind}) carries no message payload") from None


__all__ = [
    "MODELS",
    "SCHEMA_VERSION",
    "Backlog",
    "Detection",
    "Emergency",
    "FeedKind",
    "FrameKind",
    "FrameSpec",
    "IdentityStatus",
    "LateStats",
    "LatencyStats",
    "MeasuredPlot",
    "OverloadStatus",
    "PlotBatch",
    "RadarBias",
    "RadarBiasEstimate",
    "RadarHealth",
    "RadarKind",
    "RadarSite",
    "RegistrationStatus",
    "Status",
    "Track",
    "TrackBatch",
    "TrackEvent",
    "TrackEventKind",
    "TrackPicture",
    "TrackPictures",
    "TrackStatus",
    "Truth",
    "WireModel",
    "keys",
    "model_for_key",
]
