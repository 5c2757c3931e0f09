"""ASTERIX in the network services, as real processes on loopback:

* ``skyfuse sensor --asterix`` publishes every radar of the public 7-radar sample (sites
  message + liveliness per radar, the batches ``read_asterix`` gives, in time order);
* ``skyfuse sensor --asterix-udp`` decodes a live UDP stream sent to 127.0.0.1 and
  publishes the same batches as the offline stream decoder;
* ``skyfuse fusion --cat062-udp`` and the ``skyfuse cat062`` bridge send the fused feed as
  CAT062 that decodes back to the published tracks.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import signal
import socket
import threading
import time
from collections import Counter
from pathlib import Path

import pytest
from service_support import SHARED_DATA, peer, skyfuse, stop, wait_for
from skyfuse.schemas import PlotBatch, RadarSite, TrackBatch, keys
from skyfuse.services.asterix import AsterixStreamDecoder, decode_cat062, load_sites, read_asterix
from skyfuse.services.asterix.pcap import iter_file_datagrams
from skyfuse.services.runtime.transport import (
    Inbox,
    declare_liveliness,
    free_port,
    loopback_endpoint,
    open_session,
    service_alive_key,
    wait_for_tokens,
)

pytestmark = pytest.mark.service

SAMPLE = SHARED_DATA / "cat_034_048.pcap"

# Positions invented for the tests (the sample gives only 25-12's, in CAT034 I120).
SAMPLE_SITES = """
[[radar]]
sac = 25
sic = 11
lat = 45.74
lon = 16.07
alt = 120.0
[[radar]]
sac = 25
sic = 13
lat = 43.54
lon = 16.30
alt = 100.0
[[radar]]
sac = 25
sic = 14
lat = 42.56
lon = 18.27
alt = 150.0
[[radar]]
sac = 25
sic = 201
lat = 45.40
lon = 14.40
alt = 500.0
[[radar]]
sac = 25
sic = 204
lat = 44.10
lon = 15.35
alt = 90.0
[[radar]]
sac = 25
sic = 205
lat = 45.46
lon = 18.81
alt = 110.0
"""


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def udp_receiver() -> tuple[socket.socket, int]:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(0.05)
    return s, s.getsockname()[1]


def _no_epoch(b: PlotBatch) -> PlotBatch:
    """The batch as the decoder gives it (the sensor adds its numbering's epoch)."""
    return b.model_copy(update={"epoch": 0})


def drain_udp(s: socket.socket) -> list[bytes]:
    out = []
    while True:
        try:
            out.append(s.recv(65_535))
        except TimeoutError:
            return out


def simulated_pcap(tmp_path: Path, scenario: str, duration: float, params: str = "") -> Path:
    from skyfuse.services.cli.cmd_simulate import SimulateConfig, simulate_to_asterix

    out = tmp_path / f"{scenario}.pcap"
    cfg = SimulateConfig(
        scenario=scenario,
        duration=duration,
        seed=3,
        format="asterix",
        out=out,
        param=[p for p in params.split(",") if p],
    )
    simulate_to_asterix(cfg)
    return out


def test_sensor_asterix_publishes_all_seven_radars_of_the_sample(tmp_path):
    if not SAMPLE.is_file():
        pytest.skip(f"{SAMPLE} is absent")
    sites_path = tmp_path / "sites.toml"
    sites_path.write_text(SAMPLE_SITES)
    expected = read_asterix(SAMPLE, sites=load_sites(sites_path))
    assert len(expected.radars) == 7
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.ALL_PLOTS, "plots")
        inbox.subscribe(s, keys.ALL_SITES, "site")
        inbox.subscribe_liveliness(s, keys.ALL_ALIVE, "alive")
        token = declare_liveliness(s, service_alive_key("test-listener"))
        proc = skyfuse(
            "sensor", "--asterix", str(SAMPLE), "--sites", str(sites_path), "--speed", "4",
            "--connect", ep, "--wait-for", "test-listener", "--linger", "0.3",
            log_path=tmp_path / "sensor.log",
        )  # fmt: skip
        try:
            rc = proc.wait(timeout=30)
        finally:
            stop(proc)
        time.sleep(0.2)
        items = inbox.drain()
        inbox.close()
        token.undeclare()
    log = (tmp_path / "sensor.log").read_text()
    assert rc == 0, log
    plots = [PlotBatch.from_json_bytes(i.payload) for i in items if i.tag == "plots"]
    sites = {RadarSite.from_json_bytes(i.payload).radar_id for i in items if i.tag == "site"}
    alive = {i.key for i in items if i.tag == "alive" and i.put}
    radars = sorted(expected.radars)
    assert sites == set(radars)  # six from the file, 25-12 from its CAT034 I120
    assert alive == {keys.radar_alive(r) for r in radars}
    assert {b.radar_id for b in plots} == set(radars)
    assert len({b.epoch for b in plots}) == 1 and plots[0].epoch > 0  # the file's epoch
    assert [_no_epoch(b) for b in plots] == expected.batches  # the same batches, in order
    assert sum(len(b) for b in plots) == 63
    # paced by the batch times at speed 4: wall stamps follow (time_end - t0) / 4
    stamps = [i.sent_ns for i in items if i.tag == "plots"]
    span = (plots[-1].time_end - plots[0].time_end) / 4
    assert abs((stamps[-1] - stamps[0]) - span) < 20e6


