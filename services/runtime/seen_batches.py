"""Which plot batches were already received, which numbers never came, and which numbers
no sensor could have sent: one mechanism, by ``(radar, epoch, seq)``, for the fusion
service's reorder buffer and the recorder, with bounded memory.

A sensor announces the **epoch** of its numbering in every ``PlotBatch`` (``epoch``,
``services.sensors``): within one epoch of one radar, ``seq`` increases by one per batch
and is never given to two different batches; a new epoch is the only way to start the
numbering again. Per radar and epoch this keeps the highest ``seq`` accepted, the
``time_end`` of that batch, and the numbers accepted in the ``window`` below it.

**Duplicates.** A batch seen again with the same ``(radar, epoch, seq)`` is a repeat (a
restarted sensor publishing again what it published before, a file published twice):

* within the window: a repeat if its number is in the set;
* ``window`` or more below the highest: a repeat if its ``time_end`` is not after the
  highest one's — a sensor's numbers and times increase together, so an old number with
  an old time can only have been published already. An old number with a *newer* time
  shows the highest number was not the sensor's (a forged one, or one kept from an
  earlier version's state): the radar's numbering state starts again from this batch
  (``resets``), so nothing received or persisted can lock a radar out.

**Sequence and time jumps.** A radar's numbers and times advance together, at its own
rate (numbers per second of data time, measured over the epoch). A number ahead of the
highest by more than the radar could have published since is refused (``sequence
jump``) and never becomes the highest: the allowance is ``max_jump`` plus twice the rate
times the data time since the highest number. A time ahead of the highest number's by
more than twice the time the numbers in between take (plus ``max_jump`` numbers) is
refused too (``time jump``): one message dated an hour later, of a radar replaying old
data, cannot carry the radar's time (and the service time) away — which no clock check
can see, the data being older than the clock. A real jump (batches lost beyond the
publisher's cache while the rate was unknown, a radar switched off for a while) costs
``RESYNC_S`` seconds of that radar's data: the refused batches that continue each other's
numbering *without a gap* (each the next number, its time after the previous one's by at
most what two numbers take at the radar's rate) are taken once their own times span
``RESYNC_S`` with no batch of the old numbering accepted in between. The rule reads only
the batches' numbers and times, never their arrival: a receiver working through a
backlog (arrivals bunched, or stretched by back-pressure) judges them as one that kept
up, and copies of a live radar's latest batches, sent now and then with a forged number,
never continue each other without a gap.

**After a jump is taken** the numbers it skipped (between the highest number accepted
before it and its first one) were never accepted: a batch with one of them is not a
repeat (a late batch of the old numbering, one recovered from the publisher's cache), it
is accepted and counted. One dated at or after the jump's first batch shows the old
numbering still running beside the taken one, which then was not the sensor's: the
radar's numbering and counts go back to the old numbering, continued by this batch
(``resets``), and the taken numbers are no longer counted as lost.

**Gaps** (``lost``). Numbers of an epoch between the lowest and the highest one received
(accepted or refused by another check, not jumps or repeats) that never arrived are lost;
a number that arrives later (recovered from the publisher's cache, reordered) is no longer
counted. Numbers published before the first one received are not counted (the receiver
was not there). Counts of epochs forgotten (at most ``epochs`` per radar, least recently
used) are kept per radar.

**Epoch 0** is "not announced" (recordings and sensors from before the field): numbers
may start again at 0 after a restart, so only an exact repeat of one of the last
``LEGACY_RECENT`` batches of the radar, by ``(seq, time_end, scan)``, is a duplicate;
jumps are judged from the latest batch in time (a number going back is a restart), gaps
are not counted.

At most ``max_radars`` radars are kept (the least recently used forgotten).
"""

from __future__ import annotations

from collections import deque

from skyfuse.schemas.snapshot import SnapshotError, check_version, mapping

