"""One fusion cycle from wire messages to wire messages: ``PlotBatch`` → convert to the
system frame (:func:`fusion.frames.convert_plots`) → :class:`Tracker` step →
the delta of the track feed (:mod:`services.fusion.feed`: lat/lon/alt, velocity
east/north/up, speed, heading, built from arrays) + ``TrackEvent``. Several batches can go
through in one pass (:meth:`TrackPipeline.process_parts`, the bulk path), the contiguous
sectors of one radar among them as one tracker step when the service is behind
(:mod:`~skyfuse.services.fusion.coalesce`, :mod:`~skyfuse.services.fusion.overload`).

The same code path serves the live fusion service and the offline ``skyfuse track``.
"""

from __future__ import annotations

import dataclasses
import time
from collections import Counter
from collections.abc import Iterator

import numpy as np
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.frames.plot_conversion import ConvertedPlots
from skyfuse.fusion.registration import RegistrationMode
from skyfuse.fusion.tracker.config import TrackerConfig
from skyfuse.fusion.tracker.tracker import Tracker, TrackerOutput
from skyfuse.schemas import FrameSpec, PlotBatch, RadarKind, RadarSite, TrackEvent, TrackEventKind
from skyfuse.schemas.snapshot import counts, mapping
from skyfuse.services.fusion import coalesce
from skyfuse.services.fusion.adapter import measurement_batch_from
from skyfuse.services.fusion.feed import FeedBuilder, FeedMessage
from skyfuse.services.fusion.registration_link import RegistrationLink


@dataclasses.dataclass
class GroupPart:
    """What one part of a group applied (:meth:`TrackPipeline.process_parts`): its delta
    message (``None`` if no batch was applied), events, the batches applied (in order)
    and those that failed, with their exception."""

    message: FeedMessage | None = None
    events: list[TrackEvent] = dataclasses.field(default_factory=list)
    applied: list[PlotBatch] = dataclasses.field(default_factory=list)
    failed: list[tuple[PlotBatch, Exception]] = dataclasses.field(default_factory=list)


