"""No process listens on a non-loopback interface unless told to: a peer (or router)
started without ``--listen`` listens on 127.0.0.1 only, and peers on one host still form
a mesh through the one that was given a listen endpoint."""

from __future__ import annotations

import json
import time

import pytest
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    declare_publisher,
    free_port,
    open_session,
    zenoh_config,
)

pytestmark = pytest.mark.service


def test_default_listen_endpoints_are_loopback():
    for mode, expect in (("peer", ["tcp/127.0.0.1:0"]), ("router", ["tcp/127.0.0.1:7447"])):
        conf = zenoh_config(TransportConfig(mode=mode))
        assert json.loads(conf.get_json("listen/endpoints")) == expect
    conf = zenoh_config(TransportConfig(mode="client", connect=["tcp/127.0.0.1:7447"]))
    assert json.loads(conf.get_json("listen/endpoints")) == []


def test_peer_without_listen_opens_no_outside_socket_and_still_meshes(listening, until):
    before = set(listening())
    ep = f"tcp/127.0.0.1:{free_port()}"
    hub = TransportConfig(listen=[ep])
    leaf = TransportConfig(connect=[ep])  # like a sensor or the recorder: no --listen
    with open_session(hub), open_session(leaf) as sensor, open_session(leaf) as recorder:
        new = set(listening()) - before
        assert new, "the sessions listen somewhere"
        assert all(host == "127.0.0.1" for host, _ in new), new
        inbox = Inbox(100)
        inbox.subscribe(recorder, "skyfuse/test/**")
        pub = declare_publisher(sensor, "skyfuse/test/x")
        got = []

        def arrived() -> bool:
            pub.put(b"hello")
            item = inbox.get(timeout=0.05)
            if item is not None:
                got.append(item)
            return bool(got)

        # sensor -> recorder, both only connected to the hub (gossip: direct link)
        assert until(arrived, timeout=10.0)
        assert got[0].payload == b"hello"
        inbox.close()
    time.sleep(0.1)