LEGACY_RECENT = 256
"""Batches remembered per radar for epoch 0 (no epoch announced)."""
RESYNC_S = 2.0
"""Data time (the batches' own ``time_end``) a refused jump's gapless continuation must
span before it is taken, s."""
SNAPSHOT_VERSION = 2
"""Version of :meth:`SeenBatches.to_snapshot` (2: a refused jump's continuation as
``[first seq, first time, last seq, last time]``, the numbering before a taken jump)."""
MAX_GAP_S = 60.0
"""Data time a radar's next batch may be ahead of its last one while its rate is not
known yet (its first batches), s."""
DUPLICATE, JUMP, TIME_JUMP = "duplicate batch", "sequence jump", "time jump"
"""The reasons :meth:`SeenBatches.check` returns."""


def _legacy(ring: deque | None = None) -> dict:
    """The state of epoch 0: the last batches' identities and the jump guard's numbers."""
    ring = deque(maxlen=LEGACY_RECENT) if ring is None else ring
    return {"ring": ring, "high": None, "t_high": None, "s0": None, "t0": None, "pending": None}


_PRIOR = ("high", "t_high", "s0", "t0", "from", "t_from", "top", "n")
"""The numbering before a taken jump (:func:`_state` ``prior``): its highest number and
time, its rate's origin, the jump's first number and time, the count's top and number
received; with ``fill``, the skipped numbers accepted since."""


def _state(seq: int, time_end: int) -> dict:
    """The state of one epoch, starting at one batch (plain types: saved as they are)."""
    return {
        "high": seq,  # highest number accepted
        "t_high": time_end,  # its time_end, ns
        "recent": set(),  # numbers accepted within the window below `high`
        "s0": seq,  # first number accepted, and its time_end: the rate
        "t0": time_end,
        "first": seq,  # lowest and highest number received (accepted or refused)
        "top": seq,
        "n": 0,  # distinct numbers received in first..top
        "got": set(),  # numbers received within the window below `top`
        "pending": None,  # [first seq, time_end, last seq, time_end] of a refused jump's
        # gapless continuation
        "prior": None,  # the numbering before the last jump taken (_PRIOR, "fill")
    }


def _skipped(st: dict, seq: int) -> bool:
    """Whether ``seq`` is one of the numbers the last jump taken skipped."""
    pr = st.get("prior")
    return pr is not None and pr["high"] < seq < pr["from"]


