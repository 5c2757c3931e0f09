"""A TCP relay that delays each direction of every connection by a fixed time: an
emulation of a link's one-way delay for the network fault tests where the kernel has no
``tc netem``.

    python tests/delay_relay.py --listen 127.0.0.1:7500 --to 10.231.20.2:7447 --delay 0.2 \
        --stats relay.json

Every chunk read from one side is written to the other ``delay`` seconds after it was
read, in order (a bounded queue per direction: a slow side slows the other down, as TCP
does). It is not netem: the delay is added to the byte stream, not to the packets of the
link, so the TCP connection behind the relay (the one that crosses the lossy link) sees the
link's own round trip, not 2 × ``delay``, and recovers a lost segment that much sooner; the
application on both ends sees the delay. At SIGTERM it writes its counts (connections,
bytes each way) as JSON to ``--stats`` and exits 0."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import signal
import sys
import time
from pathlib import Path

QUEUE_CHUNKS = 1024
"""Chunks in flight per direction, at most (back-pressure beyond)."""


async def _pump(reader, writer, delay: float, counts: dict, way: str) -> None:
    """Copy ``reader`` to ``writer``, each chunk ``delay`` s after it was read."""
    q: asyncio.Queue = asyncio.Queue(maxsize=QUEUE_CHUNKS)

    async def read() -> None:
        while True:
            data = await reader.read(65536)
            await q.put((time.monotonic() + delay, data))
            if not data:
                return

    async def write() -> None:
        while True:
            due, data = await q.get()
            wait = due - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            if not data:
                if writer.can_write_eof():
                    writer.write_eof()
                return
            writer.write(data)
            await writer.drain()
            counts[way] += len(data)

    await asyncio.gather(read(), write())


async def _serve(a, counts: dict, stop: asyncio.Event) -> None:
    host, port = a.to.rsplit(":", 1)

    async def handle(c_reader, c_writer) -> None:
        try:
            u_reader, u_writer = await asyncio.open_connection(host, int(port))
        except OSError:
            counts["refused"] += 1
            c_writer.close()
            return
        counts["connections"] += 1
        ways = [
            asyncio.create_task(_pump(c_reader, u_writer, a.delay, counts, "bytes_to")),
            asyncio.create_task(_pump(u_reader, c_writer, a.delay, counts, "bytes_back")),
        ]
        try:
            await asyncio.wait(ways, return_when=asyncio.FIRST_EXCEPTION)
        finally:
            for t in ways:
                t.cancel()
            for w in (c_writer, u_writer):
                w.close()
            with contextlib.suppress(Exception):
                await asyncio.gather(*ways, return_exceptions=True)

    lhost, lport = a.listen.rsplit(":", 1)
    server = await asyncio.start_server(handle, lhost, int(lport))
    print(f"relay {a.listen} -> {a.to}, delay {a.delay} s", file=sys.stderr, flush=True)
    async with server:
        await stop.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--listen", required=True, help="HOST:PORT to accept on")
    ap.add_argument("--to", required=True, help="HOST:PORT to forward to")
    ap.add_argument("--delay", type=float, default=0.2, help="one-way delay, s")
    ap.add_argument("--stats", type=Path, default=None, help="JSON counts at exit")
    a = ap.parse_args()
    counts = {"connections": 0, "refused": 0, "bytes_to": 0, "bytes_back": 0}

    async def run() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)
        await _serve(a, counts, stop)

    asyncio.run(run())
    if a.stats is not None:
        a.stats.write_text(json.dumps(counts) + "\n")


if __name__ == "__main__":
    main()
