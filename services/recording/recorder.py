"""The MCAP recorder: every skyfuse message received on Zenoh goes to an MCAP file, one
channel per key with the payload model's JSON Schema (:class:`services.recording.RecordingWriter`),
plus Foxglove channels (protobuf, from foxglove-sdk) that the Foxglove Map panel shows:
``foxglove.LocationFixes`` on ``/foxglove/tracks`` (confirmed tracks of the picture
rebuilt from the delta/full feed, ``schemas.TrackPicture``), ``/foxglove/plots`` (one
per radar revolution), ``/foxglove/truth`` and ``/foxglove/sites``, and
``foxglove.GeoJSON`` on ``/foxglove/tracks_geojson`` (each track named by its callsign, or
squawk, and flight level — ``T{id}`` without identity — with its heading, speed,
altitude, existence, radars and identity, and a heading line). Every Foxglove
message is stamped with data time (plot, track, truth times; sites with the time of
the latest data), the MCAP log time is the receive time. The track picture is drawn at
most once per ``foxglove_track_period`` (1 s) of data time per fusion id: drawing it (a
GeoJSON of every confirmed track) at each of the feed's messages (≈ 70/s in a 2,000
plots/s soak) took 85 % of the recorder's time, and a recorder that falls behind holds
its backlog in memory.

Durability: the writer's chunk in progress is closed and flushed every
``flush_interval`` seconds, so a recorder killed with SIGKILL loses at most the
messages of the last interval; the complete chunks stay readable
(:func:`services.recording.iter_recording` recovers them). A cleanly stopped recorder
finishes the file with its summary and indexes (passes ``pymcap-cli doctor``).

Rotation: with ``rotate_mb`` / ``rotate_s`` the output is ``NAME-0000.mcap``,
``NAME-0001.mcap`` …; each new file starts with the last known ``RadarSite`` of every
radar so it can be replayed on its own.

**No overwriting**: an existing file is never opened for writing (files are created with
``O_EXCL``). Without rotation, if ``NAME.mcap`` exists the recording goes to
``NAME-1.mcap`` (``-2`` … the first free one); with rotation, indices already on disk
are skipped, so a restarted recorder continues the numbering. The name used is logged
and listed in the summary (``files``).

**Bounded buffers**: the Foxglove plot channel holds one scan of plots per radar with a
known site (plots of a radar without one cannot be drawn: not held, counted); at
``max_scan_plots`` plots the scan is written early, and at most ``max_scan_radars``
radars are held (``limits`` in the summary counts these); at most ``max_topics`` distinct
keys (MCAP channels) are recorded, messages on further keys counted (``too many keys``).
The MCAP writer's chunk indexes are kept on disk until the file is finished
(:class:`~skyfuse.services.recording.mcap_io.SpilledChunkIndexes`).

The recorder never crashes on bad input: a payload that does not validate against the
model of its key, or a key outside the v1 key space, is counted by reason and skipped.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pymap3d
from foxglove import messages as fg
from pydantic import BaseModel, Field
from skyfuse import schemas
from skyfuse.schemas import (
    PlotBatch,
    RadarKind,
    RadarSite,
    TrackBatch,
    TrackPicture,
    TrackPictures,
    TrackStatus,
    Truth,
    keys,
)
from skyfuse.schemas.identity import mode_3a_text
from skyfuse.schemas.rejection import decode, rejection_detail
from skyfuse.services.recording.mcap_io import SCHEMA_PREFIX, RecordingWriter, json_schema_bytes
from skyfuse.services.runtime.ratelimit import RateLimitedLog
from skyfuse.services.runtime.seen_batches import SeenBatches
from skyfuse.services.runtime.transport import Received

log = logging.getLogger(__name__)

FOXGLOVE_TOPICS = {
    "tracks": "/foxglove/tracks",
    "plots": "/foxglove/plots",
    "truth": "/foxglove/truth",
    "sites": "/foxglove/sites",
    "track_labels": "/foxglove/tracks_geojson",
}
HEADING_LINE_S = 60.0
"""The heading line of a track on the map: where it is in this many seconds, s."""
_MAX_FEEDS = 64
"""Fusion ids whose track picture the Foxglove channels rebuild, at most."""

_COLORS = {
    "tracks": fg.Color(r=0.1, g=0.4, b=1.0, a=1.0),
    "plots": fg.Color(r=1.0, g=0.6, b=0.0, a=0.6),
    "truth": fg.Color(r=0.1, g=0.7, b=0.1, a=1.0),
    "sites": fg.Color(r=0.9, g=0.0, b=0.0, a=1.0),
}


class RecorderConfig(BaseModel):
    out: Path = Field(description="Output MCAP file (NAME-0000.mcap … when rotating)")
    key_expr: str = Field(keys.ALL, description="Key expression to record")
    rotate_mb: float | None = Field(None, gt=0, description="Start a new file after this many MB")
    rotate_s: float | None = Field(None, gt=0, description="Start a new file after this many s")
    flush_interval: float = Field(
        1.0, gt=0, le=60, description="Close and flush the current chunk every this many s"
    )
    chunk_kb: int = Field(1024, ge=16, le=65536, description="MCAP chunk size, KiB")
    foxglove: bool = Field(True, description="Also write Foxglove LocationFixes map channels")
    foxglove_track_period: float = Field(
        1.0,
        ge=0,
        le=3600,
        description="Data time between two Foxglove pictures of one fusion service's tracks, "
        "s, at least (every track message still updates the picture; the last one is drawn "
        "at the end; 0: draw at every message)",
    )
    name: str = Field("recorder", pattern=keys.ID_PATTERN, description="Service id")
    duration: float | None = Field(None, gt=0, description="Stop after this many seconds")
    status_interval: float = Field(2.0, gt=0, description="Status publication period, s")
    queue: int = Field(
        2000, ge=10, le=1_000_000, description="Messages received but not yet written, at most"
    )
    stats: Path | None = Field(None, description="Write a JSON summary here at exit")
    max_message_bytes: int = Field(
        8_000_000,
        ge=1_000,
        le=1_000_000_000,
        description="Largest payload decoded and recorded, bytes; larger ones are counted",
    )
    max_scan_plots: int = Field(
        50_000,
        ge=1,
        le=100_000_000,
        description="Plots of one radar held for its Foxglove scan message, at most; "
        "beyond it the scan is written early",
    )
    max_topics: int = Field(
        2_000,
        ge=10,
        le=1_000_000,
        description="Distinct keys recorded (MCAP channels), at most; messages on further "
        "keys (e.g. invented radar ids) are counted ('too many keys'), not recorded",
    )
    max_scan_radars: int = Field(
        1_000,
        ge=1,
        le=1_000_000,
        description="Radars with plots held for Foxglove scan messages, at most; plots of "
        "further radars go to MCAP but not to the Foxglove plots channel",
    )


def _stamp(ns: int) -> fg.Timestamp:
    return fg.Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


def plot_positions(
    batch: PlotBatch | list[PlotBatch], site: RadarSite
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Approximate WGS-84 (lat°, lon°, h m) of the plots of one or more batches of a radar,
    for display only.

    Polar plots use ``pymap3d.aer2geodetic`` from the site; a 2-D radar's elevation is
    taken as ``asin((altitude - site.alt) / range)`` (flat earth; 0 if unknown);
    cartesian plots are ENU offsets at the site; WGS-84 plots are where they say (their
    altitude, else the site's height)."""
    batches = [batch] if isinstance(batch, PlotBatch) else list(batch)
    geodetic = [b for b in batches if b.lat is not None]
    if geodetic:
        lat = np.concatenate([b.column("lat") for b in geodetic])
        lon = np.concatenate([b.column("lon") for b in geodetic])
        alt = [b.column("altitude") for b in geodetic]
        h = np.concatenate([np.full(len(b), np.nan) if a is None else a
                            for a, b in zip(alt, geodetic)])  # fmt: skip
        return lat, lon, np.where(np.isfinite(h), h, site.alt)
    planar = [b for b in batches if b.x is not None]
    if planar:
        e = np.concatenate([b.column("x") for b in planar])
        n = np.concatenate([b.column("y") for b in planar])
        lat, lon, h = pymap3d.enu2geodetic(e, n, np.zeros_like(e), site.lat, site.lon, site.alt)
        return np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(h)
    r = np.concatenate([b.column("range") for b in batches])
    az = np.concatenate([b.column("azimuth") for b in batches])
    el = np.concatenate([_elevation(b, site) for b in batches])
    lat, lon, h = pymap3d.aer2geodetic(
        np.degrees(az), np.degrees(el), r, site.lat, site.lon, site.alt, deg=True
    )
    return np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(h)