class SeenBatches:
    """The ``(radar, epoch, seq)`` seen (module docstring). :meth:`check` tests a batch
    (``None``, :data:`DUPLICATE` or :data:`JUMP`), :meth:`add` records one accepted,
    :meth:`received` one refused by another check (for the gaps only)."""

    def __init__(
        self, max_radars: int = 1000, window: int = 4096, epochs: int = 4, max_jump: int = 64
    ) -> None:
        self.max_radars, self.window, self.epochs = max_radars, window, epochs
        self.max_jump = max_jump
        self.radars: dict[str, dict] = {}
        """radar → epoch → the epoch's state (:func:`_state`; epoch 0: :func:`_legacy`).
        Plain dicts in least recently used order (:meth:`to_snapshot` keeps the order)."""
        self.lost_forgotten: dict[str, int] = {}
        """Per radar: numbers lost in epochs no longer kept."""
        self.resets = 0
        """Numbering states started again by an old number with a newer time."""

    # --- state ---------------------------------------------------------------------
    def _epochs(self, radar_id: str) -> dict:
        per = self.radars.pop(radar_id, None)
        if per is None:
            per = {}
        self.radars[radar_id] = per  # most recently used last
        while len(self.radars) > self.max_radars:
            gone = next(iter(self.radars))
            del self.radars[gone]
            self._lost_forgotten().pop(gone, None)
        return per

    def _lost_forgotten(self) -> dict[str, int]:
        if not hasattr(self, "lost_forgotten"):  # a snapshot of an earlier version
            self.lost_forgotten = {}
        return self.lost_forgotten

    @staticmethod
    def _epoch_state(per: dict | None, epoch: int):
        """The state of ``epoch`` of a radar's epochs ``per`` (None: none)."""
        return None if per is None else per.get(epoch)

    # --- queries -------------------------------------------------------------------
    def check(self, batch, horizon_ns: int | None = None) -> str | None:
        """Why ``batch`` must be refused (:data:`DUPLICATE`, :data:`JUMP`,
        :data:`TIME_JUMP`), or ``None``. ``horizon_ns``: the latest time_end the receiver
        believes (its clock plus a tolerance), which bounds the data time a jump may
        claim. A refused jump is remembered as the start or the continuation of a
        claim (module docstring); nothing here depends on when the batch arrived."""
        per = self.radars.get(batch.radar_id)
        epoch = getattr(batch, "epoch", 0)
        st = self._epoch_state(per, epoch)
        if st is None:
            return None
        seq = batch.seq
        if epoch == 0:
            if (seq, batch.time_end, batch.scan) in st["ring"]:
                return DUPLICATE
        elif seq <= st["high"]:
            if seq in st["recent"] or (_skipped(st, seq) and seq in st["prior"]["fill"]):
                return DUPLICATE
            old = seq <= st["high"] - self.window
            if old and self._not_newer(st, batch.time_end) and not _skipped(st, seq):
                return DUPLICATE
        return self._jump(st, seq, batch.time_end, horizon_ns)

    def _jump(self, st: dict, seq: int, time_end: int, horizon_ns: int | None) -> str | None:
        """:data:`JUMP` or :data:`TIME_JUMP` (module docstring), or ``None``."""
        if st["high"] is None or st["t_high"] is None:
            return None
        ahead = seq - st["high"]
        rate = self._rate(st)
        # without a measured rate yet, a time more than MAX_GAP_S ahead is a jump too
        gap_s = 2.0 * (max(ahead, 0) + self.max_jump) / rate if rate > 0 else MAX_GAP_S
        if ahead > 0 and ahead > self._allowance(st, time_end, horizon_ns):
            problem = JUMP
        elif time_end - st["t_high"] > gap_s * 1e9:
            problem = TIME_JUMP
        else:
            return None
        p = st["pending"]
        if p is not None and len(p) == 4 and seq == p[2] + 1:  # the next number
            step_s = 4.0 / rate if rate > 0 else MAX_GAP_S  # what two numbers take, twice
            if 0 < time_end - p[3] <= step_s * 1e9:  # continues the refused jump
                if time_end - p[1] >= RESYNC_S * 1e9:
                    return None  # the radar's numbering moved: take it
                st["pending"] = [p[0], p[1], seq, time_end]
                return problem
        st["pending"] = [seq, time_end, seq, time_end]
        return problem

    @staticmethod
    def _rate(st: dict) -> float:
        """The radar's numbers per second of data time over the epoch (0: not known)."""
        if st["t0"] is None or st["t_high"] is None:
            return 0.0
        span_t, span_n = (st["t_high"] - st["t0"]) * 1e-9, st["high"] - st["s0"]
        return span_n / span_t if span_t > 0 and span_n > 0 else 0.0

    def duplicate(self, batch) -> bool:
        """Whether ``batch`` repeats one already added."""
        return self.check(batch) == DUPLICATE

    @staticmethod
    def _not_newer(st: dict, time_end: int) -> bool:
        return st["t_high"] is not None and time_end <= st["t_high"]

    def _allowance(self, st: dict, time_end: int, horizon_ns: int | None) -> float:
        """How far past the highest number the next one may be (module docstring)."""
        t_high = st["t_high"]
        if t_high is None or st["t0"] is None:
            return self.max_jump
        t = time_end if horizon_ns is None else min(time_end, horizon_ns)
        return self.max_jump + 2.0 * self._rate(st) * max(0.0, (t - t_high) * 1e-9)

    def lost(self, radar_id: str) -> int:
        """Numbers of ``radar_id`` that never arrived (module docstring, *Gaps*)."""
        total = self.lost_forgotten.get(radar_id, 0)
        for epoch, st in self.radars.get(radar_id, {}).items():
            if epoch != 0 and isinstance(st, dict) and st["first"] is not None:
                total += st["top"] - st["first"] + 1 - st["n"]
        return total

    # --- records -------------------------------------------------------------------
    def add(self, batch) -> None:
        """Record ``batch`` as accepted (and received)."""
        per = self._epochs(batch.radar_id)
        epoch = getattr(batch, "epoch", 0)
        seen = self._epoch_state(per, epoch)
        per.pop(epoch, None)
        if epoch == 0:
            seen = seen if seen is not None else _legacy()
            per[epoch] = seen  # most recently used last
            seen["ring"].append((batch.seq, batch.time_end, batch.scan))
            moved = self._continues(seen, batch.seq, batch.time_end)
            self._latest(seen, batch.seq, batch.time_end)
            if moved:  # the numbering moved: its rate is measured again from here
                seen["s0"], seen["t0"] = batch.seq, batch.time_end
            self._forget_epochs(batch.radar_id, per)
            return
        seq, t = batch.seq, batch.time_end
        if seen is None:
            seen = _state(seq, t)
        per[epoch] = seen
        counted = False
        if _skipped(seen, seq):  # a number a taken jump skipped (module docstring)
            counted = self._skipped_batch(seen, seq, t)
        elif seq <= seen["high"] - self.window and not self._not_newer(seen, t):
            self.resets += 1  # the highest number was not the sensor's: start again here
            seen.update(high=seq, t_high=t, recent=set(), s0=seq, t0=t, prior=None)
        else:
            taken = self._continues(seen, seq, t)
            if taken:  # the numbering moved (a refused jump taken)
                self._take(seen)
            if seq > seen["high"] or seen["t_high"] is None:
                seen["high"], seen["t_high"] = max(seq, seen["high"]), t
            if seen["t0"] is None or taken:  # the rate measured (again) from here
                seen["s0"], seen["t0"] = seq, t
        seen["pending"] = None
        seen["recent"].add(seq)
        if len(seen["recent"]) > 2 * self.window:  # forget what fell below the window
            floor = seen["high"] - self.window
            seen["recent"] = {s for s in seen["recent"] if s > floor}
        if not counted:
            self._count(seen, seq)
        self._forget_epochs(batch.radar_id, per)

    def _take(self, st: dict) -> None:
        """A refused jump's continuation is taken: the numbering before it is kept (when
        numbers were skipped), its refused batches counted as received."""
        first, t_first, last = st["pending"][:3]
        if first > st["high"] + 1:
            st["prior"] = {k: st[k] for k in ("high", "t_high", "s0", "t0", "top", "n")}
            st["prior"].update({"from": first, "t_from": t_first, "fill": set()})
        for s in range(max(first, last - self.window + 1), last + 1):
            self._count(st, s)  # refused (counted as such), but not lost

    def _skipped_batch(self, st: dict, seq: int, t: int) -> bool:
        """A batch numbered between the numbering before a taken jump and the jump: taken
        as a late batch of the old numbering, or, dated at or after the jump, as the old
        numbering running on: back to it (module docstring). Whether it is counted."""
        pr = st["prior"]
        fill = pr["fill"]
        if t < pr["t_from"]:  # late: accepted, counted here (below the count's window)
            if len(fill) < 2 * self.window and seq not in st["got"]:
                fill.add(seq)
                st["n"] += 1
            return True
        self.resets += 1  # the taken numbering was not the sensor's
        old = {s for s in st["recent"] if s < pr["from"]} | fill
        got = {s for s in st["got"] if s < pr["from"]} | fill
        st.update(
            high=max(old | {pr["high"], seq}), t_high=t, s0=pr["s0"], t0=pr["t0"],
            recent=old, got=got, top=max(got | {pr["top"]}), n=pr["n"] + len(fill), prior=None,
        )  # fmt: skip
        return False

    @staticmethod
    def _continues(st: dict, seq: int, t: int) -> bool:
        """Whether ``seq`` at ``t`` is the batch :meth:`check` took as the end of a refused
        jump's continuation."""
        p = st["pending"]
        return (
            p is not None and len(p) == 4 and seq == p[2] + 1
            and 0 < t - p[3] and t - p[1] >= RESYNC_S * 1e9
        )  # fmt: skip

    @staticmethod
    def _latest(st: dict, seq: int, t: int) -> None:
        """Epoch 0: the jump guard follows the latest batch in time; a number going back
        is a restart of the numbering (the rate is measured again from it)."""
        if st["t_high"] is None or t >= st["t_high"]:
            if st["high"] is None or seq < st["high"]:
                st["s0"], st["t0"] = seq, t
            st["high"], st["t_high"] = seq, t
        st["pending"] = None  # any batch accepted ends a refused jump's claim

    def received(self, batch) -> None:
        """Record ``batch`` as received but refused by another check (a time check): its
        number is not lost. Not for batches :meth:`check` refused."""
        epoch = getattr(batch, "epoch", 0)
        if epoch == 0:
            return
        per = self._epochs(batch.radar_id)
        seen = self._epoch_state(per, epoch)
        if seen is None:  # nothing accepted yet: a state for the count only
            seen = per[epoch] = _state(batch.seq, None)
            seen["high"] = batch.seq - 1
        self._count(seen, batch.seq)
        self._forget_epochs(batch.radar_id, per)

    def _count(self, st: dict, seq: int) -> None:
        if st["first"] is None:
            st["first"] = st["top"] = seq
        if seq in st["got"] or seq <= st["top"] - self.window:
            return
        st["got"].add(seq)
        st["n"] += 1
        st["first"], st["top"] = min(st["first"], seq), max(st["top"], seq)
        if len(st["got"]) > 2 * self.window:
            floor = st["top"] - self.window
            st["got"] = {s for s in st["got"] if s > floor}

    def _forget_epochs(self, radar_id: str, per: dict) -> None:
        while len(per) > self.epochs:
            old = per.pop(next(iter(per)))
            if isinstance(old, dict) and old.get("first") is not None:
                lost = old["top"] - old["first"] + 1 - old["n"]
                book = self.lost_forgotten
                book[radar_id] = book.get(radar_id, 0) + lost

    # --- snapshot ------------------------------------------------------------------
    def to_snapshot(self) -> dict:
        """``{"version": SNAPSHOT_VERSION, "radars": [[radar, [[epoch, state], …]], …],
        "lost_forgotten": {radar: n}, "resets": n}``, radars and epochs in least recently
        used order; each state is the dict of :func:`_state` (epoch 0: :func:`_legacy`)
        with its sets as sorted lists (``prior``'s ``fill`` too) and the epoch-0 ring as
        ``[[seq, time_end, scan], …]``. The bounds are this object's configuration."""
        radars = [
            [rid, [[epoch, _state_snapshot(st)] for epoch, st in per.items()]]
            for rid, per in self.radars.items()
        ]
        return {"version": SNAPSHOT_VERSION, "radars": radars,
                "lost_forgotten": dict(self.lost_forgotten), "resets": self.resets}  # fmt: skip

    def from_snapshot(self, snap) -> None:
        """Hold the state of :meth:`to_snapshot` (the least recently used radars and
        epochs beyond this object's bounds dropped); :class:`SnapshotError` if it is
        malformed or of another :data:`SNAPSHOT_VERSION` (then nothing changes). Version 1
        (saved without a version) is read with its refused jumps' claims dropped (they were
        timed by arrival): a claim starts again from the next refused batch."""
        snap = mapping(snap, "seen batches")
        if "version" not in snap:  # version 1 (unnumbered): its arrival-timed claims dropped
            snap = {**snap, "version": SNAPSHOT_VERSION, "radars": _from_v1(snap.get("radars"))}
        snap = check_version(snap, "seen batches", SNAPSHOT_VERSION)
        radars, lost, resets = snap.get("radars"), snap.get("lost_forgotten"), snap.get("resets")
        if type(radars) is not list or type(resets) is not int or type(lost) is not dict:
            raise SnapshotError("seen batches: no radar list, lost counts or resets")
        if not all(type(k) is str and type(v) is int for k, v in lost.items()):
            raise SnapshotError("seen batches: lost counts are not radar → integer")
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
        self.radars, self.lost_forgotten, self.resets = out, dict(lost), resets


