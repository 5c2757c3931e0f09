"""The fusion service core: input validation, radar registry, time-ordered reorder buffer,
tracking, outputs and health counters. Network-free (the Zenoh side is ``server``),
so it is tested directly.

Data flow for one received plot batch::

    payload ─ validate (PlotBatch) ─ duplicate? future? late? ─ reorder buffer ─(bounded wait)→
        site known? ─ track pipeline (convert_plots + tracker, shared with `skyfuse track`)
        → TrackBatch + TrackEvents → publish; latency = publish wall time − sweep end

**Reorder buffer** (:mod:`services.fusion.reorder`). Batches from several radars arrive
with network jitter. Each batch is held for ``reorder_wait`` seconds of wall time after
its arrival (when Zenoh delivered it: the time it then waits for the main loop counts),
and batches are applied in the order of ``(time_end, arrival)``; each group's output is
published as soon as it is computed (:meth:`FusionCore.ready_cycles`). Each radar
has its own watermark: only a batch earlier than its own radar's last applied one is *out
of sequence*. A batch further ahead of this host's clock than ``future_tolerance`` is
refused (``time in the future``) and never moves the service time; a batch up to
``max_lateness`` behind the service time (a lagging radar) is applied
(``counters["batches_late_applied"]``): the tracks it finds ahead of its time take its
plots through the out-of-sequence update (retrodiction to the plot time, Bar-Shalom's
A1, :mod:`fusion.tracker.oosm`; counted in ``Status.late``), and the feed's time stays
at the newest batch time; an older batch is refused (``too late``). Every batch leaves
the buffer within ``max_hold`` (one far ahead of all the data received since is refused:
``ahead of the data``). A batch seen twice (same radar, epoch and seq) is counted as a
duplicate, a number far beyond what the radar can have published as a ``sequence jump``;
numbers never received are counted per radar (``RadarHealth.batches_lost``), so every
batch a sensor published is applied, refused with a counted reason, or counted as lost.

**Sites.** A radar's site comes from its ``RadarSite`` messages or from the
configuration; a batch from a radar without a known site is counted
(``rejected["no site for radar"]``) and reported, never converted with a guessed site.
A site message further than ``site_tolerance`` from the radar's *accepted* site
(configured, saved, operator-accepted with ``accept_sites``, or the first received) is
held and reported (:meth:`FusionCore.on_site`).
Unless its origin is configured, the system frame is fixed when the first batch is
applied, from the sites heard until then (its reorder hold included:
:mod:`~skyfuse.services.fusion.system_frame`).

**Latency** (plot time → track publication) is ``publish wall time − sender stamp``; the
sender stamp is the wall-clock instant the sector sweep ended, sent as the sample
attachment by ``skyfuse sensor`` / ``replay``. A batch without one, or with one no clock
could give, is left out of the figures and counted (``LatencyStats.unstamped``,
``implausible``): its payload times are the sender's word, not a clock reading.
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections import Counter, deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
import pymap3d
from pydantic import BaseModel, Field, field_validator
from skyfuse.fusion.tracker.identity import EMERGENCY
from skyfuse.schemas import (
    Backlog,
    FrameKind,
    FrameSpec,
    IdentityStatus,
    LatencyStats,
    LateStats,
    PlotBatch,
    RadarHealth,
    RadarSite,
    Status,
    TrackEvent,
    keys,
)
from skyfuse.schemas.rejection import decode, rejection_detail, rejection_reason
from skyfuse.services.fusion.feed import FeedMessage
from skyfuse.services.fusion.overload import OverloadPolicy
from skyfuse.services.fusion.reorder import ReorderBuffer, _Pending
from skyfuse.services.fusion.system_frame import frame_for_sites
from skyfuse.services.runtime.lifecycle import RateWindow
from skyfuse.services.runtime.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)


class FusionConfig(BaseModel):
    """Configuration of the fusion service (TOML table ``[fusion]``; the tracker is the
    ``[tracker]`` table, the transport ``[transport]``)."""

    fusion_id: str = Field("main", pattern=keys.ID_PATTERN, description="Fusion service id")
    reorder_wait: float = Field(
        0.5, ge=0.0, le=60.0, description="Hold each batch this long to order radars, s"
    )
    frame_kind: FrameKind | None = Field(
        None, description="System frame: stereographic, ned or planar (default: stereographic)"
    )
    frame_lat0: float | None = Field(
        None, ge=-90, le=90, description="Frame origin latitude, deg (default: mean of the sites)"
    )
    frame_lon0: float | None = Field(
        None,
        ge=-180,
        le=180,
        description="Frame origin longitude, deg (default: mean of the sites)",
    )
    frame_alt0: float = Field(0.0, description="Frame origin height, m")
    sites: list[RadarSite] = Field(
        default_factory=list, description="Known radar sites (TOML [[fusion.sites]])"
    )
    assumed_altitude: float | None = Field(
        None,
        ge=-1000,
        le=30000,
        description="Height assumed for plots without altitude or elevation (primary-only "
        "ASTERIX plots), m, carried with a ±3000 m uncertainty (default: the radar site's "
        "height, i.e. its ground level)",
    )
    status_interval: float = Field(1.0, gt=0, description="Status publication period, s")
    full_interval: float = Field(
        1.0, gt=0, description="Period of the full-picture TrackBatch on the feed, s"
    )
    bulk_max: int = Field(
        200,
        ge=1,
        le=100_000,
        description="Batches applied in one pass at most, when behind (the overload policy "
        "widens the steps within a pass)",
    )
    coalesce_max_deg: float | None = Field(
        360.0,
        gt=0,
        le=360,
        description="Overload policy (services/fusion/overload.py): when applying the "
        "batches ready together one by one would take longer than group_budget_s (the "
        "service is behind), contiguous sector batches of one radar go through the "
        "tracker as one step, just as wide as needed and at most this azimuth width, deg; "
        "while the service keeps up every batch is one step (the tracks of batch-by-batch "
        "processing). Status 'overload' says when and how much. off = never widen",
    )
    group_budget_s: float = Field(
        0.1,
        gt=0,
        le=60.0,
        description="Overload policy: the time one pass over the ready batches should "
        "take, s; steps are widened only when batch by batch would exceed it (the lag "
        "behind the input stays near it while the service is overloaded)",
    )
    delta_split_s: float | None = Field(
        0.05,
        gt=0,
        description="When applying a group of batches takes longer than this, s, the "
        "delta of the batches applied so far is published before the next step runs, so "
        "the first batches of a long group do not wait for its last ones (Status counter "
        "group_parts); the tracks are the same. off = one delta per group",
    )
    max_backlog: float | None = Field(
        None,
        gt=0,
        description="Opt-in: stop reading input while a batch has waited longer than the "
        "reorder wait plus this, s (the inbox fills and the publishers are slowed down); "
        "batches held back in the senders may then arrive out of sequence (counted). "
        "Default: off, back-pressure only from the queue bound",
    )
    inbox: int = Field(
        10_000, ge=10, le=1_000_000, description="Messages in the receive queue, at most"
    )
    behind_after: float = Field(
        0.5,
        gt=0,
        description="Status says 'behind' when a batch has waited longer than the reorder "
        "wait plus this, s",
    )
    latency_window: int = Field(
        20_000, ge=10, description="Latency percentiles over the last N publications"
    )
    rate_window: float = Field(5.0, gt=0, description="Plot-rate averaging window, s")
    queue: int = Field(
        10_000,
        ge=10,
        le=1_000_000,
        description="Batches waiting in the reorder buffer, at most; beyond it the "
        "publishers are slowed down",
    )
    future_tolerance: float | None = Field(
        1.0,
        ge=0.0,
        le=3600.0,
        description="Refuse batches whose times are this far ahead of this host's clock, s "
        "('off': no check, for recordings replayed with future times)",
    )
    max_lateness: float = Field(
        2.0,
        ge=0.0,
        le=600.0,
        description="Apply batches up to this far behind the service time (late radars, "
        "through the tracker's out-of-sequence update), refuse older ones, s",
    )
    max_hold: float = Field(
        3.0,
        gt=0.0,
        le=600.0,
        description="Every batch leaves the reorder buffer at most this long after its "
        "arrival (at least the reorder wait), s: with the batches in front of it, or "
        "refused ('ahead of the data') when everything received since is more than "
        "max_lateness behind it",
    )
    max_seq_jump: int = Field(
        64,
        ge=1,
        le=1_000_000,
        description="A batch number may run ahead of the radar's highest one by this much "
        "plus twice the radar's measured rate times the data time since; further ahead it "
        "is refused ('sequence jump')",
    )
    site_tolerance: float | None = Field(
        100.0,
        ge=0.0,
        description="A site message further than this (3-D, m) from the radar's accepted "
        "site (configured, saved, or the first received) is held and reported, not "
        "applied; smaller corrections are applied ('off': apply every change)",
    )
    accept_sites: list[str] = Field(
        default_factory=list,
        description="Radars whose site as published now is accepted as their new accepted "
        "site (an operator accepting a move held beyond site_tolerance); once accepted, "
        "later moves are held again",
    )
    max_message_bytes: int = Field(
        8_000_000,
        ge=1_000,
        le=1_000_000_000,
        description="Largest payload decoded, bytes; larger ones are rejected unread",
    )
    max_plots_per_batch: int = Field(
        50_000, ge=1, le=10_000_000, description="Most plots accepted in one PlotBatch"
    )
    max_radars: int = Field(
        256,
        ge=1,
        le=1_000_000,
        description="Most radar ids tracked (and reported in Status); input from further "
        "ids is rejected",
    )

    state_dir: Path | None = Field(
        None,
        description="Directory of this fusion id's saved state (snapshots, next track id, "
        "epoch; owner-only). Default: $XDG_STATE_HOME/skyfuse/fusion-{id}, i.e. "
        "~/.local/state/skyfuse/fusion-{id}",
    )
    snapshot_interval: float | None = Field(
        2.0,
        gt=0,
        le=3600.0,
        description="Save the tracker state this often, s ('off': no saved state, no resume, "
        "no persisted ids)",
    )
    resume_max_age: float = Field(
        60.0, ge=0.0, description="At start, resume a saved state at most this old, s"
    )
    id_horizon: float = Field(
        30 * 86400.0,
        ge=0.0,
        description="Never reuse a track id while the persisted next id is younger than "
        "this, s (default 30 days)",
    )

    state_max_bytes: int = Field(
        64_000_000,
        ge=10_000,
        le=2_000_000_000,
        description="Largest state snapshot a standby accepts from the active instance "
        "(fusion/{id}/state), bytes; larger ones are counted and dropped unread",
    )
    standby: bool = Field(
        False,
        description="Hot standby: if another instance of this fusion id is active, follow "
        "it and take over when it goes away (else: refuse to start, exit 1)",
    )

    @field_validator(
        "future_tolerance",
        "site_tolerance",
        "snapshot_interval",
        "delta_split_s",
        "coalesce_max_deg",
        mode="before",
    )
    @classmethod
    def _off(cls, v):
        """``off`` (flag, TOML or environment) switches a check off."""
        return None if isinstance(v, str) and v.strip().lower() in ("off", "none") else v

    def frame_spec(self, sites: list[RadarSite]) -> FrameSpec | None:
        """The configured frame, or one centred on ``sites``
        (:func:`~skyfuse.services.fusion.system_frame.frame_for_sites`, the rule shared
        with the offline runner)."""
        return frame_for_sites(
            sites, self.frame_kind, self.frame_lat0, self.frame_lon0, self.frame_alt0
        )


class CyclePipeline(Protocol):
    """Fusion cycles: batches in (in time order), one delta of the track feed and the
    TrackEvents out, the full picture on demand (the code path shared with the offline
    ``skyfuse track``; :class:`skyfuse.services.fusion.pipeline.TrackPipeline`)."""

    rejected: dict[str, int]

    def process_parts(
        self,
        items: list[tuple[RadarSite, PlotBatch]],
        *,
        part_s: float | None = None,
        coalesce_max: float | None = None,
        mergeable: list[bool] | None = None,
        max_members: int | None = None,
        on_step=None,
    ) -> Iterator:
        """The group's parts (``services.fusion.pipeline.GroupPart``: message, events,
        applied and failed batches), each yielded before the next part's steps run; each
        tracker step reported to ``on_step(plots, seconds, width)``. (Only asked to
        coalesce when the overload policy widens the steps.)"""

    def full(self) -> FeedMessage | None: ...

    def picture(self): ...

    def snapshot(self) -> FeedMessage | None: ...

    def to_snapshot(self) -> dict:
        """Its state by declared names (``services.fusion.state_store`` saves it)."""

    def from_snapshot(self, snap: dict) -> None:
        """Hold a :meth:`to_snapshot` (on a pipeline just made with the same settings)."""


@dataclass
class _Radar:
    radar_id: str
    site: RadarSite | None = None
    alive: bool = False
    batches: int = 0
    plots: int = 0
    last_time: int | None = None
    rate: RateWindow = field(default_factory=RateWindow)
    site_held: RadarSite | None = None
    """A received site beyond ``site_tolerance`` of the accepted site: not applied."""
    site_accepted: RadarSite | None = None
    """The site moves are measured from: configured, saved, operator-accepted or the
    first received (:meth:`FusionCore.on_site`)."""
    refused: int = 0
    """Valid batches refused (at intake or later in the reorder buffer), any reason."""
    missed: int = 0
    """Samples Zenoh reported missed from the radar's publisher (beyond its cache)."""


