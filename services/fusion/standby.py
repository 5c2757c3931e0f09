"""One active publisher per fusion id: election through Zenoh liveliness, hot standby
(docs/reliability.md §5).

Every instance of fusion id ``F`` declares a liveliness token
``skyfuse/@v1/fusion/F/active/{start_ns}-{zid}`` (its start instant in ns, zero-padded,
and its Zenoh session id). The **active** instance is the one whose token is the
smallest — the one started first, the session id breaking a tie — as seen by every
instance, since all follow the same tokens (:class:`Election`):

* **Without** ``--standby`` an instance that is not the smallest after ``settle`` s (the
  time for tokens to propagate) **refuses to publish**: it logs which instance holds the
  id and exits with status 1 (:class:`FusionIdTaken`). An active instance that later
  sees a smaller token (two instances started at the same instant on hosts whose tokens
  had not met yet) also stops and exits 1: never two publishers of one feed.
* **With** ``--standby`` such an instance waits: it subscribes to the plots and sites
  like the active one and keeps what it receives in a bounded buffer (:class:`Follower`:
  at most ``inbox`` messages, none older than ``keep_s``), publishes nothing and answers
  no query. When the active instance's token goes away (process killed: Zenoh sees the
  link close at once; host lost: after the Zenoh lease, 10 s by default), the smallest
  remaining token — the standby — becomes active: it resumes the newest state the active
  one saved, applies the buffered batches newer than that state's per-radar watermarks,
  and starts publishing with the same track ids and a new ``epoch``.

The state comes two ways, the newer one wins (``written_ns``):

* **over Zenoh** (:class:`StateFollower`): the active instance publishes every snapshot
  blob (``services.fusion.state_codec``, the same bytes as its state file) on
  ``fusion/{id}/state``; a standby keeps the newest valid one (at most
  ``state_max_bytes``; decoded and checked when it arrives — a malformed, foreign or
  hostile blob is a counted rejection with a reason, ``standby_state_rejected``). Its
  epoch and id ceiling are taken too: track ids given by the active instance are never
  given again, on any host (the active one publishes a snapshot at once whenever it
  raises its id ceiling, before it publishes the ids);
* from the standby's own **state directory** (a shared file system, or the same host).

A standby publishes its own :class:`~skyfuse.schemas.Status` (``role`` standby, the
instance it ``following``, ``state_age_s`` of the snapshot it holds) on
``fusion/{id}/standby/{instance}/status`` (:func:`standby_status`), never on the active
one's key.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque

from skyfuse.schemas import PlotBatch, Status, keys
from skyfuse.schemas.rejection import decode
from skyfuse.services.fusion.state_codec import StateRejected
from skyfuse.services.fusion.state_store import age_s
from skyfuse.services.runtime.transport import Inbox, TransportError

log = logging.getLogger(__name__)


class FusionIdTaken(TransportError):
    """Another instance is the active publisher of this fusion id (exit status 1)."""


def active_prefix(fusion_id: str) -> str:
    return f"{keys.PREFIX}/fusion/{keys.check_id(fusion_id, 'fusion id')}/active"


class Election:
    """The liveliness tokens of the instances of one fusion id (module docstring)."""

    def __init__(self, session, fusion_id: str, *, settle: float = 0.5) -> None:
        self.prefix = active_prefix(fusion_id)
        self.name = f"{time.time_ns():020d}-{session.info.zid()}"
        self.key = f"{self.prefix}/{self.name}"
        self.settle = settle
        self._alive: set[str] = set()
        self._lock = threading.Lock()
        self._changed = threading.Event()
        self._sub = session.liveliness().declare_subscriber(
            f"{self.prefix}/*", self._on_token, history=True
        )
        self._token = session.liveliness().declare_token(self.key)
        self._since = time.monotonic()

    def _on_token(self, sample) -> None:
        import zenoh

        name = str(sample.key_expr).rsplit("/", 1)[-1]
        with self._lock:
            if sample.kind == zenoh.SampleKind.PUT:
                self._alive.add(name)
            else:
                self._alive.discard(name)
        self._changed.set()

    def leader(self) -> str:
        """The smallest live token (this one included)."""
        with self._lock:
            return min(self._alive | {self.name})

    def settled(self) -> bool:
        return time.monotonic() - self._since >= self.settle

    def is_active(self) -> bool:
        """This instance is the smallest token, after the settle time."""
        return self.settled() and self.leader() == self.name

    def wait_change(self, timeout: float) -> None:
        self._changed.wait(timeout)
        self._changed.clear()

    def close(self) -> None:
        for h in (self._token, self._sub):
            try:
                h.undeclare()
            except Exception as e:  # closing must never mask the real exit path
                log.debug("undeclare: %s", e)


class Follower:
    """What a standby instance receives, kept for its takeover: the inbox's items of the
    last ``keep_s`` seconds, at most ``capacity``."""

    def __init__(self, capacity: int, keep_s: float) -> None:
        self.items: deque = deque(maxlen=capacity)
        self.keep_ns = int(keep_s * 1e9)

    def add(self, items) -> None:
        self.items.extend(items)
        horizon = time.time_ns() - self.keep_ns
        while self.items and self.items[0].recv_ns < horizon:
            self.items.popleft()

    def newer_than_state(self, core) -> list:
        """The buffered items to apply after the saved state was resumed: sites, alive
        tokens, and the batches whose ``time_end`` is after their radar's restored
        watermark (the others are already in the state)."""
        out = []
        for item in self.items:
            if item.tag == "plots":
                batch, _ = decode(PlotBatch, item.payload)
                mark = None if batch is None else core.buffer.radar_time.get(batch.radar_id)
                if mark is not None and batch.time_end <= mark:
                    core.counters["standby_batches_in_state"] += 1
                    continue
            out.append(item)
        return out


class StateFollower:
    """The newest valid snapshot the active instance published on ``fusion/{id}/state``.

    The Zenoh callback only keeps the newest raw blob (at most ``max_bytes``; larger
    ones are counted and dropped unread); :meth:`poll` (the standby's loop) decodes it
    with ``store.check`` and keeps it if it is valid and newer than the one held."""

    def __init__(self, session, fusion_id: str, store, max_bytes: int) -> None:
        self.store, self.max_bytes = store, max_bytes
        self.state: dict | None = None
        self.received = 0
        self.rejected: Counter[str] = Counter()
        self._raw: bytes | None = None
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(keys.fusion_state(fusion_id), self._on_sample)

    def _on_sample(self, sample) -> None:
        size = len(sample.payload)
        with self._lock:
            self.received += 1
            if size > self.max_bytes:
                self.rejected["too large"] += 1
                return
            self._raw = sample.payload.to_bytes()

    def poll(self) -> None:
        """Decode the blob received last, if any (counted rejection if invalid)."""
        with self._lock:
            blob, self._raw = self._raw, None
        if blob is None:
            return
        try:
            saved = self.store.check(blob, self.max_bytes)
        except StateRejected as e:
            self.rejected[e.reason] += 1
            log.warning("standby: snapshot refused (%s)", e)
            return
        if self.state is None or saved["written_ns"] > self.state["written_ns"]:
            self.state = saved
        else:
            self.rejected["older than the one held"] += 1

    def age_s(self) -> float | None:
        return None if self.state is None else max(0.0, age_s(self.state))

    def close(self) -> None:
        try:
            self._sub.undeclare()
        except Exception as e:  # closing must never mask the real exit path
            log.debug("undeclare: %s", e)


def standby_status(core, election: Election, follower: Follower, states) -> Status:
    """The Status a standby publishes on its own key (module docstring)."""
    counters = {"standby_items_buffered": len(follower.items)}
    rejected = {}
    if states is not None:
        counters["standby_states_received"] = states.received
        rejected = {f"state: {k}": n for k, n in states.rejected.items()}
    leader = election.leader()
    return Status(
        service="fusion",
        service_id=core.cfg.fusion_id,
        time=time.time_ns(),
        uptime_s=time.monotonic() - core.started,
        counters=counters,
        rejected=rejected,
        role="standby",
        following=None if leader == election.name else leader,
        state_age_s=None if states is None else states.age_s(),
        message="standby" + ("" if leader == election.name else f": following {leader}"),
    )


def become_active(
    election: Election, inbox: Inbox, stop, *, standby: bool, follower: Follower, tick=None
):
    """Block until this instance is the active one (``True``), or ``stop`` (``False``).
    Without ``standby``, raise :class:`FusionIdTaken` if another instance is active.
    A standby keeps what ``inbox`` receives meanwhile in ``follower`` and calls ``tick()``
    every loop (snapshots, its Status)."""
    announced = False
    while not stop.is_set():
        if election.settled():
            leader = election.leader()
            if leader == election.name:
                return True
            if not standby:
                raise FusionIdTaken(
                    f"fusion id {election.prefix.split('/')[-2]!r} is already active "
                    f"(instance {leader}): refusing to publish; stop it, choose another "
                    "--fusion-id, or start both with --standby"
                )
            if not announced:
                log.info("standby: instance %s is active; following it", leader)
                announced = True
        follower.add(inbox.drain(10_000))
        if tick is not None:
            tick()
        election.wait_change(0.05)
    return False
