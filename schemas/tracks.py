"""Fused track feed: ``Track``, ``TrackBatch`` (a delta or the full picture),
``TrackEvent``, and :class:`TrackPicture`, which rebuilds the picture from the feed.

**Feed contract** (key ``skyfuse/@v1/fusion/{id}/tracks``): every message is a
``TrackBatch`` whose ``kind`` says what it is.

* ``kind = "delta"`` (after each fusion cycle, or group of cycles when the service works
  in bulk): ``tracks`` holds only the tracks that changed — new, updated by a plot,
  confirmed — and ``removed`` the ids that left the picture (terminated, merged, no
  longer published). Tracks not named keep their last row (each ``Track`` has its own
  ``time``). ``cycle`` is +1 per delta; ``batches`` counts the plot batches it applies.
* ``kind = "full"`` (at the service's ``full_interval``, default 1 s, and as the answer
  of the ``snapshot`` queryable): every track of the picture after delta ``cycle``; it
  replaces the picture.

A client subscribes to ``tracks`` first, then either queries ``snapshot`` or waits for
the next full message, and applies the deltas whose ``cycle`` is greater than the full's;
a gap in the delta cycles means a lost message: the picture is marked incomplete until
the next full message (:class:`TrackPicture` does exactly that). A feed read from its
first delta (``cycle`` 1, e.g. the MCAP of ``skyfuse track``) is complete from the start.
Every message carries the service's incarnation ``epoch`` (+1 at every restart or
standby takeover): a restarted service that resumed its saved state continues its cycles
from the snapshot (possibly a little behind the last one published), one that did not
starts again from 1; either way a delta of a new epoch is applied and marks the picture
incomplete until the next full message (sent with the first cycle of a new epoch).
Messages without ``kind`` (older recordings) are full pictures.
"""

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


class FeedKind(StrEnum):
    """``delta``: changed tracks + removed ids; ``full``: the whole picture."""

    DELTA = "delta"
    FULL = "full"


class TrackBatch(WireModel):
    """One message of the track feed: the changes of one fusion cycle (``delta``) or the
    whole picture (``full``); see the module docstring for the contract."""

    fusion_id: str = Field(pattern=ID_PATTERN)
    cycle: int = Field(ge=0, description="Fusion cycle number")
    epoch: int | None = Field(
        None,
        ge=0,
        description="Incarnation of the fusion service: +1 at every (re)start or standby "
        "takeover; a change means a restart (cycles continue when the state was resumed)",
    )
    time: int = Field(
        ge=0,
        description="Time of the cycle: the newest batch time applied (a late batch does not "
        "move it back; the tracks are predicted to it), ns UTC",
    )
    kind: FeedKind = Field(FeedKind.FULL, description="delta (changed tracks) or full picture")
    frame: FrameSpec
    state_labels: list[str] = Field(description="Names of the state components, e.g. x, vx, y, vy")
    source_radar: str | None = Field(None, description="Radar whose batch triggered this cycle")
    source_seq: int | None = Field(None, description="That batch's sequence number")
    batches: int = Field(1, ge=0, description="Plot batches this delta applies (0 in a full)")
    tracks: list[Track] = Field(default_factory=list)
    removed: list[int] = Field(
        default_factory=list, description="delta: ids of tracks that left the picture"
    )

    @model_validator(mode="after")
    def _check_dims(self) -> TrackBatch:
        n = len(self.state_labels)
        for t in self.tracks:
            if len(t.state) != n:
                raise ValueError(
                    f"track {t.track_id} has a state of length {len(t.state)} but "
                    f"state_labels has {n}"
                )
        if self.kind is FeedKind.FULL and self.removed:
            raise ValueError("removed: a full message lists no removed tracks")
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


class TrackPicture:
    """The picture rebuilt from the track feed (consumer side of the contract above).

    ``apply`` each received TrackBatch in arrival order; ``tracks`` (id → Track) is the
    picture, ``complete`` tells whether it is known to be whole (a full message seen and
    no delta lost since), ``batch()`` gives it as one full TrackBatch."""

    def __init__(self) -> None:
        self.tracks: dict[int, Track] = {}
        self.cycle: int | None = None
        self.complete = False
        self.header: TrackBatch | None = None

    def apply(self, batch: TrackBatch) -> bool:
        """Apply one message; ``False`` if it was already contained (an old delta)."""
        if batch.kind is FeedKind.FULL:
            self.tracks = {t.track_id: t for t in batch.tracks}
            self.complete = True
        else:
            new_epoch = self.header is not None and batch.epoch != self.header.epoch
            if not new_epoch and self.cycle is not None and batch.cycle <= self.cycle:
                return False
            if new_epoch:  # the service restarted: cycles may repeat or restart
                self.complete = False
            elif self.cycle is None:  # joined the feed at its first delta, or late
                self.complete = batch.cycle == 1
            elif batch.cycle != self.cycle + 1:
                self.complete = False
            for i in batch.removed:
                self.tracks.pop(i, None)
            for t in batch.tracks:
                self.tracks[t.track_id] = t
        self.cycle = batch.cycle
        self.header = batch
        return True

    def batch(self) -> TrackBatch | None:
        """The picture as a full TrackBatch (header of the last message), or ``None``."""
        if self.header is None:
            return None
        tracks = [self.tracks[i] for i in sorted(self.tracks)]
        return self.header.model_copy(
            update={"kind": FeedKind.FULL, "tracks": tracks, "removed": [], "batches": 0}
        )


class TrackPictures:
    """One :class:`TrackPicture` per fusion id, for a consumer of ``fusion/*/tracks``;
    at most ``max_ids`` ids (a bound against invented ids), ``latest`` the last updated."""

    def __init__(self, max_ids: int) -> None:
        self.max_ids = max_ids
        self.by_id: dict[str, TrackPicture] = {}
        self.last: str | None = None

    def get(self, fusion_id: str) -> TrackPicture | None:
        """The picture of ``fusion_id`` (made on first sight); ``None`` beyond the bound."""
        pic = self.by_id.get(fusion_id)
        if pic is None and len(self.by_id) < self.max_ids:
            pic = self.by_id[fusion_id] = TrackPicture()
        return pic

    def apply(self, batch: TrackBatch) -> bool:
        """Apply ``batch`` to its fusion id's picture; ``False`` beyond the bound or for an
        old delta."""
        pic = self.get(batch.fusion_id)
        if pic is None:
            return False
        self.last = batch.fusion_id
        return pic.apply(batch)

    def latest(self) -> TrackBatch | None:
        """The picture last updated, as a full TrackBatch."""
        return None if self.last is None else self.by_id[self.last].batch()
