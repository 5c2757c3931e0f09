"""Fused track feed: ``Track``, ``TrackBatch`` (one fusion cycle), ``TrackEvent``."""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np
from pydantic import Field, model_validator

from .base import WireModel
from .keys import ID_PATTERN


class TrackStatus(StrEnum):
    TENTATIVE = "tentative"
    CONFIRMED = "confirmed"
    TERMINATED = "terminated"


class FrameKind(StrEnum):
    """System frame of track states, all with x east, y north, z up (metres):
    ``stereographic`` — the plane of PROJ ``+proj=sterea`` at lat0/lon0 on WGS-84, z height
    above the ellipsoid; ``ned`` — the local tangent plane at lat0/lon0/alt0 (state kept
    east/north/up; NED order is a view of it); ``planar`` — a planar test scenario's
    plane, tied to the Earth like ``stereographic`` but with cartesian sensors taken flat
    (offsets in the plane from the site)."""

    STEREOGRAPHIC = "stereographic"
    NED = "ned"
    PLANAR = "planar"


class FrameSpec(WireModel):
    kind: FrameKind
    lat0: float = Field(0.0, ge=-90.0, le=90.0, description="Frame origin latitude, degrees")
    lon0: float = Field(0.0, ge=-180.0, le=180.0, description="Frame origin longitude, degrees")
    alt0: float = Field(0.0, description="Frame origin height above the ellipsoid, m")


class Track(WireModel):
    """One fused track at ``time``. ``state``/``covariance`` are in the system frame of the
    enclosing TrackBatch, ordered as its ``state_labels`` (metres, m/s)."""

    track_id: int = Field(ge=0, description="Stable track id")
    time: int = Field(ge=0, description="Time of the estimate, ns UTC")
    status: TrackStatus
    existence: float = Field(ge=0.0, le=1.0, description="Probability of target existence")
    state: list[float] = Field(description="State vector in the system frame")
    covariance: list[list[float]] = Field(description="State covariance, row-major")
    lat: float = Field(ge=-90.0, le=90.0, description="Latitude, WGS-84, degrees")
    lon: float = Field(ge=-180.0, le=180.0, description="Longitude, WGS-84, degrees")
    alt: float | None = Field(None, description="Height above the ellipsoid, m (None if 2-D)")
    vel_east: float = Field(description="Velocity east, m/s")
    vel_north: float = Field(description="Velocity north, m/s")
    vel_up: float = Field(0.0, description="Velocity up, m/s")
    speed: float = Field(ge=0.0, description="Horizontal speed, m/s")
    heading: float = Field(
        ge=0.0, lt=2 * math.pi, description="Course over ground, rad clockwise from north"
    )
    radars: list[str] = Field(default_factory=list, description="Radars that updated the track")
    updates: int = Field(0, ge=0, description="Number of scans with a plot assigned (weight>0.5)")

    @model_validator(mode="after")
    def _check_shapes(self) -> Track:
        n = len(self.state)
        if len(self.covariance) != n or any(len(r) != n for r in self.covariance):
            raise ValueError(
                f"covariance must be {n}x{n} to match state of length {n}, got "
                f"{len(self.covariance)} rows"
            )
        if n and not np.isfinite(np.asarray(self.covariance, dtype=float)).all():
            raise ValueError("covariance has a NaN or inf entry")
        return self


class TrackBatch(WireModel):
    """All live tracks after one fusion cycle (one applied plot batch)."""

    fusion_id: str = Field(pattern=ID_PATTERN)
    cycle: int = Field(ge=0, description="Fusion cycle number")
    time: int = Field(ge=0, description="Time of the cycle (the applied batch's time_end), ns UTC")
    frame: FrameSpec
    state_labels: list[str] = Field(description="Names of the state components, e.g. x, vx, y, vy")
    source_radar: str | None = Field(None, description="Radar whose batch triggered this cycle")
    source_seq: int | None = Field(None, description="That batch's sequence number")
    tracks: list[Track] = Field(default_factory=list)

    @model_validator(mode="after")
    def _check_dims(self) -> TrackBatch:
        n = len(self.state_labels)
        for t in self.tracks:
            if len(t.state) != n:
                raise ValueError(
                    f"track {t.track_id} has a state of length {len(t.state)} but "
                    f"state_labels has {n}"
                )
        return self


class TrackEventKind(StrEnum):
    CONFIRMED = "confirmed"
    TERMINATED = "terminated"
    MERGED = "merged"


class TrackEvent(WireModel):
    """A track life-cycle event. For ``merged``, ``track_id`` was removed as a duplicate of
    ``other_track_id``."""

    fusion_id: str = Field(pattern=ID_PATTERN)
    time: int = Field(ge=0, description="ns UTC")
    kind: TrackEventKind
    track_id: int = Field(ge=0)
    other_track_id: int | None = Field(None, ge=0)
    existence: float = Field(ge=0.0, le=1.0)
    reason: str = ""
