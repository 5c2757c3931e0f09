"""Restart with the same picture: the fusion service's state on disk (docs/reliability.md).

Two files in the state directory of one fusion id (``--state-dir``, default
``$XDG_STATE_HOME/skyfuse/fusion-{id}``, i.e. ``~/.local/state/skyfuse/fusion-{id}``):

* ``state.npz`` — the whole tracker state, written every ``snapshot_interval`` s
  (default 2 s) and at a clean stop: the snapshot of each owner of the state, by the
  names and shapes it declares (:mod:`schemas.snapshot`) — the track pipeline's
  (``TrackPipeline.to_snapshot``: the tracker's track store and parts with the tracker
  configuration and a version, the feed's picture and cycle counter, the registration
  estimate), the system frame and the radar sites (their wire models' JSON), the reorder
  buffer's per-radar watermarks and recently seen batch ids (so batches already applied
  are refused as duplicates after a restart) — under a header with the snapshot
  :data:`FORMAT`, the fusion id, the time written, the epoch and the id ceiling. The
  container is :mod:`~skyfuse.services.fusion.state_codec` (a JSON manifest + NumPy
  arrays of plain values: reading it cannot execute code). At start the service resumes
  from it when it was written less than ``resume_max_age`` s ago (default 60 s), by the
  same fusion id, with the same tracker configuration and the same configured frame, and
  every part fits its declaration; otherwise it starts empty and says why (a snapshot of
  another format or version is refused with a message naming both). The same blob is
  what a standby on another host receives on ``fusion/{id}/state``
  (:mod:`~skyfuse.services.fusion.standby`).
* ``ids.json`` — a ceiling of the track ids given so far and the incarnation ``epoch``.
  Before any output is published, the service checks that its tracker's next id is below
  the persisted ceiling, else it first writes a new one (next id + a reserve: ``ID_RESERVE``,
  or the ids of two snapshot intervals while ids are given faster); at
  start a tracker — resumed or new (the state too old to resume) — numbers from the
  ceiling. Tracks created after the last snapshot are lost by a ``kill -9``, but their
  ids are never given again: **track ids are never reused** while this file is younger
  than ``id_horizon`` (default 30 days). ``epoch`` is +1 at every start (and
  every standby takeover) and is sent in every ``TrackBatch`` and ``Status``: a consumer
  sees a restart as a change of ``epoch``.

**Writes are atomic**: a temporary file in the same directory, ``fsync``, ``os.replace``
over the old file, ``fsync`` of the directory — after ``kill -9`` or a power loss the file
is the previous or the new snapshot, never a torn one. The service loop only pickles the
state (consistent: nothing changes it meanwhile); a writer thread writes the bytes.

**Trust**: reading a snapshot never executes code (no pickle); a malformed or hostile
blob is refused with a reason (``state_codec.REASONS``). The state directory is still
created owner-only (0700, files 0600) and a directory writable by others is refused:
whoever can write it can replace the picture.
"""

from __future__ import annotations

import hashlib
import json
import logging
import stat
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from skyfuse.schemas import FrameSpec, RadarSite
from skyfuse.schemas.snapshot import SnapshotError
from skyfuse.services.fusion import state_codec
from skyfuse.services.fusion.state_codec import StateRejected
from skyfuse.services.runtime.state_files import atomic_write, state_home

log = logging.getLogger(__name__)

FORMAT = 5
"""Version of what a snapshot holds (1: the pickle of earlier versions; 2-4: the private
attributes of the pipeline's objects; 5: the owners' declared snapshots). A snapshot of
another version is refused (``format version``, naming both) and the service starts
empty."""
STATE_FILE, IDS_FILE = "state.npz", "ids.json"
ID_RESERVE = 1000
"""Ids reserved by one write of ``ids.json`` at least (the jump at a restart is at most
the reserve in force: this, or more while ids are given fast, see ``ID_RESERVE_MAX``)."""
ID_RESERVE_MAX = 1_000_000
"""Bound on the reserve of one write. While the tracker gives ids fast (thousands of
tentative tracks per second in clutter or under overload), the reserve is the ids of
about two snapshot intervals at the rate seen since the last write, so the ceiling — and,
with a standby, the snapshot published with it — is written about once per two
intervals instead of every ``ID_RESERVE`` ids (each write is an fsync'd file and a
snapshot serialised on the service loop)."""