_OPTIONAL_INT = ("high", "t_high", "s0", "t0", "first", "top")
"""State entries that are an integer or None (a state made by a refused batch has no
times; epoch 0 has neither first nor top)."""


def _from_v1(radars):
    """The radars of a version-1 snapshot in version 2: no claim pending, no prior
    numbering (anything malformed is left for the checks of version 2)."""
    if type(radars) is not list:
        return radars
    out = []
    for item in radars:
        if type(item) is list and len(item) == 2 and type(item[1]) is list:
            item = [item[0], [_epoch_v1(e) for e in item[1]]]
        out.append(item)
    return out


def _epoch_v1(item):
    if type(item) is not list or len(item) != 2 or type(item[1]) is not dict:
        return item
    st = {**item[1], "pending": None}
    if item[0] != 0:
        st.setdefault("prior", None)
    return [item[0], st]


def _state_snapshot(st: dict) -> dict:
    """One epoch's state as plain JSON values (see :meth:`SeenBatches.to_snapshot`)."""
    out = {k: v for k, v in st.items() if k not in ("ring", "recent", "got", "pending", "prior")}
    out["pending"] = None if st["pending"] is None else list(st["pending"])
    if "prior" in st:
        pr = st["prior"]
        out["prior"] = None if pr is None else {**pr, "fill": sorted(pr["fill"])}
    if "ring" in st:
        out["ring"] = [list(t) for t in st["ring"]]
    else:
        out["recent"], out["got"] = sorted(st["recent"]), sorted(st["got"])
    return out


