"""``skyfuse cat062 --udp HOST:PORT [--fusion-id main] [--sac N --sic N] [--connect EP]``:
a bridge from the fused track feed to ASTERIX CAT062 over UDP.

Subscribes to ``skyfuse/@v1/fusion/{id}/tracks`` (and ``…/events``), encodes each
TrackBatch as CAT062 system-track records (:class:`services.asterix.Cat062Writer`:
I010, I015, I070, I105, I100, I185, I040, I080, I136, I500) and sends the data blocks
as UDP datagrams (≤ 1400 bytes each) to HOST:PORT, where an ATC display or recorder
listens. A track's first record carries TSB; when a ``terminated`` or ``merged`` event
arrives, its last known state is sent once more with TSE (track ended).

    skyfuse cat062 --udp 127.0.0.1:30062 --sac 25 --sic 100 --connect tcp/127.0.0.1:7447

``skyfuse fusion --cat062-udp HOST:PORT`` does the same inside the fusion service.
Exits 0 on SIGINT/SIGTERM (or after ``--count`` batches / ``--duration`` s), 1 if the
network fails, 2 on a bad configuration."""

from __future__ import annotations

import argparse
import logging
import socket
import time
from collections import Counter

from pydantic import BaseModel, Field, ValidationError, field_validator
from skyfuse.schemas import TrackBatch, TrackEvent, TrackEventKind, TrackStatus, keys
from skyfuse.services.cli.service_command import add_service_parser, service_config
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK, StopFlag
from skyfuse.services.runtime.startup_heap import freeze_startup_heap
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportError,
    declare_liveliness,
    open_session,
    service_alive_key,
)

log = logging.getLogger("skyfuse.cat062")

FORGET_AFTER_NS = 600 * 10**9
"""A track not in any batch for this long (and never terminated by an event) is
forgotten: no TSE is sent for it."""


class Cat062Config(BaseModel):
    udp: str = Field(description="Send CAT062 datagrams to HOST:PORT")
    fusion_id: str = Field("main", description="Fusion service id whose feed is bridged")
    sac: int = Field(0, ge=0, le=255, description="I062/010 SAC of this tracker")
    sic: int = Field(1, ge=0, le=255, description="I062/010 SIC of this tracker")
    service_id: int = Field(1, ge=0, le=255, description="I062/015 service identification")
    simulated: bool = Field(False, description="Set SIM in I062/080 (tracks of simulated data)")
    count: int | None = Field(None, gt=0, description="Exit after this many track batches")
    answer_wait: float = Field(
        3.0,
        gt=0,
        description="Warn (listing the fusion ids alive) when the fusion service "
        "has not been heard within this many seconds",
    )
    duration: float | None = Field(None, gt=0, description="Exit after this many seconds")

    @field_validator("udp")
    @classmethod
    def _udp(cls, v: str) -> str:
        from skyfuse.services.sensors.config import parse_host_port

        parse_host_port(v, "udp")
        return v

    @field_validator("fusion_id")
    @classmethod
    def _fid(cls, v: str) -> str:
        return keys.check_id(v, "fusion id")


