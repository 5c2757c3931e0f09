"""The incremental track feed of one fusion id, over arrays of tracks.

Contract (``schemas.tracks``: ``TrackBatch.kind``): a **delta** message carries only the
tracks its cycle(s) changed — a track is *changed* when it enters the published set
(new, or confirmed with ``publish = confirmed``), when a plot updated it (its
``last_update`` time moved), when its status changed, or when a plot confirmed its
identity (:mod:`~skyfuse.services.fusion.feed_identity`: its identity revision moved,
e.g. by a late plot) — and lists in ``removed`` the
ids that left the set (terminated, merged, or no longer published). A **full** message
carries every published track, predicted to the message time, and replaces the
picture. The service keeps the same picture its subscribers rebuild
(:class:`FeedBuilder.picture`), so the snapshot answered at any instant plus the deltas
after it give exactly the picture of a subscriber that has been listening all along.

Several plot batches applied in one pass (the bulk path) give one delta whose rows are,
per track, the row of the last cycle that changed it: the picture after the group is the
picture after the same batches one by one. Outgoing messages are serialised from the
arrays (``pydantic_core.to_json`` of plain lists; no ``Track`` model per row); their
validity is checked by the tests against ``schemas.TrackBatch``.

Units: ``state``/``covariance`` in the system frame (m, m/s, x east, y north, z up),
lat/lon in degrees (WGS-84), alt in m above the ellipsoid, velocities east/north/up in
m/s, heading in rad clockwise from north in [0, 2π).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np
import pydantic_core
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.tracker.identity import TrackIdentity
from skyfuse.fusion.tracker.tracker import TrackerOutput
from skyfuse.schemas import FeedKind, TrackBatch
from skyfuse.schemas.snapshot import SnapshotError, array_field, counts, entry, mapping
from skyfuse.services.fusion.feed_identity import track_rows

TWO_PI = 2.0 * math.pi

_ARRAYS = (
    "ids", "time", "last_update", "confirmed", "existence", "updates", "radar_mask",
    "states", "covariances",
)  # fmt: skip
_GEO = ("lat", "lon", "alt", "vel_east", "vel_north", "vel_up", "speed", "heading")


def _declared(d: int) -> dict[str, tuple[type, tuple[int, ...]]]:
    """dtype and row shape of each column of a :class:`TrackTable` with ``d`` states."""
    i8, f8 = np.int64, np.float64
    return {"ids": (i8, ()), "time": (i8, ()), "last_update": (i8, ()),
            "confirmed": (np.bool_, ()), "existence": (f8, ()), "updates": (i8, ()),
            "radar_mask": (i8, ()), "states": (f8, (d,)), "covariances": (f8, (d, d))}  # fmt: skip


@dataclass
class TrackTable:
    """Rows of published tracks as columns (row i = one track). ``states`` (n, d),
    ``covariances`` (n, d, d); the geodetic columns are filled by :meth:`with_geodetic`;
    ``ident``: the tracks' identity (None: a tracker without identity)."""

    ids: np.ndarray
    time: np.ndarray
    last_update: np.ndarray
    confirmed: np.ndarray
    existence: np.ndarray
    updates: np.ndarray
    radar_mask: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    geo: dict[str, np.ndarray] = field(default_factory=dict)
    ident: TrackIdentity | None = None

    @classmethod
    def empty(cls, d: int) -> TrackTable:
        z = np.zeros(0)
        return cls(
            *(z.astype(np.int64) for _ in range(3)), z.astype(bool), z, z.astype(np.int64),
            z.astype(np.int64), np.zeros((0, d)), np.zeros((0, d, d)),
            {k: z for k in _GEO},
        )  # fmt: skip

    @classmethod
    def from_output(cls, out: TrackerOutput, rows: np.ndarray) -> TrackTable:
        """The rows ``rows`` of a tracker output, predicted to its time (only those rows:
        ``TrackerOutput.predicted``)."""
        x, P, psi = out.predicted(rows)
        return cls(
            out.ids[rows], np.full(len(rows), out.time_ns, np.int64), out.last_update_ns[rows],
            out.confirmed[rows], np.clip(psi, 0.0, 1.0), out.updates[rows],
            out.radar_mask[rows], x, P,
            ident=None if out.identity is None else out.identity.take(rows),
        )  # fmt: skip

    def __len__(self) -> int:
        return len(self.ids)

    def take(self, idx: np.ndarray) -> TrackTable:
        t = TrackTable(*(getattr(self, k)[idx] for k in _ARRAYS))
        t.geo = {k: v[idx] for k, v in self.geo.items()}
        t.ident = None if self.ident is None else self.ident.take(idx)
        return t

    def identity_revision(self) -> np.ndarray:
        """(n,) each row's identity revision (0 without identity)."""
        return np.zeros(len(self), np.int64) if self.ident is None else self.ident.revision

    @staticmethod
    def concat(parts: list[TrackTable]) -> TrackTable:
        t = TrackTable(*(np.concatenate([getattr(p, k) for p in parts]) for k in _ARRAYS))
        if all(p.geo for p in parts):
            t.geo = {k: np.concatenate([p.geo[k] for p in parts]) for k in _GEO}
        if any(p.ident is not None for p in parts):  # the picture before the first step
            none = TrackIdentity.none
            t.ident = TrackIdentity.concat([none(len(p)) if p.ident is None else p.ident
                                            for p in parts])  # fmt: skip
        return t

    def to_snapshot(self) -> dict:
        """The columns by name (the geodetic ones under ``geo``, empty when not filled;
        the identity under ``identity``, None without)."""
        ident = None if self.ident is None else self.ident.to_snapshot()
        return {"columns": {k: getattr(self, k) for k in _ARRAYS}, "geo": dict(self.geo),
                "identity": ident}  # fmt: skip

    @classmethod
    def from_snapshot(cls, snap, d: int) -> TrackTable:
        """A table of :meth:`to_snapshot` with states of ``d`` entries; every column with
        its declared dtype and one row per track
        (:class:`~skyfuse.schemas.snapshot.SnapshotError` otherwise)."""
        snap = mapping(snap, "track table")
        cols = mapping(snap.get("columns"), "track table columns")
        n = len(array_field(cols, "ids", np.int64, (None,)))
        values = [array_field(cols, k, dt, (n, *shape)) for k, (dt, shape) in _declared(d).items()]
        geo = mapping(snap.get("geo"), "track table geo")
        if geo and set(geo) != set(_GEO):
            raise SnapshotError(f"geodetic columns {sorted(geo)}")
        table = cls(*values)
        table.geo = {k: array_field(geo, k, np.float64, (n,)) for k in _GEO if geo}
        ident = snap.get("identity")
        table.ident = None if ident is None else TrackIdentity.from_snapshot(ident, n)
        return table

    def with_geodetic(self, frame: SystemFrame, ndim: int) -> TrackTable:
        """Fill lat/lon/alt and the ENU velocity, speed and heading from the states
        (state layout x, vx, y, vy[, z, vz]; the frame's inverse projection and its
        velocity rotation, ``SystemFrame.to_geodetic`` / ``velocity_to_enu``)."""
        x, n = self.states, len(self)
        px, py, vx, vy = x[:, 0], x[:, 2], x[:, 1], x[:, 3]
        pz = x[:, 4] if ndim == 3 else np.zeros(n)
        vz = x[:, 5] if ndim == 3 else np.zeros(n)
        if n:
            lat, lon, alt = frame.to_geodetic(px, py, pz)
            ve, vn, vu = frame.velocity_to_enu(px, py, pz, vx, vy, vz, (lat, lon, alt))
        else:
            lat = lon = alt = ve = vn = vu = np.zeros(0)
        heading = np.mod(np.arctan2(ve, vn), TWO_PI)
        heading = np.where(heading >= TWO_PI, 0.0, heading)
        if ndim != 3:
            vu = np.zeros(n)
        geo = (lat, lon, alt, ve, vn, vu, np.hypot(ve, vn), heading)
        self.geo = {k: np.asarray(v, dtype=float) for k, v in zip(_GEO, geo)}
        return self

    def publishable(self) -> np.ndarray:
        """Rows that satisfy the wire constraints of ``schemas.Track`` (finite state and
        covariance, lat/lon/heading in range, non-negative id and time)."""
        g = self.geo
        finite = np.isfinite(self.states).all(axis=1)
        finite &= np.isfinite(self.covariances).all(axis=(1, 2))
        for k in _GEO:
            finite &= np.isfinite(g[k])
        return (
            finite
            & (np.abs(g["lat"]) <= 90.0)
            & (np.abs(g["lon"]) <= 180.0)
            & (g["heading"] >= 0.0)
            & (g["heading"] < TWO_PI)
            & (self.ids >= 0)
            & (self.time >= 0)
        )

    def rows(self, radar_names: list[str], ndim: int) -> list[dict]:
        """The ``schemas.Track`` JSON objects of the rows (plain lists for the codec)."""
        names = {}
        for m in np.unique(self.radar_mask).tolist():
            names[m] = [r for b, r in enumerate(radar_names) if m >> b & 1]
        g = self.geo
        cols = {
            "track_id": self.ids.tolist(),
            "time": self.time.tolist(),
            "status": np.where(self.confirmed, "confirmed", "tentative").tolist(),
            "existence": self.existence.tolist(),
            "state": self.states.tolist(),
            "covariance": self.covariances.tolist(),
            **{k: g[k].tolist() for k in _GEO if k != "alt" or ndim == 3},
            "radars": [names[m] for m in self.radar_mask.tolist()],
            "updates": self.updates.tolist(),
        }
        return track_rows(cols, self.ident)


