"""The reorder buffer of the fusion service: batches from several radars arrive with
network jitter; each is held ``wait`` seconds of wall time after its arrival and released
in ``(time_end, arrival order)`` order. A batch whose ``time_end`` is earlier than the last
released batch's is refused as *out of sequence*; a batch seen twice (same radar, seq,
time_end and scan) as a *duplicate*. See ``services.fusion.service`` for how the service
uses it."""

from __future__ import annotations

import heapq
import itertools
from collections import deque
from dataclasses import dataclass, field

from skyfuse.schemas import PlotBatch


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
