"""Re-publish a recording's radar sites and plot batches on Zenoh in their original timing.

Timing: the message with log time ``t`` is published at ``wall0 + (t - t0) / speed``
(``fast``: as fast as the BLOCK publishers allow), ``t0`` the start of the whole recording
(the first site or plots message of any radar), not of the radars this replay
publishes: several ``skyfuse replay --radars ID`` processes of one file started together
stay in phase (with the first replayed message as ``t0``, a radar whose first message,
site included, comes 3 s into the file was published 3 s / speed early against the
others, and the fusion's reorder buffer held every other radar's batches that long).
``start_at`` puts replays started at different instants on one clock. Message contents —
including plot times — are published unchanged, so a live replay through the fusion
service sees the same data as ``skyfuse track FILE.mcap`` offline. Each PlotBatch carries
the wall-clock publication instant as its attachment (:func:`services.transport.
wall_stamp`), from which the fusion service measures latency.

Every radar whose site is replayed gets a liveliness token ``radar/{id}/alive`` for the
duration of the replay, as a live sensor would.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path

from skyfuse.schemas import keys
from skyfuse.services.recording.mcap_io import ReadStats, iter_recording
from skyfuse.services.runtime.transport import (
    PLOT_CACHE,
    declare_cached_publisher,
    declare_liveliness,
    declare_publisher,
    wall_stamp,
)

log = logging.getLogger(__name__)

REPLAYED_KINDS = ("site", "plots")


@dataclass
class ReplayResult:
    published: Counter = field(default_factory=Counter)
    """Messages published, by topic."""
    skipped: Counter = field(default_factory=Counter)
    """Messages read but not published, by reason."""
    read: ReadStats = field(default_factory=ReadStats)
    interrupted: bool = False
    wall_s: float = 0.0
    subscribed: bool = False
    """Some subscriber matched a plots publisher during the replay (Zenoh matching status)."""

    @property
    def plot_batches(self) -> int:
        return sum(n for k, n in self.published.items() if k.endswith("/plots"))


def replay_start(path: str | Path, kinds: tuple[str, ...]) -> int | None:
    """First log time, ns, of the messages of ``kinds`` of *every* radar in ``path`` (the
    time origin shared by replays of different radars of one file), or ``None`` if there
    is none (an unindexed file: the first replayed message is the origin)."""
    topics = replay_topics(path, kinds, None)
    if not topics:
        return None
    with closing(iter_recording(path, topics=topics, decode=False)) as first:
        for rec in first:
            return int(rec.log_time)
    return None


def replay_topics(
    path: str | Path, kinds: tuple[str, ...], radars: set[str] | None = None
) -> list[str]:
    """The topics of ``path`` whose key kind is in ``kinds`` (and radar in ``radars``)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        try:
            summary = make_reader(f).get_summary()
        except Exception:
            summary = None
    if summary is None:
        return []
    out = []
    for ch in summary.channels.values():
        try:
            info = keys.parse(ch.topic)
        except ValueError:
            continue
        if info.kind in kinds and (radars is None or info.kind == "truth" or info.owner in radars):
            out.append(ch.topic)
    return sorted(out)


def replay(
    session,
    path: str | Path,
    *,
    speed: float = 1.0,
    fast: bool = False,
    radars: set[str] | None = None,
    truth: bool = False,
    stop=None,
    liveliness: bool = True,
    start_at: float | None = None,
    cache: int = PLOT_CACHE,
) -> ReplayResult:
    """Publish the sites and plots (and ``truth``) of ``path``; return what was sent.

    ``radars`` restricts the replay to those radar ids. ``stop`` (an Event-like object)
    ends the replay early. ``start_at``: the Unix time (s, this host's clock) at which the
    recording's start is due (default: now); replays given the same value, in one or
    several processes, publish in phase (messages already due are published at once).
    Plots go through advanced publishers that keep ``cache`` batches per radar for
    receivers that missed them (``services.runtime.transport``)."""
    if speed <= 0:
        raise ValueError(f"speed = {speed}: must be > 0")
    kinds = (*REPLAYED_KINDS, "truth") if truth else REPLAYED_KINDS
    result = ReplayResult()
    topics = replay_topics(path, kinds, radars)
    out = _Publishers(session, cache, liveliness)
    lead = 0.0 if start_at is None else start_at - time.time()  # s until the start
    if lead < 0:
        log.warning("start_at is %.1f s in the past: what is already due is published at "
                    "once", -lead)  # fmt: skip
    wall0 = time.monotonic() + lead
    t0 = replay_start(path, kinds)  # None: the first replayed message
    source = iter_recording(path, topics=topics or None, stats=result.read)
    try:
        for rec in source:
            if stop is not None and stop.is_set():
                result.interrupted = True
                break
            try:
                info = keys.parse(rec.topic)
            except ValueError:
                result.skipped["topic outside the key space"] += 1
                continue
            if info.kind not in kinds:
                result.skipped[f"kind {info.kind} not replayed"] += 1
                continue
            if radars is not None and info.kind != "truth" and info.owner not in radars:
                result.skipped["other radar"] += 1
                continue
            if t0 is None:
                t0 = rec.log_time
            if not fast:
                due = wall0 + (rec.log_time - t0) / 1e9 / speed
                delay = due - time.monotonic()
                if delay > 0:
                    if stop is not None:
                        if stop.wait(delay):
                            result.interrupted = True
                            break
                    else:
                        time.sleep(delay)
            if out.put(rec.topic, info, rec.data):
                result.subscribed = True
            result.published[rec.topic] += 1
    finally:
        result.wall_s = time.monotonic() - wall0
        out.close()
    return result


class _Publishers:
    """The replay's publishers, declared on first use: plots through advanced publishers
    with a cache of ``cache`` batches (and a plain one each, never used to send, for its
    matching status), sites and truth through plain ones; a radar's liveliness token
    from its first site (with ``liveliness``)."""

    def __init__(self, session, cache: int, liveliness: bool) -> None:
        self.session, self.cache, self.liveliness = session, cache, liveliness
        self.pubs: dict[str, object] = {}
        self.probes: dict[str, object] = {}
        self.tokens: dict[str, object] = {}

    def put(self, topic: str, info, data: bytes) -> bool:
        """Publish ``data``; whether it is a plot batch someone subscribes to."""
        pub = self.pubs.get(topic)
        if pub is None:
            if info.kind == "plots":
                pub = declare_cached_publisher(self.session, topic, self.cache)
                self.probes[topic] = declare_publisher(self.session, topic)
            else:
                pub = declare_publisher(self.session, topic)
            self.pubs[topic] = pub
        if info.kind == "site" and self.liveliness and info.owner not in self.tokens:
            self.tokens[info.owner] = declare_liveliness(self.session, keys.radar_alive(info.owner))
        if info.kind != "plots":
            pub.put(data)
            return False
        pub.put(data, attachment=wall_stamp())
        return self.probes[topic].matching_status.matching

    def close(self) -> None:
        for handle in [*self.tokens.values(), *self.pubs.values(), *self.probes.values()]:
            handle.undeclare()