def default_state_dir(fusion_id: str) -> Path:
    """``$XDG_STATE_HOME/skyfuse/fusion-{id}`` (default ``~/.local/state/...``)."""
    return state_home() / f"fusion-{fusion_id}"


def tracker_fingerprint(pipeline) -> str:
    """SHA-256 of the pipeline's tracker configuration (JSON), to resume only a state
    made by the same tracker settings."""
    cfg = getattr(pipeline, "cfg", None)
    text = cfg.model_dump_json() if hasattr(cfg, "model_dump_json") else repr(cfg)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass
class Ids:
    """Content of ``ids.json``."""

    next_track_id: int = 1
    epoch: int = 0
    written_ns: int = 0


class StateStore:
    """The state directory of one fusion id (see the module docstring)."""

    def __init__(
        self, directory: Path, fusion_id: str, *, max_age: float, id_horizon: float
    ) -> None:
        self.dir = Path(directory)
        self.fusion_id = fusion_id
        self.max_age = max_age
        self.id_horizon = id_horizon
        self.dir.mkdir(parents=True, exist_ok=True, mode=0o700)
        self._check_private(self.dir)
        self.saves = 0
        self._ids_lock = threading.Lock()
        self.last_save_s = 0.0
        self.next_id_floor = 1
        """Lowest id a new tracker may give (from ``ids.json``, within the horizon)."""

    @staticmethod
    def _check_private(path: Path) -> None:
        mode = path.stat().st_mode
        if mode & (stat.S_IWGRP | stat.S_IWOTH):
            raise PermissionError(
                f"state {str(path)!r} is writable by group/others: refused (whoever "
                "writes it sets the picture; make it owner-only, chmod go-w)"
            )

    # --- ids -------------------------------------------------------------------------
    def read_ids(self) -> Ids | None:
        path = self.dir / IDS_FILE
        try:
            d = json.loads(path.read_text())
            return Ids(int(d["next_track_id"]), int(d["epoch"]), int(d["written_ns"]))
        except FileNotFoundError:
            return None
        except (ValueError, KeyError, TypeError) as e:
            log.warning("state: %s unreadable (%s): starting ids from 1", path, e)
            return None

    def write_ids(self, epoch: int, raise_to: int = 0) -> None:
        """Persist the id ceiling (raised to ``raise_to`` first) and ``epoch``. Under a
        lock (the snapshot writer thread and the service loop both write): the ceiling
        on disk never goes down."""
        with self._ids_lock:
            self.next_id_floor = max(self.next_id_floor, raise_to)
            ids = Ids(self.next_id_floor, epoch, time.time_ns())
            atomic_write(self.dir / IDS_FILE, json.dumps(ids.__dict__).encode())

    def begin_epoch(self, received: dict | None = None) -> Ids:
        """At start or takeover: the new incarnation (persisted epoch + 1) and the next
        id floor (the persisted next id if younger than ``id_horizon``). ``received``: a
        snapshot of the active instance (a standby on another host): its epoch and id
        ceiling count too, so neither goes back."""
        old = self.read_ids() or Ids()
        age = (time.time_ns() - old.written_ns) / 1e9
        floor = old.next_track_id if age <= self.id_horizon else 1
        epoch = old.epoch
        if received is not None:
            floor, epoch = max(floor, received["id_ceiling"]), max(epoch, received["epoch"])
        self.next_id_floor = max(1, floor)
        self.write_ids(epoch + 1)
        return Ids(self.next_id_floor, epoch + 1)

    # --- state -----------------------------------------------------------------------
    def serialise(self, state: dict, epoch: int) -> bytes:
        """``state`` (:func:`capture`) as one blob (:func:`state_codec.dumps`), with the id
        ceiling persisted when it was made."""
        return state_codec.dumps(
            {"format": FORMAT, "fusion_id": self.fusion_id, "written_ns": time.time_ns(),
             "epoch": epoch, "id_ceiling": self.next_id_floor, **state},
        )  # fmt: skip

    def write(self, blob: bytes, next_track_id: int, epoch: int) -> None:
        """Write a serialised state and the ids, both atomically (any thread)."""
        t0 = time.perf_counter()
        atomic_write(self.dir / STATE_FILE, blob)
        self.write_ids(epoch, raise_to=next_track_id)
        self.saves += 1
        self.last_save_s = time.perf_counter() - t0

    def save(self, state: dict, next_track_id: int, epoch: int) -> None:
        """Serialise and write ``state`` now."""
        self.write(self.serialise(state, epoch), next_track_id, epoch)

    def load(self) -> tuple[dict | None, str]:
        """The saved state if it may be resumed, else ``None``; and why (for the log)."""
        path = self.dir / STATE_FILE
        if not path.exists():
            return None, "no saved state"
        try:
            self._check_private(path)
            blob = path.read_bytes()
        except (PermissionError, OSError) as e:
            return None, str(e)
        try:
            saved = self.check(blob)
        except StateRejected as e:
            return None, f"saved state refused ({e})"
        return saved, f"saved state {age_s(saved):.2f} s old"

    def check(self, blob: bytes, max_bytes: int = 256_000_000) -> dict:
        """Decode a snapshot blob (file or network) and check that it may be resumed;
        :class:`StateRejected` (a reason of :data:`state_codec.REASONS` or ``other
        fusion id``, ``malformed header``, ``too old``) if not. Runs no code of the
        blob."""
        saved = state_codec.loads(blob, max_bytes=max_bytes)
        _check_header(saved, self.fusion_id)
        if age_s(saved) > self.max_age:
            raise StateRejected(
                "too old", f"{age_s(saved):.1f} s (resume_max_age {self.max_age:g} s)"
            )
        return saved


