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
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from . import identity as ident
from .base import NonNegInt64, WireModel
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


def _downlinked(name: str):
    q = ident.DOWNLINKED_BY_NAME[name]
    bounds = {"ge": q.lo, "lt" if q.hi_open else "le": q.hi}
    return Field(None, **bounds, description=f"{q.description}; None if not known")


def _confirmed(what: str):
    return Field(None, ge=0, description=f"When {what} was last confirmed by a plot, ns UTC")


class MeasuredPlot(WireModel):
    """What the last plot that updated a track measured (the content of CAT062 I340):
    its radar, time, polar position and the codes it replied with (names, units and
    flags as the plot columns, :mod:`schemas.identity`)."""

    radar_id: str = Field(pattern=ID_PATTERN, description="Radar of the plot")
    time: NonNegInt64 = Field(description="Plot time, ns UTC")
    range: float | None = Field(None, ge=0.0, description="Slant range, m")
    azimuth: float | None = Field(
        None, ge=0.0, lt=2 * math.pi, description="Azimuth, rad clockwise from true north"
    )
    plot_type: int | None = Field(
        None, ge=0, le=7, description="Detection type (I048/020 TYP: 1 PSR, 2 SSR, 3 SSR + "
        "PSR, 4 Mode S all-call, 5 roll-call, 6/7 all-call/roll-call + PSR)",
    )  # fmt: skip
    flight_level: float | None = Field(
        None, ge=ident.FLIGHT_LEVEL_MIN, le=ident.FLIGHT_LEVEL_MAX, description="Mode C, FL"
    )
    flight_level_not_validated: bool = False
    flight_level_garbled: bool = False
    mode_3a: int | None = Field(None, ge=0, le=ident.MODE_3A_MAX, description="Mode-3/A code")
    mode_3a_not_validated: bool = False
    mode_3a_garbled: bool = False
    mode_3a_smoothed: bool = False


class Track(WireModel):
    """One fused track at ``time``. ``state``/``covariance`` are in the system frame of the
    enclosing TrackBatch, ordered as its ``state_labels`` (metres, m/s).

    Identity and downlinked parameters (optional; names and units as the plot columns,
    :mod:`schemas.identity`): what the track currently shows, each identity attribute
    with the time a plot last confirmed it (its age is ``time`` minus that), the
    downlinked parameters with the time of their register's last report."""

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

    mode_3a: int | None = Field(
        None, ge=0, le=ident.MODE_3A_MAX, description="Mode-3/A code (integer of its 12 bits)"
    )
    mode_3a_time: int | None = _confirmed("the Mode-3/A code")
    mode_3a_changed: bool | None = Field(
        None, description="The Mode-3/A code changed recently (CAT062 I062/060 CH; the "
        "fusion's identity_change_hold)",
    )  # fmt: skip
    mode_s: int | None = Field(
        None, ge=0, le=ident.MODE_S_MAX, description="Mode-S 24-bit ICAO aircraft address"
    )
    mode_s_time: int | None = _confirmed("the Mode-S address")
    callsign: str | None = Field(
        None, pattern=ident.CALLSIGN_PATTERN, description="Aircraft identification (callsign)"
    )
    callsign_time: int | None = _confirmed("the callsign")
    flight_level: float | None = Field(
        None,
        ge=ident.FLIGHT_LEVEL_MIN,
        le=ident.FLIGHT_LEVEL_MAX,
        description="Measured flight level (Mode C), FL (pressure altitude / 100 ft)",
    )
    flight_level_time: int | None = _confirmed("the flight level")
    spi: bool | None = Field(None, description="Special position identification is set")
    emergency: ident.Emergency | None = Field(
        None, description="Declared emergency (Mode-3/A 7500/7600/7700, Mode S)"
    )
    selected_altitude_mcp: float | None = _downlinked("selected_altitude_mcp")
    selected_altitude_fms: float | None = _downlinked("selected_altitude_fms")
    intention_time: int | None = Field(
        None, ge=0, description="Time of the selected altitudes (BDS 4,0 report), ns UTC"
    )
    roll_angle: float | None = _downlinked("roll_angle")
    true_track: float | None = _downlinked("true_track")
    ground_speed: float | None = _downlinked("ground_speed")
    track_angle_rate: float | None = _downlinked("track_angle_rate")
    true_airspeed: float | None = _downlinked("true_airspeed")
    track_turn_time: int | None = Field(
        None, ge=0, description="Time of the track and turn parameters (BDS 5,0), ns UTC"
    )
    magnetic_heading: float | None = _downlinked("magnetic_heading")
    indicated_airspeed: float | None = _downlinked("indicated_airspeed")
    mach: float | None = _downlinked("mach")
    baro_vertical_rate: float | None = _downlinked("baro_vertical_rate")
    inertial_vertical_rate: float | None = _downlinked("inertial_vertical_rate")
    heading_speed_time: int | None = Field(
        None, ge=0, description="Time of the heading and speed parameters (BDS 6,0), ns UTC"
    )
    psr_time: int | None = Field(
        None, ge=0, description="Last update by a plot with a primary detection, ns UTC"
    )
    ssr_time: int | None = Field(
        None, ge=0, description="Last update by a plot with a Mode A/C (SSR) reply, ns UTC"
    )
    mode_s_update_time: int | None = Field(
        None, ge=0, description="Last update by a plot with a Mode S reply, ns UTC"
    )
    last_plot: MeasuredPlot | None = Field(
        None, description="What the last plot that updated the track measured"
    )

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
    """What happened to a track: its life cycle, and its identity (the secondary-
    surveillance attributes the plots assigned to it carried; docs/concepts/identity.md)."""

    CONFIRMED = "confirmed"
    """The track was confirmed (published from now on)."""
    TERMINATED = "terminated"
    """The track ended."""
    MERGED = "merged"
    """The track was removed as a duplicate of ``other_track_id``."""
    IDENTITY_CHANGED = "identity_changed"
    """A new code replaced the track's (``attribute``: ``mode_3a``, a squawk change, or
    ``mode_s`` / ``callsign``; ``value`` the new, ``previous`` the old)."""
    IDENTITY_CONFLICT = "identity_conflict"
    """A Mode-S address or callsign other than the track's (``value``; ``previous`` the
    track's) was seen within the conflict window of the track's last confirmation: two
    aircraft on one track, a swap or a merge."""
    EMERGENCY = "emergency"
    """The track's Mode-3/A code became an emergency code (7500, 7600, 7700; ``value``),
    or the track was confirmed with one; the track's ``emergency`` says which."""
    SPI = "spi"
    """The special position identification was set (or the track was confirmed with it)."""


class TrackEvent(WireModel):
    """A track event (:class:`TrackEventKind`). For ``merged``, ``track_id`` was removed as
    a duplicate of ``other_track_id``. The identity kinds name the ``attribute`` and its
    values as text (Mode-3/A in octal, Mode-S address in hexadecimal, callsign)."""

    fusion_id: str = Field(pattern=ID_PATTERN)
    time: int = Field(ge=0, description="ns UTC")
    kind: TrackEventKind
    track_id: int = Field(ge=0)
    other_track_id: int | None = Field(None, ge=0)
    existence: float = Field(ge=0.0, le=1.0)
    reason: str = ""
    attribute: Literal["mode_3a", "mode_s", "callsign", "spi"] | None = Field(
        None, description="Identity events: the attribute concerned"
    )
    value: str | None = Field(
        None, max_length=8, description="Identity events: the value seen or adopted"
    )
    previous: str | None = Field(
        None, max_length=8, description="Identity events: the track's value before"
    )


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