def _int_or_none(v) -> bool:
    return v is None or type(v) is int


def _ints(values, n: int | None = None) -> bool:
    return (
        type(values) is list
        and (n is None or len(values) == n)
        and all(type(v) is int for v in values)
    )


def _epoch(epoch: int, snap) -> dict:
    """One epoch's state from its snapshot; :class:`SnapshotError` if malformed."""
    snap = mapping(snap, f"seen batches: epoch {epoch}")
    legacy = epoch == 0
    st = _legacy() if legacy else _state(0, None)
    names = set(st) | ({"ring"} if legacy else set())
    if set(snap) != names:
        raise SnapshotError(f"seen batches: epoch {epoch} has entries {sorted(snap)}")
    for k in _OPTIONAL_INT:
        if k in st and not _int_or_none(snap[k]):
            raise SnapshotError(f"seen batches: epoch {epoch} {k} is not an integer")
        if k in st:
            st[k] = snap[k]
    p = snap["pending"]
    if p is not None and not _ints(p, 4):
        raise SnapshotError(f"seen batches: epoch {epoch} pending is not [seq, time, seq, time]")
    st["pending"] = p
    if legacy:
        if type(snap["ring"]) is not list or not all(_ints(t, 3) for t in snap["ring"]):
            raise SnapshotError("seen batches: epoch 0 ring is not a list of [seq, time, scan]")
        st["ring"].extend(tuple(t) for t in snap["ring"])
        return st
    if not (_ints(snap["recent"]) and _ints(snap["got"]) and type(snap["n"]) is int):
        raise SnapshotError(f"seen batches: epoch {epoch} numbers are not integers")
    st["recent"], st["got"], st["n"] = set(snap["recent"]), set(snap["got"]), snap["n"]
    st["prior"] = _prior(epoch, snap["prior"])
    return st


def _prior(epoch: int, snap) -> dict | None:
    """The numbering before a taken jump from its snapshot (``_PRIOR`` and ``fill``)."""
    if snap is None:
        return None
    snap = mapping(snap, f"seen batches: epoch {epoch} prior")
    if set(snap) != {*_PRIOR, "fill"} or not _ints(snap["fill"]):
        raise SnapshotError(f"seen batches: epoch {epoch} prior has entries {sorted(snap)}")
    if not all(_int_or_none(snap[k]) for k in _PRIOR) or snap["from"] is None:
        raise SnapshotError(f"seen batches: epoch {epoch} prior numbers are not integers")
    return {**snap, "fill": set(snap["fill"])}


def _epochs(items) -> dict:
    """The epochs of one radar from their snapshot (see ``to_snapshot``)."""
    if type(items) is not list:
        raise SnapshotError("seen batches: epochs are not a list")
    per: dict = {}
    for item in items:
        if type(item) is not list or len(item) != 2 or type(item[0]) is not int:
            raise SnapshotError("seen batches: an epoch entry is not [epoch, state]")
        per[item[0]] = _epoch(*item)
    return per
