"""The secure deployment (docs/reliability.md §4), as real processes on loopback: a ``skyfuse
router`` with mutual TLS and the access policy written by ``skyfuse certs``, a ``skyfuse
fusion`` client of it, an authorised sensor and track client — and hostile peers: a
listed sensor injecting plots and a moved site under another radar's id and publishing
fake tracks, a certificate of the right CA that the policy does not list, a certificate
of another CA, and a plain-TCP peer. Expected: the authorised sensor is tracked and the
authorised client reads tracks and the snapshot; no hostile plot, site or track reaches
anyone, and no hostile peer reads a track."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from service_support import wait_for_router
from skyfuse.schemas import FeedKind, PlotBatch, RadarKind, RadarSite, Status, TrackBatch, keys
from skyfuse.services.runtime import security
from skyfuse.services.runtime.transport import (
    Inbox,
    TransportConfig,
    TransportError,
    declare_publisher,
    free_port,
    open_session,
)

pytestmark = pytest.mark.service
EPOCH = 1_780_000_000_000_000_000
PERIOD = 1_000_000_000


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("secure")
    hosts = ["localhost", "127.0.0.1"]
    people = security.principals(["R1", "R2"], ["main"], ["recorder"], ["viewer"])
    security.write_deployment(d / "ok", people, hosts)
    # the right CA, a name the policy does not list
    security.write_deployment(d / "unlisted", [security.Principal("client", "evil")], hosts,
                              ca_of=d / "ok")  # fmt: skip
    # another CA, an authorised name
    security.write_deployment(d / "rogue", [security.Principal("sensor", "R1")], hosts)
    return d


def client(certs: Path, cn: str, ep: str, where: str = "ok") -> TransportConfig:
    d = certs / where
    return TransportConfig(
        mode="client", connect=[ep], tls_root_ca=certs / "ok" / "ca.pem",
        tls_cert=d / f"{cn}.pem", tls_key=d / f"{cn}.key",
    )  # fmt: skip


def site(lat: float) -> RadarSite:
    return RadarSite(radar_id="R1", lat=lat, lon=20.0, alt=100.0, kind=RadarKind.TWO_D)


def batch(seq: int, rng) -> bytes:
    t = EPOCH + seq * PERIOD
    n = 4
    return PlotBatch(
        radar_id="R1", scan=seq, seq=seq, time_start=t - PERIOD, time_end=t,
        time=np.sort(rng.integers(t - PERIOD, t, n)).tolist(),
        range=rng.uniform(3e4, 8e4, n).tolist(), azimuth=rng.uniform(0, 6.28, n).tolist(),
        altitude=rng.uniform(1e3, 5e3, n).tolist(),
    ).to_json_bytes()  # fmt: skip


def drain_until(inbox: Inbox, pred, timeout: float = 15.0) -> list:
    got, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        item = inbox.get(0.1)
        if item is not None:
            got.append(item)
            if pred(item):
                break
    return got


def tracks_snapshot(certs: Path, cn: str, ep: str, where: str = "ok"):
    d = certs / where
    cmd = [sys.executable, "-m", "skyfuse.services.cli", "tracks", "--snapshot",
           "--json", "--mode", "client", "--connect", ep, "--tls-root-ca", str(certs / "ok/ca.pem"),
           "--tls-cert", str(d / f"{cn}.pem"), "--tls-key", str(d / f"{cn}.key")]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, timeout=60)


def hostile_sessions(certs: Path, ep: str):
    """Open every hostile session that the router lets in at all."""
    opened = {}
    for name, cfg in {
        "listed sensor R2": client(certs, "sensor-R2", ep),
        "unlisted client": client(certs, "client-evil", ep, "unlisted"),
        "plain TCP peer": TransportConfig(mode="peer", connect=[ep.replace("tls/", "tcp/")]),
    }.items():
        opened[name] = cfg
    with pytest.raises(TransportError):  # another CA: the TLS handshake fails
        with open_session(client(certs, "sensor-R1", ep, "rogue")):
            pass
    return opened


def test_tls_acl_authorised_work_unauthorised_neither_inject_publish_nor_read(certs, start_skyfuse):
    ep = f"tls/127.0.0.1:{free_port()}"
    ok = certs / "ok"
    start_skyfuse("router", "--config", str(ok / "router.toml"), "--listen", ep, log="router")
    wait_for_router(client(certs, "client-viewer", ep))
    start_skyfuse(
        "fusion", "--config", str(ok / "fusion-main.toml"), "--connect", ep,
        "--reorder-wait", "0.1", "--status-interval", "0.2", "--frame-lat0", "45.0",
        "--frame-lon0", "20.0", log="fusion",
    )  # fmt: skip
    rng = np.random.default_rng(1)
    hostile = hostile_sessions(certs, ep)
    with (
        open_session(client(certs, "client-viewer", ep)) as viewer,
        open_session(client(certs, "sensor-R1", ep)) as sensor,
        open_session(hostile["listed sensor R2"]) as r2,
        open_session(hostile["unlisted client"]) as evil,
        open_session(hostile["plain TCP peer"]) as plain,
    ):
        feed = Inbox()
        feed.subscribe(viewer, keys.fusion_tracks("main"), "tracks")
        feed.subscribe(viewer, keys.fusion_status("main"), "status")
        spies = {}
        for name, s in (("listed sensor R2", r2), ("unlisted client", evil), ("plain", plain)):
            spies[name] = Inbox()
            for expr in (f"{keys.PREFIX}/fusion/**", f"{keys.PREFIX}/radar/**"):
                spies[name].subscribe(s, expr, "spy", remote_only=True)
        # wait for the fusion service through the authorised client's view of its status
        assert drain_until(feed, lambda i: i.tag == "status", timeout=20.0)
        declare_publisher(sensor, keys.radar_site("R1")).put(site(45.0).to_json_bytes())
        good = declare_publisher(sensor, keys.radar_plots("R1"))
        attack_keys = (keys.radar_plots("R1"), keys.radar_site("R1"), keys.fusion_tracks("main"))
        attacks = [[declare_publisher(s, k) for k in attack_keys] for s in (r2, evil, plain)]
        time.sleep(0.3)
        real, seen = None, []
        for k in range(8):
            good.put(batch(k, rng))
            for plots, sites, tracks in attacks:
                plots.put(batch(100 + k, rng))  # ghost plots under R1's id
                sites.put(site(45.5).to_json_bytes())  # moves R1 by 55 km
                if real is not None:
                    tracks.put(real.model_copy(update={"cycle": 424242}).to_json_bytes())
            time.sleep(0.15)
            for item in feed.drain():
                if item.tag == "tracks":
                    real = TrackBatch.from_json_bytes(item.payload)
                    seen.append(real)
        got = drain_until(
            feed,
            lambda i: (
                i.tag == "status"
                and Status.from_json_bytes(i.payload).counters.get("cycles", 0) >= 8
            ),
        )
        st = Status.from_json_bytes(got[-1].payload)
        time.sleep(0.5)
        late = feed.drain()
        seen += [TrackBatch.from_json_bytes(i.payload) for i in got + late if i.tag == "tracks"]
        leaked = {name: len(inbox.drain()) for name, inbox in spies.items()}
        for inbox in (feed, *spies.values()):
            inbox.close()
        snap_ok = tracks_snapshot(certs, "client-viewer", ep)
        snap_r2 = tracks_snapshot(certs, "sensor-R2", ep)
    # the authorised sensor is tracked, nothing else came in
    assert st.counters["cycles"] == 8 and st.counters["batches_in"] == 8
    assert st.counters["sites"] == 1  # the moved site never arrived
    (r1,) = st.radars
    assert r1.batches == 8 and r1.plots == 32
    assert not st.rejected  # hostile input was not even delivered
    # the authorised client reads the feed; no fake track batch reached it
    # (a delta may carry several batches when two are released together: its cycle counts
    # deltas, its ``batches`` the plot batches it applied)
    deltas = [t for t in seen if t.kind is FeedKind.DELTA]
    assert real is not None and sum(t.batches for t in deltas) == 8
    assert [t.cycle for t in deltas] == list(range(1, len(deltas) + 1))
    assert all(t.cycle <= len(deltas) for t in seen)  # no forged batch (cycle 424242)
    assert snap_ok.returncode == 0
    snap = json.loads(snap_ok.stdout.decode().splitlines()[0])
    assert snap["topic"] == keys.fusion_snapshot("main")
    assert snap["message"]["cycle"] == deltas[-1].cycle
    # no hostile peer read anything: neither tracks, nor status, nor plots
    assert leaked == {"listed sensor R2": 0, "unlisted client": 0, "plain": 0}
    assert snap_r2.returncode == 1  # the snapshot query is denied too