@dataclass
class FeedMessage:
    """One outgoing TrackBatch (delta or full) as arrays; ``to_json_bytes`` serialises it,
    ``model`` gives the validated ``schemas.TrackBatch`` (for CAT062 and the tests)."""

    header: dict
    table: TrackTable
    removed: np.ndarray
    radar_names: list[str]
    ndim: int

    @property
    def kind(self) -> FeedKind:
        return FeedKind(self.header["kind"])

    @property
    def cycle(self) -> int:
        return self.header["cycle"]

    def __len__(self) -> int:
        return len(self.table)

    def to_json_bytes(self) -> bytes:
        obj = {
            **self.header,
            "tracks": self.table.rows(self.radar_names, self.ndim),
            "removed": self.removed.tolist(),
        }
        return pydantic_core.to_json({k: v for k, v in obj.items() if v is not None})

    def model(self) -> TrackBatch:
        return TrackBatch.from_json_bytes(self.to_json_bytes())


class FeedBuilder:
    """Change detection and the published picture of one fusion id (see the module
    docstring). Call :meth:`record` after every tracker step, :meth:`delta` to close a
    group of steps into one message, :meth:`full` for the full picture."""

    def __init__(
        self, frame: SystemFrame, ndim: int, labels: list[str], fusion_id: str, publish: str
    ) -> None:
        self.frame, self.ndim, self.publish = frame, ndim, publish
        self.labels, self.fusion_id = list(labels), fusion_id
        d = len(labels)
        self.picture = TrackTable.empty(d).with_geodetic(frame, ndim)
        self.cycle = 0
        self.rejected: dict[str, int] = {}
        self._known = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool),
                       np.zeros(0, np.int64))  # fmt: skip
        """Ids, last update, confirmation and identity revision of the tracks published."""
        self._parts: list[TrackTable] = []
        self._last: TrackerOutput | None = None
        self._pic_head: tuple[int, list[str]] | None = None
        """Time (ns) and radar names of the last output the picture includes."""
        self._lock = threading.Lock()
        self._source: tuple[str | None, int | None] = (None, None)
        """Radar and seq of the last batch the picture includes."""
        self._batches = 0

    def _rows(self, out: TrackerOutput) -> np.ndarray:
        if self.publish == "confirmed":
            return np.flatnonzero(out.confirmed)
        return np.arange(len(out))

    def record(self, out: TrackerOutput, batches: int = 1) -> None:
        """Note the rows one tracker step changed (against the picture so far); the step
        applied ``batches`` plot batches (several when coalesced)."""
        rows = self._rows(out)
        ids, lu, cf = out.ids[rows], out.last_update_ns[rows], out.confirmed[rows]
        st = np.zeros(len(rows), np.int64) if out.identity is None else (
            out.identity.revision[rows])  # fmt: skip
        kid, klu, kcf, kst = self._known
        idx, known = _lookup(kid, ids)
        changed = ~known
        i = idx[known]
        changed[known] = (klu[i] != lu[known]) | (kcf[i] != cf[known]) | (kst[i] != st[known])
        self._parts.append(TrackTable.from_output(out, rows[changed]))
        self._known = (ids, lu, cf, st)
        self._last = out
        self._batches += batches

    def delta(self, source_radar: str | None, source_seq: int | None) -> FeedMessage | None:
        """The delta of the steps recorded since the last message (``None`` if none)."""
        if self._last is None or not self._batches:
            return None
        table = TrackTable.concat(self._parts)
        # per track, the row of the last step that changed it
        _, last = np.unique(table.ids[::-1], return_index=True)
        table = table.take(np.sort(len(table) - 1 - last))
        final = self._known[0]
        table = table.take(np.flatnonzero(_member(final, table.ids)))
        table, bad = self._checked(table.with_geodetic(self.frame, self.ndim))
        if len(bad):  # not publishable now: out of the picture until it changes again
            keep = ~_member(bad, self._known[0])
            self._known = tuple(a[keep] for a in self._known)
            final = self._known[0]
        alive = _member(final, self.picture.ids)
        removed = self.picture.ids[~alive]
        keep = alive & ~_member(table.ids, self.picture.ids)
        picture = TrackTable.concat([self.picture.take(np.flatnonzero(keep)), table])
        with self._lock:  # the snapshot is read from another thread
            self.picture, self._pic_head = picture, _head(self._last)
            self._source = (source_radar, source_seq)
            self.cycle += 1
            msg = self._message(FeedKind.DELTA, table, removed, source_radar, source_seq)
        self._parts, self._batches = [], 0
        return msg

    def full(self) -> FeedMessage | None:
        """The full picture now: every published track of the last step, predicted to its
        time; it replaces the picture (``None`` before the first step)."""
        out = self._last
        if out is None:
            return None
        table = TrackTable.from_output(out, self._rows(out)).with_geodetic(self.frame, self.ndim)
        picture = self._checked(table)[0]
        self._known = (picture.ids, picture.last_update, picture.confirmed,
                       picture.identity_revision())  # fmt: skip
        with self._lock:
            self.picture, self._pic_head = picture, _head(out)
        return self.snapshot()

    def snapshot(self) -> FeedMessage | None:
        """The current picture as a full message (what a subscriber has rebuilt, after
        delta ``cycle``); callable from any thread."""
        with self._lock:
            if self._pic_head is None:
                return None
            return self._message(
                FeedKind.FULL, self.picture, np.zeros(0, np.int64), *self._source, self._pic_head
            )

    def _checked(self, table: TrackTable) -> tuple[TrackTable, np.ndarray]:
        """The publishable rows and the ids of the others (counted)."""
        ok = table.publishable()
        if ok.all():
            return table, np.zeros(0, np.int64)
        key = "track not publishable (NaN/inf or out of range)"
        self.rejected[key] = self.rejected.get(key, 0) + int((~ok).sum())
        return table.take(np.flatnonzero(ok)), table.ids[~ok]

    def _message(self, kind, table, removed, source_radar, source_seq, head=None) -> FeedMessage:
        time_ns, radar_names = _head(self._last) if head is None else head
        header = {
            "fusion_id": self.fusion_id,
            "kind": kind.value,
            "cycle": self.cycle,
            "time": time_ns,
            "frame": self.frame.spec().model_dump(mode="json"),
            "state_labels": self.labels,
            "source_radar": source_radar,
            "source_seq": source_seq,
            "batches": self._batches if kind is FeedKind.DELTA else 0,
        }
        return FeedMessage(header, table, removed.astype(np.int64), radar_names, self.ndim)

    # --- snapshots -----------------------------------------------------------------------
    def to_snapshot(self) -> dict:
        """The picture (its rows and its head), the cycle counter, the change detection's
        last view of the tracks, the rows recorded but not yet sent, the counters. Arrays
        are views: serialise before the next step."""
        kid, klu, kcf, kst = self._known
        return {
            "cycle": self.cycle,
            "rejected": dict(self.rejected),
            "picture": self.picture.to_snapshot(),
            "picture_head": None if self._pic_head is None else list(self._pic_head),
            "source": list(self._source),
            "known": {"ids": kid, "last_update": klu, "confirmed": kcf, "identity": kst},
            "pending": [t.to_snapshot() for t in self._parts],
            "batches": self._batches,
            "recorded": self._last is not None,
        }

    def from_snapshot(self, snap, last: TrackerOutput | None) -> None:
        """Hold :meth:`to_snapshot` (on a builder just made); ``last``: the tracker's output
        of the restored state (:meth:`Tracker.output`), the source of the next full
        picture. :class:`~skyfuse.schemas.snapshot.SnapshotError` if it does not fit."""
        snap = mapping(snap, "feed")
        d = len(self.labels)
        known = mapping(snap.get("known"), "feed known")
        kid = array_field(known, "ids", np.int64, (None,))
        n = len(kid)
        self._known = (kid, array_field(known, "last_update", np.int64, (n,)),
                       array_field(known, "confirmed", np.bool_, (n,)),
                       array_field(known, "identity", np.int64, (n,)))  # fmt: skip
        pending = entry(snap, "pending", list)
        self._parts = [TrackTable.from_snapshot(t, d) for t in pending]
        self.picture = TrackTable.from_snapshot(snap.get("picture"), d)
        head, source = snap.get("picture_head"), entry(snap, "source", list)
        self._pic_head = None if head is None else _checked_head(head)
        if len(source) != 2 or type(source[0]) not in (str, type(None)):
            raise SnapshotError("feed source: not [radar, seq]")
        self._source = (source[0], source[1] if type(source[1]) is int else None)
        self.cycle, self._batches = entry(snap, "cycle", int), entry(snap, "batches", int)
        self.rejected = dict(counts(snap, "rejected"))
        self._last = last if entry(snap, "recorded", bool) else None