def _elevation(batch: PlotBatch, site: RadarSite) -> np.ndarray:
    r = batch.column("range")
    if batch.elevation is not None:
        return np.nan_to_num(batch.column("elevation"), nan=0.0)
    if batch.altitude is not None and r.size:
        alt = batch.column("altitude")
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.clip((alt - site.alt) / np.maximum(r, 1.0), -1.0, 1.0)
        return np.nan_to_num(np.arcsin(s), nan=0.0)
    return np.zeros_like(r)


def location_fixes(
    time_ns: int, frame: str, lat, lon, alt, color: fg.Color, heading=None
) -> fg.LocationFixes:
    ts = _stamp(time_ns)
    fixes = []
    for i in range(len(lat)):
        kw = {}
        if heading is not None:
            kw["heading"] = float(heading[i])
        a = float(alt[i]) if alt is not None and math.isfinite(alt[i]) else 0.0
        fixes.append(
            fg.LocationFix(
                timestamp=ts,
                frame_id=frame,
                latitude=float(lat[i]),
                longitude=float(lon[i]),
                altitude=a,
                color=color,
                **kw,
            )
        )
    return fg.LocationFixes(fixes=fixes)


def track_label(t) -> str:
    """The map label of a track: its callsign, else its Mode-3/A code (octal), with the
    measured flight level (``"ROT415 FL370"``, ``"4004 FL370"``, ``"7700!"`` for an
    emergency); ``T{id}`` for a track without identity."""
    name = t.callsign or mode_3a_text(t.mode_3a)
    if t.emergency is not None:
        name = f"{name or f'T{t.track_id}'}!"
    if t.flight_level is not None:
        name = f"{name or f'T{t.track_id}'} FL{t.flight_level:03.0f}"
    return name or f"T{t.track_id}"


