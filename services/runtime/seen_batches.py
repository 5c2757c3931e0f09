"""Which plot batches were already received: duplicates by ``(radar, epoch, seq)``
(docs/reliability.md), with bounded memory. One mechanism for the fusion service's reorder
buffer and the recorder.

A sensor announces the **epoch** of its numbering in every ``PlotBatch`` (``epoch``,
``services.sensors``): within one epoch of one radar, ``seq`` increases by one per batch
and is never given to two different batches — a batch seen again with the same
``(radar, epoch, seq)`` is a repeat (a restarted sensor publishing again what it
published before, a file published twice). Per radar and epoch this keeps the highest
``seq`` seen and the set of numbers seen in the ``window`` below it:

* ``seq`` above the highest: new;
* within the window: new unless in the set (batches may arrive out of order by up to
  ``window`` numbers);
* ``window`` or more below the highest: a repeat — a sensor publishes its numbers in
  increasing order, so a number that old can only have been published already.

So a whole file published again is refused, batch by batch, with memory
``O(window)`` per radar and epoch; at most ``epochs`` epochs per radar (the least
recently used forgotten) and ``max_radars`` radars (the least recently used forgotten)
are kept.

**Epoch 0** is "not announced" (recordings and sensors from before the field): numbers
may start again at 0 after a restart, so only an exact repeat of one of the last
``LEGACY_RECENT`` batches of the radar, by ``(seq, time_end, scan)``, is a duplicate.
"""

from __future__ import annotations

from collections import deque

from skyfuse.schemas.snapshot import SnapshotError, mapping

LEGACY_RECENT = 256
"""Batches remembered per radar for epoch 0 (no epoch announced)."""


class SeenBatches:
    """The ``(radar, epoch, seq)`` seen (module docstring). :meth:`duplicate` tests,
    :meth:`add` records (call it only for a batch accepted)."""

    def __init__(self, max_radars: int = 1000, window: int = 4096, epochs: int = 4) -> None:
        self.max_radars, self.window, self.epochs = max_radars, window, epochs
        self.radars: dict[str, dict] = {}
        """radar → epoch → ``[highest seq, set of seqs within the window]``; epoch 0 →
        a deque of the last ``(seq, time_end, scan)``. Plain dicts in least recently
        used order (:meth:`to_snapshot` keeps the order)."""

    def _epochs(self, radar_id: str) -> dict:
        per = self.radars.pop(radar_id, None)
        if per is None:
            per = {}
        self.radars[radar_id] = per  # most recently used last
        while len(self.radars) > self.max_radars:
            del self.radars[next(iter(self.radars))]
        return per

    def duplicate(self, batch) -> bool:
        """Whether ``batch`` (a PlotBatch) repeats one already added."""
        per = self.radars.get(batch.radar_id)
        epoch = getattr(batch, "epoch", 0)
        seen = None if per is None else per.get(epoch)
        if seen is None:
            return False
        if epoch == 0:
            return (batch.seq, batch.time_end, batch.scan) in seen
        high, recent = seen
        if batch.seq > high:
            return False
        return batch.seq <= high - self.window or batch.seq in recent

    def add(self, batch) -> None:
        """Record ``batch`` as seen."""
        per = self._epochs(batch.radar_id)
        epoch = getattr(batch, "epoch", 0)
        seen = per.pop(epoch, None)
        if seen is None:
            seen = deque(maxlen=LEGACY_RECENT) if epoch == 0 else [batch.seq, set()]
        per[epoch] = seen  # most recently used last
        while len(per) > self.epochs:
            del per[next(iter(per))]
        if epoch == 0:
            seen.append((batch.seq, batch.time_end, batch.scan))
            return
        seen[0] = max(seen[0], batch.seq)
        seen[1].add(batch.seq)
        if len(seen[1]) > 2 * self.window:  # forget what fell below the window
            floor = seen[0] - self.window
            seen[1] = {s for s in seen[1] if s > floor}

    # --- snapshots ---------------------------------------------------------------------
    def to_snapshot(self) -> dict:
        """``{"radars": [[radar, [[epoch, seen], …]], …]}`` in least recently used order;
        ``seen`` is ``[highest seq, [seqs within the window, sorted]]`` or, for epoch 0,
        ``[[seq, time_end, scan], …]``. The bounds are this object's configuration."""
        radars = []
        for rid, per in self.radars.items():
            epochs = []
            for epoch, seen in per.items():
                if epoch == 0:
                    epochs.append([0, [list(t) for t in seen]])
                else:
                    epochs.append([epoch, [seen[0], sorted(seen[1])]])
            radars.append([rid, epochs])
        return {"radars": radars}

    def from_snapshot(self, snap) -> None:
        """Hold the batches seen of :meth:`to_snapshot` (the least recently used beyond
        this object's bounds are dropped); :class:`SnapshotError` if it is malformed (then
        nothing changes)."""
        radars = mapping(snap, "seen batches").get("radars")
        if type(radars) is not list:
            raise SnapshotError("seen batches: no radar list")
        out: dict[str, dict] = {}
        for item in radars:
            if type(item) is not list or len(item) != 2 or type(item[0]) is not str:
                raise SnapshotError("seen batches: an entry is not [radar, epochs]")
            out[item[0]] = _epochs(item[1])
        for rid in list(out)[: max(0, len(out) - self.max_radars)]:
            del out[rid]
        for per in out.values():
            for epoch in list(per)[: max(0, len(per) - self.epochs)]:
                del per[epoch]
        self.radars = out


def _ints(values, n: int | None = None) -> bool:
    return (
        type(values) is list
        and (n is None or len(values) == n)
        and all(type(v) is int for v in values)
    )


def _epochs(items) -> dict:
    """The epochs of one radar from their snapshot (see ``to_snapshot``)."""
    if type(items) is not list:
        raise SnapshotError("seen batches: epochs are not a list")
    per: dict = {}
    for item in items:
        if type(item) is not list or len(item) != 2 or type(item[0]) is not int:
            raise SnapshotError("seen batches: an epoch entry is not [epoch, seen]")
        epoch, seen = item
        if epoch == 0:
            if type(seen) is not list or not all(_ints(t, 3) for t in seen):
                raise SnapshotError("seen batches: epoch 0 is not a list of [seq, time, scan]")
            per[0] = deque((tuple(t) for t in seen), maxlen=LEGACY_RECENT)
        elif type(seen) is list and len(seen) == 2 and type(seen[0]) is int and _ints(seen[1]):
            per[epoch] = [seen[0], set(seen[1])]
        else:
            raise SnapshotError(f"seen batches: epoch {epoch} is not [highest, [seqs]]")
    return per
