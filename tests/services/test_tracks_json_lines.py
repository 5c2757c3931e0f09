"""``skyfuse tracks --json``: one line per received message, the payload's own JSON text
when it is already one line, nothing undecodable written; on a stop signal the messages
already received are still written (a pipe into a file loses none)."""

from __future__ import annotations

import io
import json
import threading
import time

import pytest
from service_support import peer
from skyfuse.services.cli.cmd_tracks import TracksConfig, _follow, _json_line
from skyfuse.services.runtime.lifecycle import StopFlag
from skyfuse.services.runtime.transport import (
    Received,
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
)

KEY = "skyfuse/@v1/fusion/t/tracks"


def _item(payload: bytes) -> Received:
    return Received("tracks", KEY, payload, True, time.time_ns())


def test_a_json_line_per_message_and_nothing_for_bad_payloads():
    out = io.StringIO()
    assert _json_line(out, _item(b'{"cycle":3,"tracks":[]}'))
    pretty = json.dumps({"cycle": 4, "tracks": [1, 2]}, indent=2).encode()
    assert b"\n" in pretty and _json_line(out, _item(pretty))  # re-encoded on one line
    for bad in (b"{not json", b'{"a": 1} trailing', b'{"a": "\xff"}', b""):
        assert not _json_line(out, _item(bad))
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    assert [json.loads(line) for line in lines] == [
        {"topic": KEY, "message": {"cycle": 3, "tracks": []}},
        {"topic": KEY, "message": {"cycle": 4, "tracks": [1, 2]}},
    ]


class SlowOut(io.StringIO):
    """An output that takes 2 ms per line, so received messages queue up behind it."""

    def write(self, s: str) -> int:
        time.sleep(0.002)
        return super().write(s)


@pytest.mark.service
def test_messages_received_before_a_stop_are_still_written():
    stop, out = StopFlag(grace=0), SlowOut()
    with open_session(peer(listen=loopback_endpoint(free_port()))) as s:
        cfg = TracksConfig(json_lines=True, fusion_id="t")
        t = threading.Thread(target=_follow, args=(s, "skyfuse/@v1/fusion/t", cfg, stop, out))
        t.start()
        time.sleep(0.5)  # the subscriptions are declared
        pub = declare_publisher(s, KEY)
        for i in range(200):
            pub.put(json.dumps({"cycle": i}).encode())
        deadline = time.monotonic() + 10
        while out.getvalue().count("\n") < 5 and time.monotonic() < deadline:
            time.sleep(0.005)
        stop.set()  # most of the 200 are still queued
        t.join(15)
        assert not t.is_alive()
    cycles = [json.loads(line)["message"]["cycle"] for line in out.getvalue().splitlines()]
    assert cycles == list(range(200))
