"""The one offline runner: recorded messages in time order through the live code path,
with observers that score, write and time the run.

:func:`run_offline` takes the messages of a recording (``RadarSite``, ``PlotBatch``,
``Truth``, ``TrackBatch``, ``Status``, … as decoded from MCAP, or the batches an ASTERIX
reader produced), the sites known up front (an ASTERIX sites file; recordings carry their
own ``RadarSite`` messages), an :class:`OfflineConfig` and a list of :class:`Observer`.

* With a tracker configuration each plot batch goes through the same
  :class:`~skyfuse.services.fusion.pipeline.TrackPipeline` as the live fusion service
  (conversion to the system frame → tracker), and every observer sees each
  :class:`Step`. The system frame is fixed at the first plot batch of a radar with a
  known site by :func:`~skyfuse.services.fusion.system_frame.frame_for_sites`, from the
  sites recorded before it — the rule the live service applies when it applies its first
  batch — so a live replay and an offline run give the same frame and the same tracks.
* With ``tracker=None`` nothing is tracked: the recording's own ``TrackBatch`` messages
  (a live fusion service's output, e.g. ``skyfuse demo``) are handed to the observers,
  in the frame they carry.

Users: ``skyfuse track``, ``skyfuse eval FILE``, the demo's report and the tests. The
observers (truth GOSPA, label scoring, MCAP writing, timing) are in
:mod:`skyfuse.services.evaluation.observers`.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field
from skyfuse.schemas import (
    FrameKind,
    PlotBatch,
    RadarSite,
    TrackBatch,
    TrackEvent,
    TrackPicture,
    Truth,
)
from skyfuse.services.evaluation.numbers import rejection_reasons
from skyfuse.services.fusion.system_frame import frame_for_sites

log = logging.getLogger(__name__)


class OfflineConfig(BaseModel):
    """How to run a recording offline (the tracker is a ``TrackerConfig``)."""

    model_config = ConfigDict(arbitrary_types_allowed=True)

    tracker: object | None = Field(
        None, description="TrackerConfig; None: score the recording's own TrackBatches"
    )
    frame_kind: FrameKind = Field(FrameKind.STEREOGRAPHIC, description="System frame kind")
    frame_lat0: float | None = Field(None, ge=-90, le=90, description="Origin latitude, deg")
    frame_lon0: float | None = Field(None, ge=-180, le=180, description="Origin longitude, deg")
    fusion_id: str = Field("main", description="Fusion id of the output messages")
    publish: Literal["confirmed", "all"] = Field("confirmed", description="Tracks published")
    assumed_altitude: float | None = Field(
        None,
        ge=-1000,
        le=30000,
        description="Height for plots without one, m, ± 3000 m (default: the site's height)",
    )
    registration: object | None = Field(
        None, description="RegistrationConfig of the online sensor registration (default: on)"
    )


@dataclass
class Step:
    """One tracked plot batch: the batch, its radar's site, the tracker output
    (:class:`~skyfuse.fusion.tracker.tracker.TrackerOutput`, states in the system frame,
    m and m/s) and the time the step took (ms). :meth:`wire` builds the published
    TrackBatch and TrackEvents once, for the observers that need them."""

    batch: PlotBatch
    site: RadarSite
    out: object
    ms: float
    pipeline: object
    _wire: tuple[object, list[TrackEvent]] | None = None

    def wire(self) -> tuple[object, list[TrackEvent]]:
        """The published delta (a ``services.fusion.feed.FeedMessage``: only the tracks
        this step changed) and the events; call it at every step or never, since each
        delta is relative to the previous one."""
        if self._wire is None:
            p = self.pipeline
            self._wire = (p.track_batch(self.out, self.batch), p.track_events(self.out))
        return self._wire


class Observer:
    """Hooks of :func:`run_offline`; each observer overrides the ones it needs and
    returns its part of the summary from :meth:`summary`."""

    def start(self, frame) -> None:
        """The system frame (a ``SystemFrame``) has been fixed."""

    def on_plots(self, batch: PlotBatch) -> None:
        """Every plot batch read, tracked or not (its ``target_id``/``mode_s`` labels)."""

    def on_step(self, step: Step) -> None:
        """A plot batch went through the tracker."""

    def on_tracks(self, tracks: TrackBatch) -> None:
        """A recorded TrackBatch (only with ``tracker=None``)."""

    def on_truth(self, truth: Truth) -> None:
        """A simulation truth message."""

    def on_message(self, msg) -> None:
        """Any other message (Status, TrackEvent, undecoded records …)."""

    def summary(self) -> dict:
        return {}


@dataclass
class OfflineResult:
    """What :func:`run_offline` did: the frame, the sites, counts, the pipeline (its
    tracker's totals and plot rejections) and the observers' summaries."""

    frame: object | None
    sites: dict[str, RadarSite]
    counts: Counter
    pipeline: object | None
    observers: Sequence[Observer] = field(default_factory=list)

    def summary(self) -> dict:
        """The run's own figures followed by every observer's summary."""
        p = self.pipeline
        out = {
            "frame": self.frame.spec().model_dump(mode="json") if self.frame else None,
            "radars": sorted(self.sites),
            "batches": self.counts["batches"],
            "plots_processed": self.counts["plots"],
            "plots_rejected": rejection_reasons(p.rejected) if p is not None else {},
            "counts": dict(self.counts),
        }
        if p is not None:
            out["tracker_totals"] = dict(p.tracker.totals)
            reg = getattr(p, "registration", None)  # services.fusion.registration_link
            if reg is not None:
                out["plots_near_radar"] = reg.plots_near_radar
                out["registration"] = reg.estimator.status()
        for obs in self.observers:
            out.update(obs.summary())
        return out


class _Run:
    """State of one :func:`run_offline` pass (split from it to keep each phase short)."""

    def __init__(self, sites, config: OfflineConfig, observers: Sequence[Observer]) -> None:
        self.sites: dict[str, RadarSite] = dict(sites or {})
        self.cfg = config
        self.obs = list(observers)
        self.counts: Counter = Counter()
        self.frame = None
        self.pipeline = None
        self.picture = TrackPicture()
        self.last_time: int | None = None

    def fix_frame(self, spec) -> None:
        from skyfuse.fusion.frames import SystemFrame

        self.frame = SystemFrame.from_spec(spec)
        log.info("system frame %s at %.4f°, %.4f°", spec.kind.value, spec.lat0, spec.lon0)
        if self.cfg.tracker is not None:
            from skyfuse.services.fusion.pipeline import TrackPipeline

            self.pipeline = TrackPipeline(
                self.frame,
                self.cfg.tracker,
                fusion_id=self.cfg.fusion_id,
                publish=self.cfg.publish,
                assumed_altitude=self.cfg.assumed_altitude,
                registration=self.cfg.registration,
            )
        for o in self.obs:
            o.start(self.frame)

    def feed(self, msg) -> None:
        if isinstance(msg, PlotBatch):
            for o in self.obs:
                o.on_plots(msg)
            if self.cfg.tracker is not None:
                self.track(msg)
        elif isinstance(msg, RadarSite):
            self.sites[msg.radar_id] = msg
        elif isinstance(msg, Truth):
            for o in self.obs:
                o.on_truth(msg)
        elif isinstance(msg, TrackBatch) and self.cfg.tracker is None:
            # the recorded feed: deltas and fulls, rebuilt into the picture (schemas.tracks)
            if self.frame is None:
                self.fix_frame(msg.frame)
            self.counts["track batches"] += 1
            if self.picture.apply(msg):
                picture = self.picture.batch()
                for o in self.obs:
                    o.on_tracks(picture)
        else:
            for o in self.obs:
                o.on_message(msg)

    def track(self, msg: PlotBatch) -> None:
        site = self.sites.get(msg.radar_id)
        if site is None:
            self.counts["batches without a site"] += 1
            return
        if self.frame is None:
            c = self.cfg
            self.fix_frame(
                frame_for_sites(self.sites.values(), c.frame_kind, c.frame_lat0, c.frame_lon0)
            )
        if self.last_time is not None and msg.time_end < self.last_time:
            self.counts["batches out of time order"] += 1
        self.last_time = (
            msg.time_end if self.last_time is None else max(self.last_time, msg.time_end)
        )
        t0 = time.perf_counter()
        try:
            out = self.pipeline.step(site, msg)
        except ValueError as e:
            self.counts["batches rejected"] += 1
            log.warning("batch %s/%s rejected: %s", msg.radar_id, msg.seq, e)
            return
        step = Step(msg, site, out, (time.perf_counter() - t0) * 1e3, self.pipeline)
        self.counts["batches"] += 1
        self.counts["plots"] += len(msg)
        if out.stats.get("oosm_tracks"):  # older than tracks it found: the OOSM update
            self.counts["batches applied out of sequence (OOSM)"] += 1
        for o in self.obs:
            o.on_step(step)


def run_offline(
    messages: Iterable,
    sites: Mapping[str, RadarSite] | None,
    config: OfflineConfig,
    observers: Sequence[Observer] = (),
) -> OfflineResult:
    """Run ``messages`` (in time order) through the tracker of ``config`` (or score their
    own TrackBatches with ``tracker=None``), feeding ``observers``; see the module
    docstring. ``sites``: ``{radar id: RadarSite}`` known before the first message."""
    run = _Run(sites, config, observers)
    for msg in messages:
        run.feed(msg)
    return OfflineResult(run.frame, run.sites, run.counts, run.pipeline, run.obs)
