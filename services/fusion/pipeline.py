"""One fusion cycle from wire messages to wire messages: ``PlotBatch`` → convert to the
system frame (:func:`fusion.frames.convert_plots`) → :class:`Tracker` step →
``TrackBatch`` + ``TrackEvent`` (lat/lon/alt, velocity east/north/up, speed, heading).

The same code path serves the live fusion service and the offline ``skyfuse track``.
"""

from __future__ import annotations

import math

import numpy as np
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.fusion.tracker.tracker import Tracker, TrackerOutput
from skyfuse.schemas import (
    FrameSpec,
    PlotBatch,
    RadarKind,
    RadarSite,
    Track,
    TrackBatch,
    TrackEvent,
    TrackEventKind,
    TrackStatus,
)
from skyfuse.services.fusion.adapter import measurement_batch_from
from skyfuse.services.fusion.registration_link import RegistrationLink

TWO_PI = 2.0 * math.pi


def assumed_height(site: RadarSite, configured: float | None) -> float | None:
    """Height given to a radar's plots without one (m above the ellipsoid, σ 3000 m):
    ``configured``, else the site's height (its ground level: the aircraft without a
    flight level are mostly on the surface near the radar, docs/registration.md §4).
    Cartesian sensors keep their own rule (the site height with σ_cartesian)."""
    if configured is not None or site.kind is RadarKind.CARTESIAN:
        return configured
    return site.alt


class TrackPipeline:
    """Conversion + tracker + output messages for one fusion id.

    frame: the system frame (a ``FrameSpec`` or ``SystemFrame``); publish: ``confirmed``
    (default) or ``all`` tracks in each TrackBatch (tentative tracks are many in clutter);
    registration: the online sensor registration (a RegistrationConfig, default on);
    assumed_altitude: height of plots without one, m (default: the radar site's height),
    ± 3000 m."""

    def __init__(
        self,
        frame: FrameSpec | SystemFrame,
        tracker_cfg: TrackerConfig | None = None,
        *,
        fusion_id: str = "main",
        publish: str = "confirmed",
        debias: bool = False,
        assumed_altitude: float | None = None,
        registration=None,
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
        self.registration = RegistrationLink(registration)

    def step(self, site: RadarSite, batch: PlotBatch) -> TrackerOutput:
        """Convert and apply one batch; return the tracker's array output."""
        corr = self.registration.correction(site)
        converted = convert_plots(
            self.frame,
            site,
            batch,
            debias=self.debias,
            ndim=self.cfg.ndim,
            assumed_altitude=assumed_height(site, self.assumed_altitude),
            bias=corr,
        )
        mb = self.registration.shift_times(measurement_batch_from(converted, site, batch), corr)
        out = self.tracker.step(mb)
        self.registration.after(out, converted, self.tracker.vel)
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
            tracks = self._tracks(out, rows, x, lat, lon, alt, ve, vn, vu, speed, heading)
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

    def _tracks(self, out, rows, x, lat, lon, alt, ve, vn, vu, speed, heading) -> list[Track]:
        """Track messages of output rows ``rows``. The wire constraints (finite
        covariance, lat/lon/heading ranges, non-negative ids) are checked for all rows at
        once; when they hold the models are built without re-validating each field (the
        shapes hold by construction), otherwise through the validating constructor,
        which names the offending field."""
        k = self.cfg.ndim
        P = out.covariances[rows]
        ok = (
            np.isfinite(P).all()
            and np.isfinite(x).all()
            and ((lat >= -90.0) & (lat <= 90.0)).all()
            and ((lon >= -180.0) & (lon <= 180.0)).all()
            and ((heading >= 0.0) & (heading < TWO_PI)).all()
            and np.isfinite(speed).all()
            and (out.ids[rows] >= 0).all()
            and out.time_ns >= 0
        )
        make = Track.model_construct if ok else Track
        masks_u, first = np.unique(out.radar_mask[rows], return_index=True)
        names = {int(m): out.radars_of(int(rows[r])) for m, r in zip(masks_u, first)}
        ids = out.ids[rows].tolist()
        conf = out.confirmed[rows].tolist()
        exist = np.clip(out.existence[rows], 0.0, 1.0).tolist()
        masks = out.radar_mask[rows].tolist()
        upd = out.updates[rows].tolist()
        cols = [a.tolist() for a in (lat, lon, ve, vn, speed, heading)]
        alts = alt.tolist() if k == 3 else [None] * len(rows)
        vus = vu.tolist() if k == 3 else [0.0] * len(rows)
        states, covs = x.tolist(), P.tolist()
        tracks = []
        for j in range(len(rows)):
            tracks.append(
                make(
                    track_id=ids[j],
                    time=out.time_ns,
                    status=TrackStatus.CONFIRMED if conf[j] else TrackStatus.TENTATIVE,
                    existence=exist[j],
                    state=states[j],
                    covariance=covs[j],
                    lat=cols[0][j],
                    lon=cols[1][j],
                    alt=alts[j],
                    vel_east=cols[2][j],
                    vel_north=cols[3][j],
                    vel_up=vus[j],
                    speed=cols[4][j],
                    heading=cols[5][j],
                    radars=list(names[masks[j]]),
                    updates=upd[j],
                )
            )
        return tracks

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
