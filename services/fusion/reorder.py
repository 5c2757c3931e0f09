"""The reorder buffer of the fusion service: batches from several radars arrive with
network jitter; each is held ``wait`` seconds of wall time after its arrival and released
in ``(time_end, arrival order)`` order. See ``services.fusion.service`` for how the
service uses it.

**Time that cannot be hijacked** (docs/reliability.md). No single message may stop or drag the
service's time:

* **Receiver clock check.** A batch whose ``time_end`` (or a plot time) is more than
  ``future_tolerance`` seconds ahead of the receiver's wall clock is refused
  (``time in the future``) before it is queued, so it never advances the service time.
* **One watermark per radar.** ``radar_time[id]`` is the latest ``time_end`` released for
  that radar; only a batch earlier than *its own radar's* watermark is *out of sequence*.
  A radar cannot make another radar's batches out of sequence.
* **Late but bounded.** The service time ``last_time`` is the latest ``time_end``
  released over all radars. A batch behind it by at most ``max_lateness`` seconds (a
  lagging radar, a slow link) is released marked ``late`` — at once, without the hold,
  since holding cannot put it back in order and would hold back every other radar's
  batches queued behind it (a lagging radar never delays the others); the tracker applies
  its plots to the tracks that are ahead of them by the out-of-sequence update
  (retrodiction of each track to the plot time and Bar-Shalom's A1 update of its current
  state, :mod:`fusion.tracker.oosm`), so a late plot is weighed against where the track
  was at the plot time, not its newer state. A batch further behind is refused
  (``too late``): the bound keeps the retrodiction short and the buffer's memory bounded.
* **Clock offset.** Every received batch gives a sample ``time_end − receive time``
  (radar clock ahead = positive, including the network delay); the per-radar estimate
  :meth:`clock_offset` is the median of the last ``offset_samples`` samples, in seconds.

* **One batch cannot carry the service time away.** A batch that would move the service
  time ahead by more than ``max_lateness`` is released only once a batch received after
  it (any radar's) is that far on too; else it waits, and is settled at ``max_hold``
  (below). The clock check cannot see such a batch when the data is older than the
  receiver's clock (a replay), nor can a radar's own numbering when the radar is new.
* **Every batch leaves within** ``max_hold``. Batches are released in time order, so a
  batch whose time is ahead of the others waits for them; when batches earlier than it
  keep arriving (a radar far ahead of the others, or one message dated just inside the
  clock tolerance while the radars' data lags the wall clock) it would wait forever and
  hold every later batch with it. A batch still queued ``max_hold`` seconds after its
  arrival is settled: if the batches received since it arrived are all more than
  ``max_lateness`` behind it, it is ahead of every source and refused (``ahead of the
  data``; it never moves the service time); otherwise it is released with the batches
  in front of it (a radar lagging behind the others never holds them: its batches then
  come late or too late, as above).

A batch seen twice (same radar, epoch and seq; without an epoch: same seq, time_end and
scan among the radar's last 256) is refused as a *duplicate*, a number far beyond what the
radar could have published since its last one as a *sequence jump*; numbers that never
arrived are counted per radar (``lost``): :mod:`services.runtime.seen_batches`.
Memory is bounded per radar (``seen``: a window of numbers, offsets: ``offset_samples``);
the number of radars is bounded by the service (``max_radars``).
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from skyfuse.schemas import PlotBatch
from skyfuse.schemas.snapshot import SnapshotError, mapping
from skyfuse.services.runtime.seen_batches import SeenBatches


@dataclass(order=True)
class _Pending:
    time_end: int
    order: int
    arrival: float = field(compare=False)
    batch: PlotBatch = field(compare=False)
    sent_ns: int | None = field(compare=False)
    late: bool = field(default=False, compare=False)
    """Released behind the service time (see the module docstring)."""
    done: bool = field(default=False, compare=False)
    """Left the buffer (released or refused)."""


class ReorderBuffer:
    """Holds batches ``wait`` seconds (arrival clock) and releases them in
    ``(time_end, arrival order)`` order, each within ``max_hold`` s; refuses duplicates,
    sequence jumps, batches from the future (``future_tolerance`` s ahead of the
    receiver's clock, ``None``: no check), batches behind their radar's watermark and
    batches more than ``max_lateness`` s behind the service time. ``on_refused(p,
    reason)`` is told of a queued batch refused later (``ahead of the data``)."""

    def __init__(
        self,
        wait: float,
        *,
        future_tolerance: float | None = 1.0,
        max_lateness: float = 2.0,
        offset_samples: int = 32,
        max_hold: float = 3.0,
        on_refused=None,
        moves_time=None,
    ) -> None:
        self.wait = wait
        self.future_tolerance = future_tolerance
        self.max_lateness = max_lateness
        self.max_hold = max(max_hold, wait)
        self.on_refused = on_refused
        self.moves_time = moves_time
        """``moves_time(radar_id)``: whether that radar's batches count for the service
        time and confirm other batches' times (the service: radars with a site, whose
        batches are applied; ``None``: every radar)."""
        self._heap: list[_Pending] = []
        self._late: deque[_Pending] = deque()
        self._arrivals: deque[_Pending] = deque()
        """Queued batches in arrival order (released ones skipped lazily)."""
        self._pushed: deque[tuple[float, int, int]] = deque()
        """(arrival, order, time_end) of the batches queued in the last 2 ``max_hold``."""
        self._order = itertools.count()
        self.last_time: int | None = None
        """Service time: the latest ``time_end`` released, ns."""
        self.radar_time: dict[str, int] = {}
        """Per-radar watermark: the latest ``time_end`` released for each radar, ns."""
        self.seen = SeenBatches()
        """Batches accepted, by ``(radar, epoch, seq)`` (``services.runtime.seen_batches``)."""
        self._offsets: dict[str, deque] = {}
        self._offset_samples = offset_samples
        self.late_released = 0

    def __len__(self) -> int:
        return len(self._heap) + len(self._late)

    def push(
        self,
        batch: PlotBatch,
        arrival: float,
        sent_ns: int | None = None,
        recv_ns: int | None = None,
    ) -> str | None:
        """Queue ``batch`` received at wall-clock ``recv_ns`` (default: now); return
        ``None`` or the reason it was refused."""
        rid = batch.radar_id
        recv_ns = time.time_ns() if recv_ns is None else recv_ns
        newest = max(batch.time_end, batch.time[-1]) if batch.time else batch.time_end
        offsets = self._offsets.setdefault(rid, deque(maxlen=self._offset_samples))
        offsets.append(batch.time_end - recv_ns)
        tol = self.future_tolerance
        horizon = None if tol is None else recv_ns + int(tol * 1e9)
        reason = self.seen.check(batch, horizon)
        if reason is None:
            reason = self._time_problem(batch, newest, horizon)
            if reason is not None:
                self.seen.received(batch)  # refused, but its number arrived
        if reason is not None:
            return reason
        self.seen.add(batch)
        p = _Pending(batch.time_end, next(self._order), arrival, batch, sent_ns)
        if self.last_time is not None and batch.time_end < self.last_time:
            p.late = True  # holding it cannot put it in order: release it at once
            self._late.append(p)
        else:
            heapq.heappush(self._heap, p)
            self._arrivals.append(p)
        if self.moves_time is None or self.moves_time(rid):
            self._pushed.append((arrival, p.order, p.time_end))
        while self._pushed and self._pushed[0][0] < arrival - 2 * self.max_hold:
            self._pushed.popleft()
        return None

    def _time_problem(self, batch: PlotBatch, newest: int, horizon: int | None) -> str | None:
        if horizon is not None and newest > horizon:
            return "time in the future"
        watermark = self.radar_time.get(batch.radar_id)
        if watermark is not None and batch.time_end < watermark:
            return "out of sequence"
        if self.last_time is not None and self.last_time - batch.time_end > self.max_lateness * 1e9:
            return "too late"
        return None

    def clock_offset(self, radar_id: str) -> float | None:
        """Median of the recent ``time_end − receive time`` samples of a radar, s."""
        samples = self._offsets.get(radar_id)
        if not samples:
            return None
        return float(np.median(np.fromiter(samples, dtype=np.float64))) / 1e9

    def pop_ready(
        self, now: float, limit: int | None = None, wall_ns: int | None = None
    ) -> list[_Pending]:
        """Batches whose hold has expired, in order (a held head holds back the rest),
        at most ``limit``. With the clock check on, a batch is also held until the
        receiver's wall clock ``wall_ns`` (default: now) reaches its ``time_end``: the
        service time never runs ahead of this host's clock, so a radar whose clock is
        ahead (within the tolerance) waits for the others instead of making them late.
        A batch queued for ``max_hold`` is settled first (module docstring)."""
        out = []
        while self._late and (limit is None or len(out) < limit):
            out.append(self._release(self._late.popleft()))
        if self.future_tolerance is not None:
            wall_ns = time.time_ns() if wall_ns is None else wall_ns
        overdue = self._overdue(now)
        while self._heap and (limit is None or len(out) < limit):
            head = self._heap[0]
            due = now - head.arrival >= self.wait and not self._unconfirmed_leap(head)
            if overdue is None and not (due and (wall_ns is None or head.time_end <= wall_ns)):
                break
            out.append(self._release(heapq.heappop(self._heap)))
            if head is overdue:
                overdue = self._overdue(now)
        return out

    def _unconfirmed_leap(self, p: _Pending) -> bool:
        """Whether releasing ``p`` would move the service time ahead by more than
        ``max_lateness`` while nothing received after it is that far on: one batch (a
        radar first heard far ahead, a message dated later than the data) does not carry
        the service time away alone; it waits for data that confirms its time, else it is
        refused at ``max_hold`` (:meth:`_overdue`)."""
        lead = self.max_lateness * 1e9
        if self.last_time is None or p.time_end - self.last_time <= lead:
            return False
        if self.moves_time is not None and not self.moves_time(p.batch.radar_id):
            return False
        return not any(order > p.order and t >= p.time_end - lead for _, order, t in self._pushed)

    def _overdue(self, now: float) -> _Pending | None:
        """The oldest queued batch if it has been held ``max_hold``, once settled: refused
        when it is ahead of everything received since, else left at the head's side (the
        caller releases up to it)."""
        while True:
            while self._arrivals and self._arrivals[0].done:
                self._arrivals.popleft()
            if not self._arrivals or now - self._arrivals[0].arrival < self.max_hold:
                return None
            p = self._arrivals[0]
            since = [t for _, order, t in self._pushed if order > p.order]
            if not since or p.time_end - max(since) <= self.max_lateness * 1e9:
                return p
            self._heap.remove(p)  # ahead of every source: it must not move the time
            heapq.heapify(self._heap)
            p.done = True
            if self.on_refused is not None:
                self.on_refused(p, "ahead of the data")

    def next_due(self) -> float | None:
        """Arrival-clock time the head of the buffer is due, or ``None`` if empty."""
        if self._late:
            return self._late[0].arrival
        if not self._heap:
            return None
        due = self._heap[0].arrival + self.wait
        while self._arrivals and self._arrivals[0].done:
            self._arrivals.popleft()
        if self._arrivals:
            due = min(due, self._arrivals[0].arrival + self.max_hold)
        return due

    def flush(self) -> list[_Pending]:
        """Everything queued: the late batches, then the others in order."""
        late = [self._release(self._late.popleft()) for _ in range(len(self._late))]
        return late + [self._release(heapq.heappop(self._heap)) for _ in range(len(self._heap))]

    def _release(self, p: _Pending) -> _Pending:
        p.done = True
        rid = p.batch.radar_id
        if self.last_time is not None and p.time_end < self.last_time:
            p.late = True
        self.late_released += p.late
        if self.moves_time is not None and not self.moves_time(rid):
            return p  # dropped by the service (no site): its time moves nothing
        self.last_time = p.time_end if self.last_time is None else max(self.last_time, p.time_end)
        self.radar_time[rid] = max(self.radar_time.get(rid, p.time_end), p.time_end)
        return p

    # --- snapshots ---------------------------------------------------------------------
    def to_snapshot(self) -> dict:
        """What a restart must keep: the per-radar watermarks, the service time and the
        batches seen (``services.runtime.seen_batches``); batches still held are not
        saved (a restart loses at most the hold)."""
        return {
            "radar_time": dict(self.radar_time),
            "last_time": self.last_time,
            "seen": self.seen.to_snapshot(),
        }

    def from_snapshot(self, snap) -> None:
        """Take the watermarks, service time and batches seen of :meth:`to_snapshot`
        (:class:`~skyfuse.schemas.snapshot.SnapshotError` if malformed; then nothing
        changes)."""
        snap = mapping(snap, "reorder buffer")
        marks = mapping(snap.get("radar_time"), "watermarks")
        last = snap.get("last_time")
        if not all(type(v) is int for v in marks.values()) or type(last) not in (int, type(None)):
            raise SnapshotError("watermarks or service time not integer ns")
        seen = SeenBatches(self.seen.max_radars, self.seen.window, self.seen.epochs)
        seen.from_snapshot(snap.get("seen"))
        self.radar_time.update(marks)
        self.last_time, self.seen = last, seen
