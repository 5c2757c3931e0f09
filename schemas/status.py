"""``Status``: service health and counters, published periodically by every service."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import WireModel
from .keys import ID_PATTERN
from .registration import RegistrationStatus


class RadarHealth(WireModel):
    radar_id: str = Field(pattern=ID_PATTERN)
    alive: bool = Field(description="Liveliness token present")
    site_known: bool = Field(description="A RadarSite has been received or configured")
    batches: int = Field(0, ge=0)
    plots: int = Field(0, ge=0)
    plots_per_s: float = Field(0.0, ge=0.0, description="Plot rate over the last window, 1/s")
    last_time: int | None = Field(None, description="Last plot batch time_end, ns UTC")
    clock_offset_s: float | None = Field(
        None,
        description="Estimated radar clock offset: median of batch time_end minus receive "
        "time, s (positive: the radar's clock is ahead; includes the network delay)",
    )
    site_held: bool = Field(
        False,
        description="A site change beyond the fusion's site_tolerance of the radar's accepted "
        "site is held, not applied (until the operator accepts it: accept_sites)",
    )
    batches_refused: int = Field(
        0,
        ge=0,
        description="Valid batches of this radar refused, any reason (duplicate, sequence "
        "jump, time checks, no site, ahead of the data; counted by reason in 'rejected')",
    )
    batches_lost: int = Field(
        0,
        ge=0,
        description="Batch numbers of this radar never received: gaps in its (epoch, seq) "
        "numbering between the first and the last received, per epoch; a number recovered "
        "later is no longer counted",
    )
    samples_missed: int = Field(
        0,
        ge=0,
        description="Samples the transport reported missed from this radar's publisher and "
        "not recoverable from its cache (Zenoh advanced subscriber miss detection)",
    )


class LatencyStats(WireModel):
    """Latency from the sender's wall-clock stamp (the end of the sector sweep) to track
    publication, milliseconds; batches without a plausible stamp are counted, not
    included."""

    count: int = Field(0, ge=0)
    p50: float | None = None
    p90: float | None = None
    p99: float | None = None
    max: float | None = None
    unstamped: int = Field(
        0, ge=0, description="Batches applied without the sender's wall-clock stamp: not included"
    )
    implausible: int = Field(
        0,
        ge=0,
        description="Batches whose stamp no clock could give (ahead of this host's clock beyond "
        "the tolerance, or more than an hour old): not included",
    )


class Backlog(WireModel):
    """Load of a service that queues its input (the fusion service's reorder buffer)."""

    batches: int = Field(0, ge=0, description="Batches waiting to be applied")
    plots: int = Field(0, ge=0, description="Plots in those batches")
    oldest_wait_s: float = Field(0.0, ge=0.0, description="Wait so far of the oldest one, s")
    plots_per_s_in: float = Field(0.0, ge=0.0, description="Plots accepted, 1/s (window)")
    plots_per_s_out: float = Field(0.0, ge=0.0, description="Plots applied, 1/s (window)")
    behind: bool = Field(
        False, description="A batch has waited longer than the reorder wait plus a margin"
    )


class OverloadStatus(WireModel):
    """The fusion service's overload policy (services/fusion/overload.py): while it keeps
    up every plot batch is one tracker step; when it falls behind, contiguous sector
    batches of one radar are applied as one wider step, just wide enough for a group of
    ready batches to take about ``budget_s``. Figures over the last rate window."""

    enabled: bool = Field(True, description="Steps may be widened (coalesce_max_deg not off)")
    active: bool = Field(False, description="Some steps were widened in the last window")
    active_for_s: float = Field(
        0.0, ge=0.0, description="How long the policy has been active without a pause, s"
    )
    batches_per_step: float = Field(
        1.0,
        ge=0.0,
        description="Plot batches per tracker step in the last window (1: none widened)",
    )
    widest_deg: float = Field(
        0.0, ge=0.0, description="Azimuth width of the widest step in the last window, deg"
    )
    busy_share: float = Field(
        0.0, ge=0.0, le=1.0, description="Share of the last window spent applying batches"
    )
    max_deg: float | None = Field(None, description="Widest step allowed, deg (None: off)")
    budget_s: float = Field(0.0, ge=0.0, description="Time a group of ready batches should take, s")
    step_cost_ms: float = Field(
        0.0, ge=0.0, description="Estimated fixed cost of one tracker step, ms"
    )
    plot_cost_us: float = Field(0.0, ge=0.0, description="Estimated cost per plot in a step, µs")
    cost_scale: float = Field(
        1.0, ge=0.0, description="Measured group time over the sum of its steps' estimates"
    )
    groups_widened: int = Field(0, ge=0, description="Groups applied with widened steps")
    widened_s: float = Field(0.0, ge=0.0, description="Time spent in groups with widened steps, s")


class LateStats(WireModel):
    """Batches behind the service time (a lagging radar, a slow link), fusion only: those
    within ``max_lateness`` are applied, their plots through the tracker's out-of-sequence
    update (retrodiction, Bar-Shalom A1: docs/reports/tracker-log.md "Out-of-sequence plots")."""

    max_lateness_s: float = Field(0.0, ge=0.0, description="Configured bound, s")
    batches_late: int = Field(0, ge=0, description="Late batches applied")
    batches_too_late: int = Field(0, ge=0, description="Batches refused as too late")
    batches_oosm: int = Field(
        0, ge=0, description="Batches whose plots updated at least one track by the OOSM update"
    )
    plots_oosm: int = Field(0, ge=0, description="Late plots gated by retrodicted tracks")
    track_updates_oosm: int = Field(0, ge=0, description="(track, late batch) OOSM updates")
    hits_oosm: int = Field(0, ge=0, description="OOSM updates whose most likely plot was late")
    no_prior_oosm: int = Field(
        0,
        ge=0,
        description="OOSM updates of tracks without a stored last step (the independent-noise "
        "retrodiction)",
    )
    unsupported: int = Field(
        0, ge=0, description="Late track updates applied at the track's time (particle trackers)"
    )


class IdentityStatus(WireModel):
    """Fusion: the identity of the tracks (docs/concepts/identity.md), counted since the
    tracker started (kept across restarts with its state)."""

    conflicts: int = Field(
        0,
        ge=0,
        description="identity_conflict events: a Mode-S address or callsign other than a "
        "track's seen on it within the conflict window (two aircraft on one track)",
    )
    changes: int = Field(0, ge=0, description="identity_changed events (e.g. squawk changes)")
    emergencies: int = Field(
        0, ge=0, description="emergency events (Mode-3/A 7500, 7600, 7700 on a confirmed track)"
    )
    spi: int = Field(0, ge=0, description="spi events (SPI set on a confirmed track)")
    tracks_in_emergency: int = Field(
        0, ge=0, description="Published tracks that show an emergency code now"
    )


class Status(WireModel):
    service: str = Field(description="Service kind: sensor, fusion, recorder, replay")
    service_id: str = Field(pattern=ID_PATTERN)
    epoch: int | None = Field(
        None, ge=0, description="Incarnation of the service: +1 at every (re)start or takeover"
    )
    time: int = Field(ge=0, description="Wall-clock time of this report, ns UTC")
    uptime_s: float = Field(ge=0.0)
    counters: dict[str, int] = Field(default_factory=dict, description="Monotonic counters")
    rejected: dict[str, int] = Field(default_factory=dict, description="Rejected inputs by reason")
    radars: list[RadarHealth] = Field(default_factory=list)
    latency_ms: LatencyStats | None = None
    tracks_confirmed: int | None = Field(None, ge=0)
    tracks_total: int | None = Field(None, ge=0)
    backlog: Backlog | None = None
    message: str = ""
    late: LateStats | None = Field(None, description="Fusion: late batches and the OOSM update")
    role: Literal["active", "standby"] | None = Field(
        None, description="Fusion: the active instance of its id, or a hot standby"
    )
    following: str | None = Field(
        None, max_length=128, description="Standby: the active instance it follows"
    )
    state_age_s: float | None = Field(
        None, ge=0.0, description="Standby: age of the newest valid state snapshot it holds, s"
    )
    overload: OverloadStatus | None = Field(
        None, description="Fusion: the overload policy, when and how much it widens the steps"
    )
    registration: RegistrationStatus | None = Field(
        None, description="Fusion: online sensor-registration estimates"
    )
    identity: IdentityStatus | None = Field(
        None, description="Fusion: identity conflicts, changes, emergencies, SPI"
    )