def test_sensor_asterix_udp_live_stream(tmp_path):
    pcap = simulated_pcap(tmp_path, "regional", 24.0, "radars=3")
    sites_path = Path(str(pcap) + ".sites.toml")
    datagrams = [d.payload for d in iter_file_datagrams(pcap, Counter())]
    first_batch = read_asterix(pcap, sites=load_sites(sites_path)).batches[0]
    date = dt.datetime.fromtimestamp(first_batch.time_start / 1e9, dt.UTC).date()
    ref = AsterixStreamDecoder(date=date, sites=load_sites(sites_path))
    expected = [b for d in datagrams for b in ref.feed(d, time.time_ns())] + ref.flush()
    port = free_udp_port()
    ep = loopback_endpoint(free_port())
    with open_session(peer(listen=ep)) as s:
        inbox = Inbox()
        inbox.subscribe(s, keys.ALL_PLOTS, "plots")
        inbox.subscribe(s, keys.ALL_SITES, "site")
        proc = skyfuse(
            "sensor", "--asterix-udp", f"127.0.0.1:{port}", "--sites", str(sites_path),
            "--date", date.isoformat(), "--connect", ep, log_path=tmp_path / "udp.log",
        )  # fmt: skip
        try:
            assert wait_for_tokens(s, [service_alive_key("sensor-asterix-udp")], 20.0) == []
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
                for i, d in enumerate(datagrams):
                    tx.sendto(d, ("127.0.0.1", port))
                    if i % 20 == 19:
                        time.sleep(0.002)
            n_live = len(expected) - len(ref.radars)  # all but the sectors left open
            got: list = []

            def enough() -> bool:
                got.extend(inbox.drain())
                return sum(g.tag == "plots" for g in got) >= n_live

            assert wait_for(enough, 15.0)
            rc, took = stop(proc, signal.SIGINT)  # flushes the open sectors
            time.sleep(0.3)
            got.extend(inbox.drain())
        finally:
            stop(proc)
        inbox.close()
    assert rc == 0 and took < 5.0, (tmp_path / "udp.log").read_text()
    batches = [PlotBatch.from_json_bytes(g.payload) for g in got if g.tag == "plots"]
    sites = {RadarSite.from_json_bytes(g.payload).radar_id for g in got if g.tag == "site"}
    assert sites == {"0-1", "0-2", "0-3"}
    key = lambda b: (b.radar_id, b.seq)  # noqa: E731
    assert len({b.epoch for b in batches}) == 1 and batches[0].epoch > 0  # announced
    assert sorted(map(_no_epoch, batches), key=key) == sorted(expected, key=key)
    assert sum(len(b) for b in batches) > 200
    # the live order of each radar is its sector order
    for rid in sites:
        seqs = [b.seq for b in batches if b.radar_id == rid]
        assert seqs == sorted(seqs)


