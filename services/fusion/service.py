"""The fusion service core: input validation, radar registry, time-ordered reorder buffer,
tracking, outputs and health counters. Network-free (the Zenoh side is ``cmd_fusion``),
so it is tested directly.

Data flow for one received plot batch::

    payload ─ validate (PlotBatch) ─ duplicate? ─ late? ─ reorder buffer ─(bounded wait)→
        site known? ─ track pipeline (convert_plots + tracker, shared with `skyfuse track`)
        → TrackBatch + TrackEvents → publish; latency = publish wall time − sweep end

**Reorder buffer.** Batches from several radars arrive with network jitter. Each batch is
held for ``reorder_wait`` seconds of wall time after its arrival, and batches are applied
in the order of ``(time_end, arrival)``. A batch whose ``time_end`` is earlier than the
last applied batch's is *out of sequence*: it is dropped and counted
(``rejected["out of sequence"]``) because the tracker's state has already moved past it.
A batch seen twice (same radar, seq and time_end) is counted as a duplicate.

**Sites.** A radar's site comes from its ``RadarSite`` messages or from the
configuration; a batch from a radar without a known site is counted
(``rejected["no site for radar"]``) and reported, never converted with a guessed site.

**Latency** (plot time → track publication) is ``publish wall time − sender stamp``; the
sender stamp is the wall-clock instant the sector sweep ended, sent as the sample
attachment by ``skyfuse sensor`` / ``replay``; without one the batch's own ``time_end``
is taken as a wall-clock time (a live radar).
"""

from __future__ import annotations

import heapq
import itertools
import logging
import re
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from pydantic import BaseModel, Field, ValidationError
from skyfuse.schemas import (
    FrameKind,
    FrameSpec,
    LatencyStats,
    PlotBatch,
    RadarHealth,
    RadarSite,
    Status,
    TrackBatch,
    TrackEvent,
    TrackStatus,
    keys,
)
from skyfuse.services.fusion.system_frame import frame_for_sites
from skyfuse.services.runtime.lifecycle import RateWindow

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
    latency_window: int = Field(
        20_000, ge=10, description="Latency percentiles over the last N publications"
    )
    rate_window: float = Field(5.0, gt=0, description="Plot-rate averaging window, s")
    queue: int = Field(
        10_000,
        ge=10,
        le=1_000_000,
        description="Batches waiting in the reorder buffer (and messages in the receive "
        "queue), at most; beyond it the publishers are slowed down",
    )

    def frame_spec(self, sites: list[RadarSite]) -> FrameSpec | None:
        """The configured frame, or one centred on ``sites``
        (:func:`~skyfuse.services.fusion.system_frame.frame_for_sites`, the rule shared
        with the offline runner)."""
        return frame_for_sites(
            sites, self.frame_kind, self.frame_lat0, self.frame_lon0, self.frame_alt0
        )


class CyclePipeline(Protocol):
    """One fusion cycle: a batch in, the resulting TrackBatch and TrackEvents out (the
    code path shared with the offline ``skyfuse track``)."""

    def process(self, site: RadarSite, batch: PlotBatch) -> tuple[TrackBatch, list[TrackEvent]]: ...


@dataclass(order=True)
class _Pending:
    time_end: int
    order: int
    arrival: float = field(compare=False)
    batch: PlotBatch = field(compare=False)
    sent_ns: int | None = field(compare=False)


class ReorderBuffer:
    """Holds batches ``wait`` seconds (arrival clock) and releases them in
    ``(time_end, arrival order)`` order; rejects late and duplicate batches."""

    def __init__(self, wait: float) -> None:
        self.wait = wait
        self._heap: list[_Pending] = []
        self._order = itertools.count()
        self.last_time: int | None = None
        self._seen: dict[str, deque] = {}

    def __len__(self) -> int:
        return len(self._heap)

    def push(self, batch: PlotBatch, arrival: float, sent_ns: int | None = None) -> str | None:
        """Queue ``batch``; return ``None`` or the reason it was refused."""
        seen = self._seen.setdefault(batch.radar_id, deque(maxlen=256))
        ident = (batch.seq, batch.time_end, batch.scan)
        if ident in seen:
            return "duplicate batch"
        if self.last_time is not None and batch.time_end < self.last_time:
            return "out of sequence"
        seen.append(ident)
        heapq.heappush(
            self._heap, _Pending(batch.time_end, next(self._order), arrival, batch, sent_ns)
        )
        return None

    def pop_ready(self, now: float, limit: int | None = None) -> list[_Pending]:
        """Batches whose hold has expired, in order (a held head holds back the rest),
        at most ``limit``."""
        out = []
        while self._heap and now - self._heap[0].arrival >= self.wait:
            if limit is not None and len(out) >= limit:
                break
            out.append(self._release())
        return out

    def next_due(self) -> float | None:
        """Arrival-clock time the head of the buffer is due, or ``None`` if empty."""
        return self._heap[0].arrival + self.wait if self._heap else None

    def flush(self) -> list[_Pending]:
        """Everything queued, in order."""
        return [self._release() for _ in range(len(self._heap))]

    def _release(self) -> _Pending:
        p = heapq.heappop(self._heap)
        self.last_time = p.time_end if self.last_time is None else max(self.last_time, p.time_end)
        return p


