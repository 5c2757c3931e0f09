"""Transport helpers: config validation, pub/sub through the Inbox with the wall-clock
attachment, liveliness appearance/disappearance, and queryables, on loopback."""

from __future__ import annotations

import json
import threading
import time

import pytest
from service_support import peer, wait_for
from skyfuse.services.runtime.config import ConfigError
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    alive_tokens,
    check_endpoint,
    declare_liveliness,
    declare_publisher,
    endpoint_port,
    free_port,
    loopback_endpoint,
    open_session,
    query,
    read_wall_stamp,
    wait_for_tokens,
    wall_stamp,
    zenoh_config,
)

pytestmark = pytest.mark.service


def test_endpoint_validation_names_the_value():
    assert check_endpoint("tcp/127.0.0.1:7447") == "tcp/127.0.0.1:7447"
    assert endpoint_port("tcp/zenohd:7447") == 7447
    for bad in ("127.0.0.1:7447", "tcp/127.0.0.1", "tcp/host:99999", "foo/x:1"):
        with pytest.raises(ValueError, match="endpoint"):
            check_endpoint(bad)
    with pytest.raises(ValueError, match="not valid"):
        TransportConfig(connect=["localhost:7447"])


def test_zenoh_config_multicast_off_and_endpoints():
    conf = zenoh_config(TransportConfig(listen=["tcp/127.0.0.1:7000"]))
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    assert json.loads(conf.get_json("mode")) == "peer"
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7000"]
    conf = zenoh_config(TransportConfig(mode="client", connect=["tcp/127.0.0.1:7001"]))
    assert json.loads(conf.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7001"]
    with pytest.raises(ConfigError, match="client needs --connect"):
        zenoh_config(TransportConfig(mode="client"))


def test_wall_stamp_roundtrip():
    assert read_wall_stamp(wall_stamp(123456789)) == 123456789
    assert read_wall_stamp(b"abc") is None


def test_pubsub_liveliness_and_query_on_loopback():
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as a, open_session(peer(connect=ep)) as b:
        inbox = Inbox(capacity=100)
        inbox.subscribe(a, "skyfuse/@v1/radar/*/plots", "plots")
        inbox.subscribe_liveliness(a, "skyfuse/@v1/radar/*/alive")
        a.declare_queryable(
            "skyfuse/@v1/fusion/f1/snapshot",
            lambda q: q.reply("skyfuse/@v1/fusion/f1/snapshot", b'{"n":3}'),
        )
        pub = declare_publisher(b, "skyfuse/@v1/radar/R7/plots")
        assert wait_for(lambda: pub.matching_status.matching, 5.0)
        token = declare_liveliness(b, "skyfuse/@v1/radar/R7/alive")
        sent = [f"m{i}".encode() for i in range(50)]
        for m in sent:
            pub.put(m, attachment=wall_stamp())
        got, alive = [], []
        deadline = time.monotonic() + 5
        while (len(got) < 50 or not alive) and time.monotonic() < deadline:
            item = inbox.get(timeout=0.1)
            if item is None:
                continue
            (got if item.tag == "plots" else alive).append(item)
        assert [g.payload for g in got] == sent  # all, in order (BLOCK, one publisher)
        assert all(g.key == "skyfuse/@v1/radar/R7/plots" for g in got)
        assert all(0 <= g.recv_ns - g.sent_ns < 5e9 for g in got)
        assert alive[0].put and alive[0].key == "skyfuse/@v1/radar/R7/alive"
        assert alive_tokens(a, "skyfuse/@v1/radar/*/alive") == ["skyfuse/@v1/radar/R7/alive"]
        # the queryable's declaration reaches b on its own (not with the subscriber's)
        expected = [("skyfuse/@v1/fusion/f1/snapshot", b'{"n":3}')]
        assert wait_for(lambda: query(b, "skyfuse/@v1/fusion/*/snapshot", 0.5) == expected, 5.0)
        token.undeclare()
        item = None
        deadline = time.monotonic() + 5
        while item is None and time.monotonic() < deadline:
            item = inbox.get(timeout=0.1)
        assert item is not None and item.tag == "alive" and not item.put
        inbox.close()


def test_listen_port_taken_is_a_clear_error():
    from skyfuse.services.runtime.transport import TransportError

    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)):
        with pytest.raises(TransportError, match="cannot open"):
            with open_session(peer(listen=ep)):
                pass


def test_wait_for_tokens_wakes_on_a_later_token_and_reports_the_missing():
    """Tokens already alive (history) and one declared later by another session both count;
    a key nobody declares is returned as missing after the timeout; a set stop ends it."""
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as a, open_session(peer(connect=ep)) as b:
        early = declare_liveliness(b, "skyfuse/@v1/service/early/alive")
        later: list = []
        t = threading.Timer(
            0.3, lambda: later.append(declare_liveliness(b, "skyfuse/@v1/service/late/alive"))
        )
        t.start()
        keys = ["skyfuse/@v1/service/early/alive", "skyfuse/@v1/service/late/alive"]
        assert wait_for_tokens(a, keys, 10.0) == []
        assert later, "returned before the late token was declared"
        absent = "skyfuse/@v1/service/nobody/alive"
        assert wait_for_tokens(a, [keys[0], absent], 0.5) == [absent]
        stop = threading.Event()
        stop.set()
        assert wait_for_tokens(a, [absent], 30.0, stop) == [absent]
        t.join()
        early.undeclare()