def _close(a: float, b: float, tol: float) -> bool:
    return abs(a - b) <= tol


def test_cat062_from_fusion_and_bridge_decode_to_the_fused_tracks(tmp_path):
    """sensor --asterix (simulated 2-D radar) → fusion --cat062-udp → UDP, and the fused
    feed → the cat062 bridge → UDP: both decode to the TrackBatches seen on Zenoh. The
    three services run in this process (threads, one Zenoh session each) to keep the
    test fast; the command-line wiring is checked in test_asterix_cli.py."""
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.cli.cmd_cat062 import Cat062Config, Cat062UdpSender, bridge
    from skyfuse.services.fusion.server import make_pipeline_factory, serve
    from skyfuse.services.fusion.service import FusionConfig, FusionCore
    from skyfuse.services.sensors.asterix_file import AsterixRecordingSensor
    from skyfuse.services.sensors.config import SensorServiceConfig

    pcap = simulated_pcap(tmp_path, "crossing-4g", 80.0)
    sites_path = Path(str(pcap) + ".sites.toml")
    rx_fusion, port_fusion = udp_receiver()
    rx_bridge, port_bridge = udp_receiver()
    ep = loopback_endpoint(free_port())
    halt = threading.Event()
    fusion_out = Cat062UdpSender(f"127.0.0.1:{port_fusion}", sac=25, sic=100)
    bridge_cfg = Cat062Config(udp=f"127.0.0.1:{port_bridge}", sac=25, sic=101)
    bridge_out = Cat062UdpSender(bridge_cfg.udp, sac=25, sic=101)
    core = FusionCore(
        FusionConfig(reorder_wait=0.05), make_pipeline_factory(TrackerConfig(), "main")
    )
    with (
        open_session(peer(listen=ep)) as s_fusion,
        open_session(peer(connect=ep)) as s_bridge,
        open_session(peer(connect=ep)) as s_sensor,
    ):
        inbox = Inbox()
        inbox.subscribe(s_sensor, keys.fusion_tracks("main"), "tracks")
        threads = [
            threading.Thread(
                target=serve, args=(s_fusion, core, halt), kwargs={"cat062": fusion_out}
            ),
            threading.Thread(target=bridge, args=(s_bridge, bridge_out, bridge_cfg, halt)),
        ]
        for t in threads:
            t.start()
        try:
            assert (
                wait_for_tokens(
                    s_sensor, [service_alive_key("fusion"), service_alive_key("cat062-main")], 10.0
                )
                == []
            )
            cfg = SensorServiceConfig(asterix=pcap, sites=sites_path, speed=40.0)
            sensor = AsterixRecordingSensor(s_sensor, cfg)
            try:
                sensor.run(threading.Event())
            finally:
                sensor.close()
            n_batches = len(sensor.batches)
            seen: list = []

            def all_tracks_in() -> bool:  # the deltas say how many batches they apply
                seen.extend(inbox.drain())
                return sum(json.loads(i.payload)["batches"] for i in seen) >= n_batches

            assert wait_for(all_tracks_in, 10.0), (len(seen), n_batches)
            time.sleep(0.3)
        finally:
            halt.set()
            for t in threads:
                t.join(10)
            inbox.close()
    assert not any(t.is_alive() for t in threads)
    fused = [TrackBatch.from_json_bytes(i.payload) for i in seen]
    published = [(b, t) for b in fused for t in b.tracks]
    assert len(published) > 20  # both targets confirmed for most of the run
    for rx, sac, sic in ((rx_fusion, 25, 100), (rx_bridge, 25, 101)):
        stats: Counter = Counter()
        decoded = [t for d in drain_udp(rx) for t in decode_cat062(d, stats)]
        rx.close()
        assert not any("malformed" in k for k in stats), stats
        updates = [t for t in decoded if not t.last]
        assert len(updates) == len(published)
        first_seen = set()
        for (_batch, tr), c in zip(published, updates, strict=True):
            assert (c.sac, c.sic, c.track_number) == (sac, sic, tr.track_id)
            assert _close(c.tod, (tr.time / 1e9) % 86_400, 1 / 128)
            assert _close(c.lat, tr.lat, 180 / 2**25) and _close(c.lon, tr.lon, 180 / 2**25)
            assert _close(c.vx, tr.vel_east, 0.125) and _close(c.vy, tr.vel_north, 0.125)
            assert c.first == (tr.track_id not in first_seen)
            first_seen.add(tr.track_id)
            assert c.confirmed and c.mono
            # I500 σx from the covariance (x east, stereographic frame)
            sx = math.sqrt(tr.covariance[0][0])
            assert _close(c.sigma_x, min(sx, 32767.5), 0.25)


