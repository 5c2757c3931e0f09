"""``skyfuse record --out FILE.mcap [--connect EP]``: record the skyfuse key space to MCAP.

Runs until SIGINT/SIGTERM (or ``--duration``), then drains what Zenoh already delivered,
finishes the file and exits 0. See :mod:`services.recorder` for the file layout."""

from __future__ import annotations

import argparse
import json
import logging
import time

from skyfuse.schemas import Status, keys
from skyfuse.services.cli.service_command import add_service_parser, run_service, service_config
from skyfuse.services.recording.recorder import Recorder, RecorderConfig
from skyfuse.services.runtime.lifecycle import EXIT_OK, StopFlag
from skyfuse.services.runtime.transport import (
    Inbox,
    Received,
    declare_liveliness,
    declare_publisher,
    service_alive_key,
)

log = logging.getLogger("skyfuse.record")


def keys_match(key_expr: str, key: str) -> bool:
    """Whether the concrete ``key`` is matched by ``key_expr``."""
    import zenoh

    return zenoh.KeyExpr(key_expr).intersects(zenoh.KeyExpr(key))


def register(sub: argparse._SubParsersAction) -> None:
    p = add_service_parser(
        sub, "record", "record every skyfuse message on Zenoh to MCAP", __doc__,
        RecorderConfig, tables="[record] and [transport]",
    )  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg, tcfg = service_config(RecorderConfig, args, "record")
    return run_service(tcfg, lambda session, stop: record(session, cfg, stop))


def record(session, cfg: RecorderConfig, stop: StopFlag) -> int:
    rec = Recorder(cfg, metadata={"command": "skyfuse record", "key_expr": cfg.key_expr})
    # a small inbox: a recorder that falls behind slows the (BLOCK) publishers down
    # instead of piling up messages it could not write before a shutdown deadline
    inbox = Inbox(capacity=cfg.queue)
    # remote only: our own Status is written directly (see below), never through the inbox
    # advanced: plots missed (a stall, a cut link) come back from the sensors' caches
    inbox.subscribe(session, cfg.key_expr, "data", remote_only=True, recover=True)
    status_key = keys.service_status(cfg.name)
    status_pub = declare_publisher(session, status_key)
    token = declare_liveliness(session, service_alive_key(cfg.name))
    start_wall = time.time_ns()
    t0 = time.monotonic()
    next_status = t0
    log.info("recording %s", cfg.key_expr)
    try:
        while not stop.is_set():
            now = time.monotonic()
            if cfg.duration is not None and now - t0 >= cfg.duration:
                break
            item = inbox.get(timeout=0.05)
            if item is not None:
                rec.handle(item)
                for more in inbox.drain(1000):
                    rec.handle(more)
            rec.maybe_flush()
            if now >= next_status:
                next_status = now + cfg.status_interval
                rec.note_missed(inbox.take_missed())
                st = Status(
                    service="recorder",
                    service_id=cfg.name,
                    time=time.time_ns(),
                    uptime_s=(time.time_ns() - start_wall) / 1e9,
                    counters={
                        "messages": rec.messages,
                        "bytes": rec.bytes,
                        "files": len(rec.files),
                        "batches_lost": sum(rec.lost().values()),
                        "samples_missed": sum(rec.missed.values()),
                    },
                    rejected=dict(rec.rejected),
                )
                payload = st.to_json_bytes()
                status_pub.put(payload)
                if keys_match(cfg.key_expr, status_key):
                    rec.handle(Received("data", status_key, payload, True, st.time))
    finally:
        token.undeclare()
        inbox.close()
        deadline = time.monotonic() + max(0.5, stop.grace - 2.0)
        left = inbox.drain(10_000_000)
        for i, item in enumerate(left):
            if time.monotonic() > deadline:
                rec.rejected["not written: shutdown deadline"] += len(left) - i
                log.error("shutdown deadline: %d received messages not written", len(left) - i)
                break
            rec.handle(item)
        if inbox.discarded:
            rec.rejected["not written: arrived after the stop"] += inbox.discarded
        rec.note_missed(inbox.take_missed())
        files = rec.close()
        summary = rec.summary()
        log.info(
            "recorded %d messages (%d bytes) into %s; rejected %s",
            rec.messages,
            rec.bytes,
            ", ".join(str(f) for f in files),
            dict(rec.rejected) or "none",
        )
        if cfg.stats is not None:
            cfg.stats.write_text(json.dumps(summary, indent=2) + "\n")
    return EXIT_OK