def age_s(saved: dict) -> float:
    """Age of a decoded snapshot, s (wall clock)."""
    return (time.time_ns() - saved["written_ns"]) / 1e9


_PARTS = {
    "frame": (dict, type(None)),
    "sites": dict,
    "reorder": dict,
    "pipeline": (dict, type(None)),
}


def _check_header(saved, fusion_id: str) -> None:
    """Refuse a decoded snapshot that is not one of this fusion id's."""
    if type(saved) is not dict or saved.get("format") != FORMAT:
        found = saved.get("format") if type(saved) is dict else None
        raise StateRejected(
            "format version", f"snapshot format {found!r}: this version reads format {FORMAT}"
        )
    if saved.get("fusion_id") != fusion_id:
        raise StateRejected("other fusion id", str(saved.get("fusion_id"))[:40])
    for name in ("written_ns", "epoch", "id_ceiling"):
        if type(saved.get(name)) is not int:
            raise StateRejected("malformed header", f"no integer {name}")
    for name, kind in _PARTS.items():
        if not isinstance(saved.get(name), kind):
            raise StateRejected("malformed header", f"no {name}")


def capture(core) -> dict:
    """The state of a :class:`~skyfuse.services.fusion.service.FusionCore` to save, by its
    owners' snapshots: the pipeline's (None before the first batch), the frame and the
    known sites (their wire models), the reorder buffer's watermarks and seen batch ids,
    and the fingerprint of the tracker configuration."""
    pipe = core.pipeline
    return {
        "frame": None if core.frame is None else core.frame.model_dump(mode="json"),
        "sites": {rid: r.site.model_dump(mode="json") for rid, r in core.radars.items() if r.site},
        "reorder": core.buffer.to_snapshot(),
        "pipeline": None if pipe is None else pipe.to_snapshot(),
        "fingerprint": None if pipe is None else tracker_fingerprint(pipe),
    }


def _parts(saved: dict) -> tuple[list[RadarSite], FrameSpec | None]:
    """The sites and frame of a decoded snapshot, validated (:class:`SnapshotError`)."""
    sites = []
    for rid, value in saved["sites"].items():
        try:
            site = RadarSite.model_validate(value)
        except ValueError:  # pydantic's ValidationError
            raise SnapshotError(f"site {rid[:40]!r}") from None
        if site.radar_id != rid:
            raise SnapshotError(f"site {rid[:40]!r} of radar {site.radar_id[:40]!r}")
        sites.append(site)
    frame = saved["frame"]
    try:
        return sites, None if frame is None else FrameSpec.model_validate(frame)
    except ValueError:
        raise SnapshotError("frame") from None