def test_cat062_command_line(tmp_path):
    """``skyfuse cat062 --udp … --count 2`` (run in a thread: the same code as the
    process, without its start-up time) forwards two published TrackBatches; bad
    addresses are configuration errors (exit 2) for the bridge and for the fusion flag."""
    from skyfuse.services.cli.main import main

    site_ll = {"lat": 45.0, "lon": 20.0}
    t0 = 1_767_226_200 * 10**9
    batches = [
        TrackBatch(
            fusion_id="main",
            cycle=k,
            time=t0 + k * 10**9,
            frame={"kind": "stereographic", "lat0": 45.0, "lon0": 20.0},
            state_labels=["x", "vx", "y", "vy"],
            tracks=[
                {
                    "track_id": 70000 + k,  # beyond 16 bits: I040 carries it mod 65536
                    "time": t0 + k * 10**9,
                    "status": "confirmed",
                    "existence": 0.99,
                    "state": [0.0, 50.0, 0.0, -20.0],
                    "covariance": [
                        [100.0, 0, 0, 0],
                        [0, 4.0, 0, 0],
                        [0, 0, 100.0, 0],
                        [0, 0, 0, 4.0],
                    ],
                    **site_ll,
                    "alt": 9144.0,
                    "vel_east": 50.0,
                    "vel_north": -20.0,
                    "speed": math.hypot(50, 20),
                    "heading": 1.95,
                    "radars": ["a", "b"],
                }
            ],
        )
        for k in (1, 2)
    ]
    rx, port = udp_receiver()
    ep = loopback_endpoint(free_port())
    result: dict = {}
    argv = ["cat062", "--udp", f"127.0.0.1:{port}", "--sac", "3", "--sic", "4", "--count", "2"]
    with open_session(peer(listen=ep)) as s:
        worker = threading.Thread(
            target=lambda: result.setdefault("rc", main([*argv, "--connect", ep]))
        )
        worker.start()
        try:
            assert wait_for_tokens(s, [service_alive_key("cat062-main")], 10.0) == []
            pub = s.declare_publisher(keys.fusion_tracks("main"))
            for b in batches:
                pub.put(b.to_json_bytes())
            worker.join(10)
        finally:
            if worker.is_alive():
                worker.join(5)
    assert result.get("rc") == 0
    got = [t for d in drain_udp(rx) for t in decode_cat062(d)]
    rx.close()
    assert [(c.sac, c.sic, c.track_number) for c in got] == [
        (3, 4, 70001 - 65536),
        (3, 4, 70002 - 65536),
    ]
    assert all(c.flight_level == pytest.approx(300.0, abs=0.125) for c in got)
    assert all(not c.mono and c.confirmed for c in got)
    assert main(["cat062", "--udp", "no-port"]) == 2
    assert main(["fusion", "--cat062-udp", "no-port"]) == 2