def _identity_properties(t) -> dict:
    """The identity a track has, as GeoJSON properties (none for a track without)."""
    out: dict = {}
    if t.callsign is not None:
        out["callsign"] = t.callsign
    if t.mode_3a is not None:
        out["squawk"] = mode_3a_text(t.mode_3a)
    if t.mode_s is not None:
        out["mode_s"] = f"{t.mode_s:06X}"
    if t.flight_level is not None:
        out["flight_level"] = round(t.flight_level, 2)
    if t.emergency is not None:
        out["emergency"] = str(t.emergency)
    if t.spi:
        out["spi"] = True
    return out


def track_features(tracks) -> fg.GeoJson:
    """The tracks as a GeoJSON FeatureCollection for Foxglove's Map panel: per track a
    Point (properties: name (:func:`track_label`), id, heading in degrees clockwise from
    north, speed m/s, altitude m, existence, radars, and the callsign, squawk, Mode-S
    address, flight level, emergency and SPI it has) and a LineString from it to where it
    will be in ``HEADING_LINE_S`` s at its velocity (local east/north offsets, pymap3d)."""
    feats = []
    if tracks:
        lat = np.array([t.lat for t in tracks])
        lon = np.array([t.lon for t in tracks])
        ve = np.array([t.vel_east for t in tracks]) * HEADING_LINE_S
        vn = np.array([t.vel_north for t in tracks]) * HEADING_LINE_S
        lat2, lon2, _ = pymap3d.enu2geodetic(ve, vn, 0 * ve, lat, lon, 0 * ve)
        for t, la2, lo2 in zip(tracks, lat2.tolist(), lon2.tolist()):
            props = {
                "name": track_label(t),
                "track_id": t.track_id,
                "heading_deg": round(math.degrees(t.heading), 1),
                "speed_mps": round(t.speed, 1),
                "alt_m": None if t.alt is None else round(t.alt),
                "existence": round(t.existence, 3),
                "radars": ",".join(t.radars),
            }
            props.update(_identity_properties(t))
            point = {"type": "Point", "coordinates": [t.lon, t.lat]}
            line = {"type": "LineString", "coordinates": [[t.lon, t.lat], [lo2, la2]]}
            for geom in (point, line):
                feats.append({"type": "Feature", "geometry": geom, "properties": props})
    return fg.GeoJson(geojson=json.dumps({"type": "FeatureCollection", "features": feats}))