@dataclass
class _Radar:
    radar_id: str
    site: RadarSite | None = None
    alive: bool = False
    batches: int = 0
    plots: int = 0
    last_time: int | None = None
    rate: RateWindow = field(default_factory=RateWindow)


@dataclass
class CycleOutput:
    tracks: TrackBatch
    events: list[TrackEvent]
    sent_ns: int | None
    """Sender's wall-clock stamp of the batch that triggered the cycle."""
    time_end: int
    latency_ms: float | None = None


class FusionCore:
    """State of one fusion service; feed it with :meth:`on_plots`, :meth:`on_site`,
    :meth:`on_alive`, and call :meth:`poll` regularly to run due cycles."""

    def __init__(self, cfg: FusionConfig, pipeline_factory) -> None:
        self.cfg = cfg
        self._factory = pipeline_factory
        self.pipeline: CyclePipeline | None = None
        self.frame: FrameSpec | None = None
        self.buffer = ReorderBuffer(cfg.reorder_wait)
        self.radars: dict[str, _Radar] = {}
        self.counters: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.latencies: deque[float] = deque(maxlen=cfg.latency_window)
        self.latest: TrackBatch | None = None
        self.started = time.monotonic()
        self._warned: set[str] = set()
        for site in cfg.sites:
            self.on_site(site, configured=True)

    # --- inputs ----------------------------------------------------------------------
    def _radar(self, radar_id: str) -> _Radar:
        r = self.radars.get(radar_id)
        if r is None:
            r = self.radars[radar_id] = _Radar(radar_id, rate=RateWindow(self.cfg.rate_window))
        return r

    def reject(self, reason: str, detail: str = "") -> None:
        self.rejected[reason] += 1
        if self.rejected[reason] <= 3:
            log.warning("rejected input: %s%s", reason, f" ({detail})" if detail else "")

    def on_site_payload(self, key: str, payload: bytes) -> None:
        try:
            site = RadarSite.from_json_bytes(payload)
        except ValidationError as e:
            self.reject(_reason("RadarSite", e), _detail(e))
            return
        owner = keys.parse(key).owner
        if site.radar_id != owner:
            self.reject("site radar_id does not match its key", f"{site.radar_id} on {key}")
            return
        self.on_site(site)

    def on_site(self, site: RadarSite, configured: bool = False) -> None:
        r = self._radar(site.radar_id)
        if r.site != site:
            if r.site is not None:
                log.info("radar %s: site changed", site.radar_id)
            r.site = site
            self.counters["sites"] += 1
            log.info(
                "radar %s: site %.4f°, %.4f° (%s)%s",
                site.radar_id,
                site.lat,
                site.lon,
                site.kind.value,
                " from configuration" if configured else "",
            )
        if self.pipeline is None and self.cfg.frame_lat0 is not None:
            self._start_pipeline()  # a configured origin: no need to wait for the plots

    def _start_pipeline(self) -> None:
        """Fix the system frame from the sites known now (at the first plot batch of a
        radar with a site, see :mod:`~skyfuse.services.fusion.system_frame`)."""
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
        if info.kind != "alive" or info.owner is None:
            return
        r = self._radar(info.owner)
        if r.alive != alive:
            log.info("radar %s %s", info.owner, "is alive" if alive else "went away")
        r.alive = alive

    def on_plots_payload(
        self, key: str, payload: bytes, arrival: float, sent_ns: int | None = None
    ) -> PlotBatch | None:
        """Validate and queue one received batch; ``None`` if rejected (reason counted)."""
        self.counters["batches_received"] += 1
        try:
            batch = PlotBatch.from_json_bytes(payload)
        except ValidationError as e:
            self.reject(_reason("PlotBatch", e), _detail(e))
            return None
        owner = keys.parse(key).owner
        if batch.radar_id != owner:
            self.reject("batch radar_id does not match its key", f"{batch.radar_id} on {key}")
            return None
        return batch if self.on_plots(batch, arrival, sent_ns) else None

    def on_plots(self, batch: PlotBatch, arrival: float, sent_ns: int | None = None) -> bool:
        r = self._radar(batch.radar_id)
        if self.pipeline is None and r.site is not None:
            self._start_pipeline()
        reason = self.buffer.push(batch, arrival, sent_ns)
        if reason is not None:
            self.reject(reason, f"radar {batch.radar_id} seq {batch.seq}")
            return False
        n = len(batch.time)
        r.batches += 1
        r.plots += n
        r.rate.add(n)
        r.last_time = batch.time_end if r.last_time is None else max(r.last_time, batch.time_end)
        self.counters["batches_in"] += 1
        self.counters["plots_in"] += n
        return True

    # --- cycles ----------------------------------------------------------------------
    def poll(
        self, now: float | None = None, *, flush: bool = False, budget_s: float | None = None
    ) -> list[CycleOutput]:
        """Run the cycles of the batches whose hold expired (all queued with ``flush``).

        ``budget_s`` bounds the time spent (at least one cycle runs): the rest stays
        queued for the next call, so a service that falls behind still reads its input
        and publishes its Status in between."""
        now = time.monotonic() if now is None else now
        if flush:
            return [out for p in self.buffer.flush() if (out := self._cycle(p)) is not None]
        t_end = None if budget_s is None else time.monotonic() + budget_s
        outs = []
        while True:
            ready = self.buffer.pop_ready(now, limit=1)
            if not ready:
                break
            out = self._cycle(ready[0])
            if out is not None:
                outs.append(out)
            if t_end is not None and time.monotonic() >= t_end:
                break
        return outs

    def cycle(self, p: _Pending) -> CycleOutput | None:
        """Run the cycle of one released batch (see :meth:`poll`)."""
        return self._cycle(p)

    def _cycle(self, p: _Pending) -> CycleOutput | None:
        batch = p.batch
        r = self._radar(batch.radar_id)
        if r.site is None:
            if batch.radar_id not in self._warned:
                self._warned.add(batch.radar_id)
                log.warning(
                    "radar %s: plots but no site (no RadarSite message or configured site): "
                    "its batches are dropped until the site is known",
                    batch.radar_id,
                )
            self.reject("no site for radar", batch.radar_id)
            return None
        if self.pipeline is None:
            self._start_pipeline()
        try:
            tracks, events = self.pipeline.process(r.site, batch)
        except ValidationError as e:  # the pipeline built an invalid output message
            self.reject("tracker error", f"invalid output: {_detail(e)}")
            log.error("tracker output invalid on radar %s seq %s: %s", batch.radar_id, batch.seq, e)
            return None
        except ValueError as e:
            self.reject("batch not convertible", f"radar {batch.radar_id}: {e}")
            return None
        except Exception as e:  # a tracker bug must not kill the service
            self.reject("tracker error", f"{type(e).__name__}: {e}")
            log.exception("tracker error on radar %s seq %s", batch.radar_id, batch.seq)
            return None
        self.counters["cycles"] += 1
        self.counters["plots_applied"] += len(batch.time)
        self.counters["events"] += len(events)
        self.latest = tracks
        return CycleOutput(tracks, events, p.sent_ns, batch.time_end)

    def published(self, out: CycleOutput) -> None:
        """Record the latency of a cycle output just published."""
        ref = out.sent_ns if out.sent_ns is not None else out.time_end
        lat = (time.time_ns() - ref) / 1e6
        out.latency_ms = lat
        self.latencies.append(lat)
        self.counters["track_batches_published"] += 1

    # --- status ----------------------------------------------------------------------
    def latency_stats(self) -> LatencyStats:
        if not self.latencies:
            return LatencyStats(count=0)
        a = np.fromiter(self.latencies, dtype=float)
        p50, p90, p99 = np.percentile(a, [50, 90, 99])
        return LatencyStats(
            count=int(a.size), p50=float(p50), p90=float(p90), p99=float(p99), max=float(a.max())
        )

    def _plot_rejections(self) -> dict[str, int]:
        """Plots the conversion rejected, by reason with the numbers masked (``#``) so
        that the reasons form a small set."""
        out: Counter[str] = Counter()
        for reason, n in getattr(self.pipeline, "rejected", {}).items():
            out["plot: " + _NUMBER.sub("#", reason)] += n
        return dict(out)

    def status(self) -> Status:
        now = time.monotonic()
        confirmed = total = None
        if self.latest is not None:
            total = len(self.latest.tracks)
            confirmed = sum(t.status == TrackStatus.CONFIRMED for t in self.latest.tracks)
        reg = getattr(self.pipeline, "registration", None)  # registration_link (issue 17)
        return Status(
            service="fusion",
            service_id=self.cfg.fusion_id,
            time=time.time_ns(),
            uptime_s=now - self.started,
            counters={
                **self.counters,
                "queued": len(self.buffer),
                "plots_near_radar": reg.plots_near_radar if reg else 0,
            },
            registration=reg.status(self.cfg.fusion_id) if reg else None,
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
                )
                for r in sorted(self.radars.values(), key=lambda r: r.radar_id)
            ],
            latency_ms=self.latency_stats(),
            tracks_confirmed=confirmed,
            tracks_total=total,
            message=""
            if self.pipeline is not None
            else "waiting for plots"
            if any(r.site is not None for r in self.radars.values())
            else "waiting for a radar site",
        )


_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _reason(model: str, e: ValidationError) -> str:
    err = e.errors()[0]
    loc = ".".join(str(p) for p in err["loc"] if not isinstance(p, int))
    if err["type"] == "json_invalid":
        return f"invalid {model}: not JSON"
    if not loc:  # a model-level check: its message starts with the column name
        m = re.match(r"(?:Value error, )?(?:column )?'?([A-Za-z_]+)", err["msg"])
        loc = m.group(1) if m else "value"
    return f"invalid {model}: {loc}"


def _detail(e: ValidationError) -> str:
    err = e.errors()[0]
    loc = ".".join(str(p) for p in err["loc"]) or "(payload)"
    return f"{loc}: {err['msg']}"