def restore(core, saved: dict) -> str | None:
    """Put a saved state (:func:`capture`) back into a new ``FusionCore``; ``None`` on
    success, else why the tracker state was not taken (the sites and watermarks are
    still restored when well-formed: batches already applied stay refused as
    duplicates). A state whose parts do not fit their declarations is refused
    (``state inconsistent: …``) and changes nothing of the tracking."""
    try:
        sites, frame = _parts(saved)
        core.buffer.from_snapshot(saved["reorder"])
    except SnapshotError as e:
        return f"state inconsistent: {e}"
    for site in sites:
        core.on_site(site, configured=True)
    state = saved["pipeline"]
    if state is None or frame is None:
        return "no tracker state saved yet"
    if core.cfg.frame_lat0 is not None and core.cfg.frame_spec(sites) != frame:
        return "the configured frame differs from the saved one"
    pipe = core._factory(frame)
    if tracker_fingerprint(pipe) != saved.get("fingerprint"):
        return "the tracker configuration differs from the saved one"
    try:
        pipe.from_snapshot(state)
        pipe.snapshot()  # the picture can be computed from it
    except SnapshotError as e:
        return f"state inconsistent: {e}"
    except Exception as e:  # values that fit their shapes but not each other
        return f"state inconsistent: picture not computable ({type(e).__name__})"
    core.pipeline, core.frame = pipe, frame
    return None


def next_track_id(pipeline) -> int:
    """The id the pipeline's tracker gives next (its ``_next_id`` counter)."""
    return int(pipeline.tracker._next_id)


def numbering_from(factory, store: StateStore):
    """Wrap a pipeline factory so that a new tracker numbers from ``store``'s floor."""

    def make(frame):
        pipe = factory(frame)
        if not hasattr(pipe.tracker, "_next_id"):
            raise AttributeError("the tracker has no _next_id counter: ids cannot be persisted")
        pipe.tracker._next_id = max(int(pipe.tracker._next_id), store.next_id_floor)
        return pipe

    return make