def assumed_height(site: RadarSite, configured: float | None) -> float | None:
    """Height given to a radar's plots without one (m above the ellipsoid, σ 3000 m):
    ``configured``, else the site's height (its ground level: the aircraft without a
    flight level are mostly on the surface near the radar, docs/reports/registration-log.md §4).
    Cartesian and WGS-84 sensors keep their own rule (the site height with σ_cartesian;
    their horizontal positions do not depend on it)."""
    if configured is not None or site.kind in (RadarKind.CARTESIAN, RadarKind.WGS84):
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
        self.rejected: dict[str, int] = {}
        self.oosm: Counter[str] = Counter()
        """Late plots applied by the tracker's out-of-sequence update (fusion.tracker.oosm):
        batches, plots, track updates, hits, updates without the stored last step."""
        self.coalesced: Counter[str] = Counter()
        """Coalesced steps (:meth:`process_group`): ``steps`` of several batches, the
        ``batches`` in them, steps ``retried`` batch by batch after an error."""
        self.registration = RegistrationLink(registration)
        self.feed = FeedBuilder(
            self.frame, self.cfg.ndim, list(self.tracker.model.labels), fusion_id, publish
        )

    def step(self, site: RadarSite, batch: PlotBatch) -> TrackerOutput:
        """Convert and apply one batch; return the tracker's array output."""
        return self._track(self._convert(site, batch), site, batch)

    def _convert(self, site: RadarSite, batch: PlotBatch):
        """The plots in the system frame, corrected by the radar's current registration
        estimate (:mod:`~skyfuse.services.fusion.registration_link`)."""
        return convert_plots(
            self.frame,
            site,
            batch,
            debias=self.debias,
            ndim=self.cfg.ndim,
            assumed_altitude=assumed_height(site, self.assumed_altitude),
            bias=self.registration.correction(site),
        )

    def _track(self, converted, site: RadarSite, batch: PlotBatch) -> TrackerOutput:
        # the batch times move by the time offset of the correction its plots were converted
        # with (``converted.bias``), not by a second look-up of the estimate
        mb = measurement_batch_from(converted, site, batch, self.frame, identity=self.cfg.identity)
        mb = self.registration.shift_times(mb, converted.bias)
        out = self.tracker.step(mb)
        self._count_oosm(out.stats)
        self.registration.after(out, converted, self.tracker.vel)
        for k, v in out.batch.rejected.items():
            self.rejected[k] = self.rejected.get(k, 0) + v
        return out

    def _count_oosm(self, stats: dict[str, int]) -> None:
        """Add one step's out-of-sequence figures to :attr:`oosm`."""
        tracks = stats.get("oosm_tracks", 0)
        if tracks:
            self.oosm["batches"] += 1
            self.oosm["plots"] += stats["oosm_plots"]
            self.oosm["track_updates"] += tracks
            self.oosm["hits"] += stats["oosm_hits"]
            self.oosm["no_prior"] += tracks - stats["oosm_prior_known"]
        if stats.get("oosm_unsupported", 0):
            self.oosm["unsupported"] += stats["oosm_unsupported"]

    def process(self, site: RadarSite, batch: PlotBatch) -> tuple[FeedMessage, list[TrackEvent]]:
        """One batch: its delta message and events."""
        out = self.step(site, batch)
        return self.track_batch(out, batch), self.track_events(out)

    def process_group(
        self,
        items: list[tuple[RadarSite, PlotBatch]],
        *,
        coalesce_max: float | None = None,
        mergeable: list[bool] | None = None,
    ) -> tuple[FeedMessage | None, list[TrackEvent], list[tuple[PlotBatch, Exception]]]:
        """Several batches, in the given (time) order, in one pass, with one delta
        message for the group (:meth:`process_parts` in one part). Returns the message
        (``None`` if no batch could be applied), the events, and the batches that failed
        with their exception (the others are applied)."""
        (part,) = self.process_parts(items, coalesce_max=coalesce_max, mergeable=mergeable)
        return part.message, part.events, part.failed

    def process_parts(
        self,
        items: list[tuple[RadarSite, PlotBatch]],
        *,
        coalesce_max: float | None = None,
        mergeable: list[bool] | None = None,
        part_s: float | None = None,
        max_members: int | None = None,
        on_step=None,
    ) -> Iterator[GroupPart]:
        """Several batches, in the given (time) order, in one pass: the plots of each
        radar converted at once, one tracker step per batch, one delta message per part
        (the same picture as one message per batch).

        part_s (s, default: one part): once the steps of the current part have taken this
        long and steps remain, the part's delta is yielded before the next step runs, so
        a long group's first batches are published without waiting for its last ones.

        coalesce_max (rad, default off): the contiguous sector batches of one radar among
        them (those where ``mergeable``, default all) are applied as one step of at most
        that azimuth width each (:mod:`~skyfuse.services.fusion.coalesce`); a coalesced
        step refused as input (ValueError: conversion, validation) is applied batch by
        batch, so a bad batch costs only itself; ``max_members``: at most this many batches
        in one step (the overload policy's choice).

        on_step (optional): called after each step with (plots, seconds, azimuth width
        rad) of the step, the measurements of the overload policy's cost model."""
        steps = self._steps(items, coalesce_max, mergeable, max_members)
        # registration on: each batch's correction depends on the steps before it, so it
        # is converted just before its step (the same tracks as batch by batch, live or
        # offline); otherwise the plots of each radar are converted at once
        learning = self.registration.mode is RegistrationMode.ON
        merged = [(site, batch) for site, batch, _ in steps]
        conversions = [None] * len(steps) if learning else self._convert_all(merged)
        part, t0 = GroupPart(), time.perf_counter()
        for k, ((site, batch, members), converted) in enumerate(zip(steps, conversions)):
            t_step = time.perf_counter()
            self._apply_step(site, batch, members, converted, part)
            if on_step is not None:
                on_step(len(batch.time), time.perf_counter() - t_step, batch.sector_width)
            more = k + 1 < len(steps)
            if more and part_s is not None and part.applied:
                if time.perf_counter() - t0 >= part_s:
                    yield self._close(part)
                    part, t0 = GroupPart(), time.perf_counter()
        yield self._close(part)

    def _apply_step(self, site, batch, members, converted, part: GroupPart) -> None:
        """One step (a batch, or a coalesced run of ``members``) into ``part``."""
        try:
            out = self._apply(site, batch, converted)
        except Exception as e:
            # a ValueError is a batch the conversion or the tracker's validation refused
            # before any state changed: its members are tried one by one; any other
            # error (a bug, the state may be half-updated) fails them all
            if len(members) == 1 or not isinstance(e, ValueError):
                part.failed += [(b, e) for b in members]
                return
            self.coalesced["retried"] += 1
            self._apply_each(site, members, part)
            return
        self.feed.record(out, len(members))
        part.events += self.track_events(out)
        part.applied += members

    def _close(self, part: GroupPart) -> GroupPart:
        """The part's delta message (``None`` if it applied no batch)."""
        if part.applied:
            last = part.applied[-1]
            part.message = self.feed.delta(last.radar_id, last.seq)
        return part

    def _steps(self, items, coalesce_max, mergeable, max_members=None) -> list:
        """(site, batch to apply, its member batches) per tracker step, in order."""
        if coalesce_max is None or len(items) < 2 or max_members == 1:
            return [(site, b, [b]) for site, b in items]
        batches = [b for _, b in items]
        ok = [True] * len(items) if mergeable is None else mergeable
        steps = []
        sources = [site for site, _ in items]
        for run in coalesce.plan(batches, ok, coalesce_max, sources, max_members):
            members = [batches[i] for i in run]
            if len(run) > 1:
                self.coalesced["steps"] += 1
                self.coalesced["batches"] += len(run)
            steps.append((items[run[-1]][0], coalesce.coalesced(members), members))
        return steps

    def _apply(self, site: RadarSite, batch: PlotBatch, converted) -> TrackerOutput:
        """Convert (unless ``converted`` is given) and track one batch."""
        if converted is None:
            converted = self._convert(site, batch)
        if isinstance(converted, Exception):
            raise converted
        return self._track(converted, site, batch)

    def _apply_each(self, site, members, part: GroupPart) -> None:
        """The members of a failed coalesced step, one by one, into ``part``."""
        for b in members:
            try:
                out = self._apply(site, b, None)
            except Exception as e:
                part.failed.append((b, e))
                continue
            self.feed.record(out)
            part.events += self.track_events(out)
            part.applied.append(b)

    def _convert_all(self, items: list[tuple[RadarSite, PlotBatch]]) -> list:
        """``convert_plots`` of every batch (or the exception it raised): the batches of
        one radar with the same columns are concatenated and converted in one call, then
        split back (row i of the result ↔ plot i, in batch order)."""
        result: list = [None] * len(items)
        groups: dict[tuple, list[int]] = {}
        for i, (site, b) in enumerate(items):
            groups.setdefault((b.radar_id, id(site), coalesce.columns(b)), []).append(i)
        for (_, _, cols), idx in groups.items():
            site = items[idx[0]][0]
            if len(idx) > 1:
                try:
                    members = [items[i][1] for i in idx]
                    merged = coalesce.concat(members, cols, members[0].sector_width)
                    conv = self._convert(site, merged)
                except ValueError:  # one of them is bad: convert one by one to tell which
                    pass
                else:
                    ends = np.cumsum([len(items[i][1]) for i in idx])
                    for i, lo, hi in zip(idx, np.r_[0, ends[:-1]], ends):
                        result[i] = _slice(conv, int(lo), int(hi))
                    continue
            for i in idx:
                try:
                    result[i] = self._convert(site, items[i][1])
                except ValueError as e:
                    result[i] = e
        return result

    def track_batch(self, out: TrackerOutput, batch: PlotBatch | None = None) -> FeedMessage:
        """The delta message of one tracker output (see :mod:`services.fusion.feed`)."""
        self.feed.record(out)
        return self.feed.delta(out.radar_id, None if batch is None else batch.seq)

    def full(self) -> FeedMessage | None:
        """The full picture now (it also becomes the picture later deltas apply to)."""
        return self.feed.full()

    def snapshot(self) -> FeedMessage | None:
        """The current picture, as a full message."""
        return self.feed.snapshot()

    def picture(self):
        """The published picture (a ``TrackTable``)."""
        return self.feed.picture

    @property
    def cycle(self) -> int:
        return self.feed.cycle

    # --- snapshots -----------------------------------------------------------------------
    def to_snapshot(self) -> dict:
        """The state of this pipeline by its owners' declarations: the tracker's (with its
        configuration), the feed's picture and cycle, the registration estimate, and the
        counters. The frame and the other settings are the factory's (the service checks
        that they are the same before it restores)."""
        return {
            "tracker": self.tracker.to_snapshot(),
            "feed": self.feed.to_snapshot(),
            "registration": self.registration.to_snapshot(),
            "rejected": dict(self.rejected),
            "oosm": dict(self.oosm),
            "coalesced": dict(self.coalesced),
        }

    def from_snapshot(self, snap) -> None:
        """Hold :meth:`to_snapshot`, on a pipeline just made with the same settings;
        :class:`~skyfuse.schemas.snapshot.SnapshotError` if a part does not fit (then
        discard the pipeline: its parts may be half restored)."""
        snap = mapping(snap, "pipeline")
        self.tracker.from_snapshot(snap.get("tracker"))
        self.registration.from_snapshot(snap.get("registration"))
        self.feed.from_snapshot(snap.get("feed"), self.tracker.output())
        self.rejected = dict(counts(snap, "rejected"))
        self.oosm = Counter(counts(snap, "oosm"))
        self.coalesced = Counter(counts(snap, "coalesced"))

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
                attribute=e.attribute or None,
                value=e.value or None,
                previous=e.previous or None,
            )
            for e in out.events
        ]


def _slice(conv: ConvertedPlots, lo: int, hi: int) -> ConvertedPlots:
    """Rows ``lo:hi`` of a conversion (reasons renumbered from 0, as for that batch)."""
    part = conv.take(np.arange(lo, hi))
    return dataclasses.replace(part, reasons=[_renumber(r, lo) for r in part.reasons])


def _renumber(reason: str, offset: int) -> str:
    if not reason.startswith("plot "):
        return reason
    head, _, rest = reason.partition(": ")
    return f"plot {int(head[5:]) - offset}: {rest}"