class Recorder:
    """Writes received samples to MCAP; the Zenoh side lives in ``cmd_record``."""

    def __init__(self, cfg: RecorderConfig, metadata: dict[str, str] | None = None) -> None:
        self.cfg = cfg
        self.metadata = dict(metadata or {})
        self.files: list[Path] = []
        self.counts: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self._pictures = TrackPictures(_MAX_FEEDS)
        self.messages = 0
        self.bytes = 0
        self.sites: dict[str, tuple[RadarSite, bytes]] = {}
        self._scan_plots: dict[str, list[PlotBatch]] = {}
        self._scan_count: dict[str, int] = {}
        self.seen = SeenBatches(max_radars=cfg.max_scan_radars)
        """Plot batches recorded, by ``(radar, epoch, seq)``: repeats and sequence jumps
        are refused, numbers never received counted (``services.runtime.seen_batches``)."""
        self.missed: dict[str, int] = {}
        """Samples Zenoh reported missed, by key (not recoverable from the sender's cache)."""
        self.skipped = 0
        """Fusion state snapshots received (``fusion/*/state``, for standbys): not recorded."""
        self.limits: Counter[str] = Counter()
        self._log = RateLimitedLog(log)
        self._writer: RecordingWriter | None = None
        self._file = None
        self._opened_at = 0.0
        self._last_flush = time.monotonic()
        self._fg_schemas = {name: fg.LocationFixes.get_schema() for name in FOXGLOVE_TOPICS}
        self._fg_schemas["track_labels"] = fg.GeoJson.get_schema()
        self._data_time: int | None = None
        """Latest data time seen (plots, tracks, truth), ns: the Foxglove time base."""
        self._drawn: dict[str, int] = {}
        """Per fusion id (at most ``_MAX_FEEDS``), the data time of its last Foxglove
        track picture, ns; ids with a newer picture not drawn yet in ``_undrawn``."""
        self._undrawn: set[str] = set()
        self._open()

    # --- files ---------------------------------------------------------------------
    def _candidates(self):
        """File names to try, in order (see *No overwriting* above)."""
        out = self.cfg.out
        suffix = out.suffix or ".mcap"
        if self.cfg.rotate_mb is None and self.cfg.rotate_s is None:
            yield out
            for k in itertools.count(1):
                yield out.with_name(f"{out.stem}-{k}{suffix}")
        start = int(self.files[-1].stem.rsplit("-", 1)[1]) + 1 if self.files else 0
        for k in itertools.count(start):
            yield out.with_name(f"{out.stem}-{k:04d}{suffix}")

    def _create(self):
        """``(path, file)`` of the first candidate that does not exist (``O_EXCL``)."""
        self.cfg.out.parent.mkdir(parents=True, exist_ok=True)
        for path in self._candidates():
            try:
                return path, open(path, "xb")
            except FileExistsError:
                continue
        raise AssertionError("unreachable: the candidates are endless")

    def _close_writer(self) -> None:
        self._writer.close()
        self._file.close()

    def _open(self) -> None:
        path, self._file = self._create()
        if not self.files and path != next(self._candidates()):
            log.warning("%s exists: not overwritten, recording to %s instead", self.cfg.out, path)
        meta = {**self.metadata, "file_index": str(len(self.files))}
        self._writer = RecordingWriter(
            self._file, metadata=meta, chunk_size=self.cfg.chunk_kb * 1024
        )
        self.files.append(path)
        self._opened_at = time.monotonic()
        log.info("recording to %s", path)
        now = time.time_ns()
        for site, payload in self.sites.values():
            self._write(keys.radar_site(site.radar_id), payload, now, now, RadarSite)
            self._foxglove_site(site, now)

    def _maybe_rotate(self) -> None:
        w = self._writer
        too_big = self.cfg.rotate_mb is not None and w.bytes >= self.cfg.rotate_mb * 1e6
        too_old = (
            self.cfg.rotate_s is not None
            and time.monotonic() - self._opened_at >= self.cfg.rotate_s
        )
        if too_big or too_old:
            self._close_writer()
            self._open()

    def maybe_flush(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        if now - self._last_flush >= self.cfg.flush_interval:
            self._writer.flush()
            self._last_flush = now
            self._maybe_rotate()

    def close(self) -> list[Path]:
        if self._writer is not None:
            for radar_id in list(self._scan_plots):
                try:
                    self._flush_plots(radar_id, time.time_ns())
                except Exception as e:  # display channel only
                    log.warning("foxglove plots of %s not written: %s", radar_id, e)
            for fusion_id in sorted(self._undrawn):  # the last picture of each feed
                header = self._pictures.get(fusion_id).header
                try:
                    self._draw_tracks(fusion_id, header.time, time.time_ns())
                except Exception as e:  # display channel only
                    log.warning("foxglove tracks of %s not written: %s", fusion_id, e)
            self._writer.add_metadata(
                "skyfuse.recorder",
                {
                    "messages": self.messages,
                    **{f"count:{k}": v for k, v in self.counts.items()},
                    **{f"rejected:{k}": v for k, v in self.rejected.items()},
                    **{f"lost:{k}": v for k, v in self.lost().items()},
                    **{f"missed:{k}": v for k, v in self.missed.items()},
                },
            )
            self._close_writer()
            self._writer = None
        return self.files

    # --- messages ------------------------------------------------------------------
    def _write(self, topic: str, payload: bytes, log_time: int, pub_time: int, model) -> None:
        cid = self._writer.channel_for(
            topic, schema_name=SCHEMA_PREFIX + model.__name__, schema_data=json_schema_bytes(model)
        )
        self._writer.write_raw(cid, payload, log_time, publish_time=pub_time)
        self.messages += 1
        self.bytes += len(payload)
        self.counts[topic] += 1

    def _write_fg(self, name: str, msg, log_time: int) -> None:
        schema = self._fg_schemas[name]
        cid = self._writer.channel_for(
            FOXGLOVE_TOPICS[name],
            schema_name=schema.name,
            schema_data=schema.data,
            schema_encoding=schema.encoding,
            message_encoding="protobuf",
        )
        self._writer.write_raw(cid, msg.encode(), log_time)

    def _foxglove_site(self, site: RadarSite, log_time: int, stamp: int | None = None) -> None:
        """The site on the map, stamped with the data time base (the scan's or the latest
        data time; the receive time only before any data)."""
        if self.cfg.foxglove:
            stamp = stamp if stamp is not None else self._data_time or log_time
            fixes = location_fixes(
                stamp, site.radar_id, [site.lat], [site.lon], [site.alt], _COLORS["sites"]
            )
            self._write_fg("sites", fixes, log_time)

    def handle(self, item: Received) -> bool:
        """Validate and write one sample; ``False`` (and a counted reason) if rejected."""
        try:
            kind = keys.parse(item.key).kind
            if kind == "state":  # a standby's input, not part of the recording
                self.skipped += 1
                return False
            model = schemas.MODELS[kind]
        except (ValueError, KeyError):
            self.rejected["key outside the skyfuse/@v1 key space"] += 1
            return False
        if len(item.payload) > self.cfg.max_message_bytes:
            self.rejected["message too large"] += 1
            return False
        if item.key not in self.counts and len(self.counts) >= self.cfg.max_topics:
            self.rejected["too many keys"] += 1  # bounded channels and per-key counts
            return False
        msg, exc = decode(model, item.payload)
        if msg is None:  # any decoding exception is a counted rejection, never a crash
            self.rejected[f"invalid {model.__name__}"] += 1
            self._log.warning(
                "rejected %s on %s: %s", model.__name__, item.key[:80], rejection_detail(exc)
            )
            return False
        if isinstance(msg, PlotBatch):
            refused = self.seen.check(msg)
            if refused is not None:  # a repeat, or a number the sensor cannot have reached
                self.rejected[refused] += 1
                return False
            self.seen.add(msg)
        pub_time = item.sent_ns if item.sent_ns is not None else item.recv_ns
        self._write(item.key, item.payload, item.recv_ns, pub_time, model)
        if self.cfg.foxglove:
            try:
                self._foxglove(msg, item.recv_ns)
            except Exception as e:  # a display channel must never stop the recording
                self.rejected["foxglove conversion failed"] += 1
                if self.rejected["foxglove conversion failed"] <= 3:
                    log.exception("foxglove conversion of %s failed: %s", item.key, e)
        elif isinstance(msg, RadarSite):
            self.sites[msg.radar_id] = (msg, item.payload)
        self.maybe_flush()
        return True

    def lost(self) -> dict[str, int]:
        """Per radar, batch numbers never received (gaps in ``(epoch, seq)``; radars with
        none left out: ``services.runtime.seen_batches``)."""
        out = {rid: self.seen.lost(rid) for rid in self.seen.radars}
        return {rid: n for rid, n in sorted(out.items()) if n}

    def note_missed(self, missed: dict[str, int]) -> None:
        """Samples Zenoh reported missed, by key (``Inbox.take_missed``)."""
        for key, n in missed.items():
            name = key if key in self.missed or len(self.missed) < _MAX_FEEDS * 16 else ""
            self.missed[name] = self.missed.get(name, 0) + n

    def _buffer_plots(self, msg: PlotBatch, log_time: int) -> None:
        """Hold ``msg`` for its radar's scan message, within the bounds
        ``max_scan_plots`` (plots per radar) and ``max_scan_radars``."""
        rid = msg.radar_id
        pending = self._scan_plots.get(rid)
        if pending and pending[0].scan != msg.scan:
            self._flush_plots(rid, log_time)
        n = len(msg.time)
        if not n:
            return
        if rid not in self.sites:  # could never be drawn (an invented id holds nothing)
            self.limits["plots without a site: not shown"] += 1
            return
        if rid in self._scan_plots and self._scan_count[rid] + n > self.cfg.max_scan_plots:
            self.limits["scan plots: written early"] += 1
            self._flush_plots(rid, log_time)
        if rid not in self._scan_plots and len(self._scan_plots) >= self.cfg.max_scan_radars:
            self.limits["scan radars: plots not shown"] += 1
            return
        self._scan_plots.setdefault(rid, []).append(msg)
        self._scan_count[rid] = self._scan_count.get(rid, 0) + n

    def _flush_plots(self, radar_id: str, log_time: int) -> None:
        batches = self._scan_plots.pop(radar_id, [])
        self._scan_count.pop(radar_id, None)
        entry = self.sites.get(radar_id)
        if not batches or entry is None:
            return
        site = entry[0]
        geometry = {RadarKind.CARTESIAN: "x", RadarKind.WGS84: "lat"}.get(site.kind, "range")
        batches = [b for b in batches if len(b)]
        if not batches:
            return
        if any(getattr(b, geometry) is None for b in batches):
            self.rejected["plots do not match their site's kind"] += 1
            return
        lat, lon, h = plot_positions(batches, site)
        fixes = location_fixes(batches[-1].time_end, radar_id, lat, lon, h, _COLORS["plots"])
        self._write_fg("plots", fixes, log_time)
        self._foxglove_site(site, log_time, stamp=batches[-1].time_end)

    def _foxglove(self, msg, log_time: int) -> None:
        if isinstance(msg, RadarSite):
            self.sites[msg.radar_id] = (msg, msg.to_json_bytes())
            self._foxglove_site(msg, log_time)
        elif isinstance(msg, PlotBatch):
            self._data_time = max(self._data_time or 0, msg.time_end)
            # one LocationFixes per radar revolution (a map shows scans, and it is 16x
            # cheaper than one per sector)
            self._buffer_plots(msg, log_time)
        elif isinstance(msg, TrackBatch):
            picture = self._picture(msg.fusion_id)
            if picture is None or not picture.apply(msg):
                return
            self._data_time = max(self._data_time or 0, msg.time)
            last = self._drawn.get(msg.fusion_id)
            period = self.cfg.foxglove_track_period * 1e9
            if last is None or not 0 <= msg.time - last < period:
                self._draw_tracks(msg.fusion_id, msg.time, log_time)
            else:
                self._undrawn.add(msg.fusion_id)
        elif isinstance(msg, Truth):
            self._write_fg(
                "truth",
                location_fixes(msg.time, "truth", msg.lat, msg.lon, msg.alt, _COLORS["truth"]),
                log_time,
            )

    def _draw_tracks(self, fusion_id: str, time_ns: int, log_time: int) -> None:
        """The confirmed tracks of ``fusion_id``'s picture on the map channels."""
        picture = self._pictures.get(fusion_id)
        conf = [t for t in picture.tracks.values() if t.status == TrackStatus.CONFIRMED]
        self._write_fg("track_labels", track_features(conf), log_time)
        fixes = location_fixes(
            time_ns,
            fusion_id,
            [t.lat for t in conf],
            [t.lon for t in conf],
            [t.alt if t.alt is not None else 0.0 for t in conf],
            _COLORS["tracks"],
            heading=[t.heading for t in conf],
        )
        self._write_fg("tracks", fixes, log_time)
        self._drawn[fusion_id] = time_ns
        self._undrawn.discard(fusion_id)

    def _picture(self, fusion_id: str) -> TrackPicture | None:
        """The track picture of one fusion id, rebuilt from its deltas and fulls (at most
        ``_MAX_FEEDS`` fusion ids; beyond, counted and not drawn)."""
        pic = self._pictures.get(fusion_id)
        if pic is None:
            self.rejected["foxglove: too many fusion ids"] += 1
        return pic

    def summary(self) -> dict:
        return {
            "files": [str(p) for p in self.files],
            "messages": self.messages,
            "bytes": self.bytes,
            "by_topic": dict(sorted(self.counts.items())),
            "rejected": dict(self.rejected),
            "limits": dict(self.limits),
            "skipped_fusion_state": self.skipped,
            "batches_lost": self.lost(),
            "samples_missed": dict(self.missed),
        }
