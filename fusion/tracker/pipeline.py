"""One fusion cycle from wire messages to wire messages: ``PlotBatch`` → convert to the
system frame (:func:`fusion.frames.convert_plots`) → :class:`Tracker` step →
``TrackBatch`` + ``TrackEvent`` (lat/lon/alt, velocity east/north/up, speed, heading).

The same code path serves the live fusion service and the offline ``skyfuse track``.
"""

from __future__ import annotations

import math

import numpy as np

from fusion.frames import SystemFrame, convert_plots
from schemas import (
    FrameSpec,
    PlotBatch,
    RadarSite,
    Track,
    TrackBatch,
    TrackEvent,
    TrackEventKind,
    TrackStatus,
)

from .adapter import measurement_batch_from
from .config import TrackerConfig
from .tracker import Tracker, TrackerOutput

TWO_PI = 2.0 * math.pi


class TrackPipeline:
    """Conversion + tracker + output messages for one fusion id.

    frame: the system frame (a ``FrameSpec`` or ``SystemFrame``); publish: ``confirmed``
    (default) or ``all`` tracks in each TrackBatch (tentative tracks are many in clutter)."""

    def __init__(
        self,
        frame: FrameSpec | SystemFrame,
        tracker_cfg: TrackerConfig | None = None,
        *,
        fusion_id: str = "main",
        publish: str = "confirmed",
        debias: bool = False,
        assumed_altitude: float | None = None,
    ) -> None:
        if publish not in ("confirmed", "all"):
            raise ValueError(f"publish = {publish!r}: must be 'confirmed' or 'all'")
        self.frame = frame if isinstance(frame, SystemFrame) else SystemFrame.from_spec(frame)
        self.cfg = tracker_cfg or TrackerConfig()
        self.tracker = Tracker(self.cfg)
        self.fusion_id = fusion_id
        self.publish = publish
        self.debias = debias
        self.assumed_altitude = assumed_altitude
        self.cycle = 0
        self.rejected: dict[str, int] = {}

    def step(self, site: RadarSite, batch: PlotBatch) -> TrackerOutput:
        """Convert and apply one batch; return the tracker's array output."""
        converted = convert_plots(
            self.frame,
            site,
            batch,
            debias=self.debias,
            ndim=self.cfg.ndim,
            assumed_altitude=self.assumed_altitude,
        )
        mb = measurement_batch_from(converted, site, batch)
        out = self.tracker.step(mb)
        for k, v in out.batch.rejected.items():
            self.rejected[k] = self.rejected.get(k, 0) + v
        return out

    def process(self, site: RadarSite, batch: PlotBatch) -> tuple[TrackBatch, list[TrackEvent]]:
        out = self.step(site, batch)
        return self.track_batch(out, batch), self.track_events(out)

    def track_batch(self, out: TrackerOutput, batch: PlotBatch | None = None) -> TrackBatch:
        """The published TrackBatch for one tracker output."""
        self.cycle += 1
        rows = np.flatnonzero(out.confirmed) if self.publish == "confirmed" else np.arange(len(out))
        x = out.states[rows]
        k = self.cfg.ndim
        px, py = x[:, 0], x[:, 2]
        pz = x[:, 4] if k == 3 else np.zeros(len(rows))
        vx, vy = x[:, 1], x[:, 3]
        vz = x[:, 5] if k == 3 else np.zeros(len(rows))
        tracks = []
        if len(rows):
            lat, lon, alt = self.frame.to_geodetic(px, py, pz)
            ve, vn, vu = self.frame.velocity_to_enu(px, py, pz, vx, vy, vz)
            heading = np.mod(np.arctan2(ve, vn), TWO_PI)
            heading = np.where(heading >= TWO_PI, 0.0, heading)
            speed = np.hypot(ve, vn)
            for j, r in enumerate(rows):
                tracks.append(
                    Track(
                        track_id=int(out.ids[r]),
                        time=out.time_ns,
                        status=TrackStatus.CONFIRMED if out.confirmed[r] else TrackStatus.TENTATIVE,
                        existence=float(np.clip(out.existence[r], 0.0, 1.0)),
                        state=x[j].tolist(),
                        covariance=out.covariances[r].tolist(),
                        lat=float(lat[j]),
                        lon=float(lon[j]),
                        alt=float(alt[j]) if k == 3 else None,
                        vel_east=float(ve[j]),
                        vel_north=float(vn[j]),
                        vel_up=float(vu[j]) if k == 3 else 0.0,
                        speed=float(speed[j]),
                        heading=float(heading[j]),
                        radars=out.radars_of(r),
                        updates=int(out.updates[r]),
                    )
                )
        return TrackBatch(
            fusion_id=self.fusion_id,
            cycle=self.cycle,
            time=out.time_ns,
            frame=self.frame.spec(),
            state_labels=list(self.tracker.model.labels),
            source_radar=out.radar_id,
            source_seq=None if batch is None else batch.seq,
            tracks=tracks,
        )

    def track_events(self, out: TrackerOutput) -> list[TrackEvent]:
        return [
            TrackEvent(
                fusion_id=self.fusion_id,
                time=e.time_ns,
                kind=TrackEventKind(e.kind),
                track_id=e.track_id,
                other_track_id=e.other_track_id,
                existence=float(np.clip(e.existence, 0.0, 1.0)),
                reason=e.reason,
            )
            for e in out.events
        ]
