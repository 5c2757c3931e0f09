"""Hot standby under the secure deployment: a ``skyfuse router`` with mutual TLS and the
policy of ``skyfuse certs``, two ``skyfuse fusion --standby`` processes with the same
``fusion-main`` certificate and separate state directories (as on two hosts). The policy
must let them see each other's election tokens (``fusion/main/active/…``) and the state
snapshots (``fusion/main/state``): the second one follows instead of publishing too,
reports itself on its own standby Status key (which the viewer may read) and holds the
first one's snapshots, which the viewer may not read; after ``kill -9`` of the first it
takes over from the snapshot it received (its Status, epoch 2, reaches the authorised
viewer). Without the rule, the second one would not see the first and both would
publish."""

from __future__ import annotations

import json
import time

import pytest
from service_support import wait_for_router
from skyfuse.schemas import Status, keys
from skyfuse.services.runtime import security
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    free_port,
    open_session,
)

pytestmark = pytest.mark.service


def viewer(d, ep: str) -> TransportConfig:
    return TransportConfig(
        mode="client", connect=[ep], tls_root_ca=d / "ca.pem",
        tls_cert=d / "client-viewer.pem", tls_key=d / "client-viewer.key",
    )  # fmt: skip


def statuses(inbox: Inbox, seconds: float) -> list[Status]:
    out, deadline = [], time.monotonic() + seconds
    while time.monotonic() < deadline:
        item = inbox.get(0.1)
        if item is not None:
            out.append(Status.from_json_bytes(item.payload))
    return out


def test_standby_election_passes_the_access_policy(tmp_path, start_skyfuse, until):
    d = tmp_path / "secure"
    people = security.principals(["R1"], ["main"], [], ["viewer"])
    security.write_deployment(d, people, ["localhost", "127.0.0.1"])
    ep = f"tls/127.0.0.1:{free_port()}"
    start_skyfuse("router", "--config", str(d / "router.toml"), "--listen", ep, log="router")
    args = (
        "fusion", "--config", str(d / "fusion-main.toml"), "--connect", ep, "--standby",
        "--status-interval", "0.2", "--snapshot-interval", "0.3",
    )  # fmt: skip
    wait_for_router(viewer(d, ep))
    with open_session(viewer(d, ep)) as session:
        inbox, spy, standby = Inbox(), Inbox(), Inbox()
        inbox.subscribe(session, keys.fusion_status("main"), "status")
        spy.subscribe(session, keys.fusion_state("main"), "state")
        standby.subscribe(session, f"{keys.PREFIX}/fusion/main/standby/*/status", "standby")
        first = start_skyfuse(*args, "--state-dir", str(tmp_path / "a"), log="fusion-1")
        assert until(lambda: inbox.qsize() > 0, 30.0)
        second = start_skyfuse(*args, "--state-dir", str(tmp_path / "b"), log="fusion-2")
        log2 = tmp_path / "fusion-2.log"
        assert until(lambda: "standby: instance" in log2.read_text(), 30.0), log2.read_text()
        before = statuses(inbox, 1.0)
        assert before and {s.epoch for s in before} == {1}  # only the first one publishes
        reports = statuses(standby, 1.0)
        assert reports and reports[-1].role == "standby" and reports[-1].following
        assert reports[-1].counters["standby_states_received"] >= 1
        assert spy.qsize() == 0  # the state snapshots reach the standby, not the viewer
        first.kill()
        first.wait()
        assert until(lambda: "running" in log2.read_text(), 15.0)
        after = statuses(inbox, 1.5)
        assert after and after[-1].epoch == 2 and second.poll() is None
        assert after[-1].role == "active"
        assert "snapshot received from the active instance" in log2.read_text()
        print(json.dumps({"epochs_after": sorted({s.epoch for s in after})}))