class Persistence:
    """The state of one running ``FusionCore``: resume at start (or at a standby's
    takeover), a snapshot every ``interval`` s, a last one at a clean stop."""

    def __init__(self, core, store: StateStore, interval: float) -> None:
        self.core, self.store, self.interval = core, store, interval
        self._next = 0.0
        self.resumed = False
        self._pending: tuple | None = None
        self._cond = threading.Condition()
        self._writer: threading.Thread | None = None
        self._last_raise: tuple[float, int] | None = None
        """(monotonic s, next id) at the last id-ceiling write or the start (:meth:`reserve`)."""
        self._closing = False
        self.publish = None
        """``publish(blob)``: also send each snapshot (the active instance's
        ``fusion/{id}/state`` publisher, for standbys on other hosts)."""

    @classmethod
    def from_config(cls, core) -> Persistence | None:
        """From the core's ``FusionConfig`` (``None`` with ``snapshot_interval`` off)."""
        cfg = core.cfg
        if cfg.snapshot_interval is None:
            return None
        store = StateStore(
            cfg.state_dir or default_state_dir(cfg.fusion_id), cfg.fusion_id,
            max_age=cfg.resume_max_age, id_horizon=cfg.id_horizon,
        )  # fmt: skip
        core._factory = numbering_from(core._factory, store)
        return cls(core, store, cfg.snapshot_interval)

    def start(self, received: dict | None = None) -> None:
        """Begin a new epoch and resume the saved state if it may be (logged either way).
        ``received``: the newest valid snapshot a standby got over Zenoh; it is resumed
        instead of the state directory's when it is newer."""
        core, store = self.core, self.store
        ids = store.begin_epoch(received)
        core.epoch = ids.epoch
        saved, why = store.load()
        if received is not None and (saved is None or received["written_ns"] > saved["written_ns"]):
            saved, why = (
                received,
                f"snapshot received from the active instance {age_s(received):.2f} s old",
            )
        if saved is not None:
            try:
                why_not = restore(core, saved)
            except Exception as e:  # a well-formed blob whose objects do not fit together
                core.pipeline = None
                why_not = f"state inconsistent: {type(e).__name__}"
            self.resumed = why_not is None
            why = f"{why}, {'resumed' if self.resumed else 'tracks not resumed: ' + why_not}"
        if core.pipeline is not None:  # resumed, or created from the configuration
            tr = core.pipeline.tracker
            tr._next_id = max(int(tr._next_id), store.next_id_floor)
        n = 0 if core.pipeline is None else len(core.pipeline.tracker.ids)
        log.info(
            "state %s: %s; epoch %d, %d tracks, next track id %d", store.dir, why, ids.epoch,
            n, store.next_id_floor if core.pipeline is None else next_track_id(core.pipeline),
        )  # fmt: skip
        self._next = time.monotonic() + self.interval
        self._last_raise = (time.monotonic(), store.next_id_floor)

    def tick(self, now: float) -> None:
        """If a snapshot is due: serialise the state here (consistent: the loop is not
        changing it; ~1.5 ms at 500 tracks) and hand the bytes to the writer thread
        (the two fsync'd writes, ~25 ms, off the service loop; the newest wins)."""
        if now < self._next:
            return
        self._next = time.monotonic() + self.interval
        job = self._serialised()
        if job is None:
            return
        blob, nid, epoch = job
        if self.publish is not None:  # here, not in the writer: before any later output
            try:
                self.publish(blob)
                self.core.counters["state_published"] += 1
            except Exception as e:  # a transport error must not stop the tracking
                self.core.counters["state_publish_errors"] += 1
                log.error("state: cannot publish the snapshot: %s", e)
        with self._cond:
            self._pending = (blob, nid, epoch)
            self._cond.notify()
        if self._writer is None:
            self._writer = threading.Thread(target=self._write_loop, name="state", daemon=True)
            self._writer.start()

    def _serialised(self) -> tuple[bytes, int, int] | None:
        """The snapshot blob, next id and epoch; ``None`` (counted, logged) if a part of
        the state holds a value outside the snapshot vocabulary (a bug of its owner)."""
        core = self.core
        nid = self.store.next_id_floor if core.pipeline is None else next_track_id(core.pipeline)
        try:
            return self.store.serialise(capture(core), core.epoch or 0), nid, core.epoch or 0
        except state_codec.StateUnsupported as e:
            core.counters["state_save_errors"] += 1
            if core.counters["state_save_errors"] == 1:
                log.error("state: cannot serialise the tracker state: %s", e)
            return None

    def _write_loop(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._closing:
                    self._cond.wait()
                job, self._pending = self._pending, None
            if job is None:
                return
            self._write(*job)

    def _write(self, blob: bytes, nid: int, epoch: int) -> None:
        try:
            self.store.write(blob, nid, epoch)
        except OSError as e:  # a full disk must not stop the tracking
            self.core.counters["state_save_errors"] += 1
            log.error("state: cannot save to %s: %s", self.store.dir, e)
            return
        self.core.counters["state_saves"] += 1

    def guard_ids(self) -> None:
        """Before publishing: if the tracker's next id reached the persisted ceiling,
        persist a new one (next id + ``ID_RESERVE``), so no published id is given again
        after a crash."""
        core, store = self.core, self.store
        if core.pipeline is None or next_track_id(core.pipeline) < store.next_id_floor:
            return
        nid = next_track_id(core.pipeline)
        try:
            store.write_ids(core.epoch or 0, raise_to=nid + self.reserve(nid, time.monotonic()))
        except OSError as e:
            core.counters["state_save_errors"] += 1
            log.error("state: cannot save the track id ceiling to %s: %s", store.dir, e)
        if self.publish is not None:  # standbys on other hosts learn the new ceiling now
            self._next = 0.0
            self.tick(time.monotonic())

    def reserve(self, next_id: int, now: float) -> int:
        """Ids to reserve at a ceiling write when the next id is ``next_id`` at monotonic
        time ``now``: ``ID_RESERVE``, or the ids of two snapshot intervals at the rate
        since the previous write (or the start), at most ``ID_RESERVE_MAX``."""
        t0, n0 = self._last_raise if self._last_raise is not None else (now, next_id)
        self._last_raise = (now, next_id)
        if now <= t0 or next_id <= n0:
            return ID_RESERVE
        rate = (next_id - n0) / (now - t0)
        return int(min(ID_RESERVE_MAX, max(ID_RESERVE, rate * 2.0 * self.interval)))

    def save(self) -> None:
        """Save now, in this thread (at a clean stop: after the writer thread's last
        write, so the newest state is the one left on disk)."""
        if self._writer is not None:
            with self._cond:
                self._closing = True
                self._cond.notify()
            self._writer.join(timeout=10.0)
            self._writer, self._closing = None, False
        job = self._serialised()
        if job is not None:
            self._write(*job)