def _head(out: TrackerOutput) -> tuple[int, list[str]]:
    """(time ns, radar names) of a tracker output: what a message's header needs."""
    return int(out.time_ns), list(out.radar_names)


def _checked_head(head) -> tuple[int, list[str]]:
    if type(head) is not list or len(head) != 2 or type(head[0]) is not int:
        raise SnapshotError("picture head: not [time, radar names]")
    if type(head[1]) is not list or not all(type(r) is str for r in head[1]):
        raise SnapshotError("picture head: radar names not strings")
    return head[0], list(head[1])


def _sorting(keys: np.ndarray) -> np.ndarray | None:
    """The order that sorts ``keys``, or None when they are already strictly increasing
    (the tracker's ids are: new tracks get larger ids and removals keep the order)."""
    if len(keys) < 2 or bool((keys[1:] > keys[:-1]).all()):
        return None
    return np.argsort(keys, kind="stable")


def _member(keys: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Whether each of ``ids`` is in ``keys`` (binary search; ``np.isin`` without
    sorting the concatenation of both every cycle)."""
    return _lookup(keys, ids)[1]


def _lookup(keys: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index into ``keys`` of each of ``ids`` and whether it is there (binary search)."""
    if not len(keys):
        return np.zeros(len(ids), np.int64), np.zeros(len(ids), bool)
    order = _sorting(keys)
    if order is None:
        pos = np.minimum(np.searchsorted(keys, ids), len(keys) - 1)
        return pos, keys[pos] == ids
    pos = np.minimum(np.searchsorted(keys[order], ids), len(keys) - 1)
    idx = order[pos]
    return idx, keys[idx] == ids