class Cat062UdpSender:
    """Encode TrackBatches as CAT062 and send each data block as one UDP datagram.

    ``address``: ``HOST:PORT``. ``send(batch)`` returns the number of datagrams sent;
    ``terminated(event)`` sends the last known record of a track that ended (TSE).
    ``stats``: batches, tracks, datagrams, bytes, send errors (counted, never raised:
    a display that is not listening must not stop the fusion)."""

    def __init__(
        self, address: str, *, sac: int, sic: int, service_id: int = 1, simulated: bool = False
    ) -> None:
        from skyfuse.services.asterix import Cat062Writer
        from skyfuse.services.sensors.config import parse_host_port

        host, port = parse_host_port(address, "cat062 udp")
        try:
            self.address = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
        except OSError as e:
            raise ConfigError(f"cat062 udp {address!r}: {e}") from None
        self.writer = Cat062Writer(sac=sac, sic=sic, service_id=service_id, simulated=simulated)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.stats: Counter = Counter()
        self._last: dict[str, dict] = {}
        self._latest: dict[str, int] = {}
        self._pending: list[TrackEvent] = []

    def _send_blocks(self, blocks: list[bytes]) -> int:
        sent = 0
        for block in blocks:
            try:
                self.sock.sendto(block, self.address)
            except OSError as e:
                self.stats["send_errors"] += 1
                if self.stats["send_errors"] == 1:
                    log.warning("cat062: cannot send to %s:%d: %s", *self.address, e)
                continue
            sent += 1
            self.stats["bytes"] += len(block)
        self.stats["datagrams"] += sent
        return sent

    def send(self, batch: TrackBatch) -> int:
        blocks = self.writer.encode_batch(batch)
        self.stats["batches"] += 1
        self.stats["tracks"] += len(batch.tracks)
        last = self._last.setdefault(batch.fusion_id, {})
        for t in batch.tracks:
            last[t.track_id] = (t, batch.frame.kind, batch.state_labels)
        sent = self._send_blocks(blocks)
        fid = batch.fusion_id
        self._latest[fid] = max(self._latest.get(fid, batch.time), batch.time)
        if self.stats["batches"] % 1000 == 0:  # forget tracks that ended without an event
            old = self._latest[fid] - FORGET_AFTER_NS
            for tid in [i for i, (t, _, _) in last.items() if t.time < old]:
                del last[tid]
        if self._pending:
            due = [e for e in self._pending if e.fusion_id == fid and e.time <= batch.time]
            self._pending = [e for e in self._pending if e not in due]
            for e in due:
                sent += self._terminate(e)
        return sent

    def terminated(self, event: TrackEvent) -> int:
        """A ``terminated``/``merged`` event: the track's last record once more with TSE.

        Events travel on their own key and can overtake the TrackBatches before them: an
        event later than the latest batch sent waits until a batch of its time has been
        sent (at most 1000 events wait; the oldest are then applied)."""
        if event.kind not in (TrackEventKind.TERMINATED, TrackEventKind.MERGED):
            return 0
        if event.time > self._latest.get(event.fusion_id, event.time):
            self._pending.append(event)
            sent = 0
            while len(self._pending) > 1000:
                sent += self._terminate(self._pending.pop(0))
            return sent
        return self._terminate(event)

    def _terminate(self, event: TrackEvent) -> int:
        known = self._last.get(event.fusion_id, {}).pop(event.track_id, None)
        if known is None:
            return 0
        from skyfuse.services.asterix.writer import datablocks

        track, frame, labels = known
        ended = track.model_copy(update={"status": TrackStatus.TERMINATED, "time": event.time})
        record = self.writer.encode_track(ended, frame, labels)
        self.stats["terminated"] += 1
        return self._send_blocks(datablocks(62, [record], self.writer.max_block_bytes))

    def close(self) -> None:
        self.sock.close()


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "cat062", "bridge the fused track feed to ASTERIX CAT062 over UDP", __doc__,
        Cat062Config, tables="[cat062] and [transport]",
    )  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg, tcfg = service_config(Cat062Config, args, "cat062")
    sender = Cat062UdpSender(
        cfg.udp, sac=cfg.sac, sic=cfg.sic, service_id=cfg.service_id, simulated=cfg.simulated
    )
    stop = StopFlag().install()
    try:
        with open_session(tcfg) as session:
            freeze_startup_heap()  # GC full passes skip what start-up built (stalls)
            bridge(session, sender, cfg, stop)
    except TransportError as e:
        log.error("%s", e)
        return EXIT_FAILED
    finally:
        sender.close()
    return EXIT_OK


class FusionIdsHeard:
    """Which fusion ids publish (from their ``status`` keys, bounded), and one warning
    when the bridged id has not been heard within ``wait`` seconds."""

    MAX_IDS = 32

    def __init__(self, fusion_id: str, wait: float) -> None:
        self.fusion_id, self.wait = fusion_id, wait
        self.ids: set[str] = set()
        self.answered = self.warned = False

    def saw(self, key: str) -> None:
        try:
            owner = keys.parse(key).owner
        except ValueError:
            return
        if owner == self.fusion_id:
            self.answered = True
        elif owner is not None and len(self.ids) < self.MAX_IDS:
            self.ids.add(owner)

    def check(self, elapsed: float) -> None:
        if self.answered or self.warned or elapsed < self.wait:
            return
        self.warned = True
        alive = ", ".join(sorted(self.ids)) or "none"
        log.warning(
            "cat062: no fusion service %r answered within %.0f s; fusion ids alive: %s "
            "(choose one with --fusion-id)",
            self.fusion_id,
            self.wait,
            alive,
        )


def bridge(session, sender: Cat062UdpSender, cfg: Cat062Config, stop) -> Counter:
    """Forward the feed until ``stop`` (or ``count`` batches / ``duration`` s)."""
    inbox = Inbox(capacity=10_000)
    inbox.subscribe(session, keys.fusion_tracks(cfg.fusion_id), "tracks")
    inbox.subscribe(session, keys.fusion_events(cfg.fusion_id), "events")
    inbox.subscribe(session, f"{keys.PREFIX}/fusion/*/status", "status")
    token = declare_liveliness(session, service_alive_key(f"cat062-{cfg.fusion_id}"))
    log.info("cat062: fusion %s → udp %s:%d", cfg.fusion_id, *sender.address)
    t0 = time.monotonic()
    heard = FusionIdsHeard(cfg.fusion_id, cfg.answer_wait)
    try:
        while not stop.is_set():
            if cfg.duration is not None and time.monotonic() - t0 >= cfg.duration:
                break
            if cfg.count is not None and sender.stats["batches"] >= cfg.count:
                break
            item = inbox.get(timeout=0.1)
            heard.check(time.monotonic() - t0)
            if item is None:
                continue
            heard.saw(item.key)
            try:
                if item.tag == "tracks":
                    sender.send(TrackBatch.from_json_bytes(item.payload))
                elif item.tag == "events":
                    sender.terminated(TrackEvent.from_json_bytes(item.payload))
            except ValidationError as e:
                sender.stats["invalid_messages"] += 1
                log.warning("invalid message on %s: %s", item.key, e.errors()[0]["msg"])
    finally:
        token.undeclare()
        inbox.close()
    log.info("cat062: %s", dict(sender.stats))
    return sender.stats