@dataclass
class CycleOutput:
    """What one group of cycles publishes: the delta, the events, and the full picture
    when it is due (``full_interval``)."""

    tracks: FeedMessage
    events: list[TrackEvent]
    sent_ns: list[int | None]
    """Senders' wall-clock stamps of the applied batches."""
    time_ends: list[int]
    full: FeedMessage | None = None
    latency_ms: float | None = None
    """The largest latency of the group's batches, once published."""


class FusionCore:
    """State of one fusion service; feed it with :meth:`on_plots`, :meth:`on_site`,
    :meth:`on_alive`, and call :meth:`poll` regularly to run due cycles."""

    def __init__(self, cfg: FusionConfig, pipeline_factory) -> None:
        self.cfg = cfg
        self._factory = pipeline_factory
        self.pipeline: CyclePipeline | None = None
        self.frame: FrameSpec | None = None
        self.buffer = ReorderBuffer(
            cfg.reorder_wait,
            future_tolerance=cfg.future_tolerance,
            max_lateness=cfg.max_lateness,
            max_hold=cfg.max_hold,
            on_refused=self._refused_in_buffer,
            moves_time=self._applies,
        )
        self.buffer.seen.max_jump = cfg.max_seq_jump
        self.radars: dict[str, _Radar] = {}
        self.counters: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.latencies: deque[float] = deque(maxlen=cfg.latency_window)
        deg = cfg.coalesce_max_deg
        self.overload = OverloadPolicy(
            None if deg is None else math.radians(deg),
            cfg.group_budget_s,
            window_s=cfg.rate_window,
        )
        """How wide the tracker steps are (:mod:`~skyfuse.services.fusion.overload`)."""
        self.started = time.monotonic()
        self.rate_in = RateWindow(cfg.rate_window)
        self.rate_out = RateWindow(cfg.rate_window)
        self._next_full = 0.0
        self._waiting: dict[int, tuple[float, int]] = {}
        """Batches in the reorder buffer: id(batch) -> (arrival, plots), arrival order."""
        self._warned: set[str] = set()
        self._log = RateLimitedLog(log)
        self.epoch: int | None = None
        self.role: str | None = None
        """``active`` once this instance publishes (``services.fusion.standby``)."""
        """Incarnation number, sent in every TrackBatch and Status (``state_store``)."""
        self._configured = {s.radar_id: s for s in cfg.sites}
        self._accepting = set(cfg.accept_sites)
        """Radars whose next received site is accepted (``accept_sites``)."""
        for site in cfg.sites:
            self.on_site(site, configured=True)

    # --- inputs ----------------------------------------------------------------------
    def _radar(self, radar_id: str) -> _Radar:
        r = self.radars.get(radar_id)
        if r is None:
            r = self.radars[radar_id] = _Radar(radar_id, rate=RateWindow(self.cfg.rate_window))
        return r

    def _admit(self, radar_id: str) -> bool:
        """Whether input from ``radar_id`` may be tracked: a known id, or room for a new
        one under ``max_radars`` — made, if needed, by forgetting the oldest radar that
        has no site (so ids invented by a hostile peer cannot crowd out real radars);
        else counted as ``too many radars``."""
        if radar_id in self.radars or len(self.radars) < self.cfg.max_radars:
            return True
        victim = next((rid for rid, r in self.radars.items() if r.site is None), None)
        if victim is None:
            self.reject("too many radars", radar_id)
            return False
        del self.radars[victim]
        self.counters["radars_forgotten"] += 1
        return True

    def reject(self, reason: str, detail: str = "", n: int = 1) -> None:
        """Count ``n`` rejections; ``reason`` must come from a fixed vocabulary (see
        :mod:`schemas.rejection`), the free text goes to the rate-limited log only."""
        self.rejected[reason] += n
        self._log.warning("rejected input: %s%s", reason, f" ({detail})" if detail else "")

    def _decode(self, model, key: str, payload: bytes):
        """``(message, owner id)`` of a payload on ``key``, or ``None`` (rejection counted)."""
        if len(payload) > self.cfg.max_message_bytes:
            self.reject("message too large", f"{len(payload)} bytes on {key[:80]}")
            return None
        msg, exc = decode(model, payload)
        if msg is None:
            self.reject(rejection_reason(model, exc), rejection_detail(exc))
            return None
        try:
            owner = keys.parse(key).owner
        except ValueError:
            owner = None
        if msg.radar_id != owner:
            self.reject(
                f"{'site' if model is RadarSite else 'batch'} radar_id does not match its key",
                f"{msg.radar_id} on {key[:80]}",
            )
            return None
        return msg if self._admit(msg.radar_id) else None

    def on_site_payload(self, key: str, payload: bytes) -> None:
        site = self._decode(RadarSite, key, payload)
        if site is not None:
            self.on_site(site)

    def on_site(self, site: RadarSite, configured: bool = False) -> None:
        """A radar's site: from its messages, or ``configured`` (the configuration, a
        saved state). Moves are measured from the radar's *accepted* site — configured
        (the configuration wins over a saved site), saved, accepted by the operator
        (``accept_sites``: the next one received) or else the first one received — not
        from the last one applied, so small steps cannot add up: a site further than
        ``site_tolerance`` from it is held and reported until the operator accepts it."""
        r = self._radar(site.radar_id)
        rid = site.radar_id
        if configured:
            if rid in self._configured and site != self._configured[rid]:
                return  # a saved site never overrides the configured one
            r.site_accepted = site
        elif r.site_accepted is None or rid in self._accepting:
            if rid in self._accepting and r.site_accepted is not None:
                log.warning("radar %s: site accepted by the operator (accept_sites)", rid)
            self._accepting.discard(rid)
            r.site_accepted = site
        elif self.cfg.site_tolerance is not None:
            moved = site_displacement_m(r.site_accepted, site)
            if moved > self.cfg.site_tolerance:
                # a moved radar shifts its whole picture: hold it for the operator
                r.site_held = site
                self.reject("site change held", f"{rid} {moved:.0f} m from its accepted site")
                return
        r.site_held = None
        if r.site != site:
            if r.site is not None:
                log.info("radar %s: site changed", rid)
            r.site = site
            self.counters["sites"] += 1
            log.info(
                "radar %s: site %.4f°, %.4f° (%s)%s",
                rid,
                site.lat,
                site.lon,
                site.kind.value,
                " from configuration" if configured else "",
            )
        if self.pipeline is None and self.cfg.frame_lat0 is not None:
            self._start_pipeline()  # a configured origin: no need to wait for the plots

    def _start_pipeline(self) -> None:
        """Fix the system frame from the sites known now: when the first plot batch of a
        radar with a site is applied, after its reorder hold — not when it is received,
        since Zenoh delivers the site and plot keys on separate threads with no order
        between them (:mod:`~skyfuse.services.fusion.system_frame`)."""
        known = [r.site for r in self.radars.values() if r.site is not None]
        frame = self.cfg.frame_spec(known)
        if frame is None:
            return
        self.frame = frame
        self.pipeline = self._factory(frame)
        log.info("system frame %s at %.4f°, %.4f°", frame.kind.value, frame.lat0, frame.lon0)

    def on_alive(self, key: str, alive: bool) -> None:
        try:
            info = keys.parse(key)
        except ValueError:
            return
        if info.kind != "alive" or info.owner is None or not self._admit(info.owner):
            return
        r = self._radar(info.owner)
        if r.alive != alive:
            log.info("radar %s %s", info.owner, "is alive" if alive else "went away")
        r.alive = alive

    def on_plots_payload(
        self,
        key: str,
        payload: bytes,
        arrival: float,
        sent_ns: int | None = None,
        *,
        recv_ns: int | None = None,
    ) -> PlotBatch | None:
        """Validate and queue one received batch; ``None`` if rejected (reason counted)."""
        self.counters["batches_received"] += 1
        batch = self._decode(PlotBatch, key, payload)
        if batch is None:
            return None
        if len(batch.time) > self.cfg.max_plots_per_batch:
            self.reject("too many plots in batch", f"{len(batch.time)} plots, {batch.radar_id}")
            return None
        return batch if self.on_plots(batch, arrival, sent_ns, recv_ns=recv_ns) else None

    def on_plots(
        self,
        batch: PlotBatch,
        arrival: float,
        sent_ns: int | None = None,
        *,
        recv_ns: int | None = None,
    ) -> bool:
        """Queue a validated batch received at wall-clock ``recv_ns`` (default: now)."""
        r = self._radar(batch.radar_id)
        reason = self.buffer.push(batch, arrival, sent_ns, recv_ns)
        if reason is not None:
            self.reject(reason, f"radar {batch.radar_id} seq {batch.seq}")
            r.refused += 1
            return False
        n = len(batch.time)
        self._waiting[id(batch)] = (arrival, n)
        # the rates run on the clock of ``arrival`` (monotonic in the live path)
        self.rate_in.add(n, arrival)
        r.batches += 1
        r.plots += n
        r.rate.add(n, arrival)
        r.last_time = batch.time_end if r.last_time is None else max(r.last_time, batch.time_end)
        self.counters["batches_in"] += 1
        self.counters["plots_in"] += n
        return True

    # --- cycles ----------------------------------------------------------------------
    def poll(
        self, now: float | None = None, *, flush: bool = False, budget_s: float | None = None
    ) -> list[CycleOutput]:
        """The outputs of :meth:`ready_cycles`, as a list."""
        return list(self.ready_cycles(now, flush=flush, budget_s=budget_s))

    def ready_cycles(
        self, now: float | None = None, *, flush: bool = False, budget_s: float | None = None
    ) -> Iterator[CycleOutput]:
        """Run the cycles of the batches whose hold expired (all queued with ``flush``),
        yielding each group's output as soon as it is computed, so the caller publishes
        it before the next group runs (a group's batches never wait for later groups).

        Every batch ready now is taken at once (at most ``bulk_max`` per group) and
        applied in one pass, in the buffer's time order, with one delta message for the
        group (:meth:`CyclePipeline.process_group`). ``budget_s`` bounds the time spent,
        the caller's publication included (at least one group runs): the rest stays
        queued for the next call, so a service that falls behind still reads its input
        and publishes its Status in between."""
        clock = now  # the caller's clock for the output rate (None: each group's own now)
        now = time.monotonic() if now is None else now
        t_end = None if budget_s is None else time.monotonic() + budget_s
        while True:
            if flush:
                ready = self.buffer.flush()
            else:
                ready = self.buffer.pop_ready(now, limit=self.cfg.bulk_max)
            if not ready:
                return
            yield from self.cycle_group(ready, clock)
            if flush or (t_end is not None and time.monotonic() >= t_end):
                return

    def cycle(self, p: _Pending) -> CycleOutput | None:
        """Run the cycle of one released batch (see :meth:`poll`)."""
        return next(self.cycle_group([p]), None)

    def cycle_group(self, ready: list[_Pending], now: float | None = None) -> Iterator[CycleOutput]:
        """Apply released batches (in their order) in one pass, yielding the output of
        each part (one per group unless ``delta_split_s`` splits a long one); nothing if
        no batch was applied. ``now``: the monotonic time of the output rate (default:
        now)."""
        for p in ready:
            self._left_buffer(p)
        ready = [p for p in ready if self._has_site(p.batch)]
        if not ready:
            return
        if self.pipeline is None:
            self._start_pipeline()
        items = [(self.radars[p.batch.radar_id].site, p.batch) for p in ready]
        policy = self.overload
        kw = {"part_s": self.cfg.delta_split_s, "on_step": policy.on_step}
        mergeable = [not p.late for p in ready]  # late batches are never coalesced
        t = time.monotonic() if now is None else now
        lag = max(0.0, t - min(p.arrival for p in ready) - self.cfg.reorder_wait)
        k = policy.members([b for _, b in items], mergeable, [site for site, _ in items], lag)
        if k > 1:
            kw |= {"coalesce_max": policy.max_width, "mergeable": mergeable, "max_members": k}
        pending = {id(p.batch): p for p in ready}
        parts = self.pipeline.process_parts(items, **kw)
        policy.start_group()
        try:
            yield from self._parts_output(parts, pending, now, len(ready))
        finally:
            policy.end_group(t, len(ready))

    def _parts_output(self, parts, pending, now, n: int) -> Iterator[CycleOutput]:
        """The output of each part of a group that applied a batch (see cycle_group)."""
        first = True
        while True:
            try:
                part = next(parts, None)
            except Exception as e:  # a tracker bug must not kill the service
                self.reject("tracker error", f"{type(e).__name__}: {e}", len(pending))
                log.exception("tracker error on a group of %d batches", n)
                return
            if part is None:
                return
            out = self._part_output(part, pending, now)
            if out is not None:
                self.counters["groups" if first else "group_parts"] += 1
                first = False
                yield out

    def _part_output(self, part, pending: dict[int, _Pending], now) -> CycleOutput | None:
        """Count one part's failed and applied batches (taken out of ``pending``); its
        output, unless it applied none."""
        for batch, e in part.failed:
            pending.pop(id(batch), None)
            if isinstance(e, ValueError):
                self.reject("batch not convertible", f"radar {batch.radar_id}: {e}")
            else:
                self.reject("tracker error", f"{type(e).__name__}: {e}")
                log.error("tracker error on radar %s seq %s: %r", batch.radar_id, batch.seq, e)
        applied = [pending.pop(id(b)) for b in part.applied]
        if part.message is None:
            return None
        self._stamp(part.message)
        n = sum(len(p.batch.time) for p in applied)
        self.counters["cycles"] += len(applied)
        self.counters["plots_applied"] += n
        late = sum(p.late for p in applied)
        if late:  # behind the service time, within max_lateness: applied (reorder.py)
            self.counters["batches_late_applied"] += late
        self.counters["events"] += len(part.events)
        self.rate_out.add(n, now)
        full = None
        if time.monotonic() >= self._next_full:
            self._next_full = time.monotonic() + self.cfg.full_interval
            full = self._stamp(self.pipeline.full())
        return CycleOutput(
            part.message,
            part.events,
            [p.sent_ns for p in applied],
            [p.time_end for p in applied],
            full,
        )

    def _left_buffer(self, p: _Pending) -> None:
        self._waiting.pop(id(p.batch), None)

    def _applies(self, radar_id: str) -> bool:
        """Whether batches of ``radar_id`` are applied now (a known radar with a site):
        only they move the service time (``ReorderBuffer.moves_time``)."""
        r = self.radars.get(radar_id)
        return r is not None and r.site is not None

    def _refused_in_buffer(self, p: _Pending, reason: str) -> None:
        """A queued batch refused by the reorder buffer (``ahead of the data``)."""
        self._left_buffer(p)
        self._moved_to_refused(p.batch)
        self.reject(reason, f"radar {p.batch.radar_id} seq {p.batch.seq}")

    def _moved_to_refused(self, batch: PlotBatch) -> None:
        """A batch accepted at intake and refused after: per radar, counted as refused."""
        r = self.radars.get(batch.radar_id)
        if r is not None:
            r.batches -= 1
            r.plots -= len(batch.time)
            r.refused += 1

    def note_missed(self, missed: dict[str, int]) -> None:
        """Samples Zenoh reported missed, by key (``Inbox.take_missed``): per radar."""
        for key, n in missed.items():
            try:
                info = keys.parse(key)
            except ValueError:
                continue
            r = self.radars.get(info.owner) if info.kind == "plots" else None
            if r is not None:
                r.missed += n
            else:
                self.counters["samples_missed_other"] += n

    def backlog(self, now: float | None = None) -> Backlog:
        """Batches and plots waiting, the oldest one's wait, plot rates in and out, and
        whether the service is behind (a batch waited longer than reorder wait +
        ``behind_after``)."""
        now = time.monotonic() if now is None else now
        oldest = next(iter(self._waiting.values()), None)  # dicts keep arrival order
        age = 0.0 if oldest is None else max(0.0, now - oldest[0])
        return Backlog(
            batches=len(self._waiting),
            plots=sum(n for _, n in self._waiting.values()),
            oldest_wait_s=age,
            plots_per_s_in=self.rate_in.rate(now),
            plots_per_s_out=self.rate_out.rate(now),
            behind=age > self.cfg.reorder_wait + self.cfg.behind_after,
        )

    def over_backlog(self, now: float | None = None) -> bool:
        """A batch has waited longer than reorder wait + ``max_backlog``: stop reading."""
        oldest = next(iter(self._waiting.values()), None)
        if oldest is None or self.cfg.max_backlog is None:
            return False
        now = time.monotonic() if now is None else now
        return now - oldest[0] > self.cfg.reorder_wait + self.cfg.max_backlog

    def _has_site(self, batch: PlotBatch) -> bool:
        r = self.radars.get(batch.radar_id)  # None: forgotten meanwhile (see _admit)
        if r is not None and r.site is not None:
            return True
        self._moved_to_refused(batch)
        if batch.radar_id not in self._warned and len(self._warned) < self.cfg.max_radars:
            self._warned.add(batch.radar_id)
            log.warning(
                "radar %s: plots but no site (no RadarSite message or configured site): "
                "its batches are dropped until the site is known",
                batch.radar_id,
            )
        self.reject("no site for radar", batch.radar_id)
        return False

    def published(self, out: CycleOutput) -> None:
        """Record the latency of each batch of a cycle output just published: publication
        wall time − the sender's wall-clock stamp. A batch without a stamp, or with one
        no clock could give (more than ``future_tolerance`` ahead of this host's clock, or
        older than ``LATENCY_MAX_S``), is counted and left out: a foreign publisher
        cannot move the figures with its payload times."""
        t = time.time_ns()
        ahead = (self.cfg.future_tolerance or 1.0) * 1e3
        lats = []
        for sent in out.sent_ns:
            if sent is None:
                self.counters["latency_unstamped"] += 1
                continue
            lat = (t - sent) / 1e6
            if not -ahead <= lat <= LATENCY_MAX_S * 1e3:
                self.counters["latency_implausible"] += 1
                continue
            lats.append(lat)
        out.latency_ms = max(lats) if lats else None
        self.latencies.extend(lats)
        self.counters["track_batches_published"] += 1 + (out.full is not None)

    def snapshot_payload(self) -> bytes | None:
        """The current picture as a full TrackBatch (JSON), or ``None`` before any track
        cycle; safe to call from another thread (the snapshot queryable)."""
        pipe = self.pipeline
        snap = None if pipe is None else self._stamp(pipe.snapshot())
        return None if snap is None else snap.to_json_bytes()

    def _stamp(self, msg: FeedMessage | None) -> FeedMessage | None:
        """Put the incarnation ``epoch`` into a feed message's header."""
        if msg is not None and self.epoch is not None:
            msg.header["epoch"] = self.epoch
        return msg

    # --- status ----------------------------------------------------------------------
    def latency_stats(self) -> LatencyStats:
        left_out = {
            "unstamped": self.counters["latency_unstamped"],
            "implausible": self.counters["latency_implausible"],
        }
        if not self.latencies:
            return LatencyStats(count=0, **left_out)
        a = np.fromiter(self.latencies, dtype=float)
        p50, p90, p99 = np.percentile(a, [50, 90, 99])
        return LatencyStats(
            count=int(a.size),
            p50=float(p50),
            p90=float(p90),
            p99=float(p99),
            max=float(a.max()),
            **left_out,
        )

    def late_stats(self) -> LateStats:
        """Late batches applied / refused and the tracker's out-of-sequence updates
        (``TrackPipeline.oosm``)."""
        oosm = getattr(self.pipeline, "oosm", None) or {}
        return LateStats(
            max_lateness_s=self.cfg.max_lateness,
            batches_late=self.counters["batches_late_applied"],
            batches_too_late=self.rejected["too late"],
            batches_oosm=oosm.get("batches", 0),
            plots_oosm=oosm.get("plots", 0),
            track_updates_oosm=oosm.get("track_updates", 0),
            hits_oosm=oosm.get("hits", 0),
            no_prior_oosm=oosm.get("no_prior", 0),
            unsupported=oosm.get("unsupported", 0),
        )

    def identity_status(self) -> IdentityStatus | None:
        """The identity counters (the tracker's totals of its identity events) and the
        published tracks in emergency; None before the first batch or without identity."""
        tracker = getattr(self.pipeline, "tracker", None)
        if tracker is None or tracker.identity is None:
            return None
        tot = tracker.totals
        ident = self.pipeline.picture().ident
        emergency = 0 if ident is None else int(np.isin(ident.codes[:, 0], EMERGENCY).sum())
        return IdentityStatus(
            conflicts=tot.get("identity_conflicts", 0), changes=tot.get("identity_changes", 0),
            emergencies=tot.get("emergencies", 0), spi=tot.get("spi_raised", 0),
            tracks_in_emergency=emergency,
        )  # fmt: skip

    def _coalesced(self) -> dict[str, int]:
        """Coalesced tracker steps (``coalesce_max_deg``; ``TrackPipeline.coalesced``)."""
        co = getattr(self.pipeline, "coalesced", None) or {}
        return {
            "coalesced_steps": co.get("steps", 0),
            "batches_coalesced": co.get("batches", 0),
            "coalesced_retried": co.get("retried", 0),
        }

    def _plot_rejections(self) -> dict[str, int]:
        """Plots the conversion rejected, by reason with the numbers masked (``#``) so
        that the reasons form a small set."""
        out: Counter[str] = Counter()
        for reason, n in getattr(self.pipeline, "rejected", {}).items():
            out["plot: " + _NUMBER.sub("#", reason)] += n
        return dict(out)

    def status(self, now: float | None = None) -> Status:
        """The Status now (``now``: the monotonic clock of the backlog, rates and the
        overload policy's window; default: now)."""
        now = time.monotonic() if now is None else now
        confirmed = total = None
        if self.pipeline is not None and self.counters["groups"]:
            picture = self.pipeline.picture()
            total = len(picture)
            confirmed = int(np.count_nonzero(getattr(picture, "confirmed", [])))
        reg = getattr(self.pipeline, "registration", None)  # registration_link
        return Status(
            service="fusion",
            service_id=self.cfg.fusion_id,
            epoch=self.epoch,
            role=self.role,
            time=time.time_ns(),
            uptime_s=time.monotonic() - self.started,
            counters={
                **self.counters,
                "queued": len(self.buffer),
                "plots_near_radar": reg.plots_near_radar if reg else 0,
                **self._coalesced(),
            },
            registration=reg.status(self.cfg.fusion_id) if reg else None,
            identity=self.identity_status(),
            rejected={**self.rejected, **self._plot_rejections()},
            radars=[
                RadarHealth(
                    radar_id=r.radar_id,
                    alive=r.alive,
                    site_known=r.site is not None,
                    batches=r.batches,
                    plots=r.plots,
                    plots_per_s=r.rate.rate(now),
                    last_time=r.last_time,
                    clock_offset_s=self.buffer.clock_offset(r.radar_id),
                    site_held=r.site_held is not None,
                    batches_refused=r.refused,
                    batches_lost=self.buffer.seen.lost(r.radar_id),
                    samples_missed=r.missed,
                )
                for r in sorted(self.radars.values(), key=lambda r: r.radar_id)
            ],
            latency_ms=self.latency_stats(),
            backlog=self.backlog(now),
            late=self.late_stats(),
            overload=self.overload.status(now),
            tracks_confirmed=confirmed,
            tracks_total=total,
            message=self._status_message(),
        )

    def _status_message(self) -> str:
        if self.pipeline is None:
            if any(r.site is not None for r in self.radars.values()):
                return "waiting for plots"
            return "waiting for a radar site"
        held = sorted(r.radar_id for r in self.radars.values() if r.site_held is not None)
        if held:
            shown = ", ".join(held[:5]) + (" …" if len(held) > 5 else "")
            return (
                f"site change held (beyond site_tolerance of the accepted site) for "
                f"{len(held)} radar(s): {shown}; accept with accept_sites"
            )
        return ""


def site_displacement_m(a: RadarSite, b: RadarSite) -> float:
    """Distance between two sites' antenna positions, m (WGS-84 ECEF chord, 3-D)."""
    pa = np.array(pymap3d.geodetic2ecef(a.lat, a.lon, a.alt))
    pb = np.array(pymap3d.geodetic2ecef(b.lat, b.lon, b.alt))
    return float(np.linalg.norm(pa - pb))


LATENCY_MAX_S = 3600.0
"""Latencies longer than this are taken as a wrong stamp, not a slow service, s."""
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
