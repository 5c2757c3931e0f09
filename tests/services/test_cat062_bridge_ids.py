"""``skyfuse cat062`` with a fusion id nobody publishes warns within ``answer_wait`` and
lists the fusion ids that are alive (real Zenoh sessions on loopback)."""

from __future__ import annotations

import logging
import socket
import threading
import time

import pytest
from skyfuse.schemas import Status, keys
from skyfuse.services.cli.cmd_cat062 import Cat062Config, Cat062UdpSender, bridge
from skyfuse.services.runtime.transport import (
    TransportConfig,
    declare_publisher,
    free_port,
    loopback_endpoint,
    open_session,
)

pytestmark = pytest.mark.service


@pytest.mark.parametrize("bridged", ["main", "demo"])
def test_bridge_warns_and_lists_alive_fusion_ids(bridged, caplog):
    ep = loopback_endpoint(free_port())
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    cfg = Cat062Config(udp=f"127.0.0.1:{rx.getsockname()[1]}", fusion_id=bridged,
                       duration=2.5, answer_wait=1.5)  # fmt: skip
    sender = Cat062UdpSender(cfg.udp, sac=1, sic=2)
    stop = threading.Event()
    caplog.set_level(logging.WARNING)
    with (
        open_session(TransportConfig(mode="peer", listen=[ep])) as s_pub,
        open_session(TransportConfig(mode="peer", connect=[ep])) as s_bridge,
    ):
        pub = declare_publisher(s_pub, keys.fusion_status("demo"))
        t = threading.Thread(target=bridge, args=(s_bridge, sender, cfg, stop))
        t.start()
        end = time.monotonic() + 3.0
        while time.monotonic() < end and t.is_alive():  # the `skyfuse demo` fusion's Status
            st = Status(service="fusion", service_id="demo", time=time.time_ns(), uptime_s=1)
            pub.put(st.to_json_bytes())
            time.sleep(0.2)
        t.join(10)
    rx.close()
    warned = [r.getMessage() for r in caplog.records if "answered within" in r.getMessage()]
    if bridged == "main":
        assert len(warned) == 1 and "'main'" in warned[0] and "alive: demo" in warned[0]
    else:
        assert warned == []
